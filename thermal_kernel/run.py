"""Running a scene: packing + law -> network -> solver -> ``thermal.h5``.

The public path from a scene to a result, two ways: :func:`run_scene` writes the run's output
file (``tdem run``), :func:`run_in_memory` writes nothing and returns the same run as a
:class:`SceneRun` (temperatures, flows, the network, the neighbour choice): the path the
validation cases and other library callers take. Both go through the same build
(:func:`_build_network`), solve (:func:`_solve`) and physics checks (:func:`checked`)."""
from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import json
import math
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .atomic import OutputBusyError, history_rows, output_lock
from .checkpoint import checkpoint_path, packing_sha256, read_checkpoint, write_checkpoint
from .network import Network, ThermalProblem, assemble
from .neighbours import NeighbourChoice
from .output import scene_text_difference, scene_to_json, stored_energy_change, write_thermal
from .packing import Packing, read_packing, write_packing
from .problem import build_problem
from .scene import Scene, SceneError, load_scene
from .solvers import (PhysicsCheck, SolverState, ThermalResult, UnstableTimeStepError,
                      check_physics)
from .solvers.explicit import run_explicit
from .solvers.implicit import run_implicit, scheme_name
from .solvers.steady import solve_steady


@dataclass(frozen=True)
class SceneRun:
    """One scene run on one packing (:func:`run_in_memory`, or :func:`run_scene` before it
    writes): the result with every physics check's flags (temperatures in K and boundary heat
    flows in W at the output times, the energy ledger), the problem (the law's conductance per
    dumped contact row, in the packing's order; the boundaries' rows), the assembled network
    (which particles conduct or are held, capacities), the scene's ``[neighbours]`` choice
    (None: every dumped row conducts) and the law's parameters as used."""
    scene: Scene
    packing: Packing
    problem: ThermalProblem
    network: Network
    neighbours: NeighbourChoice | None
    law_params: dict                       # the law's defaults with the scene's [law_params]
    initial_temperature_k: np.ndarray      # (N,) the start (a steady solve: of its rattlers;
    #                                        a continued run: of the run it continues)
    result: ThermalResult
    check: PhysicsCheck
    assemble_seconds: float

    @property
    def final_temperature_k(self) -> np.ndarray:
        """(N,) the temperatures at the last output time (a steady solve: its one row)."""
        return self.result.temperature_k[-1]

    @property
    def conducting(self) -> np.ndarray:
        """(N,) bool: the particles with at least one conducting contact."""
        return np.asarray(self.network.degree_w_k) > 0


@dataclass(frozen=True)
class RunSummary:
    """A run written to its output file: the file and the run."""
    output: Path
    run: SceneRun

    @property
    def result(self) -> ThermalResult:
        return self.run.result

    @property
    def network(self) -> Network:
        return self.run.network

    @property
    def scene(self) -> Scene:
        return self.run.scene


def _progress_bar(total_steps, end_time, quiet, label="explicit"):
    """A tqdm bar over steps showing simulated time, labelled with the method; None when
    quiet."""
    if quiet:
        return None, None
    from tqdm import tqdm
    bar = tqdm(total=total_steps, unit="step", unit_scale=True, dynamic_ncols=True,
               mininterval=0.5, desc=label)

    def progress(done, n_total, t):
        bar.total = n_total
        bar.n = done
        bar.set_postfix_str(f"t = {t:.4g} / {end_time:.4g} s", refresh=False)
        bar.refresh()
    return bar, progress


def _transient(net, start, times, scene, threads, progress, on_output):
    """One explicit or theta-scheme run from ``start`` (array or state) through ``times``, its
    temperatures handed to ``on_output(k, t, T)`` (:func:`run_in_chunks`), not kept."""
    solver = scene.solver
    if solver.method == "explicit":
        dt = None if math.isnan(solver.dt) else solver.dt
        try:
            return run_explicit(net, start, times, dt=dt, safety=solver.safety,
                                allow_unstable=solver.allow_unstable, progress=progress,
                                threads=threads, keep_temperatures=False,
                                on_output=on_output)
        except UnstableTimeStepError as e:
            raise SceneError(f"{scene.path}: solver.dt: {e}") from None
    return run_implicit(net, start, times, dt=solver.dt, theta=solver.theta,
                        scheme=solver.scheme, startup_steps=solver.startup_steps,
                        progress=progress, keep_temperatures=False, on_output=on_output)


