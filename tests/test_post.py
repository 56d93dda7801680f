"""tdem_post: partial-volume profiles, gamma and tau fits, power laws, and post_run on a YADE bed.

Tolerances, and why:
- partial volumes: the bins that cover a sphere hold its whole volume to 1e-12 relative (exact
  cap formula); a field that is constant per layer of a lattice whose layers fill the bins is
  reproduced to round-off;
- gamma from synthetic profiles (slab solution + 0.5 K Gaussian noise, 40 seeded realisations):
  each within 2 %, and the 95 % interval covers the true value in at least 32 of 40;
- tau of a fine 1-D chain (the slab's discretisation, 200 layers): the network's exact tau equals
  the slab's closed form (003 eq. 41) within 0.5 % (discretisation error ~ 1/n^2 and the held end
  layers);
- tau from a finely sampled time series equals the network's exact tau within 1 %;
- power law: recovers a, b, c of noise-free data to 1e-6.
"""
import json
import math
from pathlib import Path

import numpy as np
import pytest

from tdem.committed_beds import BED_THERMAL
from tdem.cli import main
from tdem_post.analytic import slab_characteristic_time, slab_mean_temperature
from tdem_post.fits import (characteristic_time_network, characteristic_time_series, fit_gamma,
                            fit_power_law)
from tdem_post.post_run import post_run
from tdem_post.profiles import binned_profile, partial_volumes
from thermal_kernel.network import assemble, make_problem
from thermal_kernel.solvers.implicit import run_implicit
from thermal_kernel.solvers.steady import solve_steady

DATA = Path(__file__).resolve().parent / "data"


def test_partial_volumes_conserve_each_sphere():
    rng = np.random.default_rng(3)
    x = rng.uniform(0.1, 0.9, 200)
    r = rng.uniform(0.01, 0.05, 200)
    edges = np.linspace(0.0, 1.0, 17)
    w = partial_volumes(x, r, edges)
    np.testing.assert_allclose(w.sum(axis=1), 4 / 3 * np.pi * r ** 3, rtol=1e-12)
    assert np.all(w >= -1e-18)
    # uneven edges too
    w2 = partial_volumes(x, r, np.sort(np.r_[0.0, rng.uniform(0, 1, 9), 1.0]))
    np.testing.assert_allclose(w2.sum(axis=1), 4 / 3 * np.pi * r ** 3, rtol=1e-12)


def test_profile_of_constant_and_layered_fields():
    rng = np.random.default_rng(4)
    x = rng.uniform(0.1, 0.9, 100)
    r = rng.uniform(0.01, 0.05, 100)
    edges = np.linspace(0.0, 1.0, 6)
    np.testing.assert_allclose(binned_profile(x, r, np.full(100, 7.5), edges), 7.5, rtol=1e-14)
    # layers of spheres of diameter = bin width, centred in the bins: bin b holds layer b only
    layer = np.repeat(np.arange(5), 9)
    xc = (layer + 0.5) * 0.2
    values = 300.0 + 40.0 * xc              # a linear field, sampled per layer
    prof = binned_profile(xc, np.full(45, 0.1), values, edges)
    np.testing.assert_allclose(prof, 300.0 + 40.0 * (np.arange(5) + 0.5) * 0.2, rtol=1e-14)


