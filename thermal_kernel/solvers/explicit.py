"""Forward-Euler (explicit) transient solver: a numba kernel that gathers per particle.

One step, for every free particle p (held particles keep their temperature)::

    T_p' = T_p + dt / C_p [ sum_q H_pq (T_q - T_p) + b_p - g_p T_p + S_p ]

b_p = sum g Tw + P_p and g_p (exchange) are constant and precomputed per particle by
:func:`~thermal_kernel.network.assemble`; S_p is the source's mean power over the step.

Each particle sums its own row of the adjacency CSR in column order and writes only its own
new temperature: no atomics, no reduction across threads, so the result is bit-identical for
any number of threads (YADE's ThermalEngine loses updates with 2 threads; FINDINGS.md).

Exact positivity bound: written as T_p' = (1 - dt D_p / C_p) T_p + dt / C_p (sum_q H_pq T_q +
b_p + S_p) with D_p = sum_q H_pq + g_p, the update is a non-negative combination of the old
temperatures iff dt <= dt_max = min_free C_p / D_p; then the maximum principle holds. Since
lambda_max(C^-1 (L + G)) lies in [max D/C, 2 max D/C], the stability (boundedness) limit lies in
[dt_max, 2 dt_max]: above 2 dt_max the scheme always diverges.
"""
from __future__ import annotations

import contextlib
import math
import signal
import threading
import time

import numba
import numpy as np
from numba import njit, prange

# The threading layer (OpenMP first: TBB's fork/join cost dominated a step, docs/solvers.md) is
# chosen by the entry points, not here: thermal_kernel/threading_layer.py.
from .common import (Recorder, SolverState, ThermalResult, UnstableTimeStepError, as_network,
               check_times, instantaneous_source, start_state, step_plan)


# ----------------------------------------------------------------------------- kernels
@njit(parallel=True, cache=True, nogil=True)
def _step_plain(indptr, indices, hval, inv_c, held, dt, t_old, t_new):
    """Laplacian only (no exchange, power or source): T' = T + dt/C sum H (T_q - T_p)."""
    n = t_old.shape[0]
    for p in prange(n):
        tp = t_old[p]
        if held[p]:
            t_new[p] = tp
            continue
        acc = 0.0
        for k in range(indptr[p], indptr[p + 1]):
            acc += hval[k] * (t_old[indices[k]] - tp)
        t_new[p] = tp + (dt * inv_c[p]) * acc


@njit(parallel=True, cache=True, nogil=True)
def _step_rhs(indptr, indices, hval, inv_c, held, g, rhs, dt, t_old, t_new):
    """With the per-particle exchange g_p and right-hand side rhs_p = b_p (+ S_p)."""
    n = t_old.shape[0]
    for p in prange(n):
        tp = t_old[p]
        if held[p]:
            t_new[p] = tp
            continue
        acc = 0.0
        for k in range(indptr[p], indptr[p + 1]):
            acc += hval[k] * (t_old[indices[k]] - tp)
        t_new[p] = tp + (dt * inv_c[p]) * (acc + rhs[p] - g[p] * tp)


@njit(parallel=True, cache=True, nogil=True)
def _held_rows(indptr, indices, hval, t, fixed_p, out):
    """out[r] = sum_q H_pq (T_p - T_q) for the held particle p = fixed_p[r] (parallel over rows,
    each row summed in column order by one thread)."""
    for r in prange(fixed_p.shape[0]):
        p = fixed_p[r]
        tp = t[p]
        acc = 0.0
        for k in range(indptr[p], indptr[p + 1]):
            acc += hval[k] * (tp - t[indices[k]])
        out[r] = acc