def _check_finite(scene, result, temperatures):
    """A run that blew up (allow_unstable above the bound) ends in one line, nothing written.
    ``temperatures``: the result's rows, kept apart in the run's history (:func:`run_in_chunks`)."""
    bad = np.array([not np.all(np.isfinite(row)) for row in temperatures], dtype=bool)
    if not bad.any():
        return
    t = float(result.times[int(np.argmax(bad))])
    key = "solver.allow_unstable" if scene.solver.allow_unstable else "solver.dt"
    raise SceneError(f"{scene.path}: {key}: the run diverged (non-finite temperatures by t = "
                     f"{t:.6g} s with dt = {result.dt:.4g} s, {result.dt / result.dt_max:.3g} x "
                     f"the stability bound {result.dt_max:.4g} s); nothing written: expected a "
                     "dt at most the bound")


def run_in_chunks(transient, T0, scene, every, resumed, n_particles, packing_hash="", *,
                  n_contacts=0, on_root=None, resumed_at=None, history_dir=None):
    """The transient through the scene's output times in chunks of ``every`` of them, a
    checkpoint after each (0: one chunk, no checkpoint); or from a checkpoint ``resumed`` =
    (state, outputs, totals). ``transient(start, times, on_output)`` runs one chunk from
    ``start`` (array or state), calls ``on_output(k, t, T)`` at its k-th output time (rank 0)
    and returns its ThermalResult (without the temperatures, which ``on_output`` keeps).
    Returns (ThermalResult over all output times, checkpoint path).

    The temperatures at every output time go into one :func:`~.atomic.history_rows` array
    (``history_dir``: the output's folder, where a large history is paged to disk; None: in
    memory), never a list of chunks joined at the end.

    The one loop of the in-process run and of the PETSc backend's ranks
    (thermal_kernel/mpi_run.py), where ``transient`` is collective and returns the result on
    rank 0 only (None elsewhere, and this returns (None, path) there), ``on_root(fn)`` runs
    rank 0's part -- the finite check, the outputs kept, the checkpoint written: the
    in-process checkpoint -- and raises its error on every rank, ``resumed`` is rank 0's and
    ``resumed_at`` its time, given on every rank."""
    on_root = on_root or (lambda fn: fn())
    times = np.asarray(scene.solver.output_times, dtype=np.float64)
    ckpt = checkpoint_path(scene.output)
    outputs = {key: [] for key in ("times", "boundary_heat_flow_w", "boundary_energy_j",
                                   "source_energy_j", "stored_energy_j")}
    totals = {"steps": 0, "wall_seconds": 0.0, "step_seconds": 0.0}
    start = T0
    # rank 0's temperatures at every output time (n_particles is 0 on the other ranks)
    history = history_rows(len(times), n_particles, history_dir)
    rows = 0                # output times recorded in it
    if resumed is not None:
        start, done, totals = resumed
        resumed_at = start.time_s
        for key in outputs:
            outputs[key].append(done[key])
        rows = len(done["times"])
        history[:rows] = done["temperature_k"]
        print(f"  resuming from {ckpt} at t = {start.time_s:.6g} s ({rows} "
              f"outputs done, {int(np.sum(times > start.time_s))} to go)", flush=True)
    if resumed_at is not None:
        rows = int(np.sum(times <= resumed_at))
        times = times[times > resumed_at]
    size = every if every > 0 else max(len(times), 1)
    last = None
    for i in range(0, len(times), size):
        first = rows

        def into_history(k, t, T, first=first):
            history[first + k] = T

        last = transient(start, times[i:i + size], into_history)

        def keep(last=last, first=first):
            nonlocal totals
            _check_finite(scene, last, history[first:first + len(last.times)])
            for key in outputs:
                outputs[key].append(getattr(last, key))
            totals = {"steps": totals["steps"] + last.steps,
                      "wall_seconds": totals["wall_seconds"] + last.wall_seconds,
                      "step_seconds": totals["step_seconds"]
                      + last.info.get("step_seconds", 0.0)}
            if every > 0:
                write_checkpoint(ckpt, last.state,
                                 {**{k: np.concatenate(v) for k, v in outputs.items()},
                                  "temperature_k": history[:first + len(last.times)]},
                                 totals, scene.text, n_particles, packing_hash)
            return True
        on_root(keep)
        rows += len(times[i:i + size])
        start = None if last is None else last.state
    if last is None:
        return None, ckpt
    joined = {k: np.concatenate(v) for k, v in outputs.items()}
    cups = (n_contacts * totals["steps"] / totals["step_seconds"]
            if totals["step_seconds"] > 0 else float("nan"))
    return dataclasses.replace(last, **joined, temperature_k=history,
                               steps=int(totals["steps"]),
                               wall_seconds=float(totals["wall_seconds"]),
                               contact_updates_per_second=cups), ckpt


