"""The `liggghts` law (LIGGGHTS' fix heat/gran/conduction) against closed forms written here
independently of the law's formula:

- the lens of two spheres: its radius a from the intersection circle of the two spheres
  (a^2 = r_i^2 - x^2, x = (d^2 + r_i^2 - r_j^2) / (2 d) the distance of the circle's plane from
  centre i), so H = 4 k_i k_j/(k_i + k_j) sqrt(pi) a; for equal k, 2 sqrt(pi) k a, i.e.
  sqrt(pi) x the Batchelor-O'Brien 2 k a at the same contact radius;
- area_correction: the overlap multiplied by (Y_soft/Y_real)^(2/3), then the same lens;
- the wall: the circle a plane cuts, a^2 = r^2 - (r - delta)^2;
- the scene: `tdem laws` lists it, bad parameters are one line and exit 2.
Tolerances: 1e-12 relative (a few roundings of the same double-precision numbers; the law's
product form and the circle form differ by cancellation of order eps r/delta ~ 1e-13 at the
smallest overlap used, 1e-3 of a radius); 1e-10 where area_correction shrinks the overlap to
~3e-6 of a radius.
"""
import dataclasses
import math
import subprocess
import sys

import numpy as np
import pytest

from thermal_kernel.laws import LAWS, get_law
from thermal_kernel.laws.base import ContactInput, WallContactInput

E, NU = 5e10, 0.2
TDEM = [sys.executable, "-m", "tdem.cli"]


def _contacts(r_i, r_j, d, k_i, k_j):
    a = lambda x: np.atleast_1d(np.asarray(x, dtype=float))  # noqa: E731
    r_i, r_j, d = a(r_i), a(r_j), a(d)
    k_i, k_j = np.broadcast_to(a(k_i), d.shape), np.broadcast_to(a(k_j), d.shape)
    zeros = np.zeros(d.shape)
    return ContactInput(radius_i_m=r_i, radius_j_m=r_j, distance_m=d, overlap_m=r_i + r_j - d,
                        normal_force_n=zeros, conductivity_i=k_i, conductivity_j=k_j,
                        neighbours_i=zeros, neighbours_j=zeros, young_pa=E, poisson=NU)


def _h(contacts, **params):
    law = get_law("liggghts")
    return law.conductance(contacts, {**law.defaults, **params})


def _circle_radius(r_i, r_j, d):
    """Radius of the circle where two sphere surfaces meet (plane at x from centre i)."""
    x = (d ** 2 + r_i ** 2 - r_j ** 2) / (2 * d)
    return np.sqrt(r_i ** 2 - x ** 2)


def _random_pairs(seed=3, m=200):
    rng = np.random.default_rng(seed)
    r_i = rng.uniform(0.5e-3, 1.5e-3, m)
    r_j = rng.uniform(0.5e-3, 1.5e-3, m)
    overlap = rng.uniform(1e-3, 5e-2, m) * np.minimum(r_i, r_j)
    return r_i, r_j, r_i + r_j - overlap


