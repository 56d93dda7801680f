"""Theta-scheme (implicit) transient solver: backward Euler (theta = 1), Crank-Nicolson (0.5).

Free particles f, held particles d (T_d fixed), K = L_ff + diag(g_f)::

    (C/dt + theta K) (T^{n+1} - T^n) = F(T^n),   F(T) = -K T_f - L_fd T_d + b_f + S_f

which is the theta-scheme C (T^{n+1} - T^n)/dt = -theta K T^{n+1} - (1-theta) K T^n + ...
written for the increment: the matrix M = C/dt + theta K is symmetric positive definite (the
Dirichlet rows are eliminated, not overwritten), and a relative tolerance on the increment's
right-hand side F stays meaningful as the run approaches steady state.

Solver for M, chosen by size (``method="auto"``): a direct sparse LU (SuperLU with the
symmetric MMD_AT_PLUS_A ordering), factorised once per distinct dt and reused for every step,
for up to ``DIRECT_MAX`` free particles; above that, conjugate gradients preconditioned by a
smoothed-aggregation AMG hierarchy (pyamg, built once per dt), started from zero, relative
residual ``tol``.

Schemes (``scheme``):

* ``"theta"``: the plain theta-scheme above. theta = 1 (backward Euler) is L-stable; theta = 0.5
  (Crank-Nicolson) is A-stable but not L-stable: its amplification factor (1 - z/2)/(1 + z/2),
  z = lambda dt, tends to -1 for the stiff modes (lambda dt >> 1), so the particles next to a held
  wall overshoot and ring (the 300-sphere bed at dt = 5 s reaches 595.6 K between walls at 500
  and 400 K).
* ``"tr-bdf2"``: TR-BDF2 (Bank et al. 1985, gamma = 2 - sqrt 2): a trapezoidal stage to
  t + gamma dt, then BDF2 through t, t + gamma dt, t + dt. Second order and L-stable (the
  amplification factor tends to 0 for stiff modes); both stages solve with the same SPD matrix
  C/d + K, d = (1 - 1/sqrt 2) dt, so one factorisation per step size serves; two solves a step.
* ``"rannacher"``: Crank-Nicolson whose first ``startup_steps`` (2) steps of a run (from
  t_start, where the held particles jump to their temperature) are each replaced by two
  backward-Euler half steps (Rannacher 1984), which damps the stiff modes the jump excites;
  still second order. The default second-order scheme of scenes (``theta = 0.5``): chosen by
  measurement over TR-BDF2 (docs/solvers.md): no overshoot on the 300-sphere bed at dt = 5 s
  where TR-BDF2 overshoots by 29 K (3 K with one start-up step), and the same error per linear
  solve on the stiff transients. Not restarted when a source switches on or off mid-run.
"""
from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from . import (blas_threads, Recorder, SolverState, ThermalResult, as_network, check_times,
               instantaneous_source, interval_steps, start_state)

# Free particles up to which the implicit solver factorises (SuperLU) instead of AMG-CG.
# Measured (docs/solvers.md, random packing-like networks, Z ~ 6): factorisation 1.4 s at 1e5,
# 5.3 s at 2e5, 110 s at 4e5 (fill-in), then 0.02 / 0.04 / 0.2 s per step; AMG-CG 0.2 / 0.5 /
# 1.4 s setup and 0.18 / 0.32 / 0.94 s per step. Direct pays off after ~20 steps at 2e5 but
# only after ~150 steps at 4e5.
DIRECT_MAX = 200_000


class SpdSolver:
    """Solve M x = r for a fixed SPD matrix M: direct (SuperLU) or AMG-preconditioned CG."""

    def __init__(self, m: sp.csr_matrix, method: str = "auto", tol: float = 1e-10,
                 maxiter: int = 1000, direct_max: int = DIRECT_MAX):
        n = m.shape[0]
        if method == "auto":
            method = "direct" if n <= direct_max else "amg"
        if method not in ("direct", "amg"):
            raise ValueError(f"method = {method!r}: use 'auto', 'direct' or 'amg'")
        self.method, self.tol, self.maxiter = method, tol, maxiter
        self.iterations = []
        self.m = m
        if n == 0:
            self.method = "empty"
        elif method == "direct":
            self.lu = splu(m.tocsc(), permc_spec="MMD_AT_PLUS_A",
                           options=dict(SymmetricMode=True))
        else:
            import pyamg
            self.ml = pyamg.smoothed_aggregation_solver(m.tocsr(), symmetry="symmetric",
                                                        max_coarse=500)

    def solve(self, r: np.ndarray, x0=None) -> np.ndarray:
        if self.method == "empty":
            return np.zeros(0)
        if self.method == "direct":
            return self.lu.solve(r)
        res = []
        x = self.ml.solve(r, x0=x0, tol=self.tol, accel="cg", maxiter=self.maxiter,
                          residuals=res)
        self.iterations.append(len(res) - 1)
        nr = np.linalg.norm(r)
        if nr > 0 and np.linalg.norm(r - self.m @ x) > 10 * self.tol * nr:
            raise RuntimeError(f"AMG-CG did not reach the relative residual {self.tol} in "
                               f"{self.maxiter} iterations")
        return x