def transient_label(solver) -> str:
    """The progress bar's label: the method, the implicit scheme named."""
    return "explicit" if solver.method == "explicit" else scheme_name(solver.scheme,
                                                                      solver.theta)


def check_resume(scene, checkpoint_every, resume, packing_n, packing_hash, packing_path):
    """Before anything runs: a steady solve takes no checkpoint options; ``resume`` reads the
    checkpoint (one line if it is missing, of another scene or packing, or already complete).
    The checkpoint's (state, outputs, totals), or None. In-process and on rank 0."""
    solver = scene.solver
    if solver.method == "steady":
        if checkpoint_every or resume:
            raise SceneError(f"{scene.path}: solver.method: a steady solve has no checkpoints "
                             "(--checkpoint-every and --resume are for transient runs)")
        return None
    if not resume:
        return None
    resumed = read_checkpoint(checkpoint_path(scene.output), scene.text, packing_n,
                              packing_hash, packing_path=packing_path)
    if resumed[0].time_s >= solver.output_times[-1]:
        raise SceneError(f"{checkpoint_path(scene.output)}: --resume: the checkpoint "
                         "already holds every output time (delete it to run again)")
    return resumed


def run_scene(scene: Scene, packing_path: Path | None = None, *, quiet: bool = False,
              threads: int | None = None, checkpoint_every: int = 0,
              resume: bool = False, run_args: dict | None = None) -> RunSummary:
    """Run ``scene`` (its packing, or ``packing_path``) and write its output file.

    Transient runs can write a checkpoint every ``checkpoint_every`` output times (beside the
    output, ``<name>.checkpoint.h5``, removed when the run ends) and ``resume`` from it.
    The output is locked for the run (``<name>.lock``, :func:`~thermal_kernel.atomic.output_lock`):
    a second run onto the same output is refused at once.

    The output holds what is needed to post-process the run from it alone
    (:func:`~thermal_kernel.output.read_thermal`): the scene as text and resolved (JSON, every
    default filled in), the time step used, ``run_args`` (how the run was started: the CLI's
    arguments, JSON) and the packing's path and content hash."""
    try:
        with _sigterm_as_interrupt(), output_lock(scene.output):
            return _run_scene(scene, packing_path, quiet=quiet, threads=threads,
                              checkpoint_every=checkpoint_every, resume=resume,
                              run_args=run_args)
    except OutputBusyError as e:
        raise SceneError(str(e)) from None
    except KeyboardInterrupt as e:
        ckpt = checkpoint_path(scene.output)
        kind = type(e) if isinstance(e, Terminated) else KeyboardInterrupt
        raise kind(("terminated (SIGTERM): " if kind is Terminated else "") +
                   f"{scene.output} not written" + (
                       f"; checkpoint {ckpt} kept (--resume continues from it)"
                       if ckpt.exists() else "")) from None


class Terminated(KeyboardInterrupt):
    """The run was ended by SIGTERM (``kill``, a batch system's time limit): cleaned up as for
    Ctrl-C -- the lock removed, no output or temporary file left, a checkpoint kept -- and
    reported in one line (the command line's exit code for it is 128 + SIGTERM = 143 by
    convention)."""
    exit_code = 143


@contextlib.contextmanager
def _sigterm_as_interrupt():
    """For the block, SIGTERM raises :class:`Terminated` in the main thread (between two kernel
    calls, ~0.1 s apart) instead of killing the process on the spot, which left the output's
    lock file behind. Only where Python allows it (the main thread) and nobody else handles
    SIGTERM already (a handler of the caller wins); restored after."""
    import signal
    import threading
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.getsignal(signal.SIGTERM)
    if old not in (signal.SIG_DFL, None):
        yield
        return

    def handler(signum, frame):
        raise Terminated("terminated (SIGTERM)")

    signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def _check_step_count(scene, dt, what):
    """Refuse, before anything runs, a run of more than solver.max_steps steps of ``dt``."""
    solver = scene.solver
    n = solver.end_time / dt if dt > 0 else math.inf
    if not n <= solver.max_steps:
        raise SceneError(f"{scene.path}: {what}: end_time = {solver.end_time:g} s in steps of "
                         f"dt = {dt:g} s is {n:.3g} steps; expected at most solver.max_steps = "
                         f"{solver.max_steps:.6g} (a longer dt, a shorter end_time, or a larger "
                         "max_steps)")


