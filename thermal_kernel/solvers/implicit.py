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

import contextlib
import time

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from .common import (blas_threads, Recorder, SolverState, ThermalResult, as_network, check_times,
               instantaneous_source, start_state, step_plan)

# Free particles up to which the implicit solver factorises (SuperLU) instead of AMG-CG.
# Measured (docs/solvers.md, random packing-like networks, Z ~ 6): factorisation 1.4 s at 1e5,
# 5.3 s at 2e5, 110 s at 4e5 (fill-in), then 0.02 / 0.04 / 0.2 s per step; AMG-CG 0.2 / 0.5 /
# 1.4 s setup and 0.18 / 0.32 / 0.94 s per step. Direct pays off after ~20 steps at 2e5 but
# only after ~150 steps at 4e5.
DIRECT_MAX = 200_000
# pyamg weights its Jacobi prolongation smoother by a spectral-radius estimate whose Krylov
# start is np.random.rand (numpy's global generator): unseeded, each setup builds another
# hierarchy and the answer moves at the solver's tolerance from run to run (the steady flux test
# of runs/dense_box_1e5: lambda_e 34.83881660123666 / ...657 / ... on three runs). Every AMG setup
# runs with the generator seeded by AMG_SEED (:func:`seeded_global_rng`): the same bits every run.
AMG_SEED = 0


@contextlib.contextmanager
def seeded_global_rng(seed: int = AMG_SEED):
    """numpy's global generator seeded for the block, its state put back after (a library that
    draws from it, pyamg, gives the same result every time; the caller's stream is untouched)."""
    state = np.random.get_state()
    try:
        np.random.seed(seed)
        yield
    finally:
        np.random.set_state(state)


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
            with seeded_global_rng():
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
    theta, startup_steps = scheme_args(scheme, theta, startup_steps)
    with blas_threads(blas):
        op = LocalOperator(as_network(problem), method, tol, keep_temperatures, on_output)
        return drive_implicit(op, T0, times, dt=dt, theta=theta, scheme=scheme,
                              startup_steps=startup_steps, t_start=t_start, progress=progress)


def scheme_name(scheme: str, theta: float) -> str:
    if scheme == "theta":
        return f"implicit(theta={theta:g})"
    return f"implicit({scheme})"


def scheme_args(scheme, theta, startup_steps):
    """(theta, startup_steps) the scheme runs with, checked: 'rannacher' and 'tr-bdf2' run at
    theta 0.5; the start-up steps default to 2 for 'rannacher', 0 otherwise (none for 'theta')."""
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
    return theta, startup_steps


def implicit_start(net, T0, t_start, times):
    """(T, t, step, boundary energy, source energy, T_ref, times) of an implicit run from
    ``T0`` (array or state): :func:`start_state` and the output times checked. In-process and
    on the PETSc backend's rank 0."""
    T, t, step0, energy, src, ref, _ = start_state(net, T0, t_start, "implicit")
    return T, t, step0, energy, src, ref, check_times(times, t)


class LocalOperator:
    """The in-process network for :func:`drive_implicit`: the unknowns are the free particles'
    temperatures (one array), the matrices scipy's, each solved by :class:`SpdSolver`.

    The interface (the PETSc backend's ``DistributedOperator`` is the other one): ``net`` (None
    on a rank that does not hold it), ``is_root``, ``start``, ``setup``, ``unknowns``,
    ``factor``, ``capacity``, ``free_only``, ``rhs``, ``source``, ``source_power``, ``ledger``,
    ``record``, ``barrier``, ``finish``, ``recorder``, ``solver_info``."""
    is_root = True

    def __init__(self, net, method="auto", tol=1e-10, keep_temperatures=True, on_output=None):
        self.net, self.method, self.tol = net, method, tol
        self.keep, self.on_output = keep_temperatures, on_output

    def start(self, T0, t_start, times):
        """(times, t, step, source energy, flags) of the run from ``T0`` (array or state)."""
        self.T, t, step0, self.energy0, src, self.ref, times = implicit_start(
            self.net, T0, t_start, times)
        self.recorder = Recorder(self.net, times, self.ref, self.keep, self.on_output)
        return times, t, step0, src, list(self.net.flags)

    def setup(self):
        self.free, self.k_ff, self.r_d = _split(self.net)
        self.b_f = self.net.constant_rhs_w[self.free]
        self.capacity = self.net.capacity_j_k[self.free]

    def unknowns(self):
        """(x, energy): the free temperatures and the ledger to start from."""
        return self.T[self.free], self.energy0

    def factor(self, h, th):
        return SpdSolver((sp.diags(self.capacity / h) + th * self.k_ff).tocsr(), self.method,
                         self.tol)

    @staticmethod
    def free_only(v):
        return v

    def rhs(self, x, sw):
        """F(T) = -K T_f - L_fd T_d + b_f + S_f."""
        r = self.r_d + self.b_f - self.k_ff @ x
        if sw is not None:
            r += sw[self.free]
        return r

    def source(self, t0, t1):
        src = self.net.problem.source
        return None if src is None else np.asarray(src(t0, t1), dtype=np.float64)

    @staticmethod
    def source_power(sw):
        return float(sw.sum())

    def _whole(self, x):
        T = self.T.copy()
        T[self.free] = x
        return T

    def ledger(self, energy, h, x, sw):
        """The heat through the boundaries over a step of ``h`` at the temperatures ``x``."""
        energy += h * self.net.boundary_heat_flow(self._whole(x), sw)

    def record(self, k, x, energy, src_energy, tk):
        self.T[self.free] = x
        self.recorder.record(k, self.T, energy, src_energy,
                             instantaneous_source(self.net.problem, tk))

    def barrier(self):
        pass

    def finish(self, x, energy, flags):
        """(T at the end, the ledger, flags with non_finite if a temperature is not)."""
        T = self._whole(x)
        return T, energy.copy(), list(flags) + ([] if np.all(np.isfinite(T))
                                                else ["non_finite"])

    @staticmethod
    def solver_info(solvers):
        return dict(linear_solver=solvers[0].method if solvers else "none",
                    cg_iterations=[i for s in solvers for i in getattr(s, "iterations", [])])