def _split(net):
    """L_ff + diag(g_f), L_fd T_d term, and the free capacities (built once per run)."""
    free = net.free
    lap = net.laplacian
    k_ff = (lap[free][:, free] + sp.diags(net.exchange_g_w_k[free])).tocsr()
    t_d = np.where(net.held, net.held_temperature_k, 0.0)
    r_d = -(lap[free] @ t_d) if net.fixed_particle.size else np.zeros(free.size)
    return free, k_ff, r_d


SCHEMES = ("theta", "tr-bdf2", "rannacher")
RANNACHER_STEPS = 2      # start-up steps of "rannacher" (4 backward-Euler half steps)
_SQRT2 = np.sqrt(2.0)
_GAMMA = 2.0 - _SQRT2                        # TR-BDF2 stage point
_TRB_D = 1.0 - 1.0 / _SQRT2                  # d / dt: both stages' matrix C/d + K
_TRB_A1 = 1.0 / (_GAMMA * (2.0 - _GAMMA)) - 1.0   # BDF2 stage: weight of C (T_gamma - T_n)
_TRB_W01 = 1.0 / (2.0 * (2.0 - _GAMMA))      # ledger weights of T_n, T_gamma ...
_TRB_W2 = (1.0 - _GAMMA) / (2.0 - _GAMMA)    # ... and T_{n+1} (sum 1)


def run_implicit(problem, T0, times, *, dt, theta=1.0, scheme="theta", startup_steps=None,
                 t_start=None, method="auto", tol=1e-10, progress=None, keep_temperatures=True,
                 on_output=None, blas=1) -> ThermalResult:
    """Implicit run from ``T0`` (array or a previous result's ``state``) to each of ``times``,
    steps <= ``dt`` (each output interval cut into ceil(interval/dt) equal steps). ``scheme``
    'theta' (``theta`` 1 = backward Euler, L-stable, first order; 0.5 = Crank-Nicolson, second
    order, rings for dt far above the stiff modes' time constants), 'tr-bdf2' (second order,
    L-stable, two solves a step) or 'rannacher' (Crank-Nicolson, the first ``startup_steps``
    steps of the run, default 2, each as two backward-Euler half steps; ``theta`` ignored;
    ``startup_steps`` also applies to 'tr-bdf2', default 0). The start-up steps are counted
    from the run's first step (a resumed state continues the count, so a resumed run equals
    the uninterrupted one bit for bit). One
    factorisation (or AMG hierarchy) per distinct matrix; step sizes within 1e-9 relative of a
    factorised one reuse it (and that dt). ``method`` 'auto' | 'direct' | 'amg'; ``tol`` the
    AMG-CG relative residual; ``blas`` the OpenBLAS thread count during the run (1: see
    :class:`~thermal_kernel.solvers.blas_threads`)."""
    with blas_threads(blas):
        return _run_implicit(problem, T0, times, dt=dt, theta=theta, scheme=scheme,
                             startup_steps=startup_steps, t_start=t_start,
                             method=method, tol=tol, progress=progress,
                             keep_temperatures=keep_temperatures, on_output=on_output)


def scheme_name(scheme: str, theta: float) -> str:
    if scheme == "theta":
        return f"implicit(theta={theta:g})"
    return f"implicit({scheme})"


