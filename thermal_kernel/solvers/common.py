"""What the three solvers share (results, states, output times, the recorder, the BLAS
thread limit, the physics checks), below them so that each imports it and the package
only re-exports (no import circle between the package and its solvers)."""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from threadpoolctl import threadpool_limits

from ..network import Network, PrincipleInputs, ThermalProblem, assemble, principle_inputs
from ..physical import TEMPERATURE_MAX_K   # one home: scenes refuse temperatures above it


class UnstableTimeStepError(ValueError):
    """A requested explicit time step above the positivity/stability bound."""


@dataclass(frozen=True)
class SolverState:
    """What a transient run needs to continue bit for bit: temperatures, time, step count, and
    the energy ledger (cumulative since the ledger's reference state)."""
    temperature_k: np.ndarray          # (N,)
    time_s: float
    step: int
    boundary_energy_j: np.ndarray      # (B,) cumulative heat in through each boundary
    source_energy_j: float             # cumulative source heat
    reference_temperature_k: np.ndarray  # (N,) T0 of the ledger: stored = sum C (T - T_ref)
    dt_s: float                        # the requested/default dt (reused on resume if None)
    method: str


@dataclass(frozen=True)
class ThermalResult:
    """Output of any solver. Rows are output times.

    boundary_heat_flow_w[k, b]: heat entering the network through boundary b at times[k] (W);
    boundary_energy_j[k, b]: its time integral since the ledger's start (J); the column of the
    source boundary (problem.source_boundary, if >= 0) holds the source heat, which
    source_energy_j repeats. Ledger: stored_energy_j = sum_b boundary_energy_j (+ source_energy_j
    when the source has no column); see :meth:`ledger_residual_j`.
    contact_updates_per_second = active contacts (H > 0, each counted once) x steps / seconds
    spent stepping (assembly, JIT compilation and factorisation excluded, see info)."""
    method: str
    times: np.ndarray                  # (K,) s
    temperature_k: np.ndarray          # (K, N)
    boundary_heat_flow_w: np.ndarray   # (K, B)
    boundary_energy_j: np.ndarray      # (K, B)
    source_energy_j: np.ndarray        # (K,)
    stored_energy_j: np.ndarray        # (K,) sum_p C_p (T_p - T_ref,p)
    boundary_names: tuple
    source_boundary: int
    dt: float                          # requested (or default) step; steps may be shorter
    dt_max: float                      # explicit positivity bound (inf if no conduction)
    dt_paper: float                    # paper 002 eq. 15-16 estimate, for comparison
    steps: int
    wall_seconds: float
    contact_updates_per_second: float
    flags: tuple = ()
    info: dict = field(default_factory=dict)
    state: SolverState | None = None

    @property
    def temperatures(self) -> np.ndarray:   # the brief's name
        return self.temperature_k

    def ledger_residual_j(self) -> np.ndarray:
        """(K,) stored energy change minus the heat that came in (boundaries and source)."""
        heat = self.boundary_energy_j.sum(axis=1)
        if self.source_boundary < 0:
            heat = heat + self.source_energy_j
        return self.stored_energy_j - heat


def as_network(problem) -> Network:
    if isinstance(problem, Network):
        return problem
    if isinstance(problem, ThermalProblem):
        return assemble(problem)
    raise TypeError(f"expected a ThermalProblem or an assembled Network, got {type(problem)!r}")


def check_times(times, t_start: float) -> np.ndarray:
    times = np.atleast_1d(np.asarray(times, dtype=np.float64))
    if times.ndim != 1 or times.size == 0:
        raise ValueError("times: give at least one output time")
    if not np.all(np.isfinite(times)):
        raise ValueError("times: output times must be finite")
    if times[0] < t_start:
        raise ValueError(f"times: first output time {times[0]} is before t_start = {t_start}")
    if times.size > 1 and np.any(np.diff(times) <= 0):
        raise ValueError("times: output times must be strictly increasing")
    return times


