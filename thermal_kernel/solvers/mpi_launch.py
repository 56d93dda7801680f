"""Starting the PETSc backend from the project's venv: ``tdem run SCENE --ranks N`` (issue 25).

The ranks run :mod:`thermal_kernel.mpi_run` under ``mpirun`` with the PETSc venv's
Python (``.venv-mpi``, made by ``make``; Debian's petsc4py needs Debian's numpy 1.24, the
project's ``.venv`` has numpy 2). ``TDEM_MPI_PYTHON`` names another interpreter. Each rank runs one
thread (``OMP_NUM_THREADS=1``, ``NUMBA_NUM_THREADS=1``): the ranks are the parallelism, and a
second thread per rank on a 2-core machine only competes with the other rank.
"""
from __future__ import annotations

import contextlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from ..errors import UserError

ROOT = Path(__file__).resolve().parents[2]
# mpirun's options for a run on this machine (``tdem run --ranks``; a cluster run is the user's
# own mpirun line, docs/scaling.md). More ranks than cores are allowed (tests run 3 on 2), and
# a waiting rank yields its core instead of polling, unbound: on the shared 2-core machine
# (load ~4.5 from other jobs) a 3e5 steady solve on 2 ranks took 4.7 s against 8.6 s with
# Open MPI's polling, core-bound default (1 rank: 2.6-3.6 s; bench/bench_scaling.py workers).
MPIRUN_LOCAL = ["--oversubscribe", "--bind-to", "none", "--mca", "mpi_yield_when_idle", "1"]
MPI_VENV_PYTHON = ROOT / ".venv-mpi" / "bin" / "python"


def mpi_python() -> Path:
    """The interpreter the ranks run: $TDEM_MPI_PYTHON, else the checkout's .venv-mpi."""
    given = os.environ.get("TDEM_MPI_PYTHON")
    path = Path(given) if given else MPI_VENV_PYTHON
    if not path.exists():
        raise UserError(f"--ranks: {path}: no such interpreter; expected the PETSc venv "
                        "(`make .venv-mpi/.installed`, or `make test`, builds it; "
                        "TDEM_MPI_PYTHON names another)")
    return path


def missing() -> str | None:
    """Why the backend cannot run here (None when it can): tests skip with this reason."""
    if shutil.which("mpirun") is None:
        return "mpirun not installed (Debian: apt-get install openmpi-bin; `make test` does)"
    try:
        python = mpi_python()
    except UserError as e:
        return str(e)
    done = subprocess.run([str(python), "-c", "import petsc4py, mpi4py, thermal_kernel"],
                          capture_output=True, text=True)
    if done.returncode:
        last = (done.stderr.strip().splitlines() or ["?"])[-1]
        return f"{python} cannot import petsc4py / mpi4py / thermal_kernel: {last}"
    return None


