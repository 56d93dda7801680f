"""tdem_post.continuum: the finite-volume continuum reference (docs/validation.md cases 3 and 9)
against closed forms of tdem_post.analytic, with its order under refinement, its energy ledger and
the Richardson estimate it reports."""
import numpy as np
import pytest

from tdem_post import analytic
from tdem_post import continuum as fv

ALPHA = 134 / (2790 * 880)      # 000 Table 2 (aluminium)
RHO_C = 2790 * 880


def slab_grid(n, length=1e-3, along=0):
    shape = [1, 1, 1]
    shape[along] = n
    hi = [1e-4, 1e-4, 1e-4]
    hi[along] = length
    return fv.make_grid((0, 0, 0), hi, shape)


def test_steady_layered_conductivity_is_exact():
    # two layers in series: the flux is Delta T / sum(l_i / k_i); the field is linear per layer
    # and the harmonic face conductance makes the cell-centred scheme exact (faces on the jump)
    length, n = 1.0, 20
    g = slab_grid(n, length)
    x = g.centres(0)
    k = np.where(x < 0.3, 2.0, 10.0).reshape(g.shape)
    res = fv.solve_steady(g, k, {"xmin": 400.0, "xmax": 300.0})
    area = 1e-8
    q = 100.0 / (0.3 / 2.0 + 0.7 / 10.0)            # W/m^2
    exact = np.where(x < 0.3, 400 - q * x / 2.0, 400 - q * 0.3 / 2.0 - q * (x - 0.3) / 10.0)
    np.testing.assert_allclose(res.temperature.ravel(), exact, rtol=0, atol=1e-10)
    assert res.face_heat_w["xmin"] == pytest.approx(q * area, rel=1e-10)
    assert res.face_heat_w["xmax"] == pytest.approx(-q * area, rel=1e-10)
    assert res.balance < 1e-12


@pytest.mark.parametrize("along", [0, 1, 2])
def test_steady_uniform_source_is_a_parabola_on_every_axis(along):
    # k T'' = -q, T(0) = T(L) = 0: T = q x (L - x) / (2 k). The 3-point interior stencil is
    # exact for a parabola; the half-cell Dirichlet link is not, and shifts the whole field by
    # exactly q h^2 / (8 k): second order, measured to round-off
    length, k, q = 2e-3, 5.0, 1e9
    g = slab_grid(16, length, along)
    res = fv.solve_steady(g, k, {("xmin", "ymin", "zmin")[along]: 0.0,
                                 ("xmax", "ymax", "zmax")[along]: 0.0}, source=q)
    x = g.centres(along)
    h = length / 16
    np.testing.assert_allclose(res.temperature.ravel() - q * x * (length - x) / (2 * k),
                               q * h * h / (8 * k), rtol=1e-9)
    assert res.balance < 1e-12


def slab_transient_error(n, theta=0.5, dt_per_h2=0.5):
    length = 2.18445e-3
    g = slab_grid(n, length)
    h = length / n
    dt = dt_per_h2 * h * h / ALPHA
    end = 0.02                                       # Fo = 0.23
    steps = 4 * max(1, int(round(end / dt / 4)))
    dt = end / steps
    times = [end / 4, end / 2, end]
    res = fv.solve_transient(g, 134.0, RHO_C, {"xmin": 798.0, "xmax": 298.0}, 298.0,
                             times, dt, theta=theta)
    x = g.centres(0)
    err = max(np.max(np.abs(res.temperature[k].ravel()
                            - analytic.slab_temperature(x, t, length, ALPHA, 798, 298, 298)))
              for k, t in enumerate(times))
    return err / 500.0, res


def test_slab_transient_converges_at_second_order():
    # Crank-Nicolson (Rannacher start) with dt ~ h^2: error ~ h^2 in space and time
    errs = [slab_transient_error(n)[0] for n in (10, 20, 40)]
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(orders > 1.8), (errs, orders)
    assert errs[-1] < 5e-4          # measured 3.6e-4 of the 500 K step at 40 cells


def test_backward_euler_is_first_order_in_time():
    # fixed fine grid, dt halved: error ~ dt
    length, n, end = 1e-3, 200, 4e-3
    g = slab_grid(n, length)
    x = g.centres(0)
    ref = analytic.slab_temperature(x, end, length, ALPHA, 1.0, 0.0, 0.0)
    errs = []
    for steps in (10, 20, 40):
        r = fv.solve_transient(g, 134.0, RHO_C, {"xmin": 1.0, "xmax": 0.0}, 0.0, [end],
                               end / steps, theta=1.0)
        errs.append(np.max(np.abs(r.temperature[-1].ravel() - ref)))
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(np.abs(orders - 1.0) < 0.15), orders


def test_rod_heated_at_one_end_against_terreros_eq8():
    # 000 eq. 8: held at 798 K at x = 0, adiabatic at x = L (no Dirichlet face there)
    length, n = 2.18445e-3, 80
    g = slab_grid(n, length)
    h = length / n
    dt = 0.25 * h * h / ALPHA
    times = np.array([0.002, 0.01, 0.04])
    times = np.round(times / dt) * dt
    res = fv.solve_transient(g, 134.0, RHO_C, {"xmin": 798.0}, 298.0, times, dt,
                             probes=[[length / 2, 5e-5, 5e-5]])
    x = g.centres(0)
    for k, t in enumerate(times):
        exact = analytic.rod_temperature(x, t, length, ALPHA, 798.0, 298.0)
        assert np.max(np.abs(res.temperature[k].ravel() - exact)) < 1e-3 * 500
        assert res.probe_temperature[k, 0] == pytest.approx(
            analytic.rod_temperature(length / 2, t, length, ALPHA, 798.0, 298.0), abs=0.5)