def _step(op, x, energy, sw, h, solver, scheme, theta):
    """One step of ``h`` from ``x`` with the factorised ``solver`` (TR-BDF2's two stages, or
    the theta step), the boundary energy of its fluxes added to ``energy``: the new ``x``."""
    if scheme == "tr-bdf2":
        d = _TRB_D * h
        inc1 = solver.solve(2.0 * op.rhs(x, sw))                   # trapezoidal stage
        xg = x + inc1
        inc2 = solver.solve(op.rhs(xg, sw) + op.free_only(
            (_TRB_A1 / d) * (op.capacity * inc1)))                 # BDF2 stage
        # Ledger: C (T_{n+1} - T_n) = h [w01 (f_n + f_gamma) + w2 f_{n+1}]
        op.ledger(energy, h, _TRB_W01 * (x + xg) + _TRB_W2 * (xg + inc2), sw)
        return xg + inc2
    inc = solver.solve(op.rhs(x, sw))   # from zero: no better start known
    # Ledger with the theta-weighted temperatures: the fluxes this step used.
    op.ledger(energy, h, x + theta * inc, sw)
    return x + inc


class _Factorisations:
    """The run's factorisations (or AMG hierarchies) by ``op.factor``, one per distinct matrix
    M = C/h + th K, and the seconds they took."""

    def __init__(self, op):
        self.op, self.cache, self.seconds = op, {}, 0.0

    def __call__(self, h, th):
        """(h0, solver) for M = C/h0 + th K, h0 = h or a factorised step within 1e-9."""
        for (h0, th0), s in self.cache.items():
            if th0 == th and abs(h - h0) <= 1e-9 * h0:
                return h0, s
        f0 = time.perf_counter()
        s = self.op.factor(h, th)
        self.seconds += time.perf_counter() - f0
        self.cache[(h, th)] = s
        return h, s


class _TimeLoop:
    """The theta / Rannacher / TR-BDF2 time loop of :func:`drive_implicit` and its running
    totals (steps done, source energy, seconds spent stepping)."""

    def __init__(self, op, factors, scheme, theta, startup_steps, step0, src_energy, progress):
        self.op, self.factors, self.progress = op, factors, progress
        self.scheme, self.theta, self.startup_steps, self.step0 = (scheme, theta, startup_steps,
                                                                   step0)
        self.src_energy, self.done, self.step_seconds = src_energy, 0, 0.0

    def interval_solver(self, h):
        """(h, solver) of an output interval's steps of ``h``: TR-BDF2's C/d + K (``h`` from a
        factorised d), or C/h + theta K."""
        if self.scheme == "tr-bdf2":
            d, solver = self.factors(_TRB_D * h, 1.0)
            return d / _TRB_D, solver
        return self.factors(h, self.theta)

    def step(self, x, energy, h, solver, t0, t1):
        """One step over [t0, t1] (of ``h``): the source's energy booked, a Rannacher start-up
        step (two backward-Euler half steps) or the scheme's :func:`_step`; the new ``x``."""
        op = self.op
        s0 = time.perf_counter()
        sw = op.source(t0, t1)
        if sw is not None:
            self.src_energy += h * op.source_power(sw)
        if self.step0 + self.done < self.startup_steps:
            # Rannacher start-up: two backward-Euler half steps
            hh, half = self.factors(0.5 * h, 1.0)
            for _ in range(2):
                x = x + half.solve(op.rhs(x, sw))
                op.ledger(energy, hh, x, sw)
        else:
            x = _step(op, x, energy, sw, h, solver, self.scheme, self.theta)
        self.step_seconds += time.perf_counter() - s0
        self.done += 1
        return x

    def run(self, x, energy, times, plan, t, started):
        """Every output interval's steps from ``x`` at ``t``, each output time recorded: the
        last ``x``. ``progress`` (on the root) about every 0.1 s after ``started`` and at the
        end."""
        op, progress = self.op, self.progress
        n_total = sum(n for n, _ in plan)
        last_report = started
        t_prev = t
        for k, (tk, (n, h)) in enumerate(zip(times, plan)):
            tk = float(tk)
            if n:
                h, solver = self.interval_solver(h)
            for s in range(n):
                t0 = t_prev + s * h
                t1 = tk if s == n - 1 else t_prev + (s + 1) * h
                x = self.step(x, energy, h, solver, t0, t1)
                if progress is not None and op.is_root and (
                        time.perf_counter() - last_report > 0.1 or self.done == n_total):
                    last_report = time.perf_counter()
                    progress(self.done, n_total, t1)
            t_prev = tk
            op.record(k, x, energy, self.src_energy, tk)
        return x