def mpi_env() -> dict:
    env = dict(os.environ, OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1")
    env.pop("VIRTUAL_ENV", None)        # the ranks' venv is their interpreter's own
    env.pop("PYTHONHOME", None)
    if hasattr(os, "geteuid") and os.geteuid() == 0:    # Open MPI refuses root unless told
        env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    return env


def command(scene, ranks: int, *, packing=None, out=None, quiet=False, pc="gamg",
            run_args=None, status=None, checkpoint_every=0, resume=False,
            scene_data=None, inputs=None) -> list[str]:
    cmd = ["mpirun", "-n", str(int(ranks)), *MPIRUN_LOCAL, "-x", "OMP_NUM_THREADS",
           "-x", "NUMBA_NUM_THREADS", str(mpi_python()), "-m", "thermal_kernel.mpi_run",
           str(scene)]
    if packing:
        cmd += ["--packing", str(packing)]
    if out:
        cmd += ["--out", str(out)]
    if quiet:
        cmd.append("--quiet")
    if pc != "gamg":
        cmd += ["--pc", pc]
    if run_args:
        cmd += ["--run-args", json.dumps(run_args, sort_keys=True, default=str)]
    if status:
        cmd += ["--status", str(status)]
    if checkpoint_every:
        cmd += ["--checkpoint-every", str(int(checkpoint_every))]
    if resume:
        cmd.append("--resume")
    if scene_data:
        cmd += ["--scene-data", str(scene_data)]
    for option, path in (inputs or {}).items():     # run_in_memory's inputs (mpi_run's options)
        cmd += [f"--{option}", str(path)]
    return cmd


def checked_ranks(ranks) -> int:
    """``--ranks`` as given: a number of MPI ranks, at least 1, else one line (UserError). The
    one check of ``tdem run``, ``tdem calibrate``, ``tdem campaign`` and :func:`run_on_ranks`."""
    if int(ranks) < 1:
        raise UserError(f"--ranks: expected a number of MPI ranks >= 1, got {ranks}")
    return int(ranks)


def run_on_ranks(scene, ranks: int, *, packing=None, out=None, quiet=False, pc="gamg",
                 run_args=None, checkpoint_every=0, resume=False, data=None,
                 output=None, inputs=None, log=None) -> None:
    """Run the scene on ``ranks`` MPI ranks (output: the scene's thermal.h5, as in-process;
    rank 0 writes the in-process checkpoint every ``checkpoint_every`` output times, and
    ``resume`` continues from one). ``data``: the scene's tables, already parsed, instead of
    the file's (a campaign's case: the campaign file with law and packing set; JSON-able).
    A bad input is one line (UserError); so is mpirun failing. Interrupted (KeyboardInterrupt:
    Ctrl-C, SIGTERM), mpirun and the ranks are ended and, given the run's ``output`` path, the
    interrupt says what the in-process run says (not written, the checkpoint kept). ``inputs``:
    {mpi_run option: file} (``thermal_kernel.run.run_in_memory``'s scene text, start and
    conductance factors, written by it); ``log``: a file that takes what mpirun and the ranks
    print (its last lines then in the error when mpirun fails), instead of the terminal."""
    ranks = checked_ranks(ranks)
    if shutil.which("mpirun") is None:
        raise UserError("--ranks: mpirun not found (Debian: apt-get install openmpi-bin)")
    with tempfile.TemporaryDirectory(prefix="tdem-mpi-") as tmp:
        status = Path(tmp) / "status"
        scene_data = None
        if data is not None:
            scene_data = Path(tmp) / "scene.json"
            try:
                scene_data.write_text(json.dumps(data), encoding="utf-8")
            except (TypeError, ValueError) as e:
                raise UserError(f"{scene}: a value of the scene's tables does not go to the "
                                f"ranks ({e}); expected numbers, strings, arrays and tables "
                                "(a TOML date does not)") from None
        cmd = command(scene, ranks, packing=packing, out=out, quiet=quiet, pc=pc,
                      run_args=run_args, status=status, checkpoint_every=checkpoint_every,
                      resume=resume, scene_data=scene_data, inputs=inputs)
        sys.stdout.flush()
        with contextlib.ExitStack() as stack:
            out = None if log is None else stack.enter_context(open(log, "w"))
            proc = subprocess.Popen(cmd, env=mpi_env(), cwd=os.getcwd(), stdout=out,
                                    stderr=None if out is None else subprocess.STDOUT)
            returncode = _wait(proc, output)
        if status.exists():     # rank 0's one line (a bad scene, packing or solve)
            raise UserError(status.read_text(encoding="utf-8").strip())
        if returncode:
            tail = "" if log is None else " ".join(
                Path(log).read_text(encoding="utf-8", errors="replace").split()[-60:])
            raise UserError(f"--ranks {ranks}: mpirun exited with {returncode} "
                            f"({' '.join(cmd[:3])} ... thermal_kernel.mpi_run)"
                            + (f"; its output ends: {tail}" if tail else ""))


def _wait(proc, output) -> int:
    """mpirun's exit code; interrupted (Ctrl-C, SIGTERM: tdem/cli.py), mpirun and the ranks
    are ended and the interrupt says what the in-process run says."""
    try:
        return proc.wait()
    except KeyboardInterrupt as e:
        _stop(proc)
        if output is None:
            raise
        raise type(e)(_interrupted(Path(output))) from None


def _stop(proc) -> None:
    """End mpirun and its ranks: SIGTERM, which mpirun forwards to the ranks, then (10 s
    later) SIGKILL; returns when mpirun has ended (so have the ranks: it waits for them)."""
    with contextlib.suppress(ProcessLookupError):
        proc.terminate()
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def _interrupted(output: Path) -> str:
    """The in-process run's words for an interrupted run (thermal_kernel/run.py), once the
    lock rank 0 held on ``output`` is removed (a rank ended by a signal leaves its file)."""
    from ..atomic import OutputBusyError, output_lock
    from ..checkpoint import checkpoint_path
    with contextlib.suppress(OutputBusyError, OSError), output_lock(output):
        pass                            # nobody holds it now: taken and removed
    ckpt = checkpoint_path(output)
    return f"{output} not written" + (f"; checkpoint {ckpt} kept (--resume continues from it)"
                                      if ckpt.exists() else "")