def checked(net, T0, result, principle=None) -> tuple[ThermalResult, PhysicsCheck]:
    """Every run's physics checks (thermal_kernel.solvers.check_physics) on a run from ``T0``,
    their flags added to the result's: (result with the flags, check). One home for the file
    path, the in-memory path and the PETSc backend's rank 0 (``principle``: the network's
    PrincipleInputs, made there when the ranks' build ended)."""
    check = check_physics(net, T0, result, inputs=principle)
    flags = tuple(result.flags) + tuple(f for f in check.flags if f not in result.flags)
    return dataclasses.replace(result, flags=flags), check


def write_run_output(scene, result, net, T0, packing, info, scene_json, packing_hash,
                     assemble_seconds, run_args_json, extra_attrs=None, principle=None,
                     capacity_j_k=None):
    """Every run's physics checks (thermal_kernel.solvers.check_physics) added to the result's
    flags, and thermal.h5 written with the run's attributes: the one home of both for the
    in-process run and the PETSc backend's rank 0 (thermal_kernel/mpi_run.py, which adds its
    own attributes in extra_attrs, and gives the network's PrincipleInputs ``principle`` and
    the capacities ``capacity_j_k`` gathered from the ranks). Returns (output path, result
    with the flags, check)."""
    result, check = checked(net, T0, result, principle)
    attrs = {
        "law": scene.law, "method": result.method, "dt": float(result.dt),
        "dt_max": float(result.dt_max), "dt_paper": float(result.dt_paper),
        "steps": int(result.steps), "wall_seconds": float(result.wall_seconds),
        "assemble_seconds": float(assemble_seconds),
        "contact_updates_per_second": float(result.contact_updates_per_second),
        "flags": ",".join(result.flags), "scene": scene.text, "scene_path": str(scene.path),
        "packing": str(packing.path), "n_particles": packing.n_particles,
        "n_conducting_contacts": int(net.n_active_contacts),
        "n_floating_clusters": net.clusters.n_floating, "n_rattlers": net.clusters.n_rattlers,
        "law_params": json.dumps(info["law_params"], sort_keys=True),
        # the scene's [neighbours] criterion as applied to this packing (issue 23): the gap
        # used and the bulk Z it gives ("null": every dumped row conducts)
        "neighbours": json.dumps(None if info["neighbours"] is None else
                                 info["neighbours"].summary(), sort_keys=True, default=float),
        "scene_json": scene_json,
        # 1: the scene ran as its text says (read_thermal then checks the two still agree);
        # 0: changed through the API after it was read (the resolved scene is what ran)
        "scene_text_agrees": int(scene_text_difference(
            scene.text, str(scene.path), scene_json, scene.law, scene.output.parent) is None),
        "run_args": run_args_json,
        "packing_sha256": packing_hash,
        # every run's physics checks (thermal_kernel.solvers.check_physics)
        "max_principle_checked": int(check.max_principle_checked),
        "max_principle_bounds_k": np.array(check.bounds_k, dtype=np.float64),
        "max_principle_excess_relative": float(check.overshoot_relative),
        "ledger_residual_relative": float(check.ledger_relative),
        "check_messages": "\n".join(check.messages),
        **(extra_attrs or {}),
    }
    boundary_energy, source_energy = result.boundary_energy_j, result.source_energy_j
    if result.method == "steady":
        # a steady solve has no time, hence no energy crossed: no rows (never a NaN); its
        # balance is boundary_heat_flow (and the attribute ledger_residual_relative)
        attrs["energies"] = ("none: a steady solve has no time (boundary_energy and "
                             "source_energy have no rows; boundary_heat_flow holds the balance)")
        boundary_energy = np.zeros((0, len(result.boundary_names)))
        source_energy = np.zeros(0)
    out = write_thermal(scene.output, times=result.times, temperatures=result.temperature_k,
                        boundary_heat_flow_w=result.boundary_heat_flow_w,
                        boundary_energy_j=boundary_energy,
                        source_energy_j=source_energy,
                        capacity_j_k=net.capacity_j_k if capacity_j_k is None
                        else capacity_j_k, initial_temperature_k=T0,
                        boundary_names=result.boundary_names, attrs=attrs)
    return out, result, check


