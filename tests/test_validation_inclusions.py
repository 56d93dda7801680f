"""Cases 8-10 of docs/validation.md kept honest at small N (validation/case8_inclusion.py,
case9_inclusion_points.py, case10_dispersion.py, their quick instances: the committed 400-sphere
YADE box tests/data/dense_box.h5 and the 400-sphere periodic cell tests/data/dense_periodic.h5,
no YADE run), plus the closed-form and two-method checks their references rest on.

Measured on the quick instances (2026-12-01, the bounds below add a margin of about 20 %):
- case 8: faces (400 spheres, a = 5 radii) max |k/k_Maxwell - 1| 37.08 % (c = 100); periodic
  2^3 cells (3,200) 3.69 % harmonic / 3.56 % cut against Rayleigh (c = 0.01);
- case 9: FV reference (16/24/36 grids) T 30.000 / 30.000 / 33.508 C, |q| 7769 / 2255 / 6484
  W/m^2 (002's FE: 30 / 30 / 33.5 C, 7767 / 2318 / 6424); 400 spheres: T max 3.51 %;
- case 10: f 0.1 (41 inclusions), FV reference 1.2343 +- 0.0024 on 24/36/54 grids (1.2262 +- 0.0013
  on 36/54/81); 400 spheres 1.1940, -3.3 % from it.
"""

import numpy as np
import pytest

from tdem_post.analytic import hashin_shtrikman, maxwell, rayleigh_cubic_array
from validation import case8_inclusion as case8
from validation import case9_inclusion_points as case9
from validation import case10_dispersion as case10
from validation import inclusions as I
from validation.framework import Context

F = I.SINGLE_FRACTION


def test_rayleigh_cubic_array_limits_and_maxwell():
    # equal phases, f = 0, and within 0.11 % of Maxwell at 002's fraction for any contrast
    assert rayleigh_cubic_array(1.0, 1.0, F) == pytest.approx(1.0)
    assert rayleigh_cubic_array(2.0, 7.0, 0.0) == pytest.approx(2.0, rel=1e-14)
    c = np.logspace(-3, 3, 13)
    r = rayleigh_cubic_array(1.0, c, F)
    assert np.all(np.abs(r / maxwell(1.0, c, F) - 1) < 1.2e-3)
    low, high = hashin_shtrikman(1.0, c, F)
    assert np.all((r >= low * (1 - 1e-12)) & (r <= high * (1 + 1e-12)))


def test_continuum_reference_converges_to_rayleigh():
    # the FV operator of case 9/10 on case 8's cube: harmonic cell mixing below and arithmetic
    # above the exact value at c = 5, the gap closing with refinement
    exact = float(rayleigh_cubic_array(1.0, 5.0, F))
    cen, a = I.centred_inclusion_unit()
    ks = {m: [I.continuum_field(cen, a, 5.0, n, mixing=m)[2] for n in (12, 24)]
          for m in ("arithmetic", "harmonic")}
    assert ks["harmonic"][1] < exact < ks["arithmetic"][1]
    assert ks["arithmetic"][1] - ks["harmonic"][1] < ks["arithmetic"][0] - ks["harmonic"][0]
    assert abs(0.5 * (ks["arithmetic"][1] + ks["harmonic"][1]) / exact - 1) < 0.01


def test_periodic_homogenisation_is_tiling_invariant():
    # the same periodic network copied 2^3 times has the same k_eff, along every axis
    scene, cell = I.load(case8.DATA / "dense_periodic.h5")
    k1 = [I.periodic_conductivity(cell, I.contact_conductance(scene, cell, 0 * cell.phase, 1.0),
                                  axis=a)[0] for a in range(3)]
    block = I.periodic_block(cell, 2)
    assert block.n_particles == 8 * cell.n_particles and len(block.pair) == 8 * len(cell.pair)
    k2 = I.periodic_conductivity(block, I.contact_conductance(scene, block, 0 * block.phase,
                                                              1.0))[0]
    assert k2 == pytest.approx(k1[0], rel=1e-8)
    assert max(k1) / min(k1) < 1.05           # nearly isotropic cell


def test_cut_interface_factor():
    # a contact cut at its middle keeps the harmonic mean (factor 1); s -> 1 gives l_i
    s = I.cut_fraction(np.array([[0.0, 0, 0]]), np.array([[2.0, 0, 0]]), np.zeros(3), 1.0)
    assert s[0] == pytest.approx(0.5)
    s = I.cut_fraction(np.array([[0.5, 0, 0]]), np.array([[1.5, 0, 0]]), np.zeros(3), 1.0)
    assert s[0] == pytest.approx(0.5)


