"""Fits of a bed's conduction: gamma = k_eff / k_p from binned profiles against the slab solution
(003 sec. 4.3, Fig. 7), the characteristic time tau (003 eq. 41), and power laws over pressure
y = a p^b + c (003 Fig. 7 and 10)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.optimize import curve_fit, least_squares
from scipy.sparse.linalg import spsolve
from scipy.stats import t as student_t

from .analytic import slab_mean_temperature

# The paper's fitted curves, p in bar (003, Fig. 7 and Fig. 10 captions / text).
PAPER_GAMMA = dict(a=0.01039, b=-0.2919, c=5.353e-4)      # gamma = a p^b + c


def power_law(p, a, b, c):
    return a * np.power(p, b) + c


@dataclass(frozen=True)
class GammaFit:
    gamma: float              # k_eff / k_p
    ci95: tuple               # 95 % confidence interval of gamma
    residual_rms_k: float     # rms of (profile - fitted slab solution), K
    n_points: int
    diffusivity_m2_s: float   # alpha = gamma k_p / (rho c)_bed


def fit_gamma(times_s, edges_m, profiles_k, *, conductivity_w_mk, volumetric_capacity_j_m3k,
              t_bottom, t_top, t_initial, gamma0=0.05) -> GammaFit:
    """Least-squares gamma of profiles (K, B) binned on ``edges_m`` (from the bottom at 0 to the
    top at L) at ``times_s`` against the slab solution (003 App. A, eq. A5-A6) with the
    diffusivity gamma k_p / (rho c)_bed. The 95 % interval is from the Jacobian (Student t)."""
    edges = np.asarray(edges_m, dtype=float)
    length = float(edges[-1] - edges[0])
    lo, hi = edges[:-1] - edges[0], edges[1:] - edges[0]
    profiles = np.asarray(profiles_k, dtype=float)
    ok = np.isfinite(profiles)

    def model(log_gamma):
        alpha = np.exp(log_gamma) * conductivity_w_mk / volumetric_capacity_j_m3k
        return np.array([slab_mean_temperature(lo, hi, t, length, alpha, t_bottom, t_top,
                                               t_initial) for t in times_s])

    def resid(x):
        return (model(x[0]) - profiles)[ok]

    sol = least_squares(resid, [np.log(gamma0)], method="lm", x_scale=1.0)
    gamma = float(np.exp(sol.x[0]))
    r = sol.fun
    n = r.size
    dof = max(n - 1, 1)
    s2 = float(r @ r) / dof
    jac = sol.jac[:, 0] * 1.0                       # d resid / d log gamma
    var_log = s2 / float(jac @ jac) if float(jac @ jac) > 0 else np.inf
    half = student_t.ppf(0.975, dof) * np.sqrt(var_log)
    with np.errstate(over="ignore"):        # a profile that no longer depends on gamma
        interval = (gamma * np.exp(-half), gamma * np.exp(half))
    return GammaFit(gamma, interval,
                    float(np.sqrt(np.mean(r * r))), n,
                    gamma * conductivity_w_mk / volumetric_capacity_j_m3k)


def characteristic_time_network(net, steady_k, initial_k, weights):
    """tau of a section (003 eq. 41) from the network itself, exactly: with e = T_s - T,
    C de/dt = -K e on the free particles, so int_0^inf e dt = K^-1 C e(0) - one sparse solve.
    ``weights`` (N,): the section's partial volumes. Returns
    tau = sum_w int e dt / sum_w (T_s - T_init)."""
    held = np.asarray(net.held)
    # only clusters tied to a reservoir (a held particle or an exchange row) relax; rattlers and
    # floating clusters keep their own temperature and are left out (their e stays 0)
    tied = net.clusters.tied_particle
    u = np.flatnonzero(tied & ~held)
    lap = (net.laplacian + sp.diags(net.exchange_g_w_k)).tocsr()
    e0 = np.asarray(steady_k, float) - np.asarray(initial_k, float)
    integral = np.zeros_like(e0)
    integral[u] = spsolve(lap[u][:, u].tocsc(), net.capacity_j_k[u] * e0[u])
    w = np.asarray(weights, dtype=float) * tied * ~held
    return float((w @ integral) / (w @ e0))


def characteristic_time_series(times_s, section_k, steady_k, initial_k):
    """tau (003 eq. 41) from a time series of a section's mean temperature: trapezoid from t = 0
    (where T = T_init) over the outputs, plus the exponential tail fitted to the last two."""
    t = np.concatenate([[0.0], np.asarray(times_s, float)])
    e = steady_k - np.concatenate([[initial_k], np.asarray(section_k, float)])
    integral = float(np.trapezoid(e, t))
    if len(t) >= 3 and e[-1] * e[-2] > 0 and abs(e[-1]) < abs(e[-2]):
        rate = np.log(e[-2] / e[-1]) / (t[-1] - t[-2])
        integral += e[-1] / rate
    return integral / (steady_k - initial_k)


@dataclass(frozen=True)
class PowerFit:
    a: float
    b: float
    c: float
    stderr: tuple             # standard errors of a, b, c
    rms: float

    def __call__(self, p):
        return power_law(np.asarray(p, float), self.a, self.b, self.c)


def fit_power_law(p, y, p0=None) -> PowerFit:
    """y = a p^b + c by nonlinear least squares (scipy curve_fit), with standard errors."""
    p = np.asarray(p, float)
    y = np.asarray(y, float)
    if p0 is None:
        b0 = np.polyfit(np.log(p), np.log(np.abs(y) + 1e-300), 1)[0]
        p0 = (y[0] / p[0] ** b0, b0, 0.0)
    popt, pcov = curve_fit(power_law, p, y, p0=p0, maxfev=20000)
    err = tuple(np.sqrt(np.diag(pcov))) if np.all(np.isfinite(pcov)) else (np.inf,) * 3
    rms = float(np.sqrt(np.mean((power_law(p, *popt) - y) ** 2)))
    return PowerFit(*map(float, popt), err, rms)
