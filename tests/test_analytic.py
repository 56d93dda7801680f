"""The analytical solutions against independent checks."""
import numpy as np
import pytest
from scipy.integrate import quad
from scipy.sparse import diags
from scipy.sparse.linalg import splu

from tdem_post import analytic

# `make coverage` counts this module (marker kernel: its subject is thermal_kernel, and it is
# fast enough with NUMBA_DISABLE_JIT=1)
pytestmark = pytest.mark.kernel

L, ALPHA = 0.1, 1e-4


def _fd_slab(n_cells, t_end, t_bottom, t_top, t_initial, steps=4000):
    """Independent check: a fine finite-volume / Crank-Nicolson solve of the same slab."""
    h = L / n_cells
    x = (np.arange(n_cells) + 0.5) * h
    main = np.full(n_cells, -2.0)
    main[0] = main[-1] = -3.0          # Dirichlet at the faces, half a cell away
    lap = diags([np.ones(n_cells - 1), main, np.ones(n_cells - 1)], [-1, 0, 1]) * (ALPHA / h ** 2)
    b = np.zeros(n_cells)
    b[0] = 2 * ALPHA / h ** 2 * t_bottom
    b[-1] = 2 * ALPHA / h ** 2 * t_top
    dt = t_end / steps
    eye = diags([np.ones(n_cells)], [0])
    lu = splu((eye - 0.5 * dt * lap).tocsc())
    rhs_op = (eye + 0.5 * dt * lap).tocsr()
    temp = np.full(n_cells, t_initial)
    for _ in range(steps):
        temp = lu.solve(rhs_op @ temp + dt * b)
    return x, temp


@pytest.mark.parametrize("t_end", [2.0, 20.0])
def test_slab_against_finite_differences(t_end):
    x, fd = _fd_slab(800, t_end, 500.0, 300.0, 400.0)
    exact = analytic.slab_temperature(x, t_end, L, ALPHA, 500.0, 300.0, 400.0)
    assert np.max(np.abs(fd - exact)) < 2e-3   # K, of a 200 K range: FD error O(h^2, dt^2)


def test_slab_short_and_long_time_forms_agree_at_the_switch():
    x = np.linspace(0, L, 101)
    t_switch = analytic._SWITCH * L ** 2 / ALPHA
    below = analytic.slab_temperature(x, t_switch * (1 - 1e-13), L, ALPHA, 500.0, 300.0, 400.0)
    above = analytic.slab_temperature(x, t_switch * (1 + 1e-13), L, ALPHA, 500.0, 300.0, 400.0)
    assert np.max(np.abs(below - above)) < 1e-9


def test_slab_limits():
    x = np.linspace(0, L, 51)
    # t -> 0: initial temperature inside, boundary values on the faces
    early = analytic.slab_temperature(x, 1e-12, L, ALPHA, 500.0, 300.0, 400.0)
    np.testing.assert_allclose(early[1:-1], 400.0, atol=1e-9)
    assert early[0] == 500.0 and early[-1] == 300.0
    # t -> infinity: the linear steady profile
    late = analytic.slab_temperature(x, 1e3 * L ** 2 / ALPHA, L, ALPHA, 500.0, 300.0, 400.0)
    np.testing.assert_allclose(late, analytic.slab_steady(x, L, 500.0, 300.0), atol=1e-10)


def test_slab_matches_haddad_eq17_form():
    # 002 eq. 17: T = T1 + y dT/L + dT sum C_n sin(n pi y/L) e^{-(n pi/L)^2 alpha t},
    # C_n = 2 ((-1)^n (1 - theta0) + theta0)/(n pi), theta0 = (T0 - T1)/(T2 - T1)
    t1, t2, t0, t = 308.15, 298.15, 298.15, 0.5
    y = np.linspace(0, L, 41)
    d = t2 - t1
    theta0 = (t0 - t1) / d
    n = np.arange(1, 20001)[:, None]
    c_n = 2 * ((-1.0) ** n * (1 - theta0) + theta0) / (n * np.pi)
    eq17 = t1 + y * d / L + d * np.sum(c_n * np.sin(n * np.pi * y / L)
                                       * np.exp(-(n * np.pi / L) ** 2 * ALPHA * t), axis=0)
    ours = analytic.slab_temperature(y, t, L, ALPHA, t1, t2, t0)
    np.testing.assert_allclose(ours, eq17, atol=1e-9)


def test_rod_is_adiabatic_at_the_far_end_and_matches_terreros_eq8():
    length, t_hot, t_init, t = 2.18445e-3, 798.0, 298.0, 2e-3
    alpha = 134 / (2790 * 880)       # Terreros 2012, Table 2
    x = np.linspace(0, length, 21)   # from the hot end
    ours = analytic.rod_temperature(x, t, length, alpha, t_hot, t_init)
    # 000 eq. 8 with its x measured from the adiabatic end
    xe = length - x
    n = np.arange(0, 5000)[:, None]
    eq8 = t_hot - 4 * (t_hot - t_init) / np.pi * np.sum(
        (-1.0) ** n / (2 * n + 1) * np.cos((2 * n + 1) * np.pi * xe / (2 * length))
        * np.exp(-alpha * (2 * n + 1) ** 2 * np.pi ** 2 * t / (4 * length ** 2)), axis=0)
    np.testing.assert_allclose(ours, eq8, atol=1e-8)
    h = 1e-7 * length
    slope = (analytic.rod_temperature(length, t, length, alpha, t_hot, t_init)
             - analytic.rod_temperature(length - h, t, length, alpha, t_hot, t_init)) / h
    assert abs(slope) < 1e-3 * (t_hot - t_init) / length


