"""VTK export for ParaView: what goes in comes back out of the .vtu file."""
import subprocess
import sys

import meshio
import numpy as np
import pytest

from thermal_kernel.lattice import simple_cubic_packing
from thermal_kernel.packing import write_packing


def test_export_round_trips_particles_and_contacts(tmp_path):
    packing = simple_cubic_packing((3, 2, 2), spacing_m=1e-3, radius_m=0.502e-3)
    write_packing(tmp_path / "packing.h5", packing)
    proc = subprocess.run([sys.executable, "-m", "tdem.cli", "export",
                           str(tmp_path / "packing.h5")], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    mesh = meshio.read(tmp_path / "packing.vtu")
    np.testing.assert_array_equal(mesh.points, packing.position)
    np.testing.assert_array_equal(mesh.point_data["radius_m"], packing.radius)
    lines = mesh.cells_dict["line"]
    np.testing.assert_array_equal(lines, packing.pair)
    # coordination from the exported lines equals the packing's
    z = np.bincount(lines.reshape(-1), minlength=packing.n_particles)
    np.testing.assert_array_equal(mesh.point_data["coordination"], z)
    force = mesh.cell_data_dict["normal_force_n"]["line"]
    np.testing.assert_allclose(force, packing.normal_force)
    assert not list(tmp_path.glob("*.tmp*"))


# slow: `tdem run` and `tdem export` in subprocesses;
# over ~1.3 s on the shared 2-core machine, warm numba cache (--durations, 2026-12-01)
@pytest.mark.slow
def test_export_with_the_temperatures_of_a_run(tmp_path):
    """A steady run on a lattice held at 400 K (xmin) and 300 K (xmax): the exported fields are
    the run's temperatures, bit for bit; a thermal file of another packing is a one-line error."""
    import h5py
    packing = simple_cubic_packing((4, 2, 2), spacing_m=1e-3, radius_m=0.502e-3)
    write_packing(tmp_path / "packing.h5", packing)
    (tmp_path / "s.toml").write_text('''packing = "packing.h5"
law = "bob"
[material]
conductivity = 10.0
density = 1000.0
heat_capacity = 1000.0
[initial]
temperature = 350.0
[[boundary]]
kind = "temperature"
on = "xmin"
value = 400.0
[[boundary]]
kind = "temperature"
on = "xmax"
value = 300.0
[solver]
method = "steady"
''')
    run = subprocess.run([sys.executable, "-m", "tdem.cli", "run", str(tmp_path / "s.toml"),
                          "--out", str(tmp_path / "out"), "--quiet"], capture_output=True,
                         text=True)
    assert run.returncode == 0, run.stderr
    thermal = tmp_path / "out" / "thermal.h5"
    proc = subprocess.run([sys.executable, "-m", "tdem.cli", "export", str(tmp_path / "packing.h5"),
                           "--thermal", str(thermal)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    mesh = meshio.read(tmp_path / "packing.vtu")
    with h5py.File(thermal) as f:
        expected = f["temperature"][()]
    np.testing.assert_array_equal(mesh.point_data["temperature_k"], expected[-1])
    # steady between 400 K and 300 K along x: the four layers are 400, 366.7, 333.3, 300 K
    np.testing.assert_allclose(np.unique(mesh.point_data["temperature_k"].round(6)),
                               [300.0, 300 + 100 / 3, 300 + 200 / 3, 400.0], rtol=1e-9)
    other = simple_cubic_packing((3, 2, 2), spacing_m=1e-3, radius_m=0.502e-3)
    write_packing(tmp_path / "other.h5", other)
    bad = subprocess.run([sys.executable, "-m", "tdem.cli", "export", str(tmp_path / "other.h5"),
                          "--thermal", str(thermal)], capture_output=True, text=True)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1
    # refused by the content hash the run stored (before: by the temperature array's shape)
    assert "packing_sha256: not the packing" in bad.stderr and "Traceback" not in bad.stderr
    assert str(tmp_path / "packing.h5") in bad.stderr
    assert not (tmp_path / "other.vtu").exists()
