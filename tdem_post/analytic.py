"""Analytical solutions of transient conduction used by tdem's tests, validation and plots.

One module, one implementation of each; every series is summed until its remaining terms are
bounded by ``tol`` (absolute, in units of the temperature difference), and each solution switches
to its short-time (error-function, image) form when the Fourier series would need many terms, so
values are right at t -> 0 as well as at t -> infinity. References: Carslaw & Jaeger (1959),
*Conduction of Heat in Solids*, sec. 3.3 (slab) and 9.3 (sphere); the papers' own forms are
cited where they are used.

Symbols: alpha = k / (rho c_p) thermal diffusivity (m^2/s); lengths in m; times in s.
"""
from __future__ import annotations

import numpy as np
from scipy.special import erfc

# Fourier series are used when alpha t / L^2 >= this; the image series below it. At the switch
# both need only a handful of terms for 1e-12 accuracy.
_SWITCH = 0.05


def _unit_step_slab(x, t, length, alpha, tol):
    """U(x, t): slab 0 <= x <= L, U(0) = 1, U(L) = 0, U(x, 0) = 0 (Carslaw & Jaeger 3.3)."""
    x = np.asarray(x, dtype=float)
    if t <= 0:
        return np.where(x <= 0, 1.0, 0.0)
    fo = alpha * t / length ** 2
    if fo < _SWITCH:
        # Images: U = sum_k erfc((2kL + x)/s) - erfc((2(k+1)L - x)/s), s = 2 sqrt(alpha t)
        s = 2.0 * np.sqrt(alpha * t)
        out = np.zeros_like(x)
        k = 0
        while True:
            term = erfc((2 * k * length + x) / s) - erfc((2 * (k + 1) * length - x) / s)
            out += term
            if erfc(2 * (k + 1) * length / s) < tol:
                return out
            k += 1
    # Fourier: U = 1 - x/L - sum_n 2/(n pi) sin(n pi x / L) exp(-n^2 pi^2 Fo)
    out = 1.0 - x / length
    n = 1
    while True:
        decay = np.exp(-(n * np.pi) ** 2 * fo)
        out -= 2.0 / (n * np.pi) * np.sin(n * np.pi * x / length) * decay
        # remaining terms: sum_{m>n} 2/(m pi) e^{-m^2 pi^2 Fo}
        #                  < 2/pi * e^{-(n+1)^2 pi^2 Fo}/(1-e^{-pi^2 Fo})
        if 2.0 / np.pi * np.exp(-((n + 1) * np.pi) ** 2 * fo) \
                / (1 - np.exp(-np.pi ** 2 * fo)) < tol:
            return out
        n += 1


def slab_temperature(x, t, length, alpha, t_bottom, t_top, t_initial, tol=1e-12):
    """Slab 0 <= x <= L with T(0) = t_bottom, T(L) = t_top held from t = 0 and a uniform initial
    temperature (Haddad 2021, 002 eq. 17; 003 Appendix A, eq. A5-A6). By superposition,
    T = T_i + (T_b - T_i) U(x) + (T_t - T_i) U(L - x)."""
    x = np.asarray(x, dtype=float)
    return (t_initial + (t_bottom - t_initial) * _unit_step_slab(x, t, length, alpha, tol)
            + (t_top - t_initial) * _unit_step_slab(length - x, t, length, alpha, tol))


def slab_steady(x, length, t_bottom, t_top):
    return t_bottom + (t_top - t_bottom) * np.asarray(x, dtype=float) / length


def slab_mean_temperature(x0, x1, t, length, alpha, t_bottom, t_top, t_initial, tol=1e-12):
    """Mean of the slab solution over x0 <= x <= x1 (what a binned profile measures), by
    Gauss-Legendre quadrature exact to round-off for the smooth field (t > 0)."""
    nodes, weights = np.polynomial.legendre.leggauss(32)
    x0 = np.atleast_1d(np.asarray(x0, float))
    x1 = np.atleast_1d(np.asarray(x1, float))
    xs = 0.5 * (x1[:, None] - x0[:, None]) * nodes[None, :] + 0.5 * (x1 + x0)[:, None]
    vals = slab_temperature(xs, t, length, alpha, t_bottom, t_top, t_initial, tol)
    return 0.5 * vals @ weights


