"""Heat flux per particle and Halo smoothing (002 eq. 20, 22-23); ETC estimates and bounds.

- Uniform gradient on a simple-cubic lattice: the flux of every particle whose halo lies in the
  lattice's interior is exactly -k_lattice grad T (k_lattice = H / s), for halo ratios 0, 2, 5:
  zero coefficient of variation (to round-off);
- on a YADE dense box at steady state (haddad law, faces held), the CoV of |q| falls as the halo
  grows (002 Fig. 10), and the halo-smoothed mean flux equals Q / A within 10 %;
- Maxwell / Hashin-Shtrikman / Bruggeman: limits f = 0 and 1, the ordering HS_lower <= Bruggeman
  <= HS_upper, Maxwell = the HS bound on the matrix side; Zehner-Schluender = k_f when the solid
  equals the fluid.
"""
from pathlib import Path

import numpy as np
import pytest

from tdem_post.etc import bruggeman, hashin_shtrikman, maxwell, zehner_schluender
from tdem_post.flux import coefficient_of_variation, particle_flux
from thermal_kernel.lattice import simple_cubic_packing
from thermal_kernel.laws import LAWS
from thermal_kernel.network import assemble
from thermal_kernel.packing import read_packing
from thermal_kernel.problem import build_problem
from thermal_kernel.scene import load_scene
from thermal_kernel.solvers.steady import solve_steady

DATA = Path(__file__).resolve().parent / "data"


@pytest.mark.parametrize("halo", [0.0, 2.0, 5.0])
def test_uniform_gradient_on_a_lattice_gives_the_exact_flux(halo):
    s = 1e-3
    p = simple_cubic_packing((12, 12, 12), spacing_m=s)
    gradient = np.array([300.0, -120.0, 50.0])            # K/m
    temperature = 400.0 + p.position @ gradient
    h = 0.7                                               # W/K on every contact
    q = particle_flux(p.position, p.radius, p.pair, p.branch, np.full(len(p.pair), h),
                      temperature, np.pi / 6, halo_ratio=halo)
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
    covs, means = [], []
    r_mean = packing.radius.mean()
    # particles whose largest halo stays clear of the two held faces (the flux is along x; the
    # other faces are adiabatic and parallel to it)
    margin = 2.5 * packing.radius.max() + r_mean
    x = packing.position[:, 0]
    inside = (x - packing.domain_lo[0] > margin) & (packing.domain_hi[0] - x > margin)
    assert inside.sum() > 50
    for halo in (0.0, 1.5, 2.5):
        q = particle_flux(packing.position, packing.radius, packing.pair, packing.branch,
                          problem.conductance_w_k, T, phi, halo_ratio=halo)
        covs.append(coefficient_of_variation(q, inside))
        means.append(q[inside, 0].mean())
    assert covs[0] > covs[1] > covs[2]
    assert means[2] == pytest.approx(q_in / (ext[1] * ext[2]), rel=0.10)

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
