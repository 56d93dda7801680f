"""`tdem calibrate`: the Haddad C_t from one steady flux test (002, eq. 8-9).

- Simple-cubic lattice of n_x x n_y x n_z touching spheres (pitch s), faces x held: the n_y n_z
  columns are chains of n_x - 1 equal conductances H = lambda C_t pi (s/2)^2 / s, so
  Q = n_y n_z H dT / (n_x - 1) and lambda_e = Q L / (A dT) in closed form; the calibrated
  C_t = C_t lambda / lambda_e follows, all to round-off (1e-12).
- On a YADE-made dump, a second steady solve with the calibrated C_t gives lambda_e = lambda to
  1e-9 (linearity: the calibration needs no iteration).
"""
import dataclasses
import math
import subprocess
import sys
from pathlib import Path

import pytest

from thermal_kernel.calibrate import calibrate_axes, calibrate_ct, cross_section
from thermal_kernel.lattice import simple_cubic_packing
from thermal_kernel.laws import LAWS
from thermal_kernel.packing import PackingError, read_packing, write_packing
from thermal_kernel.scene import SceneError, load_scene

# `make coverage` counts this module (marker kernel: its subject is thermal_kernel, and it is
# fast enough with NUMBA_DISABLE_JIT=1)
pytestmark = pytest.mark.kernel

DATA = Path(__file__).resolve().parent / "data"
SCENE = '''packing = "{packing}"
law = "{law}"
[law_params]
{params}
[material]
conductivity = 33.0
density = 7800.0
heat_capacity = 460.0
[initial]
temperature = 300.0
[solver]
method = "steady"
'''


def scene_file(tmp_path, packing, law="haddad", params="ct = 0.806"):
    path = tmp_path / "scene.toml"
    path.write_text(SCENE.format(packing=packing, law=law, params=params if law == "haddad"
                                 else ""))
    return path


@pytest.mark.parametrize("shape", [(6, 4, 4), (3, 5, 7)])
def test_simple_cubic_lattice_closed_form(tmp_path, shape):
    spacing = 2e-3
    write_packing(tmp_path / "sc.h5", simple_cubic_packing(shape, spacing_m=spacing))
    packing = read_packing(tmp_path / "sc.h5")
    scene = load_scene(scene_file(tmp_path, tmp_path / "sc.h5"), known_laws=LAWS)
    nx, ny, nz = shape
    ext = packing.domain_hi - packing.domain_lo
    r = calibrate_ct(scene, packing, "x", t_hot=310.0, t_cold=300.0)
    h = 33.0 * 0.806 * math.pi * (spacing / 2) ** 2 / spacing          # 002, eq. 1-7
    q = ny * nz * h * 10.0 / (nx - 1)
    assert r.n_hot == ny * nz and r.n_cold == ny * nz
    assert r.heat_flow_w == pytest.approx(q, rel=1e-12)
    assert r.effective_w_mk == pytest.approx(q * ext[0] / (ext[1] * ext[2] * 10.0), rel=1e-12)
    assert r.ct == pytest.approx(0.806 * 33.0 / r.effective_w_mk, rel=1e-12)
    assert r.balance < 1e-12


@pytest.mark.parametrize("dump, axis", [("dense_box.h5", "y"), ("dense_cylinder.h5", "z")])
def test_calibrated_ct_reproduces_the_conductivity_on_a_yade_dump(tmp_path, dump, axis):
    packing = read_packing(DATA / dump)
    scene = load_scene(scene_file(tmp_path, DATA / dump), known_laws=LAWS)
    first = calibrate_ct(scene, packing, axis)
    if axis == "z":     # cylinder along z: the cross-section is the circle, not the box face
        assert first.area_m2 == pytest.approx(math.pi * packing.wall_radius[
            packing.wall_name.index("cylinder")] ** 2, rel=1e-12)
    assert 0.3 < first.ct < 1.5
    assert first.balance < 1e-9
    again = calibrate_ct(dataclasses.replace(scene, law_params={"ct": first.ct}), packing, axis)
    assert again.effective_w_mk == pytest.approx(33.0, rel=1e-9)
    assert again.ct == pytest.approx(first.ct, rel=1e-9)


def test_periodic_axis_is_refused(tmp_path):
    scene = load_scene(scene_file(tmp_path, DATA / "dense_periodic.h5"), known_laws=LAWS)
    with pytest.raises(SceneError, match="periodic along x"):
        calibrate_ct(scene, read_packing(DATA / "dense_periodic.h5"), "x")