def _build_network(scene: Scene, packing: Packing, conductance_factor=None):
    """The scene's problem on the packing and its network, and the checks made before anything
    runs (an explicit run's step count): (problem, info, network, assemble seconds).
    ``conductance_factor``: (contacts,) multiplies the law's conductances (None: as the law
    gives them)."""
    problem, info = build_problem(scene, packing)
    if conductance_factor is not None:
        problem = dataclasses.replace(
            problem, conductance_w_k=problem.conductance_w_k * np.asarray(conductance_factor))
    t_assemble = time.perf_counter()
    net = assemble(problem)
    assemble_seconds = time.perf_counter() - t_assemble
    solver = scene.solver
    if solver.method == "explicit":
        if math.isnan(solver.dt):
            _check_step_count(scene, solver.safety * net.dt_max_s, "solver.end_time")
        else:
            _check_step_count(scene, solver.dt, "solver.dt")
    return problem, info, net, assemble_seconds


def _solve(scene: Scene, net, T0, threads, *, progress=None, checkpoint_every=0, resumed=None,
           n_particles=0, packing_hash="", history_dir=None):
    """The scene's solver on the network from ``T0`` (an array; a transient also a
    SolverState): a steady solve, or the transient through the output times
    (:func:`run_in_chunks`; checkpoints only with ``checkpoint_every``; ``history_dir``: where
    a large history of temperatures is paged to disk, None: memory).
    (ThermalResult, checkpoint path or None)."""
    if scene.solver.method == "steady":
        return solve_steady(net, T0), None
    return run_in_chunks(
        lambda start, times, on_output: _transient(net, start, times, scene, threads,
                                                   progress, on_output),
        T0, scene, checkpoint_every, resumed, n_particles, packing_hash,
        n_contacts=net.n_active_contacts, history_dir=history_dir)


def _start(scene: Scene, n_particles: int, initial_temperature_k=None) -> np.ndarray:
    """(N,) the run's start: the scene's initial temperature, or ``initial_temperature_k`` (K,
    one number or one per particle)."""
    value = scene.initial_temperature if initial_temperature_k is None else \
        initial_temperature_k
    return np.array(np.broadcast_to(np.asarray(value, dtype=np.float64), (n_particles,)))


_RANKS = contextvars.ContextVar("run_in_memory_ranks", default=None)


@contextlib.contextmanager
def ranks_of_run_in_memory(ranks: int | None):
    """Within the block, :func:`run_in_memory` called without ``ranks`` runs on ``ranks`` MPI
    ranks (0: in-process whatever the scene's backend; None: as the scene says): how ``tdem
    validate --ranks R`` reaches the cases' runs (validation/run.py)."""
    token = _RANKS.set(ranks)
    try:
        yield
    finally:
        _RANKS.reset(token)


def ranks_in_effect() -> int | None:
    """The ranks :func:`ranks_of_run_in_memory` set for this block (None: none set)."""
    return _RANKS.get()


def run_in_memory(scene: Scene, packing: Packing | Path | str | None = None, *,
                  initial_temperature_k=None, start_state: SolverState | None = None,
                  conductance_factor=None, threads: int | None = None,
                  ranks: int | None = None) -> SceneRun:
    """Run ``scene`` on ``packing`` (a :class:`~thermal_kernel.packing.Packing` already in
    memory, a packing file, or None: the scene's) and return the run; nothing is written, nothing
    printed. The same build, solver and physics checks as :func:`run_scene` (whose output file
    holds the same temperatures and flows).

    ``initial_temperature_k`` (K, one number or (N,)) replaces the scene's initial temperature
    (a steady solve's start: what its rattlers and floating clusters keep);
    ``conductance_factor`` ((contacts,), one per dumped row) multiplies the law's conductances
    (a variant of the law no scene key expresses, e.g. validation's cut interfaces);
    ``start_state`` (a transient run's ``result.state``, e.g. of this scene run with a shorter
    dt to its first output time) continues that run instead of starting one: its temperatures,
    time, step count (a Rannacher start-up is not repeated) and energy ledger go on through the
    scene's output times after it, with the scene's solver settings; the physics checks judge
    the whole run from the ledger's start (``SceneRun.initial_temperature_k``).

    ``ranks`` (None: :func:`ranks_of_run_in_memory`'s, else 1 when the scene says ``[solver]
    backend = "petsc"``, else in-process; 0: in-process) > 0 runs the scene on that many MPI
    ranks through PETSc, as ``tdem run --ranks`` does (:func:`_on_ranks`)."""
    if ranks is None:
        ranks = _RANKS.get()
    if ranks is None:
        ranks = 1 if scene.solver.backend == "petsc" else 0
    if int(ranks) < 0:
        raise SceneError(f"{scene.path}: ranks: expected a number of MPI ranks >= 1 (0: "
                         f"in-process), got {ranks}")
    if start_state is not None and (scene.solver.method == "steady"
                                    or initial_temperature_k is not None):
        raise SceneError(f"{scene.path}: start_state continues a transient run (solver.method "
                         f"is {scene.solver.method!r}) and replaces initial_temperature_k")
    if ranks:
        return _on_ranks(scene, packing, int(ranks), initial_temperature_k, start_state,
                         conductance_factor)
    if not isinstance(packing, Packing):
        packing = read_packing(packing or scene.packing)
    problem, info, net, assemble_seconds = _build_network(scene, packing, conductance_factor)
    if start_state is None:
        T0 = start = _start(scene, packing.n_particles, initial_temperature_k)
    else:
        start = start_state
        T0 = np.array(start_state.reference_temperature_k, dtype=np.float64)
    result, _ = _solve(scene, net, start, threads, n_particles=packing.n_particles)
    result, check = checked(net, T0, result)
    return SceneRun(scene=scene, packing=packing, problem=problem, network=net,
                    neighbours=info["neighbours"], law_params=info["law_params"],
                    initial_temperature_k=T0, result=result, check=check,
                    assemble_seconds=assemble_seconds)