def slab_characteristic_time(x, length, alpha, t_bottom, t_top, t_initial):
    """tau(x) = int_0^inf (T_steady - T) dt / (T_steady - T_init) (003 eq. 41), in closed form.

    D = T - T_steady solves D_t = alpha D_xx with D = 0 at both faces and D(x, 0) = T_i - T_s(x);
    W(x) = int_0^inf D dt then solves alpha W'' = -(T_i - T_s(x)), W(0) = W(L) = 0, a cubic:
    with T_s - T_i = a + b x, W = (a x^2/2 + b x^3/6 - (a L/2 + b L^2/6) x) / alpha and
    tau = -W / (T_s - T_i). Undefined (NaN) where T_steady(x) = T_init."""
    x = np.asarray(x, dtype=float)
    a = t_bottom - t_initial
    b = (t_top - t_bottom) / length
    w = (a * x ** 2 / 2 + b * x ** 3 / 6 - (a * length / 2 + b * length ** 2 / 6) * x) / alpha
    excess = a + b * x
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(excess != 0, -w / excess, np.nan)


def rod_temperature(x, t, length, alpha, t_hot, t_initial, tol=1e-12):
    """Rod 0 <= x <= L heated at x = 0 (held at t_hot), adiabatic at x = L, uniform initial
    temperature (Terreros 2012, 000 eq. 8, whose x runs from the adiabatic end). Equal to the
    slab of length 2L with both faces hot, by symmetry."""
    x = np.asarray(x, dtype=float)
    return slab_temperature(x, t, 2 * length, alpha, t_hot, t_hot, t_initial, tol)


def sphere_temperature(r, t, radius, alpha, t_surface, t_initial, tol=1e-12):
    """Sphere of radius R, uniform initial temperature T_0, surface held at T_s from t = 0
    (Carslaw & Jaeger 9.3, eq. 9.3(4)):

        T(r, t) = T_s + (2 R (T_s - T_0) / (pi r)) sum_n (-1)^n / n sin(n pi r / R)
                  exp(-n^2 pi^2 alpha t / R^2)

    Derivation: v = r (T - T_s) solves v_t = alpha v_rr on [0, R] with v = 0 at both ends and
    v(r, 0) = r (T_0 - T_s); its sine series has b_n = 2 (T_0 - T_s) R (-1)^(n+1) / (n pi).

    Haddad 2021 (002) prints this as eq. 18,
        T = T_0 + (2 (T_0 - T_i) / (pi r)) sum_n (-1)^n / n sin(n pi r / R) e^(...),
    with T_0 the initial and T_i the surface temperature: two misprints. (i) The roles of the
    two temperatures are swapped (read literally it tends to the *initial* temperature as
    t -> infinity); (ii) the factor R is missing from 2R/(pi r) (the printed sum is not
    dimensionless; at t = 0 it would give T_0 + (T_i - T_0) / R instead of T_0). With T_0 <-> T_i
    exchanged and R restored it is the form above, which is what this function evaluates
    (tested against an independent finite-volume solve of the radial equation,
    tests/test_validation_case5_7.py, and the limits in tests/test_analytic.py). For
    alpha t / R^2 < 0.05 the equivalent image (erfc) series is summed instead."""
    r = np.asarray(r, dtype=float)
    if t <= 0:
        return np.where(r < radius, t_initial, t_surface) + 0.0 * r
    theta = _sphere_theta(r, t, radius, alpha, tol)
    return t_surface + (t_initial - t_surface) * theta