def test_registered_and_listed():
    assert LAWS["liggghts"].name == "liggghts"
    r = subprocess.run([*TDEM, "laws"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    line = [x for x in r.stdout.splitlines() if "liggghts" in x]
    assert line and "sqrt(A)" in r.stdout


def test_equal_conductivity_is_two_sqrt_pi_k_a():
    r_i, r_j, d = _random_pairs()
    k = 7.3
    h = _h(_contacts(r_i, r_j, d, k, k))
    a = _circle_radius(r_i, r_j, d)
    np.testing.assert_allclose(h, 2 * math.sqrt(math.pi) * k * a, rtol=1e-12)
    # sqrt(pi) x Batchelor-O'Brien (2 k a) at the same contact radius
    np.testing.assert_allclose(h / (2 * k * a), math.sqrt(math.pi), rtol=1e-12)


def test_equal_spheres_small_overlap_is_the_sqrt_r_delta_lens():
    # equal spheres: a^2 = r delta - delta^2 / 4 exactly
    r = 1e-3
    delta = np.array([1e-6, 1e-5, 1e-4])
    h = _h(_contacts(r, r, 2 * r - delta, 2.0, 2.0))
    np.testing.assert_allclose(h, 2 * math.sqrt(math.pi) * 2.0 * np.sqrt(r * delta - delta ** 2
                                                                        / 4), rtol=1e-12)


def test_unequal_conductivity_is_the_harmonic_mean():
    r_i, r_j, d = _random_pairs(seed=4)
    rng = np.random.default_rng(5)
    k_i, k_j = rng.uniform(0.1, 300, d.size), rng.uniform(0.1, 300, d.size)
    h = _h(_contacts(r_i, r_j, d, k_i, k_j))
    k_h = 2 * k_i * k_j / (k_i + k_j)
    np.testing.assert_allclose(h, 2 * math.sqrt(math.pi) * k_h * _circle_radius(r_i, r_j, d),
                               rtol=1e-12)
    # between the two equal-k values, and LIGGGHTS' SMALL: a zero conductivity gives 0
    low = _h(_contacts(r_i, r_j, d, np.minimum(k_i, k_j), np.minimum(k_i, k_j)))
    high = _h(_contacts(r_i, r_j, d, np.maximum(k_i, k_j), np.maximum(k_i, k_j)))
    assert np.all(low <= h * (1 + 1e-12)) and np.all(h <= high * (1 + 1e-12))
    assert np.all(_h(_contacts(r_i, r_j, d, 0.0, k_j)) == 0)


def test_gaps_and_nested_spheres_give_zero():
    h = _h(_contacts([1e-3, 1e-3, 1e-3, 1e-3], [1e-3, 1e-3, 0.3e-3, 1e-3],
                     [2.0e-3, 2.1e-3, 0.5e-3, 1.999e-3], 5.0, 5.0))
    assert h[0] == 0 and h[1] == 0 and h[2] == 0 and h[3] > 0


@pytest.mark.parametrize("soft,real", [(1e7, 7e10), (5e8, 5e10), (3e9, 2e9)])
def test_area_correction_scales_the_overlap(soft, real):
    r_i, r_j, d = _random_pairs(seed=6)
    k = 3.0
    ratio = (soft / real) ** (2 / 3)
    d_corr = (r_i + r_j) - (r_i + r_j - d) * ratio
    expected = 2 * math.sqrt(math.pi) * k * _circle_radius(r_i, r_j, d_corr)
    c = _contacts(r_i, r_j, d, k, k)
    # the corrected overlap goes down to ~3e-6 of a radius: both forms cancel digits,
    # eps r / delta ~ 3e-11 in A (measured 2.4e-12 in H)
    np.testing.assert_allclose(_h(c, young_softened_pa=soft, young_real_pa=real), expected,
                               rtol=1e-10)
    # young_real_pa left out: the scene's real modulus (ContactInput.young_pa)
    np.testing.assert_allclose(_h(dataclasses.replace(c, young_pa=real),
                                  young_softened_pa=soft), expected, rtol=1e-10)
    # small overlaps: A ~ pi r* delta, so H scales as sqrt(ratio)
    r = 1e-3
    tiny = _contacts(r, r, 2 * r - 1e-9, k, k)
    assert _h(tiny, young_softened_pa=soft, young_real_pa=real)[0] == pytest.approx(
        math.sqrt(ratio) * _h(tiny)[0], rel=1e-5)


def test_no_correction_by_default_and_equal_moduli_change_nothing():
    r_i, r_j, d = _random_pairs(seed=7)
    c = _contacts(r_i, r_j, d, 4.0, 9.0)
    np.testing.assert_allclose(_h(c, young_softened_pa=E, young_real_pa=E), _h(c), rtol=1e-12)


def test_wall_is_the_cap_circle():
    law = get_law("liggghts")
    rng = np.random.default_rng(8)
    r = rng.uniform(0.5e-3, 1.5e-3, 50)
    delta = rng.uniform(1e-3, 5e-2, 50) * r
    k_p, k_w = rng.uniform(1, 50, 50), rng.uniform(1, 50, 50)
    w = WallContactInput(radius_m=r, overlap_m=delta, normal_force_n=np.zeros(50),
                         conductivity_particle=k_p, conductivity_wall=k_w, young_pa=E,
                         poisson=NU)
    a = np.sqrt(2 * r * delta - delta ** 2)            # circle cut by the plane
    g = law.wall_conductance(w, dict(law.defaults))
    np.testing.assert_allclose(g, 4 * k_p * k_w / (k_p + k_w) * math.sqrt(math.pi) * a,
                               rtol=1e-12)
    ratio = (1e8 / E) ** (2 / 3)
    d2 = delta * ratio
    np.testing.assert_allclose(
        law.wall_conductance(w, {**law.defaults, "young_softened_pa": 1e8}),
        4 * k_p * k_w / (k_p + k_w) * math.sqrt(math.pi) * np.sqrt(2 * r * d2 - d2 ** 2),
        rtol=1e-12)


def _scene(tmp_path, law_params=""):
    """A 3 x 1 x 1 chain of overlapping spheres (pitch 2r - delta), phase 1 at the xmin end
    held at 400 K by a phase_temperature boundary, the rest at 300 K."""
    from thermal_kernel.lattice import simple_cubic_packing
    from thermal_kernel.packing import write_packing
    r, delta = 1e-3, 2e-6
    pk = simple_cubic_packing((3, 1, 1), 2 * r - delta, radius_m=r, young_pa=E, poisson=NU,
                              density=2500.0, phase=np.array([1, 0, 0], np.int32))
    path = tmp_path / "chain.h5"
    write_packing(path, pk)
    scene = tmp_path / "scene.toml"
    scene.write_text(f'''packing = "{path}"
law = "liggghts"
{law_params}
[material]
conductivity = 20.0
density = 2500.0
heat_capacity = 800.0
young_pa = {E!r}
poisson = {NU!r}
[initial]
temperature = 300.0
[[boundary]]
kind = "phase_temperature"
phase = 1
value = 400.0
[solver]
method = "explicit"
dt = 0.0625
end_time = 0.125
output_times = [0.0625, 0.125]
''')
    return scene, r, delta


def test_two_explicit_steps_through_tdem_run(tmp_path):
    """Two forward-Euler steps of the chain by hand (H from the circle form) against the
    pipeline (scene -> law -> phase_temperature -> explicit solver)."""
    import h5py
    from thermal_kernel.run import run_scene
    from thermal_kernel.scene import load_scene
    scene, r, delta = _scene(tmp_path)
    summary = run_scene(load_scene(scene, out_dir=tmp_path / "run"), quiet=True)
    with h5py.File(summary.output) as f:
        temps = f["temperature"][()]
    h = 2 * math.sqrt(math.pi) * 20.0 * _circle_radius(r, r, 2 * r - delta)
    c = 2500.0 * 800.0 * 4 / 3 * math.pi * r ** 3
    t = np.array([400.0, 300.0, 300.0])
    for _ in range(2):
        flow = np.array([0.0, h * (t[0] - t[1]) + h * (t[2] - t[1]), h * (t[1] - t[2])])
        t = t + 0.0625 / c * flow
    np.testing.assert_allclose(temps[-1], t, rtol=1e-12)
    assert temps[-1][1] > 300.0 and temps[-1][0] == 400.0


@pytest.mark.parametrize("params,words", [
    ("[law_params]\nyoung_softened_pa = 0", "law_params.young_softened_pa"),
    ("[law_params]\nyoung_real_pa = -1.0", "law_params.young_real_pa"),
    ("[law_params]\narea_correction = true", "law_params.area_correction"),
])
def test_bad_parameter_is_one_line_exit_2(tmp_path, params, words):
    scene, _, _ = _scene(tmp_path, params)
    r = subprocess.run([*TDEM, "run", str(scene), "--out", str(tmp_path / "run"), "--quiet"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and words in r.stderr, r.stderr
    assert str(scene) in r.stderr


# --- the phase_temperature boundary (holding a LIGGGHTS type) ---------------------------------

def _typed_chain(tmp_path, types_attr):
    """Five overlapping spheres along x, phases [1, 0, 0, 0, 2]; ``types_attr`` the packing's
    liggghts_atom_types (None: left out)."""
    from thermal_kernel.lattice import simple_cubic_packing
    from thermal_kernel.packing import write_packing
    r = 1e-3
    pk = simple_cubic_packing((5, 1, 1), 2 * r - 2e-6, radius_m=r, young_pa=E, poisson=NU,
                              density=2500.0, phase=np.array([1, 0, 0, 0, 2], np.int32))
    attrs = dict(pk.attrs)
    if types_attr is not None:
        attrs["liggghts_atom_types"] = types_attr
    path = tmp_path / "typed.h5"
    write_packing(path, dataclasses.replace(pk, attrs=attrs))
    return path


def _typed_scene(tmp_path, packing, boundaries, solver='method = "steady"'):
    scene = tmp_path / "typed.toml"
    scene.write_text(f'packing = "{packing}"\nlaw = "liggghts"\n[material]\nconductivity = 5.0\n'
                     'density = 2500.0\nheat_capacity = 800.0\n[initial]\ntemperature = 300.0\n'
                     f'{boundaries}\n[solver]\n{solver}\n')
    return scene


HELD = ('[[boundary]]\nkind = "phase_temperature"\nliggghts_type = 4\nvalue = 500.0\n'
        '[[boundary]]\nkind = "phase_temperature"\nliggghts_type = 7\nvalue = 300.0\n')


def test_liggghts_types_hold_their_phases_steady_is_linear(tmp_path):
    """Types 1, 4, 7 present -> phases 0, 1, 2: type 4 (phase 1, x = 0) at 500 K, type 7
    (phase 2, x = end) at 300 K; the chain of equal conductances is linear in steady state and
    the heat in equals the heat out, H (500 - 300) / 4."""
    import h5py
    from thermal_kernel.run import run_scene
    from thermal_kernel.scene import load_scene
    packing = _typed_chain(tmp_path, "1 4 7")
    scene = load_scene(_typed_scene(tmp_path, packing, HELD), out_dir=tmp_path / "run")
    assert [b.name for b in scene.boundaries] == ["phase_temperature:type4",
                                                  "phase_temperature:type7"]
    summary = run_scene(scene, quiet=True)
    with h5py.File(summary.output) as f:
        t = f["temperature"][-1]
        flow = f["boundary_heat_flow"][-1]
    np.testing.assert_allclose(t, [500, 450, 400, 350, 300], rtol=1e-12)
    r, delta = 1e-3, 2e-6
    h = 2 * math.sqrt(math.pi) * 5.0 * _circle_radius(r, r, 2 * r - delta)
    np.testing.assert_allclose(flow, [h * 200 / 4, -h * 200 / 4], rtol=1e-9)


@pytest.mark.parametrize("types_attr,boundary,words", [
    ("1 4 7", 'liggghts_type = 2', "boundary[0].liggghts_type: type 2 is not in"),
    (None, 'liggghts_type = 4', "has no attribute liggghts_atom_types"),
    ("1 4 7", 'phase = 5', "boundary[0].phase: no particle of phase 5"),
    ("1 4 7", 'phase = 1\nliggghts_type = 4', "exactly one of phase"),
    ("1 4 7", 'phase = 1.5', "boundary[0].phase: expected an integer >= 0"),
])
def test_phase_temperature_bad_input_one_line_exit_2(tmp_path, types_attr, boundary, words):
    packing = _typed_chain(tmp_path, types_attr)
    scene = _typed_scene(tmp_path, packing, f'[[boundary]]\nkind = "phase_temperature"\n'
                                            f'{boundary}\nvalue = 500.0\n')
    r = subprocess.run([*TDEM, "run", str(scene), "--out", str(tmp_path / "run"), "--quiet"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and words in r.stderr, r.stderr
