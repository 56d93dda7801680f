"""VTK export for ParaView: what goes in comes back out of the .vtu file."""
import subprocess
import sys

import meshio
import numpy as np

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