def _on_ranks(scene, packing, ranks, initial_temperature_k, start_state, conductance_factor):
    """:func:`run_in_memory` on ``ranks`` MPI ranks: ``thermal_kernel.mpi_run`` through the
    launcher (:func:`~.solvers.mpi_launch.run_on_ranks`, ``.venv-mpi``) into a temporary folder,
    its ``thermal.h5`` read back. The ranks get the scene's text, the packing as it is in memory
    (written to a temporary file: a case may scale it or set its phases), and as .npy files the
    start (``initial_temperature_k``) and the factor per dumped row
    (``conductance_factor``). What differs from the in-process run: the
    problem, network and neighbour choice are the in-process build's (made here too; the ranks
    build theirs, checked to agree on the conducting contacts and the choice), the result is the
    ranks' temperatures, flows and energies as thermal.h5 holds them (the stored energy
    recomputed from them, ``info`` the backend's entries), the check is
    :func:`checked` on them (its messages not printed: what the ranks print goes to a log
    quoted only when mpirun fails), ``assemble_seconds`` is everything but the ranks' solve
    (``result.wall_seconds``): the launch, both builds, the files; ``threads`` is not used (a
    rank runs one thread). ``start_state`` becomes the checkpoint the ranks resume from (the
    scene's text, no outputs done; its ledger's reference the start); a transient run's final
    state comes back through ``mpi_run --state-out``."""
    from .output import scene_text_difference
    from .solvers.mpi_launch import run_on_ranks
    wall0 = time.perf_counter()
    if scene_text_difference(scene.text, str(scene.path), scene_to_json(scene), scene.law,
                             scene.output.parent) is not None:
        raise SceneError(f"{scene.path}: the scene was changed after it was read and the ranks "
                         "read its text; expected a scene read from its text (load_scene)")
    if not isinstance(packing, Packing):
        packing = read_packing(packing or scene.packing)
    problem, info, net, _ = _build_network(scene, packing, conductance_factor)
    if start_state is None:
        T0 = _start(scene, packing.n_particles, initial_temperature_k)
    else:
        T0 = initial_temperature_k = np.array(start_state.reference_temperature_k, np.float64)
        if np.min(scene.solver.output_times) <= start_state.time_s:
            raise SceneError(f"{scene.path}: solver.output_times: a run continued from "
                             f"t = {start_state.time_s:.6g} s on MPI ranks needs every output "
                             "time after it")
    transient = scene.solver.method != "steady"
    with tempfile.TemporaryDirectory(prefix="tdem-ranks-") as tmp:
        tmp = Path(tmp)
        output = load_scene(scene.path, out_dir=tmp / "out", text=scene.text).output
        inputs = _files_for_ranks(tmp, output, scene, packing, problem, T0,
                                  initial_temperature_k is not None, conductance_factor,
                                  start_state)
        run_on_ranks(scene.path, ranks, packing=tmp / "packing.h5", out=tmp / "out", quiet=True,
                     inputs=inputs, resume=start_state is not None, log=tmp / "ranks.log")
        state = (read_checkpoint(inputs["state-out"], scene.text, packing.n_particles)[0]
                 if transient else None)
        result, T0 = _ranks_result(output, scene, problem, info, net, state)
    result, check = checked(net, T0, result)
    return SceneRun(scene=scene, packing=packing, problem=problem, network=net,
                    neighbours=info["neighbours"], law_params=info["law_params"],
                    initial_temperature_k=T0, result=result, check=check,
                    assemble_seconds=time.perf_counter() - wall0 - result.wall_seconds)