def interval_steps(t_from: float, t_to: float, dt: float) -> tuple[int, float]:
    """Steps for one output interval: n = ceil((t_to - t_from) / dt) equal steps of
    (t_to - t_from) / n <= dt, so every output time falls on a step without a sliver step."""
    span = t_to - t_from
    if span <= 0:
        return 0, 0.0
    if not math.isfinite(dt):
        return 1, span
    n = max(1, math.ceil(span / dt))
    h = span / n
    while h > dt and n < 2 ** 62:      # division rounding: never exceed dt
        n += 1
        h = span / n
    return n, h


def step_plan(times, t_start: float, dt: float) -> list[tuple[int, float]]:
    """(n, h) of each output interval from ``t_start`` (:func:`interval_steps`): the steps every
    transient solver (in-process and on ranks) takes."""
    plan, t_prev = [], float(t_start)
    for tk in times:
        plan.append(interval_steps(t_prev, float(tk), dt))
        t_prev = float(tk)
    return plan


def start_state(net: Network, T0, t_start, method: str):
    """(T, t, step, boundary_energy, source_energy, T_ref, dt or None) from an array or a
    SolverState. From an array, held particles are set to their temperature and the energy this
    takes, C_p (T_held - T0_p), is credited to their boundary at t_start."""
    T, t, step, energy, src, ref, dt = start_parts(T0, t_start, net.n)
    if ref is not None:                 # a state: as it was
        return T, t, step, energy, src, ref, dt
    ref = T.copy()
    energy = hold_start(T, net.fixed_particle, net.fixed_boundary,
                        net.capacity_j_k[net.fixed_particle],
                        net.held_temperature_k[net.fixed_particle], net.problem.n_boundaries)
    return T, t, step, energy, src, ref, dt


def start_parts(T0, t_start, n: int):
    """:func:`start_state` before the held particles are set: (T, t, step, boundary_energy,
    source_energy, T_ref, dt) from a SolverState as it was; from an array or a number, T (a new
    (n,) array, checked), t_start (0 if None), step 0, and None for the energy, T_ref and dt
    (:func:`hold_start` books the hold; T_ref is T before it). In-process and on the PETSc
    backend's rank 0 (whose ranks hold the particles' rows)."""
    if isinstance(T0, SolverState):
        if t_start is not None and t_start != T0.time_s:
            raise ValueError(f"t_start = {t_start} given with a state at t = {T0.time_s}")
        T = np.array(T0.temperature_k, dtype=np.float64)
        if T.shape != (n,):
            raise ValueError(f"state: temperature has shape {T.shape}, expected ({n},)")
        return (T, float(T0.time_s), int(T0.step),
                np.array(T0.boundary_energy_j, dtype=np.float64), float(T0.source_energy_j),
                np.asarray(T0.reference_temperature_k, dtype=np.float64), T0.dt_s)
    T = np.array(T0, dtype=np.float64)
    if T.ndim == 0:
        T = np.full(n, float(T))
    if T.shape != (n,):
        raise ValueError(f"T0: shape {T.shape}, expected ({n},)")
    if not np.all(np.isfinite(T)):
        raise ValueError("T0: non-finite initial temperatures")
    return T, float(0.0 if t_start is None else t_start), 0, None, 0.0, None, None


def hold_start(T, fixed, fixed_boundary, capacity_fixed, held_t_fixed, nb: int) -> np.ndarray:
    """Sets the held rows ``fixed`` of ``T`` (in place) to their temperature ``held_t_fixed``
    and returns (nb,) the energy this takes, C_p (T_held - T0_p) by boundary (the ledger's start):
    the whole network in-process, a rank's own rows on the PETSc backend."""
    energy = np.zeros(nb)
    if fixed.size:
        jump = capacity_fixed * (held_t_fixed - T[fixed])
        energy += np.bincount(fixed_boundary, weights=jump, minlength=nb)
        T[fixed] = held_t_fixed
    return energy