def test_energy_ledger_with_a_moving_source_and_held_face_is_exact():
    g = fv.make_grid((0, 0, 0), (10e-3, 6e-3, 1e-3), (20, 12, 2))
    k = np.full(g.shape, 134.0)
    k[5:9, 3:6, :] = 13.4                             # a conductivity jump on the way
    rc = np.full(g.shape, float(RHO_C))
    rc[:, :6, :] *= 2.0

    def q(t):
        xc = 2e-3 + 3.3e-3 * t
        return fv.cell_average(g, lambda x, y, z: 1e10 * ((x - xc) ** 2 + (y - 3e-3) ** 2
                                                           <= (1.5e-3) ** 2), sub=3)
    for theta in (1.0, 0.5):
        res = fv.solve_transient(g, k, rc, {"xmin": 350.0}, 300.0, [0.1, 0.3, 0.6], 0.05,
                                 source=q, theta=theta, fields=False,
                                 probes=[[5e-3, 3e-3, 5e-4]])
        assert res.temperature is None and res.probe_temperature.shape == (3, 1)
        scale = np.max(np.abs(res.stored_energy_j))
        assert np.max(np.abs(res.ledger_residual_j())) < 1e-11 * scale
        # the source heats the held face region above 350 K: heat leaves through it
        assert np.all(res.source_energy_j > 0) and res.boundary_energy_j[-1] < 0


def test_source_energy_is_the_integral_of_a_moving_disc():
    # a disc of radius r moving inside the domain: source heat = q pi r^2 depth t (to the
    # sampling of its edge by cell_average, which converges as the cells shrink)
    g = fv.make_grid((0, 0, 0), (20e-3, 10e-3, 2e-3), (80, 40, 1))
    q0, r, v = 1e9, 2e-3, 3.3e-3

    def q(t):
        xc = 5e-3 + v * t
        return fv.cell_average(g, lambda x, y, z: q0 * ((x - xc) ** 2 + (y - 5e-3) ** 2
                                                        <= r * r), sub=8)
    res = fv.solve_transient(g, 134.0, RHO_C, {}, 298.0, [1.0], 0.1, source=q, fields=False)
    assert res.source_energy_j[-1] == pytest.approx(q0 * np.pi * r * r * 2e-3, rel=2e-3)
    assert abs(res.ledger_residual_j()[-1]) < 1e-11 * res.stored_energy_j[-1]


def test_spherical_inclusion_steady_conserves_flux():
    # a conducting ball between two held faces: inflow equals outflow, the field stays between
    # the held temperatures, and the effective conductance rises above the matrix one
    g = fv.make_grid((0, 0, 0), (1, 1, 1), (16, 16, 16))
    frac = fv.ball_fraction(g, (0.5, 0.5, 0.5), 0.3)
    assert frac.sum() * g.cell_volume == pytest.approx(4 / 3 * np.pi * 0.3 ** 3, rel=0.02)
    k = 1.0 / (frac / 5.0 + (1 - frac) / 1.0)        # harmonic mixing in the cut cells
    res = fv.solve_steady(g, k, {"xmin": 1.0, "xmax": 0.0})
    assert res.balance < 1e-10
    assert res.temperature.min() > 0 and res.temperature.max() < 1
    assert res.face_heat_w["xmin"] > 1.0 * 1.0 * 1.0 / 1.0


def test_richardson_recovers_order_and_limit():
    h = np.array([0.4, 0.2, 0.1])
    vals = [3.0 + 0.7 * hh ** 2 for hh in h]
    est = fv.richardson(vals, 2.0)
    assert float(est.order) == pytest.approx(2.0, rel=1e-9)
    assert float(est.extrapolated) == pytest.approx(3.0, abs=1e-12)
    assert float(est.error) == pytest.approx(0.7 * 0.01, rel=1e-9)
    fixed = fv.richardson(vals[1:], 2.0, order=2)
    assert float(fixed.extrapolated) == pytest.approx(3.0, abs=1e-12)


def test_richardson_estimates_the_true_error_of_the_slab():
    errs, fields = [], []
    for n in (10, 20, 40):
        e, r = slab_transient_error(n)
        errs.append(e)
        fields.append(r.probe_temperature)
    # probe-free check on the mean field: cell averages over the coarse cells agree in position
    coarse = [slab_transient_error(n)[1] for n in (10, 20, 40)]
    means = [c.temperature[-1].reshape(10, -1).mean(axis=1) for c in coarse]
    est = fv.richardson(means, 2.0)
    x0 = np.linspace(0, 2.18445e-3, 11)
    exact = analytic.slab_mean_temperature(x0[:-1], x0[1:], 0.02, 2.18445e-3, ALPHA,
                                           798, 298, 298)
    true = np.abs(means[-1] - exact)
    assert 1.5 < float(est.order) < 2.5
    # the estimate is of the right size: within a factor 3 of the true error where it matters
    big = true > 0.1 * true.max()
    assert np.all(est.error[big] < 3 * true[big] + 1e-9)
    assert np.all(est.error[big] > true[big] / 3)


def test_refuses_bad_input():
    g = slab_grid(4)
    with pytest.raises(ValueError, match="face"):
        fv.solve_steady(g, 1.0, {"left": 1.0})
    with pytest.raises(ValueError, match="Dirichlet"):
        fv.solve_steady(g, 1.0, {})
    with pytest.raises(ValueError, match="k must be"):
        fv.solve_steady(g, -1.0, {"xmin": 1.0})
    with pytest.raises(ValueError, match="multiples"):
        fv.solve_transient(g, 1.0, 1.0, {"xmin": 1.0}, 0.0, [0.15], 0.1)