def _run_implicit(problem, T0, times, *, dt, theta, scheme, startup_steps, t_start, method, tol,
                  progress, keep_temperatures, on_output) -> ThermalResult:
    if scheme not in SCHEMES:
        raise ValueError(f"scheme = {scheme!r}: use one of {', '.join(SCHEMES)}")
    if scheme == "theta" and not 0.0 <= theta <= 1.0:
        raise ValueError(f"theta = {theta}: must be in [0, 1]")
    if scheme != "theta":
        theta = 0.5
    if startup_steps is None:
        startup_steps = RANNACHER_STEPS if scheme == "rannacher" else 0
    startup_steps = int(startup_steps) if scheme != "theta" else 0
    if startup_steps < 0:
        raise ValueError(f"startup_steps = {startup_steps}: must be >= 0")
    net = as_network(problem)
    prob = net.problem
    T, t, step0, energy, src_energy, ref, state_dt = start_state(net, T0, t_start, "implicit")
    times = check_times(times, t)
    dt = float(dt)
    if not dt > 0:
        raise ValueError(f"dt = {dt}: the time step must be > 0")
    flags = list(net.flags)
    c0 = time.perf_counter()
    free, k_ff, r_d = _split(net)
    b_f = net.constant_rhs_w[free]
    c_f = net.capacity_j_k[free]
    sb = prob.source_boundary
    setup_seconds = time.perf_counter() - c0
    factor_seconds = 0.0
    cache: dict[tuple, SpdSolver] = {}

    def solver_for(h, th):
        """(h0, solver) for M = C/h0 + th K, h0 = h or a factorised step within 1e-9."""
        nonlocal factor_seconds
        for (h0, th0), s in cache.items():
            if th0 == th and abs(h - h0) <= 1e-9 * h0:
                return h0, s
        f0 = time.perf_counter()
        m = (sp.diags(c_f / h) + th * k_ff).tocsr()
        s = SpdSolver(m, method, tol)
        factor_seconds += time.perf_counter() - f0
        cache[(h, th)] = s
        return h, s

    def rhs_at(Tf, sw):
        r = r_d + b_f - k_ff @ Tf
        if sw is not None:
            r += sw[free]
        return r

    rec = Recorder(net, times, ref, keep_temperatures, on_output)
    plan, t_prev = [], t
    for tk in times:
        plan.append(interval_steps(t_prev, float(tk), dt))
        t_prev = float(tk)
    n_total = sum(n for n, _ in plan)
    done = 0
    wall0 = time.perf_counter()
    step_seconds = 0.0
    t_theta = np.empty_like(T)
    t_prev = t
    last_report = wall0
    for k, (tk, (n, h)) in enumerate(zip(times, plan)):
        tk = float(tk)
        if n:
            if scheme == "tr-bdf2":
                d, solver = solver_for(_TRB_D * h, 1.0)
                h = d / _TRB_D
            else:
                h, solver = solver_for(h, theta)
        for s in range(n):
            t0 = t_prev + s * h
            t1 = tk if s == n - 1 else t_prev + (s + 1) * h
            s0 = time.perf_counter()
            sw = None
            if prob.source is not None:
                sw = np.asarray(prob.source(t0, t1), dtype=np.float64)
                src_energy += h * float(sw.sum())
            if step0 + done < startup_steps:
                # Rannacher start-up: two backward-Euler half steps
                hh, half = solver_for(0.5 * h, 1.0)
                for _ in range(2):
                    T[free] += half.solve(rhs_at(T[free], sw))
                    energy += hh * net.boundary_heat_flow(T, sw)
            elif scheme == "tr-bdf2":
                d = _TRB_D * h
                Tn = T[free].copy()
                inc1 = solver.solve(2.0 * rhs_at(Tn, sw))        # trapezoidal stage
                Tg = Tn + inc1
                inc2 = solver.solve(rhs_at(Tg, sw) + (_TRB_A1 / d) * (c_f * inc1))  # BDF2
                # Ledger: C (T_{n+1} - T_n) = h [w01 (f_n + f_gamma) + w2 f_{n+1}]
                np.copyto(t_theta, T)
                t_theta[free] = _TRB_W01 * (Tn + Tg) + _TRB_W2 * (Tg + inc2)
                energy += h * net.boundary_heat_flow(t_theta, sw)
                T[free] = Tg + inc2
            else:
                inc = solver.solve(rhs_at(T[free], sw))  # from zero: no better start known
                # Ledger with the theta-weighted temperatures: the fluxes this step used.
                np.copyto(t_theta, T)
                t_theta[free] += theta * inc
                energy += h * net.boundary_heat_flow(t_theta, sw)
                T[free] += inc
            step_seconds += time.perf_counter() - s0
            done += 1
            if progress is not None and (time.perf_counter() - last_report > 0.1 or
                                         done == n_total):
                last_report = time.perf_counter()
                progress(done, n_total, t1)
        t_prev = tk
        rec.record(k, T, energy, src_energy, instantaneous_source(prob, tk))
    wall = time.perf_counter() - wall0
    if not np.all(np.isfinite(T)):
        flags.append("non_finite")
    state = SolverState(temperature_k=T.copy(), time_s=float(times[-1]), step=step0 + done,
                        boundary_energy_j=energy.copy(), source_energy_j=src_energy,
                        reference_temperature_k=ref, dt_s=dt, method="implicit")
    solvers = list(cache.values())
    loop = step_seconds
    return ThermalResult(
        method=scheme_name(scheme, theta), times=times, temperature_k=rec.T,
        boundary_heat_flow_w=rec.flow, boundary_energy_j=rec.energy,
        source_energy_j=rec.source, stored_energy_j=rec.stored,
        boundary_names=prob.boundary_names, source_boundary=sb, dt=dt, dt_max=net.dt_max_s,
        dt_paper=net.dt_paper_s, steps=done, wall_seconds=wall + setup_seconds,
        contact_updates_per_second=(net.n_active_contacts * done / loop if loop > 0
                                    else float("nan")),
        flags=tuple(flags),
        info=dict(theta=theta, scheme=scheme, startup_steps=startup_steps,
                  linear_solver=solvers[0].method if solvers else "none",
                  factorisations=len(solvers), factor_seconds=factor_seconds,
                  setup_seconds=setup_seconds, step_seconds=step_seconds, tol=tol,
                  cg_iterations=[i for s in solvers for i in getattr(s, "iterations", [])],
                  steps_per_interval=[n for n, _ in plan], clusters=net.clusters.summary()),
        state=state)