def _sphere_theta(r, t, radius, alpha, tol):
    fo = alpha * t / radius ** 2
    rr = np.maximum(r, 1e-300)
    if fo < _SWITCH:
        # theta = 1 - (R/r) sum_k [erfc(((2k+1)R - r)/s) - erfc(((2k+1)R + r)/s)]
        s = 2.0 * np.sqrt(alpha * t)
        acc = np.zeros_like(r)
        k = 0
        while True:
            a = (2 * k + 1) * radius
            acc += erfc((a - r) / s) - erfc((a + r) / s)
            if erfc((a + radius) / s) < tol * 1e-3:
                break
            k += 1
        small = r < 1e-6 * radius
        theta = 1.0 - radius / rr * acc
        if np.any(small):
            theta = np.where(small, _sphere_centre_theta(fo, tol), theta)
        return theta
    # theta = (2R/(pi r)) sum_n (-1)^{n+1}/n sin(n pi r/R) exp(-n^2 pi^2 Fo)
    acc = np.zeros_like(r)
    centre = np.zeros_like(r)
    n = 1
    while True:
        decay = np.exp(-(n * np.pi) ** 2 * fo)
        acc += (-1.0) ** (n + 1) / n * np.sin(n * np.pi * r / radius) * decay
        centre += (-1.0) ** (n + 1) * decay
        if np.exp(-((n + 1) * np.pi) ** 2 * fo) < tol * 1e-3:
            break
        n += 1
    small = r < 1e-6 * radius
    return np.where(small, 2.0 * centre, 2.0 * radius / (np.pi * rr) * acc)


def _sphere_centre_theta(fo, tol):
    if fo < _SWITCH:
        # limit r -> 0 of the image form: theta_c = 1 - (2/sqrt(pi Fo)) sum_k e^{-(2k+1)^2/(4 Fo)}
        total, k = 0.0, 0
        while True:
            term = np.exp(-(2 * k + 1) ** 2 / (4 * fo))
            total += term
            if term < tol * 1e-3:
                break
            k += 1
        return 1.0 - 2.0 / np.sqrt(np.pi * fo) * total
    total, n = 0.0, 1
    while True:
        term = np.exp(-(n * np.pi) ** 2 * fo)
        total += (-1.0) ** (n + 1) * term
        if term < tol * 1e-3:
            break
        n += 1
    return 2.0 * total


def sphere_centre_temperature(t, radius, alpha, t_surface, t_initial, tol=1e-12):
    """Centre of the sphere, the limit r -> 0 of sphere_temperature (sin(n pi r/R)/r -> n pi/R):
    T_c = T_s + 2 (T_0 - T_s) sum_n (-1)^(n+1) exp(-n^2 pi^2 alpha t / R^2).

    002 eq. 19 prints T_c = T_0 + 2 (T_0 - T_i) sum_n (-1)^n exp(...): the same swap of the
    initial (T_0) and surface (T_i) temperatures as its eq. 18 (read literally it starts at T_i
    and ends at T_0); with the two exchanged it is the form here. The series converges slowly
    for small alpha t / R^2; there the image form 1 - (2/sqrt(pi Fo)) sum_k exp(-(2k+1)^2/(4 Fo))
    of the dimensionless excess is used."""
    if t <= 0:
        return float(t_initial)
    return t_surface + (t_initial - t_surface) * _sphere_centre_theta(alpha * t / radius ** 2,
                                                                      tol)


def sphere_shell_mean_temperature(r0, r1, t, radius, alpha, t_surface, t_initial, tol=1e-12):
    """Volume mean of sphere_temperature over the shells r0 <= r <= r1 (r0 = 0: a ball about
    the centre), i.e. int T r^2 dr / int r^2 dr, by 32-point Gauss-Legendre quadrature in r
    (exact to round-off for the smooth field at t > 0). What a shell-binned DEM profile
    measures."""
    nodes, weights = np.polynomial.legendre.leggauss(32)
    r0 = np.atleast_1d(np.asarray(r0, float))
    r1 = np.atleast_1d(np.asarray(r1, float))
    half = 0.5 * (r1 - r0)[:, None]
    rs = half * nodes[None, :] + 0.5 * (r1 + r0)[:, None]
    vals = sphere_temperature(rs.ravel(), t, radius, alpha, t_surface,
                              t_initial, tol).reshape(rs.shape)
    w = weights[None, :] * rs ** 2 * half
    return (vals * w).sum(axis=1) / w.sum(axis=1)


