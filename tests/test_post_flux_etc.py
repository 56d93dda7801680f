"""Heat flux per particle and Halo smoothing (002 eq. 20, 22-23); ETC estimates and bounds.

- Uniform gradient on a simple-cubic lattice: the flux of every particle whose halo lies in the
  lattice's interior is exactly -k_lattice grad T (k_lattice = H / s), for halo ratios 0, 2, 5
  and both halo radii ("common": ratio x the mean radius, "own": ratio x R_p): zero coefficient
  of variation (to round-off);
- the halo of an interior particle of a polydisperse cloud holds exactly the particles a
  brute-force distance search finds (common and own radius, which differ for a large sphere), and
  its Halo flux is eq. 22-23 summed by hand over that set;
- the volume-weighted CoV is the hand-computed weighted std / mean; a wrong halo_radius is refused
  with a one-line message (the flux functions and `tdem post`'s analyse);
- on a YADE dense box at steady state (haddad law, faces held), the CoV of |q| falls as the halo
  grows (002 Fig. 10), and the halo-smoothed mean flux equals Q / A within 10 %;
- Maxwell / Hashin-Shtrikman / Bruggeman: limits f = 0 and 1, the ordering HS_lower <= Bruggeman
  <= HS_upper, Maxwell = the HS bound on the matrix side; Zehner-Schluender = k_f when the solid
  equals the fluid.
"""
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from tdem_post.etc import bruggeman, hashin_shtrikman, maxwell, zehner_schluender
from tdem_post.flux import (coefficient_of_variation, contact_moments, halo_flux, halo_members,
                             particle_flux)
from tdem_post.post_run import analyse
from thermal_kernel.lattice import simple_cubic_packing
from thermal_kernel.laws import LAWS
from thermal_kernel.network import assemble
from thermal_kernel.packing import read_packing
from thermal_kernel.problem import build_problem
from thermal_kernel.scene import SceneError, load_scene
from thermal_kernel.solvers.steady import solve_steady

DATA = Path(__file__).resolve().parent / "data"


@pytest.mark.parametrize("kind", ["common", "own"])
@pytest.mark.parametrize("halo", [0.0, 2.0, 5.0])
def test_uniform_gradient_on_a_lattice_gives_the_exact_flux(halo, kind):
    s = 1e-3
    p = simple_cubic_packing((12, 12, 12), spacing_m=s)
    gradient = np.array([300.0, -120.0, 50.0])            # K/m
    temperature = 400.0 + p.position @ gradient
    h = 0.7                                               # W/K on every contact
    q = particle_flux(p.position, p.radius, p.pair, p.branch, np.full(len(p.pair), h),
                      temperature, np.pi / 6, halo_ratio=halo, halo_radius=kind)
    margin = halo * p.radius.max() + s * 1.01
    inside = np.all((p.position - p.position.min(axis=0) > margin)
                    & (p.position.max(axis=0) - p.position > margin), axis=1)
    assert inside.sum() >= 8
    np.testing.assert_allclose(q[inside], np.broadcast_to(-(h / s) * gradient,
                                                          q[inside].shape), rtol=1e-12)
    assert coefficient_of_variation(q, inside) < 1e-12