class Recorder:
    """Collects the output rows (and calls ``on_output`` if given)."""

    def __init__(self, net: Network, times, ref, keep_temperatures=True, on_output=None):
        self.net = net
        k, nb = len(times), net.problem.n_boundaries
        self.times = np.asarray(times, dtype=np.float64)
        self.keep = keep_temperatures
        self.T = np.empty((k, net.n) if keep_temperatures else (k, 0))
        self.flow = np.empty((k, nb))
        self.energy = np.empty((k, nb))
        self.source = np.empty(k)
        self.stored = np.empty(k)
        self.ref = ref
        self.on_output = on_output

    def record(self, k, T, energy, source_energy, source_w=None, *, flow_w=None,
               stored_j=None):
        """Output time ``k``: the temperatures ``T``, the ledger's totals, and the boundaries'
        heat flows and the stored energy computed here from the network at ``T`` (the source's
        powers ``source_w`` at that instant), or given (``flow_w`` (B,) W, ``stored_j`` J: the
        PETSc backend's ranks sum them over their rows)."""
        if self.keep:
            self.T[k] = T
        # a diverging run (allow_unstable) is reported in one line by run_scene; no
        # RuntimeWarning of numpy on the way there
        with np.errstate(invalid="ignore", over="ignore"):
            self.flow[k] = (self.net.boundary_heat_flow(T, source_w) if flow_w is None
                            else flow_w)
            self.stored[k] = (float(np.dot(self.net.capacity_j_k, T - self.ref))
                              if stored_j is None else float(stored_j))
        self.energy[k] = energy
        self.source[k] = source_energy
        if self.on_output is not None:
            self.on_output(k, float(self.times[k]), T)


class blas_threads:
    """Context manager: the BLAS libraries loaded in this process (numpy's and scipy's wheels
    each bring their own OpenBLAS) use ``n`` threads inside, restored after (threadpoolctl);
    ``n=None`` changes nothing. The sparse solves run with 1: on a shared 2-core machine (YADE
    busy on one core) OpenBLAS's second thread made pyamg 20-70x slower (a 20,000-unknown AMG
    setup 3.5 s instead of 0.05 s; a CG solve 0.53 s instead of 0.022 s; see docs/solvers.md)."""

    def __init__(self, n: int | None = 1):
        self.n = n
        self._ctl = None

    def __enter__(self):
        if self.n is not None:
            self._ctl = threadpool_limits(limits=self.n, user_api="blas")
        return self

    def __exit__(self, *exc):
        if self._ctl is not None:
            self._ctl.restore_original_limits()
            self._ctl = None
        return False


# Every run's physics checks (thermal_kernel/run.py): a temperature outside the maximum
# principle's bounds by more than MAX_PRINCIPLE_RTOL x their span, or an energy-ledger residual
# above LEDGER_RTOL x the energy moved, flags the output. Measured: plain Crank-Nicolson on the
# 300-sphere bed at dt = 5 s overshoots by 0.48 of the span; the default "rannacher" scheme by
# at most 5.0e-3 at dt = 40 dt_max (0 at dt <= 20 dt_max); the ledger closes to ~1e-15
# (explicit) and ~1e-12 (implicit).
MAX_PRINCIPLE_RTOL = 1e-3
LEDGER_RTOL = 1e-6
# Temperatures a solid can have: below 0 K none (flag "below_absolute_zero": a heat sink or a
# negative flux drove the linear model through absolute zero), above TEMPERATURE_MAX_K none
# either (flag "above_physical_range": the highest melting point known is ~4,300 K and tungsten
# boils at 5,930 K; constant material properties mean nothing there).


@dataclass(frozen=True)
class PhysicsCheck:
    flags: tuple                 # "max_principle", "energy_ledger", "below_absolute_zero",
    #                              "above_physical_range" (violations only)
    messages: tuple              # one line per violation
    max_principle_checked: bool  # the plain principle: no source and no prescribed power (with
    #                              them the bounds are widened by what they can add, and checked)
    bounds_k: tuple              # (lo, hi) at the last output time (+-inf when unbounded)
    overshoot_relative: float    # worst excursion outside the bounds / span (0 inside)
    ledger_relative: float       # worst |ledger residual| / energy moved