@njit(cache=True, nogil=True)
def _boundary_flows(indptr, indices, hval, t, fixed_p, fixed_b, ex_p, ex_g, ex_t, ex_b,
                    held_b, held_out, flows):
    """Heat entering through each boundary at temperatures t (W), summed serially in a fixed
    order: held p gives sum_q H_pq (T_p - T_q) minus the exchange heat it receives; exchange
    rows give g (Tw - T_p). Constant power and the source are added by the caller."""
    for b in range(flows.shape[0]):
        flows[b] = 0.0
    if fixed_p.shape[0]:
        _held_rows(indptr, indices, hval, t, fixed_p, held_out)
        for r in range(fixed_p.shape[0]):
            flows[fixed_b[r]] += held_out[r]
    for r in range(ex_p.shape[0]):
        p = ex_p[r]
        q = ex_g[r] * (ex_t[r] - t[p])
        flows[ex_b[r]] += q
        if held_b[p] >= 0:
            flows[held_b[p]] -= q


@njit(cache=True, nogil=True)
def _advance(n_steps, dt, use_rhs, indptr, indices, hval, inv_c, held, g, rhs, fixed_p,
             fixed_b, ex_p, ex_g, ex_t, ex_b, held_b, const_b, ta, tb, energy, held_out, flows):
    """n_steps forward-Euler steps of size dt; the ledger (energy, J) is advanced with the
    boundary flows at the start of each step, i.e. exactly the fluxes the step uses.
    Returns (latest, other) buffers."""
    for _s in range(n_steps):
        _boundary_flows(indptr, indices, hval, ta, fixed_p, fixed_b, ex_p, ex_g, ex_t, ex_b,
                        held_b, held_out, flows)
        for b in range(energy.shape[0]):
            energy[b] += dt * (flows[b] + const_b[b])
        if use_rhs:
            _step_rhs(indptr, indices, hval, inv_c, held, g, rhs, dt, ta, tb)
        else:
            _step_plain(indptr, indices, hval, inv_c, held, dt, ta, tb)
        ta, tb = tb, ta
    return ta, tb


# ----------------------------------------------------------------------------- helpers
class _Arrays:
    """The kernel's arrays, built once per run from the assembled network (no per-step work)."""

    def __init__(self, net, use_rhs):
        a = net.adjacency
        # Unsigned views of scipy's (non-negative) signed indices, no copy: numba then skips the
        # negative-index wrap-around test on every gather, 1.4x faster (bench/bench_explicit.py).
        self.indptr, self.indices, self.hval = _unsigned(a.indptr), _unsigned(a.indices), a.data
        self.inv_c = 1.0 / net.capacity_j_k
        self.held = net.held
        self.g = np.ascontiguousarray(net.exchange_g_w_k)
        self.b = np.ascontiguousarray(net.constant_rhs_w)
        self.rhs = self.b.copy() if use_rhs else self.b
        self.fixed_p, self.fixed_b = net.fixed_particle, net.fixed_boundary
        self.ex_p, self.ex_g = net.exchange_particle, net.exchange_row_g_w_k
        self.ex_t, self.ex_b = net.exchange_row_temperature_k, net.exchange_boundary
        self.held_b = net.held_boundary
        self.const_b = np.ascontiguousarray(net.constant_boundary_flow_w, dtype=np.float64)
        self.flows = np.zeros(net.problem.n_boundaries)
        self.held_out = np.zeros(self.fixed_p.size)
        self.use_rhs = use_rhs

    def advance(self, n_steps, dt, ta, tb, energy):
        try:
            return self._advance(n_steps, dt, ta, tb, energy)
        except SystemError as e:
            # a SIGINT during the (nogil) kernel surfaces as "CPUDispatcher ... returned a result
            # with an exception set", the KeyboardInterrupt down its chain: give that back
            cause, seen = e, 0
            while cause is not None and seen < 8:
                if isinstance(cause, KeyboardInterrupt):   # its own kind (Terminated too)
                    raise cause.with_traceback(None) from None
                cause, seen = cause.__cause__ or cause.__context__, seen + 1
            raise

    def _advance(self, n_steps, dt, ta, tb, energy):
        return _advance(n_steps, dt, self.use_rhs, self.indptr, self.indices, self.hval,
                        self.inv_c, self.held, self.g, self.rhs, self.fixed_p, self.fixed_b,
                        self.ex_p, self.ex_g, self.ex_t, self.ex_b, self.held_b, self.const_b,
                        ta, tb, energy, self.held_out, self.flows)