def test_halo_reduces_the_scatter_on_a_yade_dense_box(tmp_path):
    scene_path = tmp_path / "s.toml"
    scene_path.write_text(f'''packing = "{DATA / 'dense_box.h5'}"
law = "haddad"
[material]
conductivity = 33.0
density = 7800.0
heat_capacity = 460.0
[initial]
temperature = 300.0
[[boundary]]
kind = "temperature"
on = "xmin"
value = 310.0
[[boundary]]
kind = "temperature"
on = "xmax"
value = 300.0
[solver]
method = "steady"
''')
    scene = load_scene(scene_path, known_laws=LAWS)
    packing = read_packing(DATA / "dense_box.h5")
    problem, _ = build_problem(scene, packing)
    net = assemble(problem)
    steady = solve_steady(net, np.full(packing.n_particles, 305.0))
    T = steady.temperature_k[-1]
    q_in = steady.boundary_heat_flow_w[-1][0]
    ext = packing.domain_hi - packing.domain_lo
    phi = float(packing.attrs["solid_fraction"])
    r_mean = packing.radius.mean()
    # particles whose largest halo stays clear of the two held faces (the flux is along x; the
    # other faces are adiabatic and parallel to it)
    margin = 2.5 * packing.radius.max() + r_mean
    x = packing.position[:, 0]
    inside = (x - packing.domain_lo[0] > margin) & (packing.domain_hi[0] - x > margin)
    assert inside.sum() > 50
    for kind in ("common", "own"):
        covs, means = [], []
        for halo in (0.0, 1.5, 2.5):
            q = particle_flux(packing.position, packing.radius, packing.pair, packing.branch,
                              problem.conductance_w_k, T, phi, halo_ratio=halo,
                              halo_radius=kind)
            covs.append(coefficient_of_variation(q, inside))
            means.append(q[inside, 0].mean())
        assert covs[0] > covs[1] > covs[2], kind
        assert means[2] == pytest.approx(q_in / (ext[1] * ext[2]), rel=0.10), kind

    # exact at steady state (discrete divergence theorem): sum_p V_p q_p (eq. 20)
    # = phi sum_c H_c (T_i - T_j) l_ij = -phi sum_held x_p R_p, with R_p the heat each held
    # particle passes to the network; the R_p of a face add up to the solver's boundary flow
    q = particle_flux(packing.position, packing.radius, packing.pair, packing.branch,
                      problem.conductance_w_k, T, phi)
    volume = 4 / 3 * np.pi * packing.radius ** 3
    i, j = packing.pair.T
    flow = problem.conductance_w_k * (T[i] - T[j])
    out_of = np.zeros(packing.n_particles)
    np.add.at(out_of, i, flow)
    np.add.at(out_of, j, -flow)
    held = net.held
    free = ~held & (np.abs(out_of) > 0)
    assert np.abs(out_of[free]).max() < 1e-9 * abs(q_in)        # steady: free particles balance
    hot = held & (x < 0.5 * (packing.domain_lo[0] + packing.domain_hi[0]))
    assert out_of[hot].sum() == pytest.approx(q_in, rel=1e-9)
    np.testing.assert_allclose((volume[:, None] * q).sum(axis=0),
                               -phi * (packing.position[held] * out_of[held, None]).sum(axis=0),
                               rtol=1e-9, atol=1e-12 * abs(q_in) * ext.max() * phi)


def test_etc_estimates_limits_and_order():
    k_m, k_i = 0.2, 1.4
    f = np.linspace(0.0, 1.0, 21)
    lo, hi = hashin_shtrikman(k_m, k_i, f)
    br = bruggeman(k_m, k_i, f)
    np.testing.assert_allclose([maxwell(k_m, k_i, 0.0), bruggeman(k_m, k_i, 0.0)], k_m)
    np.testing.assert_allclose([maxwell(k_m, k_i, 1.0), bruggeman(k_m, k_i, 1.0)], k_i)
    assert np.all(lo <= br + 1e-12) and np.all(br <= hi + 1e-12)
    np.testing.assert_allclose(maxwell(k_m, k_i, f), lo, rtol=1e-12)
    # contrast below 1: Maxwell is then the upper bound
    np.testing.assert_allclose(maxwell(k_i, k_m, f), hashin_shtrikman(k_i, k_m, f)[1], rtol=1e-12)
    assert zehner_schluender(0.5, 0.5, 0.6) == pytest.approx(0.5, rel=1e-12)
    phi = np.array([0.55, 0.6, 0.65])
    zs = zehner_schluender(0.026, 205.0, phi)
    lo_bed, hi_bed = hashin_shtrikman(0.026, 205.0, phi)
    assert np.all((lo_bed < zs) & (zs < hi_bed))


