"""`tdem run SCENE --ranks N` on the ranks: the MPI program that ``mpirun`` starts (issue 25).

    mpirun -n N .venv-mpi/bin/python -m thermal_kernel.mpi_run SCENE [--packing P]
        [--out DIR] [--pc gamg|hypre] [--quiet] [--checkpoint-every K] [--resume]
        [--whole-build] [--status FILE] [--run-args JSON] [--scene-data JSON]
        [--scene-text FILE] [--initial-temperature NPY] [--conductance-factor NPY]

This is the command a user runs on a cluster (with ``--hostfile``; docs/scaling.md).
``tdem run --ranks N`` (:mod:`.solvers.mpi_launch`) starts it from the project's venv. It lives
beside :mod:`.run` (not in ``solvers/``, which never import the scene or the problem builder:
``tests/test_boundaries.py``). Every rank reads the scene and
builds its own rows (:mod:`.rank_build`: its slice of the packing's contacts, sent to the ranks
owning their particles; a ``[neighbours]`` criterion chosen with collectives over the slices;
the law evaluated on each rank's contacts; the boundary kinds on rank 0, their rows sent to
every rank; the clusters joined on rank 0); with ``--whole-build`` (for comparison) rank 0
alone reads the packing, builds the problem with the one law registry and the boundary kinds
(:func:`~thermal_kernel.problem.build_problem`) and assembles the network, then sends each
rank its rows
(:class:`~thermal_kernel.solvers.petsc_backend.DistributedNetwork`); the solve is distributed
(:mod:`.solvers.petsc_backend`); rank 0 checks the physics (the in-process
:func:`~thermal_kernel.solvers.check_physics`) and writes the ordinary ``thermal.h5`` with the
in-process run's attributes, plus ``backend``, ``ranks``, ``cut_contacts``, ``linear_solver``
and ``run_seconds``. Transient runs go through the in-process chunk loop
(:func:`~thermal_kernel.run.run_in_chunks`): rank 0 shows the in-process progress bar, writes
the in-process checkpoint (``--checkpoint-every``) and resumes from one (``--resume``).

``thermal_kernel.run.run_in_memory(..., ranks=N)`` starts it too, with files it writes: the
scene's text (``--scene-text``; SCENE names it, its paths resolve as the original's), the
start (``--initial-temperature``, read by rank 0), a factor per dumped contact row
(``--conductance-factor``, each rank reading its contacts' rows); a run continued from a
state is the checkpoint it writes there (``--resume``), and ``--state-out`` gives the run's
final state back.

Bad input: one line (``tdem: error: ...``) from rank 0, exit 2; with ``--status`` (the
launcher's) rank 0 writes the line there instead and every rank exits 0 (a non-zero exit makes
mpirun print a banner of its own): the launcher prints it and exits 2.
"""
from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np


def _args(argv):
    p = argparse.ArgumentParser(prog="thermal_kernel.mpi_run")
    p.add_argument("scene")
    p.add_argument("--packing")
    p.add_argument("--out")
    p.add_argument("--pc", default="gamg", choices=("gamg", "hypre"))
    p.add_argument("--quiet", action="store_true")
    p.add_argument("--checkpoint-every", type=int, default=0, metavar="K",
                   help="rank 0 writes the in-process checkpoint every K output times")
    p.add_argument("--resume", action="store_true",
                   help="continue from the checkpoint (in-process or ranks made)")
    p.add_argument("--scene-data", help="JSON file: the scene's tables, parsed (a campaign's "
                                        "case: the campaign file's tables, law and packing set)")
    p.add_argument("--whole-build", action="store_true",
                   help="rank 0 reads the packing and builds the whole network, then sends "
                        "each rank its rows (for comparison with the build on the ranks: "
                        "docs/scaling.md)")
    # thermal_kernel.run.run_in_memory's inputs (files it writes; the scene named by SCENE)
    p.add_argument("--scene-text", help="file holding the scene's text (SCENE names it)")
    p.add_argument("--initial-temperature", help=".npy, (N,) K: the start, read by rank 0")
    p.add_argument("--conductance-factor", help=".npy, one per dumped contact row: multiplies "
                                                "the law's conductances (each rank its rows)")
    p.add_argument("--state-out", help="rank 0 writes a transient run's final state there (the "
                                       "checkpoint's format)")
    p.add_argument("--status", help="file to write the one-line error to (the launcher's)")
    p.add_argument("--run-args", default="{}", help="the CLI's arguments (JSON), stored")
    return p.parse_args(argv)