@pytest.mark.parametrize("fo", [1e-3, 0.01, 0.049, 0.051, 0.2, 1.0])
def test_sphere_centre_is_the_limit_r_to_0(fo):
    radius, alpha = 0.05, 185 / (2700 * 900)
    t = fo * radius ** 2 / alpha
    centre = analytic.sphere_centre_temperature(t, radius, alpha, 473.15, 293.15)
    near = analytic.sphere_temperature(np.array([1e-5, 1e-4]) * radius, t, radius, alpha,
                                       473.15, 293.15)
    assert near[0] == pytest.approx(centre, abs=1e-6)
    assert abs(near[1] - centre) < abs(near[1] - 473.15)


def test_sphere_limits_and_energy():
    radius, alpha = 0.05, 1e-4
    r = np.linspace(0.0, radius, 201)
    assert analytic.sphere_centre_temperature(1e-9, radius, alpha, 473.15, 293.15) == \
        pytest.approx(293.15, abs=1e-9)
    late = analytic.sphere_temperature(r, 50 * radius ** 2 / alpha, radius, alpha, 473.15, 293.15)
    np.testing.assert_allclose(late, 473.15, atol=1e-9)
    # the mean temperature rise equals the heat that entered: 1 - 6/pi^2 sum e^{-n^2 pi^2 Fo}/n^2
    fo = 0.05
    t = fo * radius ** 2 / alpha
    mean = quad(lambda s: 3 * s ** 2 / radius ** 3 * analytic.sphere_temperature(
        np.array([s]), t, radius, alpha, 1.0, 0.0)[0], 0, radius, epsabs=1e-13)[0]
    n = np.arange(1, 2000)
    expected = 1 - 6 / np.pi ** 2 * np.sum(np.exp(-(n * np.pi) ** 2 * fo) / n ** 2)
    assert mean == pytest.approx(expected, abs=1e-9)


def test_characteristic_time_closed_form_equals_integral_of_the_series():
    x = np.array([0.25, 0.6, 0.8]) * L
    tau = analytic.slab_characteristic_time(x, L, ALPHA, 500.0, 300.0, 400.0)
    for xi, tau_i in zip(x, tau):
        steady = analytic.slab_steady(xi, L, 500.0, 300.0)
        def f(t, steady=steady, xi=xi):
            return (steady - analytic.slab_temperature(xi, t, L, ALPHA, 500.0, 300.0, 400.0)) \
                / (steady - 400.0)
        tmax = 60 * L ** 2 / ALPHA
        integral = quad(f, 0, tmax, limit=400, epsabs=1e-10, points=[L ** 2 / ALPHA])[0]
        assert integral == pytest.approx(tau_i, rel=1e-7)


def test_slab_mean_over_a_bin_equals_quadrature():
    t = 3.0
    got = analytic.slab_mean_temperature([0.0, 0.03], [0.01, 0.05], t, L, ALPHA, 500, 300, 400)
    for a, b, g in zip([0.0, 0.03], [0.01, 0.05], got):
        ref = quad(lambda x: analytic.slab_temperature(x, t, L, ALPHA, 500, 300, 400), a, b,
                   epsabs=1e-12)[0] / (b - a)
        assert g == pytest.approx(ref, abs=1e-9)


@pytest.mark.parametrize("t_b, t_t, t_i", [(500.0, 400.0, 300.0), (500.0, 300.0, 350.0),
                                           (400.0, 400.0, 300.0)])
def test_midplane_characteristic_time_is_l2_over_8_alpha(t_b, t_t, t_i):
    # the cubic of slab_characteristic_time at x = L/2, whatever the temperatures (issue 15)
    tau = analytic.slab_midplane_characteristic_time(L, ALPHA)
    assert tau == pytest.approx(L ** 2 / (8 * ALPHA), rel=1e-15)
    assert analytic.slab_characteristic_time(L / 2, L, ALPHA, t_b, t_t, t_i) == \
        pytest.approx(tau, rel=1e-12)
    # ... and the time integral of the series at the mid-plane (eq. 41 by quadrature)
    t_s = 0.5 * (t_b + t_t)
    integral = quad(lambda t: t_s - analytic.slab_temperature(L / 2, t, L, ALPHA, t_b, t_t,
                                                              t_i), 0, 60 * L ** 2 / ALPHA,
                    limit=400)[0]
    assert integral / (t_s - t_i) == pytest.approx(tau, rel=1e-6)
    # the slowest mode alone, L^2/(pi^2 alpha), is 19 % short of it
    assert L ** 2 / (np.pi ** 2 * ALPHA) / tau == pytest.approx(8 / np.pi ** 2, rel=1e-12)