def _files_for_ranks(tmp, output, scene, packing, problem, T0, start_given, conductance_factor,
                     start_state) -> dict:
    """:func:`_on_ranks`' files in ``tmp``, as {mpi_run option: file}: the packing as in memory
    (scaled, phases set ...), the scene's text, the start and the factors (.npy), the checkpoint
    a ``start_state`` becomes, and where a transient run's final state comes back."""
    write_packing(tmp / "packing.h5", packing)
    (tmp / "scene.toml").write_text(scene.text, encoding="utf-8")
    inputs = {"scene-text": tmp / "scene.toml"}
    if start_given:
        np.save(tmp / "initial.npy", T0)
        inputs["initial-temperature"] = tmp / "initial.npy"
    if conductance_factor is not None:
        np.save(tmp / "factor.npy", np.broadcast_to(np.asarray(
            conductance_factor, dtype=np.float64), problem.conductance_w_k.shape))
        inputs["conductance-factor"] = tmp / "factor.npy"
    if start_state is not None:         # the checkpoint the ranks resume from
        nb = len(problem.boundary_names)
        write_checkpoint(checkpoint_path(output), start_state, dict(
            times=np.zeros(0), temperature_k=np.zeros((0, packing.n_particles)),
            boundary_heat_flow_w=np.zeros((0, nb)), boundary_energy_j=np.zeros((0, nb)),
            source_energy_j=np.zeros(0), stored_energy_j=np.zeros(0)),
            {"steps": 0, "wall_seconds": 0.0, "step_seconds": 0.0}, scene.text,
            packing.n_particles, packing_sha256(packing))
    if scene.solver.method != "steady":
        inputs["state-out"] = tmp / "state.h5"
    return inputs


def _ranks_result(output, scene, problem, info, net, state):
    """The ranks' ``thermal.h5`` as the in-process ThermalResult (its flags before
    :func:`checked`) and the run's start: (result, T0). The network the ranks built is checked
    against the in-process build's (conducting contacts, neighbour choice)."""
    import h5py
    with h5py.File(output, "r") as f:
        a = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in f.attrs.items()}
        temps = f["temperature"][:]
        data = dict(times=f["time"][:], temperature_k=temps,
                    boundary_heat_flow_w=f["boundary_heat_flow"][:],
                    boundary_energy_j=f["boundary_energy"][:],
                    source_energy_j=f["source_energy"][:])
        T0 = f["initial_temperature"][:]
    if (int(a["n_conducting_contacts"]) != net.n_active_contacts
            or a["neighbours"] != json.dumps(None if info["neighbours"] is None else
                                             info["neighbours"].summary(), sort_keys=True,
                                             default=float)):
        raise RuntimeError(f"{scene.path}: the ranks' network differs from the in-process "
                           f"build's ({a['n_conducting_contacts']} conducting contacts against "
                           f"{net.n_active_contacts}; neighbours {a['neighbours']})")
    if a["method"] == "steady":       # no rows in thermal.h5: the in-process result's NaN
        nb = data["boundary_heat_flow_w"].shape[1]
        data.update(boundary_energy_j=np.full((1, nb), np.nan), source_energy_j=np.full(1, np.nan))
    return ThermalResult(
        method=a["method"], **data,
        stored_energy_j=stored_energy_change(temps, T0, net.capacity_j_k),
        boundary_names=tuple(problem.boundary_names), source_boundary=problem.source_boundary,
        dt=float(a["dt"]), dt_max=float(a["dt_max"]), dt_paper=float(a["dt_paper"]),
        steps=int(a["steps"]), wall_seconds=float(a["wall_seconds"]),
        contact_updates_per_second=float(a["contact_updates_per_second"]),
        flags=tuple(f for f in a["flags"].split(",") if f),
        info=dict(backend=str(a["backend"]), ranks=int(a["ranks"]),
                  cut_contacts=int(a["cut_contacts"]), linear_solver=str(a["linear_solver"]),
                  run_seconds=float(a["run_seconds"])), state=state), T0