def main(argv=None) -> int:
    import petsc4py
    petsc4py.init([sys.argv[0]])           # PETSc options come from PETSC_OPTIONS only
    from petsc4py import PETSc

    from .errors import SceneError, UserError
    from .network import NetworkError
    from .packing import PackingError
    from .atomic import OutputBusyError
    args = _args(argv)
    rank = PETSc.COMM_WORLD.getRank()
    try:
        with contextlib.ExitStack() as held:
            _run(args, rank, held)
    except (SceneError, UserError, PackingError, NetworkError, ValueError, RuntimeError,
            OutputBusyError, OSError) as e:
        line = " ".join(str(e).split("\n"))
        if rank == 0 and args.status:       # the launcher says it, once
            Path(args.status).write_text(line + "\n", encoding="utf-8")
        elif rank == 0:
            print(f"tdem: error: {line}", file=sys.stderr, flush=True)
        return 0 if args.status else 2
    return 0


def _run(args, rank, held):
    """The run, step by step (each step below says why it is where it is); ``held`` (an
    ExitStack) keeps rank 0's lock on the output until it returns."""
    from petsc4py import PETSc

    from .network import NetworkSummary, summary_of, without_source
    from .rank_build import build_on_ranks
    from .solvers import petsc_backend as backend

    t_start = time.perf_counter()
    comm = PETSc.COMM_WORLD.tompi4py()
    scene = _load_scene(args)                                           # every rank
    packing_path = Path(backend.on_root(comm, lambda: _lock_output(args, scene, held)))
    per_rank = not args.whole_build
    built = {}              # rank 0: what the output needs (packing, info, net, T0, ...)
    t0 = time.perf_counter()
    if per_rank:            # each rank reads and builds its own rows (rank_build.py)
        rb = build_on_ranks(scene, packing_path, comm, conductance_factor=args.conductance_factor)
        if rank == 0:
            built.update(packing=rb.particles, info=rb.info, net=rb.net,
                         packing_hash=rb.packing_sha256)
    resumed_at = backend.on_root(
        comm, lambda: _prepare_on_root(args, scene, packing_path, per_rank, built, t0))
    net = built.get("net")
    if per_rank:
        dist = backend.DistributedNetwork(None, built=rb)
        del rb
    else:
        dist = backend.DistributedNetwork(net, built["packing"].position if rank == 0 else None)
    if rank == 0:
        # the run reads no per-particle array of rank 0's network but its summary (made by the
        # per-rank build; of the whole network with --whole-build): the ranks sum the flows
        # and the stored energy over their rows, the checks have their inputs, the output
        # gathers the capacities, a steady solve's floating clusters and rattlers come from
        # the untied particles' rows; a source every rank evaluates on its block is not kept
        # whole either
        summary = (built["net"] if isinstance(built["net"], NetworkSummary)
                   else summary_of(built["net"]))
        if dist.local_source is not None:
            summary = without_source(summary)
        built.update(net=summary, principle=summary.principle)
        dist.net = summary
    net = built.get("net")
    if rank == 0:
        assemble_seconds = time.perf_counter() - built["assemble_t0"]
        # what the output reads of the packing (its path and size): the particles' arrays are
        # freed for the run (a source keeps the centres it evaluates)
        built["packing"] = SimpleNamespace(path=built["packing"].path,
                                           n_particles=built["packing"].n_particles)
    T0 = built.get("T0")
    if rank == 0 and not args.quiet:
        _print_network(scene, net, dist, built["info"])
    result, ckpt = _solve(args, scene, dist, T0, built, comm, resumed_at)
    # the capacities the output holds, from the ranks' rows (rank 0's network is not read)
    built["capacity"] = dist.gather(dist.capacity)
    if rank != 0:
        return
    _finish_on_root(args, scene, result, ckpt, dist, built, T0, assemble_seconds, t_start)