def test_gamma_recovered_from_noisy_synthetic_profiles():
    length, kp, rho_c = 0.05, 205.0, 0.6 * 2500 * 900
    gamma = 0.02
    alpha = gamma * kp / rho_c
    edges = np.linspace(0.0, length, 11)
    times = np.array([20.0, 50.0, 100.0, 200.0, 400.0])
    clean = np.array([slab_mean_temperature(edges[:-1], edges[1:], t, length, alpha,
                                            500.0, 400.0, 300.0) for t in times])
    rng = np.random.default_rng(5)
    covered = 0
    for _ in range(40):
        noisy = clean + rng.normal(0.0, 0.5, clean.shape)
        fit = fit_gamma(times, edges, noisy, conductivity_w_mk=kp,
                        volumetric_capacity_j_m3k=rho_c, t_bottom=500.0, t_top=400.0,
                        t_initial=300.0)
        assert fit.gamma == pytest.approx(gamma, rel=0.02)
        assert 0.3 < fit.residual_rms_k < 0.7      # the noise, not a misfit
        covered += fit.ci95[0] < gamma < fit.ci95[1]
    # the 95 % interval covers the true value in ~95 % of the realisations (binomial, n = 40:
    # below 32 would be a < 1e-3 event for a correct interval)
    assert covered >= 32
    exact = fit_gamma(times, edges, clean, conductivity_w_mk=kp,
                      volumetric_capacity_j_m3k=rho_c, t_bottom=500.0, t_top=400.0,
                      t_initial=300.0)
    assert exact.gamma == pytest.approx(gamma, rel=1e-6)


def chain(n, length=0.1, k=1.0, rho_c=1.0):
    """A 1-D chain discretising the slab: n particles at spacing h = L/(n-1), conductance k A/h,
    capacity rho c A h (A = 1), ends held at 500 K and 400 K."""
    h = length / (n - 1)
    pair = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1)
    cap = np.full(n, rho_c * h)
    prob = make_problem(cap, pair, np.full(n - 1, k / h),
                        fixed=([0, n - 1], [500.0, 400.0], [0, 1]),
                        boundary_names=("bottom", "top"))
    return assemble(prob), h


def test_tau_of_a_fine_chain_matches_the_slab_closed_form():
    n, length = 201, 0.1
    net, h = chain(n, length)
    x = np.arange(n) * h
    t_init = np.full(n, 300.0)
    steady = solve_steady(net, t_init).temperature_k[-1]
    for frac in (0.25, 0.5, 0.75):
        j = int(round(frac * (n - 1)))
        w = np.zeros(n)
        w[j] = 1.0
        tau = characteristic_time_network(net, steady, t_init, w)
        exact = slab_characteristic_time(x[j], length, 1.0, 500.0, 400.0, 300.0)
        assert tau == pytest.approx(float(exact), rel=5e-3)
    # from a finely sampled time series of the same network
    j = (n - 1) // 2
    w = np.zeros(n)
    w[j] = 1.0
    tau_net = characteristic_time_network(net, steady, t_init, w)
    times = np.linspace(tau_net / 200, 8 * tau_net, 1600)
    series = run_implicit(net, t_init, times, dt=times[0], theta=0.5).temperature_k[:, j]
    tau_ts = characteristic_time_series(times, series, steady[j], 300.0)
    assert tau_ts == pytest.approx(tau_net, rel=1e-2)


def test_power_law_fit_recovers_parameters():
    p = np.array([0.28, 1.0, 4.0, 16.0, 64.0, 160.0, 405.0])
    y = 0.01039 * p ** -0.2919 + 5.353e-4
    fit = fit_power_law(p, y)
    assert (fit.a, fit.b, fit.c) == pytest.approx((0.01039, -0.2919, 5.353e-4), rel=1e-6)
    y2 = 3.0 * p ** 0.1 + 2.0
    fit2 = fit_power_law(p, y2)
    assert (fit2.a, fit2.b, fit2.c) == pytest.approx((3.0, 0.1, 2.0), rel=1e-5)