@contextlib.contextmanager
def _signals_deferred():
    """SIGINT and SIGTERM held back for the block (the JIT compilation or cache load of the
    kernel: an exception raised inside numba's compiler left it unable to run, and a
    traceback); delivered, and handled as usual, when the block ends. Main thread only."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held = {signal.SIGINT, signal.SIGTERM}
    old = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _unsigned(a: np.ndarray) -> np.ndarray:
    return a.view(np.uint32 if a.dtype == np.int32 else np.uint64)


def explicit_step_reference(problem, T, dt, source_w=None) -> np.ndarray:
    """Plain NumPy forward-Euler step, T + dt/C (-L T - g T + b + S) with held particles kept:
    the reference the numba kernel is tested against."""
    net = as_network(problem)
    T = np.asarray(T, dtype=np.float64)
    rhs = -(net.laplacian @ T) - net.exchange_g_w_k * T + net.constant_rhs_w
    if source_w is not None:
        rhs = rhs + source_w
    out = T + dt / net.capacity_j_k * rhs
    out[net.held] = T[net.held]
    return out


def explicit_step(problem, T, dt, source_w=None) -> np.ndarray:
    """One numba step (no ledger): the kernel :func:`run_explicit` uses, for tests."""
    net = as_network(problem)
    use_rhs = source_w is not None or net.has_exchange or net.has_constant_rhs
    arr = _Arrays(net, use_rhs)
    if source_w is not None:
        np.add(arr.b, source_w, out=arr.rhs)
    ta = np.array(T, dtype=np.float64)
    tb = np.empty_like(ta)
    energy = np.zeros(net.problem.n_boundaries)
    ta, tb = arr.advance(1, float(dt), ta, tb, energy)
    return ta


def check_dt(net, dt, allow_unstable: bool):
    """Refuse dt above the exact bound unless allow_unstable; return the flags."""
    if not dt > 0:
        raise ValueError(f"dt = {dt}: the time step must be > 0")
    if dt > net.dt_max_s:
        if not allow_unstable:
            raise UnstableTimeStepError(
                f"dt = {dt:.6g} s exceeds the explicit bound dt_max = {net.dt_max_s:.6g} s "
                f"(C_p / (sum_q H_pq + g_p) at particle {net.dt_max_particle}); use dt <= dt_max "
                "or allow_unstable=True")
        return ("dt_above_bound",)
    return ()


def explicit_start(net, T0, times, t_start, dt, safety, allow_unstable):
    """(T, t, step, boundary energy, source energy, T_ref, times, dt, flags) of an explicit run
    from ``T0`` (array or state): :func:`start_state`, then :func:`explicit_schedule`."""
    T, t, step0, energy, src_energy, ref, state_dt = start_state(net, T0, t_start, "explicit")
    times, dt, flags = explicit_schedule(net, t, state_dt, times, dt, safety, allow_unstable)
    return T, t, step0, energy, src_energy, ref, times, dt, flags


def explicit_schedule(net, t, state_dt, times, dt, safety, allow_unstable):
    """(times, dt, flags) of an explicit run from ``t``: the output times checked, and dt
    (given, the state's ``state_dt``, or ``safety`` x the bound) checked against the bound.
    In-process and on the PETSc backend's rank 0."""
    times = check_times(times, t)
    if dt is None:
        dt = state_dt if state_dt is not None else safety * net.dt_max_s
        if not (0 < safety <= 1 or (safety > 1 and allow_unstable)):
            raise ValueError(f"safety = {safety}: must be in (0, 1] (above 1 only with "
                             "allow_unstable)")
    dt = float(dt)
    return times, dt, list(net.flags) + list(check_dt(net, dt, allow_unstable))


# ----------------------------------------------------------------------------- driver
def _source_into_rhs(net, arr, energy, t0, t1, h) -> float:
    """The source's powers over [t0, t1] added to the step's right-hand side, its energy (J)
    booked to its boundary and what held particles pass on to theirs taken off: the energy."""
    prob = net.problem
    sw = np.asarray(prob.source(t0, t1), dtype=np.float64)
    np.add(arr.b, sw, out=arr.rhs)
    q = h * float(sw.sum())
    if prob.source_boundary >= 0:
        energy[prob.source_boundary] += q
    if net.fixed_particle.size:
        energy -= h * np.bincount(net.fixed_boundary, weights=sw[net.fixed_particle],
                                  minlength=energy.size)
    return q


class _Steps:
    """The step loops of :func:`run_explicit` and their running totals (steps done, source
    energy, seconds spent in the kernel): chunks of kernel calls through an output interval
    without a source, one call a step with it (its power differs from step to step)."""

    def __init__(self, net, arr, energy, src_energy, n_total, chunk, progress):
        self.net, self.arr, self.energy = net, arr, energy
        self.n_total, self.chunk, self.progress = n_total, chunk, progress
        self.src_energy, self.done, self.step_seconds = src_energy, 0, 0.0

    def in_chunks(self, ta, tb, n, h, t_prev, tk):
        """The ``n`` steps of ``h`` from ``t_prev`` to ``tk``, ``chunk`` steps a kernel call."""
        s = 0
        while s < n:
            m = min(self.chunk, n - s)
            c0 = time.perf_counter()
            ta, tb = self.arr.advance(m, h, ta, tb, self.energy)
            self.step_seconds += time.perf_counter() - c0
            s += m
            self.done += m
            if self.progress is not None:
                self.progress(self.done, self.n_total, t_prev + s * h if s < n else tk)
        return ta, tb

    def with_source(self, ta, tb, n, h, t_prev, tk):
        """The ``n`` steps of ``h`` from ``t_prev`` to ``tk``, one kernel call each after the
        source's power over the step is put in the right-hand side (:func:`_source_into_rhs`)."""
        for s in range(n):
            t0 = t_prev + s * h
            t1 = tk if s == n - 1 else t_prev + (s + 1) * h
            c0 = time.perf_counter()
            self.src_energy += _source_into_rhs(self.net, self.arr, self.energy, t0, t1, h)
            ta, tb = self.arr.advance(1, h, ta, tb, self.energy)
            self.step_seconds += time.perf_counter() - c0
            self.done += 1
            if self.progress is not None and (self.done % self.chunk == 0 or s == n - 1):
                self.progress(self.done, self.n_total, t1)
        return ta, tb

    def run(self, ta, tb, times, plan, t, rec):
        """Every output interval's steps from ``ta`` at ``t``, each output time recorded in
        ``rec``: the last temperatures."""
        prob = self.net.problem
        interval = self.in_chunks if prob.source is None else self.with_source
        t_prev = t
        for k, (tk, (n, h)) in enumerate(zip(times, plan)):
            tk = float(tk)
            ta, tb = interval(ta, tb, n, h, t_prev, tk)
            t_prev = tk
            rec.record(k, ta, self.energy, self.src_energy, instantaneous_source(prob, tk))
        return ta


def run_explicit(problem, T0, times, *, t_start=None, dt=None, safety=0.9,
                 allow_unstable=False, progress=None, threads=None, keep_temperatures=True,
                 on_output=None) -> ThermalResult:
    """Forward Euler from ``T0`` (array, or a previous result's ``state`` to resume) at
    ``t_start`` (default 0, or the state's time) to each of ``times``.

    dt: default ``safety * dt_max`` (dt_max the exact positivity bound, see module doc); a dt
    above dt_max raises :class:`UnstableTimeStepError` unless ``allow_unstable`` (then the
    result is flagged ``dt_above_bound``). Each output interval is cut into
    n = ceil(interval / dt) equal steps (<= dt), so output times are hit exactly. Resuming from
    ``result.state`` reproduces the single run bit for bit when the split time was one of its
    output times. ``progress(step, n_steps, t)`` is called every ~0.1 s of work;
    ``threads`` sets numba's thread count for this run (result independent of it);
    ``on_output(k, t, T)`` is called at each output time. The steps: :class:`_Steps` (the
    loops) and :func:`_explicit_result`."""
    net = as_network(problem)
    prob = net.problem
    (T, t, step0, energy, src_energy, ref, times, dt,
     flags) = explicit_start(net, T0, times, t_start, dt, safety, allow_unstable)
    use_rhs = prob.source is not None or net.has_exchange or net.has_constant_rhs
    arr = _Arrays(net, use_rhs)
    rec = Recorder(net, times, ref, keep_temperatures, on_output)
    plan = step_plan(times, t, dt)
    # ~0.1 s of work per kernel call, also without a progress bar: Ctrl-C is seen between calls
    chunk = max(1, int(2e7 // (net.adjacency.nnz + net.n + 1)))
    steps = _Steps(net, arr, energy, src_energy, sum(n for n, _ in plan), chunk, progress)

    old_threads = numba.get_num_threads()
    if threads is not None:
        numba.set_num_threads(int(threads))
    ta, tb = T, np.empty_like(T)
    with _signals_deferred():          # a signal inside numba's compiler leaves it broken
        arr.advance(0, dt if math.isfinite(dt) else 1.0, ta, tb, energy)  # compile, untimed
    wall0 = time.perf_counter()
    try:
        ta = steps.run(ta, tb, times, plan, t, rec)
    finally:
        if threads is not None:
            numba.set_num_threads(old_threads)
    wall = time.perf_counter() - wall0
    if not np.all(np.isfinite(ta)):
        flags.append("non_finite")
    return _explicit_result(net, rec, steps, ta, times, plan, dt=dt, ref=ref, step0=step0,
                            wall_seconds=wall, flags=flags, threads=threads)


def _explicit_result(net, rec, steps, ta, times, plan, *, dt, ref, step0, wall_seconds, flags,
                     threads) -> ThermalResult:
    """The :class:`ThermalResult` of :func:`run_explicit`'s run: ``ta`` the last temperatures,
    ``steps`` the finished :class:`_Steps`, ``rec`` the output times' records."""
    prob = net.problem
    done, step_seconds = steps.done, steps.step_seconds
    state = SolverState(temperature_k=ta.copy(), time_s=float(times[-1]), step=step0 + done,
                        boundary_energy_j=steps.energy.copy(), source_energy_j=steps.src_energy,
                        reference_temperature_k=ref, dt_s=dt, method="explicit")
    cups = net.n_active_contacts * done / step_seconds if step_seconds > 0 else float("nan")
    return ThermalResult(
        method="explicit", times=times, temperature_k=rec.T, boundary_heat_flow_w=rec.flow,
        boundary_energy_j=rec.energy, source_energy_j=rec.source, stored_energy_j=rec.stored,
        boundary_names=prob.boundary_names, source_boundary=prob.source_boundary, dt=dt,
        dt_max=net.dt_max_s, dt_paper=net.dt_paper_s, steps=done, wall_seconds=wall_seconds,
        contact_updates_per_second=cups, flags=tuple(flags),
        info=dict(step_seconds=step_seconds, threads=numba.get_num_threads()
                  if threads is None else int(threads), clusters=net.clusters.summary(),
                  steps_per_interval=[n for n, _ in plan],
                  dt_per_interval=[h for _, h in plan], dt_max_particle=net.dt_max_particle),
        state=state)