def max_principle_bounds(net: Network, T0, times) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) (K,) arrays: the bounds every temperature at ``times`` (from t = 0) must lie in
    (:func:`bounds_at` of the whole network's :func:`principle_inputs`)."""
    T0 = np.broadcast_to(np.asarray(T0, dtype=np.float64), (net.n,))
    return bounds_at(principle_inputs(net), float(T0.min()), float(T0.max()), times)


def bounds_at(inputs: PrincipleInputs, t0_lo_k: float, t0_hi_k: float, times):
    """(lo, hi) (K,) arrays: the bounds every temperature at ``times`` (from t = 0) must lie in,
    for a start between ``t0_lo_k`` and ``t0_hi_k``.

    [lo0, hi0] is the range of the initial, held and exchange-wall temperatures; a prescribed
    power P_p (fluxes) and the source S_p(t) widen it by what they can add at most:
    hi(t) = hi0 + t max_p P_p^+ / C_p + (the source's largest rise by t), lo(t) alike with the
    negative parts (comparison principle: hi0 + r t, r >= max_p P_p / C_p, is a supersolution
    of C dT/dt = -(L + G) T + G Tw + P; the explicit update with dt <= dt_max and backward
    Euler keep it too). A source that cannot bound its rise leaves the bounds infinite."""
    lo0 = min(t0_lo_k, inputs.prescribed_lo_k)
    hi0 = max(t0_hi_k, inputs.prescribed_hi_k)
    times = np.asarray(times, dtype=np.float64)
    up, down = inputs.power_up_k_s, inputs.power_down_k_s
    with np.errstate(invalid="ignore", over="ignore"):
        hi = hi0 + np.where(up > 0, up * times, 0.0)
        lo = lo0 - np.where(down > 0, down * times, 0.0)
    if inputs.source_unbounded:
        lo[:], hi[:] = -math.inf, math.inf
    elif inputs.source_rate is not None:
        r_up, r_down, start, stop = inputs.source_rate
        for k, t in enumerate(times):
            on = max(0.0, min(float(t), stop) - start)
            if on > 0.0:
                hi[k] += r_up * on
                lo[k] -= r_down * on
    return lo, hi


def _ledger_relative(result: ThermalResult) -> float:
    """The energy ledger's residual relative to the energy moved: a transient run's max
    |residual| over its largest stored change, boundary or source energy; a steady solve's
    heat balance. inf when anything is not finite."""
    if result.method == "steady":
        bal = abs(float(result.info.get("heat_balance_relative", 0.0)))
        return bal if math.isfinite(bal) else math.inf
    with np.errstate(invalid="ignore", over="ignore"):
        resid = np.abs(result.ledger_residual_j())
        scale = max(float(np.nanmax(np.abs(result.stored_energy_j), initial=0.0)),
                    float(np.nanmax(np.abs(result.boundary_energy_j).sum(axis=1),
                                    initial=0.0)),
                    float(np.nanmax(np.abs(result.source_energy_j), initial=0.0)), 1e-300)
        ledger = float(np.nanmax(resid, initial=0.0)) / scale if resid.size else 0.0
    if not np.all(np.isfinite(resid)) or not math.isfinite(ledger):
        return math.inf
    return ledger


def check_physics(net: Network, T0, result: ThermalResult, rtol: float = MAX_PRINCIPLE_RTOL,
                  ledger_rtol: float = LEDGER_RTOL,
                  inputs: PrincipleInputs | None = None) -> PhysicsCheck:
    """The maximum principle, the physical range and the energy ledger of ``result`` (a run
    from ``T0`` at t = 0).

    Maximum principle: every recorded temperature lies in :func:`max_principle_bounds` (the
    range of the initial, held and exchange-wall temperatures, widened by what the fluxes and
    the source can add by then) to ``rtol`` x the span (plus 1e-12 relative round-off).
    Physical range: no temperature below 0 K, none above :data:`TEMPERATURE_MAX_K` (flags
    whatever the bounds). Ledger: transient runs, max |ledger residual| <= ``ledger_rtol`` x
    the largest energy moved (stored change, boundary and source energies); a steady solve,
    its heat balance (sum of boundary flows) <= ``ledger_rtol`` x the flows. ``inputs``: the
    network's :class:`PrincipleInputs` when made elsewhere (the PETSc backend's ranks); else
    :func:`principle_inputs` of ``net``."""
    flags, messages = [], []
    T = np.asarray(result.temperature_k, dtype=np.float64)
    lo = hi = math.nan
    overshoot = 0.0
    if inputs is None:
        inputs = principle_inputs(net)
    # the plain principle (no power, no source): what max_principle_checked has always meant
    checked = inputs.plain
    if T.size:
        t0 = np.asarray(T0, dtype=np.float64)
        los, his = bounds_at(inputs, float(t0.min()), float(t0.max()), result.times)
        lo, hi = float(los[-1]), float(his[-1])
        widened = bool(np.any(np.isfinite(los) | np.isfinite(his)))
        # per output row (no (K, N) temporaries: a big run's temperatures are gigabytes)
        with warnings.catch_warnings():          # an all-NaN row: its min and max are NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            rmin, rmax = np.nanmin(T, axis=1), np.nanmax(T, axis=1)
        with np.errstate(invalid="ignore", over="ignore"):
            span = his - los
            span = np.where(np.isfinite(span), span, np.fmax(rmax - rmin, 0.0))
            tol = rtol * span + 1e-12 * np.maximum(np.abs(np.where(np.isfinite(los), los, 0)),
                                                   np.abs(np.where(np.isfinite(his), his, 0)))
            below, above = los - rmin, rmax - his
            excess = np.fmax(np.fmax(below, above), 0.0)
            bad = excess > tol
            rel = np.where(span > 0, excess / np.where(span > 0, span, 1.0),
                           np.where(bad, math.inf, 0.0))
        if widened and np.any(bad):
            k = int(np.nanargmax(np.where(bad, rel, -1.0)))
            p = int(np.nanargmax(T[k]) if above[k] >= below[k] else np.nanargmin(T[k]))
            overshoot = float(rel[k])
            flags.append("max_principle")
            messages.append(
                f"max_principle: T = {T[k, p]:.6g} K at particle {p}, t = "
                f"{float(result.times[k]):.6g} s, outside [{los[k]:.6g}, {his[k]:.6g}] K (initial "
                "and boundary temperatures, widened by what fluxes and sources can add) by "
                f"{overshoot:.2g} of the span ({result.method}, dt = {result.dt:.4g} s: reduce "
                "dt; docs/solvers.md, stiff modes)")
        elif widened:
            overshoot = float(np.nanmax(rel, initial=0.0))
        tmin, tmax = float(np.nanmin(rmin)), float(np.nanmax(rmax))
        if tmin < 0.0:
            k = int(np.nanargmin(rmin))
            p = int(np.nanargmin(T[k]))
            flags.append("below_absolute_zero")
            messages.append(f"below_absolute_zero: T = {tmin:.6g} K at particle {p}, t = "
                            f"{float(result.times[k]):.6g} s: no temperature is below 0 K (a "
                            "heat sink or a negative flux larger than the bed can give)")
        if tmax > TEMPERATURE_MAX_K:
            k = int(np.nanargmax(rmax))
            p = int(np.nanargmax(T[k]))
            flags.append("above_physical_range")
            messages.append(f"above_physical_range: T = {tmax:.6g} K at particle {p}, t = "
                            f"{float(result.times[k]):.6g} s, above {TEMPERATURE_MAX_K:g} K "
                            "(no solid there: the constant properties mean nothing)")
    ledger = _ledger_relative(result)
    if ledger > ledger_rtol:
        flags.append("energy_ledger")
        messages.append(f"energy_ledger: residual {ledger:.2g} of the energy moved (tolerance "
                        f"{ledger_rtol:g}; {result.method})")
    return PhysicsCheck(flags=tuple(flags), messages=tuple(messages),
                        max_principle_checked=bool(checked), bounds_k=(lo, hi),
                        overshoot_relative=float(overshoot), ledger_relative=float(ledger))


def instantaneous_source(problem: ThermalProblem, t: float):
    if problem.source is None:
        return None
    return np.asarray(problem.source(t, t), dtype=np.float64)