def drive_implicit(op, T0, times, *, dt, theta, scheme, startup_steps, t_start=None,
                   progress=None) -> ThermalResult | None:
    """The theta / Rannacher / TR-BDF2 time loop over an operator ``op``: the in-process
    :class:`LocalOperator` or the PETSc backend's distributed one (collective there). The plan
    (each output interval in equal steps), the factorisations' cache, the schemes' stages, the
    ledger's weights, the progress and the result are the same for both; ``op`` supplies the
    linear algebra (see :class:`LocalOperator`). ``theta`` and ``startup_steps`` as
    :func:`scheme_args` returns them. The result on the rank that holds the network (None on
    the others). Its steps: :class:`_Factorisations` (the cache), :class:`_TimeLoop` (the loop;
    the step itself is :func:`_step`) and :func:`_implicit_result`."""
    dt = float(dt)
    if not dt > 0:
        raise ValueError(f"dt = {dt}: the time step must be > 0")
    times, t, step0, src_energy, flags = op.start(T0, times=times, t_start=t_start)
    c0 = time.perf_counter()
    op.setup()
    setup_seconds = time.perf_counter() - c0
    factors = _Factorisations(op)
    loop = _TimeLoop(op, factors, scheme, theta, startup_steps, step0, src_energy, progress)
    plan = step_plan(times, t, dt)
    x, energy = op.unknowns()
    op.barrier()
    wall0 = time.perf_counter()
    x = loop.run(x, energy, times, plan, t, started=wall0)
    wall = time.perf_counter() - wall0
    end = op.finish(x, energy, flags)
    if end is None:
        return None
    return _implicit_result(op, end, loop, times, plan, dt=dt,
                            wall_seconds=wall + setup_seconds, setup_seconds=setup_seconds)


def _implicit_result(op, end, loop, times, plan, *, dt, wall_seconds,
                     setup_seconds) -> ThermalResult:
    """The :class:`ThermalResult` of :func:`drive_implicit`'s run: ``end`` is ``op.finish``'s
    (temperatures, ledger, flags), ``loop`` the finished :class:`_TimeLoop`."""
    T_end, energy_total, flags = end
    net, rec = op.net, op.recorder
    prob = net.problem
    scheme, theta, done = loop.scheme, loop.theta, loop.done
    state = SolverState(temperature_k=T_end, time_s=float(times[-1]), step=loop.step0 + done,
                        boundary_energy_j=energy_total, source_energy_j=loop.src_energy,
                        reference_temperature_k=op.ref, dt_s=dt, method="implicit")
    solvers = list(loop.factors.cache.values())
    step_seconds = loop.step_seconds
    return ThermalResult(
        method=scheme_name(scheme, theta), times=times, temperature_k=rec.T,
        boundary_heat_flow_w=rec.flow, boundary_energy_j=rec.energy,
        source_energy_j=rec.source, stored_energy_j=rec.stored,
        boundary_names=prob.boundary_names, source_boundary=prob.source_boundary, dt=dt,
        dt_max=net.dt_max_s, dt_paper=net.dt_paper_s, steps=done,
        wall_seconds=wall_seconds,
        contact_updates_per_second=(net.n_active_contacts * done / step_seconds
                                    if step_seconds > 0 else float("nan")),
        flags=tuple(flags),
        info=dict(theta=theta, scheme=scheme, startup_steps=loop.startup_steps,
                  factorisations=len(solvers), factor_seconds=loop.factors.seconds,
                  setup_seconds=setup_seconds, step_seconds=step_seconds, tol=op.tol,
                  steps_per_interval=[n for n, _ in plan], clusters=net.clusters.summary(),
                  **op.solver_info(solvers)),
        state=state)