def test_post_run_on_a_yade_bed(tmp_path, capsys):
    """A long Crank-Nicolson run on the committed 300-sphere bed: the fitted gamma agrees with
    the steady ETC, heat in = heat out, and the tdem post command prints the table."""
    scene = tmp_path / "bed.toml"
    scene.write_text(f'''packing = "{DATA / 'bed_small_4.05e+07Pa.h5'}"
law = "pipe"
{BED_THERMAL}[solver]
method = "implicit"
theta = 0.5
dt = 0.1
end_time = 400.0
output_times = [2.0, 5.0, 10.0, 20.0, 40.0, 80.0, 150.0, 400.0]
''')
    assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    s = post_run(tmp_path / "out" / "thermal.h5", n_bins=6)
    assert s["steady_balance"] < 1e-9
    assert s["gamma_ci95"][0] < s["gamma"] < s["gamma_ci95"][1]
    assert s["gamma"] == pytest.approx(s["gamma_steady"], rel=0.25)
    assert s["tau_s"] > 0 and math.isfinite(s["tau_s"])
    assert s["tau_series_s"] == pytest.approx(s["tau_s"], rel=0.25)
    for law in ("bob", "argento", "pipe"):
        assert s["gamma_mean_field"][law] > 0
    # pipe / bob = 1.033 for equal spheres (003 eq. 40 vs 34): the mean fields keep the ratio
    assert s["gamma_mean_field"]["pipe"] / s["gamma_mean_field"]["bob"] == pytest.approx(
        1.033, rel=0.02)
    assert (tmp_path / "out" / "post" / "profiles.png").stat().st_size > 10_000
    assert (tmp_path / "out" / "post" / "summary.json").exists()
    # steady flux field: the halo lowers the scatter, and the interior's mean axial flux is the
    # heat flow per cross-section (within 15 %: the wall region and the halo's edge)
    assert s["flux_interior_particles"] > 20
    assert s["flux_cov_halo"] < s["flux_cov_raw"]
    # the halo radius named (ratio x the mean radius by default); the raw CoV also per unit
    # volume, close to the per-particle one for this bed's narrow radii (0.346 against 0.344)
    assert s["flux_halo_radius"] == "common" and s["flux_halo_ratio"] == 3.0
    assert s["flux_cov_raw_volume_weighted"] == pytest.approx(s["flux_cov_raw"], rel=0.1)
    assert s["flux_mean_over_q_per_area"] == pytest.approx(1.0, rel=0.15)
    assert (tmp_path / "out" / "post" / "flux_section.png").stat().st_size > 10_000
    # tdem post --halo-radius own: the per-particle radius, named in the summary and printed
    assert main(["post", str(tmp_path / "out"), "--halo-radius", "own", "--halo", "3"]) == 0
    own = json.loads((tmp_path / "out" / "post" / "summary.json").read_text())
    assert own["flux_halo_radius"] == "own" and own["flux_cov_halo"] != s["flux_cov_halo"]
    assert own["flux_cov_halo"] < own["flux_cov_raw"]
    assert "3 R_p (own radius)" in capsys.readouterr().out