def _run_scene(scene, packing_path, *, quiet, threads, checkpoint_every, resume, run_args):
    scene_json = scene_to_json(scene)       # before the solve: a run is never lost to it
    packing = read_packing(packing_path or scene.packing)
    packing_hash = packing_sha256(packing)
    problem, info, net, assemble_seconds = _build_network(scene, packing)
    solver = scene.solver
    T0 = _start(scene, packing.n_particles)
    if not quiet:
        print(f"tdem run: {scene.path}: law {scene.law}, method {solver.method}, "
              f"{packing.n_particles} particles, {net.n_active_contacts} conducting contacts "
              f"({net.n_zero_contacts} with H = 0)", flush=True)
        print(f"  network: {net.clusters.summary()}", flush=True)
        if info["neighbours"] is not None:
            print(f"  {info['neighbours'].line()}", flush=True)
    resumed = check_resume(scene, checkpoint_every, resume, packing.n_particles, packing_hash,
                           packing_path or scene.packing)    # before anything runs or prints
    bar, progress = (None, None) if solver.method == "steady" else \
        _progress_bar(0, solver.end_time, quiet, transient_label(solver))
    try:
        result, ckpt = _solve(scene, net, T0, threads, progress=progress,
                              checkpoint_every=checkpoint_every, resumed=resumed,
                              n_particles=packing.n_particles, packing_hash=packing_hash,
                              history_dir=scene.output.parent)
    finally:
        if bar is not None:
            bar.close()
    run_args_json = json.dumps(dict(run_args or {}, threads=threads,
                                    checkpoint_every=checkpoint_every, resume=resume,
                                    packing=str(packing_path) if packing_path else None),
                               sort_keys=True, default=str)
    out, result, check = write_run_output(scene, result, net, T0, packing, info, scene_json,
                                          packing_hash, assemble_seconds, run_args_json)
    if ckpt is not None and ckpt.exists():
        ckpt.unlink()            # the output is complete: the checkpoint has served
    if not quiet:
        _print_summary(result, out)
    if check.messages:           # a suspect answer is said even with --quiet (one line)
        print(f"tdem: warning: {out}: " + "; ".join(check.messages), file=sys.stderr,
              flush=True)
    return RunSummary(output=out, run=SceneRun(
        scene=scene, packing=packing, problem=problem, network=net,
        neighbours=info["neighbours"], law_params=info["law_params"], initial_temperature_k=T0,
        result=result, check=check, assemble_seconds=assemble_seconds))


def _print_summary(result, out):
    last = result.temperature_k[-1]
    steady = result.method == "steady"
    if steady:
        print(f"  steady: one solve ({result.info.get('linear_solver', '?')}, "
              f"{result.info.get('unknowns', 0)} unknowns), {result.wall_seconds:.3g} s",
              flush=True)
    else:
        print(f"  {result.method}: dt = {result.dt:.4g} s (bound {result.dt_max:.4g} s, paper "
              f"estimate {result.dt_paper:.4g} s), {result.steps} steps, "
              f"{result.wall_seconds:.3g} s, {result.contact_updates_per_second:.3g} "
              "contact-updates/s", flush=True)
    if result.flags:
        print(f"  flags: {', '.join(result.flags)}")
    print(f"  T at t = {result.times[-1]:.4g} s: min {last.min():.6g} K, mean {last.mean():.6g} K,"
          f" max {last.max():.6g} K")
    flows = ", ".join(f"{n} {q:+.4g} W" for n, q in zip(result.boundary_names,
                                                         result.boundary_heat_flow_w[-1]))
    print(f"  heat in through boundaries: {flows or 'none'}")
    if steady:
        bal = float(result.info.get("heat_balance_w", 0.0))
        rel = float(result.info.get("heat_balance_relative", 0.0))
        print(f"  heat balance: sum of the boundary flows {bal:+.3g} W ({abs(rel):.2g} "
              "relative)")
    else:
        with np.errstate(over="ignore", invalid="ignore"):
            resid = result.ledger_residual_j()[-1]
            scale = max(np.abs(result.boundary_energy_j[-1]).max(initial=0.0),
                        abs(result.stored_energy_j[-1]), 1e-300)
            rel = abs(resid) / scale
        print(f"  energy ledger: stored {result.stored_energy_j[-1]:+.6g} J, residual "
              f"{resid:+.3g} J ({rel:.2g} relative)")
    print(f"  wrote {out}", flush=True)