# slow: a quick validation case;
# over ~1.3 s on the shared 2-core machine, warm numba cache (--durations, 2026-12-01)
@pytest.mark.slow
def test_case8_quick_within_documented_error():
    result = case8.run(Context(8, quick=True))
    n = case8.read_numbers(result.numbers)
    assert n.faces_max_error < 0.45                 # measured 37.08 % (400 spheres)
    assert n.periodic_harmonic_max_error < 0.045    # measured 3.69 % (3,200)
    assert n.periodic_cut_max_error < 0.045         # measured 3.56 %
    for r in n.runs:
        ks = [x.k for x in r.rows]
        assert all(a < b for a, b in zip(ks, ks[1:]))   # k_eff grows with the contrast
        assert ks[0] < 1 < ks[-1]
    # the periodic error falls from 1^3 to 2^3 cells at the worst contrast
    per = sorted((r for r in n.runs if r.series == "periodic_harmonic"),
                 key=lambda r: r.n)
    assert case8.max_err(per[1], "err_rayleigh") < case8.max_err(per[0], "err_rayleigh")


# slow: a quick validation case;
# over ~1.3 s on the shared 2-core machine, warm numba cache (--durations, 2026-12-01)
@pytest.mark.slow
def test_case9_quick_reference_and_error():
    result = case9.run(Context(9, quick=True))
    n = result.numbers
    t_ref, q_ref = n["reference_T_c"], n["reference_q"]
    # A and B lie on the mid-plane y = L/2: T = 30 C exactly by the antisymmetry of the problem
    assert t_ref[0] == pytest.approx(30.0, abs=1e-6) and t_ref[1] == pytest.approx(30.0, abs=1e-6)
    # our continuum reference against 002's FE (Table 2): T at C, |q| at A, B, C
    assert t_ref[2] == pytest.approx(33.5, abs=0.05)
    for q, fe in zip(q_ref, case9.PAPER["FE"]["q"]):
        assert q == pytest.approx(fe, rel=0.04)
    assert n["max_T_error"] < 0.045                    # measured 3.51 % (400 spheres)
    # both halo radii at the paper's points; the paper's point is the first of its symmetric
    # equivalents (B: four mid-face points, C: two), read from the same solve
    run = n["runs"][0]
    assert n["main_reading"] == "common_11" and {"common_11", "own_11", "raw"} <= set(run["q"])
    for key in ("common_11", "own_11"):
        assert [run["samples"][key][lab][0] for lab in "ABC"] == run["q"][key]
        assert [len(run["samples"][key][lab]) for lab in "ABC"] == [1, 4, 2]
    assert run["q"]["common_11"] != run["q"]["own_11"]


# slow: a quick validation case;
# over ~1.3 s on the shared 2-core machine, warm numba cache (--durations, 2026-12-01)
@pytest.mark.slow
def test_case10_quick_realisation_and_error():
    centres, r, method, jam, _ = case10.realisation(0.2)
    assert method == "RSA" and len(centres) == 83 and r == case10.RADIUS   # 002: 83 at 20 %
    d = np.linalg.norm(centres[:, None] - centres[None], axis=2) + np.eye(len(centres))
    assert d.min() >= 2 * r * (1 + case10.GAP) - 1e-12
    assert np.all(centres >= r) and np.all(centres <= 1 - r)
    result = case10.run(Context(10, quick=True))
    n = result.numbers
    for _f, rl in n["realisations"].items():
        low, high = hashin_shtrikman(1.0, case10.CONTRAST, rl["f"])
        assert low <= rl["ref"] <= high                  # the FFT reference inside the bounds
        # the quick grids' (16-32^3) extrapolation against the full run's (48-128^3): 1.2285
        assert rl["ref"] == pytest.approx(1.2285, rel=0.003)
        assert abs(rl["ref"] - 1.2285) <= 2 * rl["ref_unc"]
    assert n["max_error_vs_ref"] < 0.045               # measured 2.95 % (400 spheres)


def test_case9_caches_through_the_framework(tmp_path):
    """Case 9's cache is framework.cached (one cache for every case): the record comes back
    without its version key, made once, and made again when its version changes."""
    import json
    calls = []

    def make():
        calls.append(1)
        return {"n": 5}
    path = tmp_path / "points.json"
    assert case9._cached(path, make) == {"n": 5}
    assert json.loads(path.read_text()) == {"n": 5, "version": case9.VERSION}
    assert case9._cached(path, make) == {"n": 5} and len(calls) == 1
    assert case9._cached(path, make, version=case9.VERSION + 1) == {"n": 5}
    assert len(calls) == 2