def _load_scene(args):
    """The scene, read on every rank (each needs its solver, law and boundaries): from its file,
    or from the texts and tables ``tdem campaign`` and ``run_in_memory`` write for the ranks."""
    from .scene import load_scene

    data = None
    if args.scene_data:                     # a campaign's case (tdem/campaign.py)
        data = json.loads(Path(args.scene_data).read_text(encoding="utf-8"))
    text = (Path(args.scene_text) if args.scene_text else
            Path(args.scene) if data else None)
    return load_scene(args.scene, out_dir=Path(args.out) if args.out else None,
                      text=None if text is None else text.read_text(encoding="utf-8"),
                      data=data)


def _lock_output(args, scene, held):
    """Rank 0: the output's lock, held in ``held`` until the run ends (a second run onto it is
    refused at once, as in-process); the packing's path (a [pack] scene's packing not built yet
    is refused: the ranks never build one)."""
    from .atomic import output_lock
    from .scene import SceneError

    held.enter_context(output_lock(scene.output))
    packing_path = Path(args.packing) if args.packing else scene.packing
    if packing_path is None:
        raise SceneError(f"{scene.path}: pack: a [pack] scene needs its packing built "
                         "first (tdem pack SCENE, or tdem run, which builds it)")
    return str(packing_path)


def _prepare_on_root(args, scene, packing_path, per_rank, built, t0):
    """Rank 0 only: the packing, the problem (laws, boundary kinds) and the network when the
    ranks did not build them (``--whole-build``), the checks before the run (the explicit step
    count) and the checkpoint to resume from, all into ``built`` (``t0``: when the build began,
    s). Returns the time resumed from (s; None for a fresh run), which every rank gets."""
    from .checkpoint import packing_sha256
    from .network import assemble
    from .output import scene_to_json
    from .packing import read_packing
    from .problem import build_problem
    from .run import _check_step_count, check_resume

    solver = scene.solver
    scene_json = scene_to_json(scene)
    if not per_rank:
        packing = read_packing(packing_path)
        problem, info = build_problem(scene, packing)
        if args.conductance_factor:
            problem = dataclasses.replace(problem, conductance_w_k=problem.conductance_w_k
                                          * np.load(args.conductance_factor))
        built.update(packing=packing, info=info, net=assemble(problem))
    packing, net = built["packing"], built["net"]
    if solver.method == "explicit":
        _check_step_count(scene, solver.safety * net.dt_max_s if np.isnan(solver.dt)
                          else solver.dt, "solver.end_time" if np.isnan(solver.dt)
                          else "solver.dt")
    packing_hash = built.get("packing_hash") or packing_sha256(packing)  # the ranks': made
    resumed = check_resume(scene, args.checkpoint_every, args.resume, packing.n_particles,
                           packing_hash, packing_path)
    built.update(scene_json=scene_json, packing_hash=packing_hash, assemble_t0=t0,
                 resumed=resumed, T0=np.full(packing.n_particles, scene.initial_temperature)
                 if args.initial_temperature is None else np.load(args.initial_temperature))
    return None if resumed is None else resumed[0].time_s


def _print_network(scene, net, dist, info):
    """Rank 0, unless --quiet: the in-process run's opening lines, plus the ranks and the
    contacts their Morton blocks cut (what the communication costs)."""
    print(f"tdem run: {scene.path}: law {scene.law}, method {scene.solver.method}, "
          f"{net.n} particles, {net.n_active_contacts} conducting contacts "
          f"({net.n_zero_contacts} with H = 0); PETSc on {dist.size} rank(s), "
          f"{dist.cut} contacts cut by the Morton blocks", flush=True)
    print(f"  network: {net.clusters.summary()}", flush=True)
    if info["neighbours"] is not None:
        print(f"  {info['neighbours'].line()}", flush=True)


def _solve(args, scene, dist, T0, built, comm, resumed_at):
    """The distributed solve on every rank: steady in one call; a transient run through the
    in-process chunk loop (rank 0 shows its progress bar, writes and resumes its checkpoints;
    ``resumed_at``: the time resumed from, s). Returns the result (complete on rank 0) and the
    checkpoint's path (None for steady)."""
    from .run import _progress_bar, run_in_chunks, transient_label
    from .solvers import petsc_backend as backend

    rank, solver = comm.Get_rank(), scene.solver
    if solver.method == "steady":
        return backend.solve_steady(dist, T0, pc=args.pc), None
    # rank 0 shows the in-process run's progress bar
    bar, progress = _progress_bar(0, solver.end_time, args.quiet or rank != 0,
                                  transient_label(solver))
    try:
        return run_in_chunks(
            _transient_step(args, scene, dist, progress), T0, scene, args.checkpoint_every,
            built.get("resumed"), built["net"].n if rank == 0 else 0,
            built.get("packing_hash", ""), n_contacts=dist.n_active_contacts,
            on_root=lambda fn: backend.on_root(comm, fn), resumed_at=resumed_at,
            history_dir=scene.output.parent if rank == 0 else None)
    finally:
        if bar is not None:
            bar.close()