def slab_midplane_characteristic_time(length, alpha):
    """tau at the mid-plane x = L/2 of the slab (003 eq. 41), in closed form: L^2 / (8 alpha),
    whatever the two held and the initial temperatures.

    From slab_characteristic_time with T_s - T_i = a + b x: at x = L/2,
    W = -(L^2/8)(a + b L/2)/alpha and T_s - T_i = a + b L/2, so tau = L^2/(8 alpha). (The slowest
    Fourier mode alone would give L^2/(pi^2 alpha), 19 % less.) With 003's App. A diffusivity
    alpha = gamma_paper kappa_p/(rho_p c_p): tau_mid gamma_paper = L^2 rho_p c_p/(8 kappa_p)."""
    return np.asarray(length, dtype=float) ** 2 / (8.0 * np.asarray(alpha, dtype=float))


def rod_mean_temperature(x0, x1, t, length, alpha, t_hot, t_initial, tol=1e-12):
    """Mean of the rod solution (rod_temperature, 000 eq. 8; x from the hot end) over
    x0 <= x <= x1, what a binned profile along the rod measures: the slab of length 2L with
    both faces hot, averaged by slab_mean_temperature."""
    return slab_mean_temperature(x0, x1, t, 2 * length, alpha, t_hot, t_hot, t_initial, tol)


# ------------------------------------------------ effective conductivity of two-phase media
# k_m matrix, k_i inclusions (spheres), f the inclusions' volume fraction; used by
# tdem_post.etc / etc_sweep (tdem etc) and validation cases 8-10 (002 sec. 4-5).

def maxwell(k_m, k_i, f):
    """Maxwell (Maxwell-Garnett) for dilute spheres in a matrix (002 ref. [10]); equals the
    Hashin-Shtrikman bound on the matrix side:
    k = k_m (k_i + 2 k_m + 2 f (k_i - k_m)) / (k_i + 2 k_m - f (k_i - k_m))."""
    k_m, k_i, f = (np.asarray(x, float) for x in (k_m, k_i, f))
    return k_m * (k_i + 2 * k_m + 2 * f * (k_i - k_m)) / (k_i + 2 * k_m - f * (k_i - k_m))


def hashin_shtrikman(k_m, k_i, f):
    """(lower, upper) Hashin-Shtrikman bounds of an isotropic two-phase medium (3-D): Maxwell
    with either phase as the matrix."""
    a = maxwell(k_m, k_i, f)
    b = maxwell(k_i, k_m, 1.0 - np.asarray(f, float))
    return np.minimum(a, b), np.maximum(a, b)


def bruggeman(k_m, k_i, f):
    """Bruggeman's symmetric effective-medium theory (002 ref. [13]):
    f (k_i - k)/(k_i + 2k) + (1 - f)(k_m - k)/(k_m + 2k) = 0, the positive root of
    2 k^2 - b k - k_i k_m = 0 with b = (3f - 1) k_i + (2 - 3f) k_m."""
    k_m, k_i, f = (np.asarray(x, float) for x in (k_m, k_i, f))
    b = (3 * f - 1) * k_i + (2 - 3 * f) * k_m
    return (b + np.sqrt(b * b + 8 * k_i * k_m)) / 4


def rayleigh_cubic_array(k_m, k_i, f):
    """Simple-cubic array of spheres (Rayleigh 1892, with the lattice sum 1.305 of McKenzie,
    McPhedran & Derrick 1978, Proc. R. Soc. A 362, 211):

        k / k_m = 1 - 3 f / (T1 + f - 1.305 T3 f^(10/3)),
        T1 = (2 k_m + k_i) / (k_m - k_i),  T3 = (k_m - k_i) / (4 k_m / 3 + k_i)

    (dipole and octupole terms; at f = 0.155 the octupole term itself moves k by 0.1 %, and the
    further terms of McKenzie et al. are of higher order in f). It is the exact ETC of a cube
    with one centred sphere, two opposite faces held and the others adiabatic (the faces are
    symmetry planes of the array):
    002 sec. 4's configuration, where it lies within 0.11 % of Maxwell (f = 4 pi / 81)."""
    k_m, k_i, f = (np.asarray(x, float) for x in (k_m, k_i, f))
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (2 * k_m + k_i) / (k_m - k_i)
        t3 = (k_m - k_i) / (4 * k_m / 3 + k_i)
        ratio = 1 - 3 * f / (t1 + f - 1.305 * t3 * f ** (10 / 3))
    return k_m * np.where(k_i == k_m, 1.0, ratio)