def test_case9_runs_are_records():
    """Case 9's saved cubes read back as PointsRun records and write back to the same data; a
    cube without its errors against 002's FE is refused in one line."""
    import json

    from tdem_post.records import RecordError, to_dict
    from validation import framework
    numbers = framework.load_result(9)["result"]["numbers"]
    runs = case9.read_runs(numbers["runs"])
    assert json.dumps([to_dict(r) for r in runs]) == json.dumps(numbers["runs"])
    bad = json.loads(json.dumps(numbers["runs"][1]))
    del bad["err_q_fe"]
    with pytest.raises(RecordError, match=r"runs\[0\]: err_q_fe: missing"):
        case9.read_runs([bad])


def test_case8_quotes_rayleigh_against_maxwell_computed():
    """Case 8's section says how far Rayleigh's array is from Maxwell's value by computing it
    (the bound over its contrasts rounded up, the extremes signed), and the saved section
    says the same."""
    from tdem_post.analytic import maxwell, rayleigh_cubic_array
    from validation import case8_inclusion as c8
    from validation import framework
    d = [rayleigh_cubic_array(1, c, c8.F) / maxwell(1, c, c8.F) - 1 for c in c8.CONTRASTS]
    text = c8._rayleigh_vs_maxwell()
    assert max(abs(x) for x in d) <= float(text.split()[1]) / 100 < max(abs(x) for x in d) + 1e-4
    assert text in framework.load_result(8)["result"]["section_md"]


def test_case9_quotes_case7s_cov_from_its_record():
    """Case 9's words on the halo's scatter quote case 7's CoV at ratio 11 from case 7's saved
    result (common and own halo radius), as its saved section says."""
    from validation import case7_halo, case9_inclusion_points as c9
    from validation import framework
    cov = case7_halo.cov_at(framework.load_result(7)["result"]["numbers"])
    assert set(cov) == {"common", "own"} and 0 < min(cov.values()) < max(cov.values()) < 0.05
    text = c9._case7_cov()
    assert text == f"≈ {100 * min(cov.values()):.1f}–{100 * max(cov.values()):.1f} %"
    assert f"case 7's CoV ({text} at ratio 11" in framework.load_result(9)["result"]["section_md"]
    numbers7 = framework.load_result(7)["result"]["numbers"]
    assert case7_halo.cov_at(dict(numbers7, records=[])) == {} == case7_halo.cov_at({})


def test_amg_solve_gives_the_same_bits_and_leaves_the_callers_generator():
    # pyamg starts its smoother's spectral-radius estimate at numpy's global random generator:
    # unseeded, two solves of the same system differed at the tolerance (case 9's reference in
    # the 10th digit). A 3-D Laplacian of 729 unknowns (two levels at max_coarse 500; unseeded,
    # its solves differ):
    # two solves with the global generator moved in between give the same bits, and the
    # caller's generator is where it was.
    import scipy.sparse as sp
    n = 9
    lap1 = sp.diags([-np.ones(n - 1), 2.0 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1])
    eye = sp.identity(n)
    a = (sp.kron(sp.kron(lap1, eye), eye) + sp.kron(sp.kron(eye, lap1), eye)
         + sp.kron(sp.kron(eye, eye), lap1)).tocsr()
    rhs = np.linspace(-1.0, 2.0, a.shape[0])
    np.random.seed(7)
    first = I.amg_solve(a, rhs, 1e-10)
    after = np.random.get_state()[1].copy()
    np.random.rand(10)
    second = I.amg_solve(a, rhs, 1e-10)
    assert np.array_equal(first, second)
    assert np.linalg.norm(a @ first - rhs) <= 1e-8 * np.linalg.norm(rhs)
    np.random.seed(7)
    assert np.array_equal(np.random.get_state()[1], after)


@pytest.mark.slow       # ~25 s: ten FV solves of the inclusion cube
def test_continuum_reference_is_reproducible():
    # case 9's reference values (T and |q| at A, B, C) from two runs with the global generator
    # moved in between: the same numbers (they moved in the 10th digit before amg_solve)
    centres, radius = I.centred_inclusion_unit()
    first = I.continuum_field(centres, radius, 5.0, 14)
    np.random.rand(10)
    second = I.continuum_field(centres, radius, 5.0, 14)
    assert np.array_equal(first[1], second[1]) and first[2] == second[2]
    ref_a, _ = case9.continuum_points((12, 14))
    np.random.rand(3)
    assert case9.continuum_points((12, 14))[0] == ref_a