# slow: `tdem calibrate` in a subprocess;
# over ~1.3 s on the shared 2-core machine, warm numba cache (--durations, 2026-12-01)
@pytest.mark.slow
def test_wrong_law_and_cli(tmp_path):
    path = scene_file(tmp_path, DATA / "dense_box.h5", law="terreros")
    with pytest.raises(SceneError, match="law: tdem calibrate calibrates the haddad"):
        calibrate_ct(load_scene(path, known_laws=LAWS), read_packing(DATA / "dense_box.h5"))
    proc = subprocess.run([sys.executable, "-m", "tdem.cli", "calibrate", str(path)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert "Traceback" not in proc.stderr and "law" in proc.stderr
    good = scene_file(tmp_path, DATA / "dense_box.h5")
    proc = subprocess.run([sys.executable, "-m", "tdem.cli", "calibrate", str(good),
                           "--axis", "x"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    ct = float(proc.stdout.strip().splitlines()[-1].split("=")[1])
    expected = calibrate_ct(load_scene(good, known_laws=LAWS),
                            read_packing(DATA / "dense_box.h5"), "x").ct
    assert ct == pytest.approx(expected, abs=1e-6)


# ---- cross-sections that are not a box face (issue 16, sec. 1): refused, never the bounding box

def _cli(*args):
    return subprocess.run([sys.executable, "-m", "tdem.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize("dump", ["dense_cylinder.h5", "bed_small_4.05e+07Pa.h5"])
@pytest.mark.parametrize("axis", ["x", "y"])
def test_axis_across_a_cylinder_is_refused(tmp_path, dump, axis):
    packing = read_packing(DATA / dump)
    path = scene_file(tmp_path, DATA / dump)
    with pytest.raises(SceneError) as info:
        calibrate_ct(load_scene(path, known_laws=LAWS), packing, axis)
    text = str(info.value)
    assert text.startswith(f"{path}: --axis: ") and "\n" not in text
    assert "'cylinder' is a cylinder along z" in text and "axes with one: z" in text
    with pytest.raises(PackingError) as info:
        cross_section(packing, "xyz".index(axis))
    assert str(info.value).startswith(f"{DATA / dump}: walls: no cross-section area normal to "
                                      f"{axis}: ")
    proc = _cli("calibrate", path, "--axis", axis)
    assert proc.returncode == 2 and proc.stdout == ""
    assert "Traceback" not in proc.stderr and proc.stderr.count("\n") == 1
    assert str(path) in proc.stderr and "--axis" in proc.stderr and "expected a box face" in \
        proc.stderr


def test_sphere_container_is_refused_on_every_axis(tmp_path):
    packing = read_packing(DATA / "dense_sphere.h5")
    path = scene_file(tmp_path, DATA / "dense_sphere.h5")
    scene = load_scene(path, known_laws=LAWS)
    for axis in "xyz":
        with pytest.raises(SceneError, match="'surface' is a sphere"):
            calibrate_ct(scene, packing, axis)
    with pytest.raises(SceneError, match="no axis with a flux test"):
        calibrate_axes(scene, packing, "all")
    proc = _cli("calibrate", path)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert "x, y, z: wall 'surface' is a sphere" in proc.stderr


def test_all_axes_on_a_cylinder_calibrates_only_along_it(tmp_path):
    packing = read_packing(DATA / "dense_cylinder.h5")
    path = scene_file(tmp_path, DATA / "dense_cylinder.h5")
    scene = load_scene(path, known_laws=LAWS)
    results, skipped, ct = calibrate_axes(scene, packing, "all")
    assert [r.axis for r in results] == ["z"] and sorted(skipped) == ["x", "y"]
    along = calibrate_ct(scene, packing, "z")
    assert ct == along.ct
    proc = _cli("calibrate", path)
    assert proc.returncode == 0, proc.stderr
    assert "axis x: skipped" in proc.stdout and "axis y: skipped" in proc.stdout
    assert float(proc.stdout.strip().splitlines()[-1].split("=")[1]) == pytest.approx(along.ct,
                                                                                     abs=1e-6)


def test_all_axes_of_a_box_are_averaged(tmp_path):
    packing = read_packing(DATA / "dense_box.h5")
    scene = load_scene(scene_file(tmp_path, DATA / "dense_box.h5"), known_laws=LAWS)
    results, skipped, ct = calibrate_axes(scene, packing, "all")
    assert [r.axis for r in results] == ["x", "y", "z"] and skipped == {}
    assert ct == pytest.approx(sum(calibrate_ct(scene, packing, a).ct for a in "xyz") / 3,
                               rel=1e-12)


def test_periodic_cell_has_no_axis(tmp_path):
    scene = load_scene(scene_file(tmp_path, DATA / "dense_periodic.h5"), known_laws=LAWS)
    with pytest.raises(SceneError, match="x, y, z: periodic"):
        calibrate_axes(scene, read_packing(DATA / "dense_periodic.h5"), "all")


def test_flux_test_keeps_its_conductances_and_field(tmp_path):
    """FluxTest.conductance_w_k is the law's conductance per dumped row of the solve and
    effective.temperature_k its field (validation case 5 reads the test's interior from them):
    the heat entering the hot face's particles through their contacts is the test's Q."""
    import numpy as np

    from thermal_kernel.calibrate import flux_test
    from thermal_kernel.problem import boundary_particles
    packing = read_packing(DATA / "dense_box.h5")
    scene = load_scene(scene_file(tmp_path, DATA / "dense_box.h5"), known_laws=LAWS)
    test = flux_test(scene, packing, "x")
    h, temp = test.conductance_w_k, test.effective.temperature_k
    assert h.shape == (packing.n_contacts,) and temp.shape == (packing.n_particles,)
    hot = np.zeros(packing.n_particles, bool)
    hot[boundary_particles(dataclasses.replace(scene, boundaries=()), packing, "xmin", "b")] = 1
    i, j = packing.pair[:, 0], packing.pair[:, 1]
    flow = h * (temp[i] - temp[j])                           # from i to j
    q = flow[hot[i] & ~hot[j]].sum() - flow[hot[j] & ~hot[i]].sum()
    assert q == pytest.approx(test.heat_flow_w, rel=1e-9)