def test_gamma_of_a_simple_cubic_lattice_run_is_its_closed_form(tmp_path):
    """A bob run on a simple-cubic lattice (pitch a, 21 layers, every contact the same Hertz
    overlap delta): each column is a chain of conductances H = 2 k_p a_c (003 eq. 34) with
    a_c = sqrt(R* delta), so k_eff = H / a and gamma = 2 sqrt(R* delta) / a in closed form.
    The steady ETC is that value to round-off (the held layers are the slab's ends); the
    transient fit of the Crank-Nicolson profiles differs from it only by the lattice's
    finite-difference error ((pi a / L)^2 / 12 ~ 0.2 % for 20 intervals) and the binning of
    layer values (measured 0.5 % with outputs from t = 20 s, when sqrt(alpha t) > 2 pitches; the
    slab fitted between the walls, 21 pitches apart, would be 10 % off): asserted within 1 %."""
    from thermal_kernel.lattice import simple_cubic_packing
    from thermal_kernel.packing import write_packing
    pitch, delta = 4e-3, 4e-6
    radius = (pitch + delta) / 2
    packing = simple_cubic_packing((3, 3, 21), spacing_m=pitch, radius_m=radius, young_pa=5e10,
                                   poisson=0.2, density=2500.0)
    write_packing(tmp_path / "lattice.h5", packing)
    gamma_exact = 2 * math.sqrt(radius / 2 * delta) / pitch
    scene = tmp_path / "lattice.toml"
    scene.write_text(f'''packing = "lattice.h5"
law = "bob"
{BED_THERMAL.replace('on = "plate"', 'on = "zmax"')}[solver]
method = "implicit"
theta = 0.5
dt = 0.25
end_time = 600.0
output_times = [20.0, 40.0, 80.0, 150.0, 300.0, 600.0]
''')
    assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    s = post_run(tmp_path / "out" / "thermal.h5", n_bins=10, plots=False)
    assert s["length_m"] == pytest.approx(20 * pitch, rel=1e-12)
    assert s["gamma_steady"] == pytest.approx(gamma_exact, rel=1e-9)
    assert s["gamma"] == pytest.approx(gamma_exact, rel=0.01)
    assert s["gamma_ci95"][0] < gamma_exact * 1.01 and gamma_exact * 0.99 < s["gamma_ci95"][1]
    # the mean field phi Z H / (2 pi R k_p) with Z = 6, phi = pi/6 (delta -> 0) is H / (2 R k_p),
    # the lattice's exact answer; this finite lattice has 2 (2 x 3 x 21) + 3 x 3 x 20 contacts
    z_mean = 2 * (2 * 2 * 3 * 21 + 3 * 3 * 20) / (3 * 3 * 21)
    phi = 4 / 3 * math.pi * radius ** 3 / pitch ** 3
    h = 2 * 205.0 * math.sqrt(radius / 2 * delta)
    assert s["gamma_mean_field"]["bob"] == pytest.approx(
        phi * z_mean * h / (2 * math.pi * radius * 205.0), rel=1e-9)
    assert (math.pi / 6) * 6 * h / (2 * math.pi * (pitch / 2) * 205.0) == pytest.approx(
        gamma_exact, rel=1e-12)
    # summary.json is post's PostSummary record, written from its fields in their order and
    # read back to the same text (issue 26)
    import dataclasses
    from tdem_post.post_run import PostSummary
    from tdem_post.records import json_text, record_from_json
    path = tmp_path / "out" / "post" / "summary.json"
    record = record_from_json(PostSummary, path)
    assert json_text(record) == path.read_text() and record.gamma == s["gamma"]
    assert list(s) == [f.name for f in dataclasses.fields(PostSummary) if f.name in s]
    # a 3 x 3 lattice has no interior sphere for the flux CoV: the keys are absent, as before
    assert s["files"] == ["summary.json"] and "flux_cov_raw" not in s
    assert record.flux_cov_raw is None and record.flux_interior_particles == s[
        "flux_interior_particles"]


def test_post_of_a_steady_run_reports_the_steady_etc_and_no_fit(tmp_path, capsys):
    """A steady run has no transient: `tdem post` says so instead of fitting one output at
    t = inf, and gives the lattice's closed-form steady gamma (a law with parameters, haddad,
    also checks that the mean-field laws do not inherit them)."""
    from thermal_kernel.lattice import simple_cubic_packing
    from thermal_kernel.packing import write_packing
    pitch, delta = 4e-3, 4e-6
    radius = (pitch + delta) / 2
    write_packing(tmp_path / "lattice.h5", simple_cubic_packing(
        (3, 3, 9), spacing_m=pitch, radius_m=radius, young_pa=5e10, poisson=0.2))
    scene = tmp_path / "steady.toml"
    scene.write_text('packing = "lattice.h5"\nlaw = "haddad"\n[law_params]\nct = 0.8\n'
                     + BED_THERMAL.replace('on = "plate"', 'on = "zmax"')
                     + '[solver]\nmethod = "steady"\n')
    assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    assert main(["post", str(tmp_path / "out")]) == 0
    printed = capsys.readouterr().out
    assert "not measurable from this run: a steady run has no transient" in printed
    assert "nan" not in printed.lower()
    s = json.loads((tmp_path / "out" / "post" / "summary.json").read_text())
    assert s["gamma"] is None and s["tau_series_s"] is None
    # haddad on a lattice: H = k C_t pi R_m^2 / d between layers a apart -> k_eff = H / a
    h = 205.0 * 0.8 * math.pi * radius ** 2 / pitch
    assert s["gamma_steady"] == pytest.approx(h / (pitch * 205.0), rel=1e-9)
    assert not (tmp_path / "out" / "post" / "profiles.png").exists()