def _cloud(n=20_000, seed=7):
    """A polydisperse cloud (radii sigma/mu 0.3) with random contacts between near neighbours."""
    rng = np.random.default_rng(seed)
    pos = rng.uniform(0.0, 1.0, (n, 3))
    rad = np.clip(rng.normal(0.02, 0.006, n), 0.008, 0.032)
    pairs = np.array(sorted(cKDTree(pos).query_pairs(0.05, output_type="set")))
    branch = pos[pairs[:, 1]] - pos[pairs[:, 0]]
    return pos, rad, pairs, branch, rng.uniform(0.5, 2.0, len(pairs)), rng.normal(300, 5, n)


@pytest.mark.parametrize("kind", ["common", "own"])
def test_halo_members_and_flux_equal_a_brute_force_search(kind):
    pos, rad, pairs, branch, h, temp = _cloud()
    ratio, phi = 6.0, 0.6
    reach = ratio * (rad.mean() if kind == "common" else rad)
    centre = np.all(np.abs(pos - 0.5) < 0.5 - 1.01 * ratio * rad.max(), axis=1)
    interior = np.flatnonzero(centre)
    big = interior[np.argmax(rad[interior])]
    small = interior[np.argmin(rad[interior])]
    sets = halo_members(pos, rad, [big, small], ratio, halo_radius=kind)
    m = contact_moments(len(rad), pairs, branch, h, temp)
    vol = 4 / 3 * np.pi * rad ** 3
    q = halo_flux(pos, rad, m, vol, phi, ratio, particles=[big, small], halo_radius=kind)
    for k, p in enumerate((big, small)):
        r_p = reach if np.ndim(reach) == 0 else reach[p]
        brute = np.flatnonzero(np.linalg.norm(pos - pos[p], axis=1) <= r_p)
        assert len(brute) > 5
        assert sorted(sets[k].tolist()) == brute.tolist()
        np.testing.assert_allclose(q[k], phi * m[brute].sum(axis=0) / (2 * vol[brute].sum()),
                                   rtol=1e-12)
    # the two readings differ: the own halo of the largest interior sphere is larger than the
    # common one and that of the smallest one smaller
    own, common = (halo_members(pos, rad, [big, small], ratio, halo_radius=c)
                   for c in ("own", "common"))
    assert len(own[0]) > len(common[0]) and len(own[1]) < len(common[1])


def test_volume_weighted_cov_is_the_hand_computation():
    q = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, -4.0], [9.0, 9.0, 9.0]])
    w = np.array([1.0, 1.0, 2.0, 5.0])
    mask = np.array([True, True, True, False])
    # |q| 1, 2, 4 with weights 1, 1, 2: mean 11/4, variance (1.75^2 + 0.75^2 + 2 x 1.25^2) / 4
    mean = 11 / 4
    std = np.sqrt((1.75 ** 2 + 0.75 ** 2 + 2 * 1.25 ** 2) / 4)
    assert coefficient_of_variation(q, mask, weights=w) == pytest.approx(std / mean, rel=1e-14)
    assert coefficient_of_variation(q, mask) == pytest.approx(np.std([1, 2, 4]) / (7 / 3),
                                                              rel=1e-14)
    # equal weights are the number-weighted CoV
    assert coefficient_of_variation(q, weights=np.ones(4)) == pytest.approx(
        coefficient_of_variation(q), rel=1e-14)


def test_a_wrong_halo_radius_is_refused_in_one_line(tmp_path):
    pos, rad, pairs, branch, h, temp = _cloud(200)
    for call in (lambda: particle_flux(pos, rad, pairs, branch, h, temp, 0.6, halo_ratio=2.0,
                                       halo_radius="mean"),
                 lambda: halo_members(pos, rad, [0], 2.0, halo_radius="Common")):
        with pytest.raises(ValueError) as err:
            call()
        text = str(err.value)
        assert "\n" not in text and "'common', 'own'" in text and "halo_radius" in text
    with pytest.raises(SceneError) as err:
        analyse(tmp_path / "thermal.h5", halo_radius="per-particle")
    assert "\n" not in str(err.value) and "--halo-radius" in str(err.value) \
        and "'per-particle'" in str(err.value)