def _transient_step(args, scene, dist, progress):
    """The chunk loop's solver: ``(start temperatures K, output times s, on_output) -> result``
    by the scene's method on the ranks (rank 0 hands its temperatures to ``on_output``, not
    kept); an unstable explicit dt is the scene's error, as in-process."""
    from .scene import SceneError
    from .solvers import UnstableTimeStepError
    from .solvers import petsc_backend as backend

    solver = scene.solver

    def transient(start, times, on_output):
        if solver.method == "explicit":
            try:
                return backend.run_explicit(
                    dist, start, times, dt=None if np.isnan(solver.dt) else solver.dt,
                    safety=solver.safety, allow_unstable=solver.allow_unstable,
                    progress=progress, on_output=on_output)
            except UnstableTimeStepError as e:
                raise SceneError(f"{scene.path}: solver.dt: {e}") from None
        return backend.run_implicit(
            dist, start, times, dt=solver.dt, theta=solver.theta, scheme=solver.scheme,
            startup_steps=solver.startup_steps, pc=args.pc, progress=progress,
            on_output=on_output)

    return transient


def _finish_on_root(args, scene, result, ckpt, dist, built, T0, assemble_seconds, t_start):
    """Rank 0: thermal.h5 with the in-process run's attributes and checks plus the backend's
    own (``assemble_seconds``: the build, s; ``t_start``: perf_counter at the start), the spent
    checkpoint removed, the final state for ``run_in_memory`` (``--state-out``), the summary
    and the checks' warning."""
    from .run import _print_summary, write_run_output

    net, packing_hash = built["net"], built["packing_hash"]
    run_args_json = json.dumps(dict(json.loads(args.run_args), threads=None,
                                    checkpoint_every=args.checkpoint_every, resume=args.resume,
                                    packing=str(args.packing) if args.packing else None),
                               sort_keys=True, default=str)
    # the in-process run's attributes and checks (thermal_kernel/run.py), and the backend's own
    out, result, check = write_run_output(
        scene, result, net, T0, built["packing"], built["info"], built["scene_json"],
        packing_hash, assemble_seconds, run_args_json, extra_attrs={
            "backend": "petsc", "ranks": int(dist.size), "cut_contacts": int(dist.cut),
            "linear_solver": str(result.info.get("linear_solver", "none")),
            "run_seconds": float(time.perf_counter() - t_start)},
        principle=built["principle"], capacity_j_k=built["capacity"])
    if ckpt is not None and ckpt.exists():
        ckpt.unlink()            # the output is complete: the checkpoint has served
    if args.state_out and result.state is not None:     # run_in_memory's result.state
        _write_state(Path(args.state_out), result, scene, net.n, packing_hash)
    if not args.quiet:
        its = result.info.get("cg_iterations", [])
        if its:
            print(f"  PETSc CG ({result.info['linear_solver']}): {len(its)} solve(s), "
                  f"{int(np.sum(its))} iterations", flush=True)
        _print_summary(result, out)
    if check.messages:
        print(f"tdem: warning: {out}: " + "; ".join(check.messages), file=sys.stderr,
              flush=True)


def _write_state(path, result, scene, n, packing_hash):
    """A transient run's final state in the checkpoint's format (``run_in_memory`` reads it
    back to continue the run; ``n`` particles)."""
    from .checkpoint import write_checkpoint

    write_checkpoint(path, result.state, {
        k: getattr(result, k) for k in ("times", "temperature_k", "boundary_heat_flow_w",
                                        "boundary_energy_j", "source_energy_j",
                                        "stored_energy_j")},
        {"steps": result.steps}, scene.text, n, packing_hash)


if __name__ == "__main__":
    sys.exit(main())
