"""Running the YADE generators (``yade_scripts/``) from tdem: environment, progress, errors."""
from __future__ import annotations

import importlib
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import time
from collections import deque
from pathlib import Path

from thermal_kernel.atomic import write_text_atomic

YADE_SCRIPTS = Path(os.environ.get("TDEM_YADE_SCRIPTS",
                                   Path(__file__).resolve().parent.parent / "yade_scripts"))
SCRIPTS = {"dense": "dense_packing.py", "bed": "compressed_bed.py"}


class YadeError(RuntimeError):
    """YADE is missing or a generator failed; the message is one line."""


def yade_environment() -> dict:
    """The environment YADE runs in: ours without any virtualenv or PYTHONPATH.

    With VIRTUAL_ENV set, YADE 2023.02a adds the venv's site-packages to sys.path and mixes
    Debian's numpy with the venv's h5py (shared/FINDINGS.md); the generators must run on
    Debian's own numpy and python3-h5py."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("VIRTUAL_ENV", "PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP")}
    venv_bin = os.path.join(sys.prefix, "bin")
    env["PATH"] = os.pathsep.join(p for p in env.get("PATH", "").split(os.pathsep)
                                  if p != venv_bin)
    return env


def yade_executable() -> str:
    exe = shutil.which("yade", path=yade_environment()["PATH"])
    if exe is None:
        raise YadeError("yade: not found on PATH; install Debian's YADE "
                        "(`apt-get install -y yade python3-h5py`, which `make demo` does)")
    return exe


_PACKAGE = "tdem_yade_scripts"      # the name yade_scripts/ is loaded under on this side


def scripts_module(name: str):
    """A pure module of ``yade_scripts/`` (``params``, ``placement``, ``dense_geometry``, ...),
    imported from YADE_SCRIPTS as a submodule of the package ``tdem_yade_scripts``: the folder
    YADE will run (``TDEM_YADE_SCRIPTS`` may point elsewhere than the installed
    ``yade_scripts``), so the checks before YADE are those of the scripts it runs."""
    if _PACKAGE not in sys.modules:
        spec = importlib.util.spec_from_file_location(
            _PACKAGE, YADE_SCRIPTS / "__init__.py", submodule_search_locations=[str(YADE_SCRIPTS)])
        package = importlib.util.module_from_spec(spec)
        sys.modules[_PACKAGE] = package
        spec.loader.exec_module(package)
    return importlib.import_module(f"{_PACKAGE}.{name}")


def resolve_params(generator: str, table: dict) -> dict:
    """Defaults filled in, every key checked, then the generator's cross-field checks (the
    ones its YADE script runs): raises ValueError('key: ...') before YADE starts."""
    params = scripts_module("params")
    return params.resolve_and_check(generator, table)


def run_generator(generator: str, params: dict, out_dir: Path, *, threads: int = 1,
                  quiet: bool = False) -> float:
    """Run one generator under YADE with ``params`` (already resolved); return wall seconds.

    Writes ``out_dir/params.json`` and ``out_dir/yade.log``; YADE's output is streamed to
    stdout (unless quiet). A non-zero exit raises YadeError with the script's last error line.
    """
    out_dir = Path(out_dir).resolve()      # YADE runs in another folder: no relative paths
    out_dir.mkdir(parents=True, exist_ok=True)
    params = dict(params, output_dir=str(out_dir))
    params_path = out_dir / "params.json"
    write_text_atomic(params_path, json.dumps(params, indent=1, sort_keys=True))
    script = YADE_SCRIPTS / SCRIPTS[generator]
    cmd = [yade_executable(), "-n", f"-j{threads}", "-x", str(script), str(params_path)]
    log_path = out_dir / "yade.log"
    start = time.perf_counter()
    rc, tail = _run_logged(cmd, out_dir, log_path,
                           lambda line: None if quiet or _is_banner(line) else "  yade | " + line)
    wall = time.perf_counter() - start
    if rc != 0:
        errors = [line for line in tail if line.startswith("error:")]
        last = (errors[-1] if errors else
                next((line for line in reversed(tail) if line.strip()), ""))
        raise YadeError(f"{script.name} failed (exit {rc}): {last.strip()} (full log: {log_path})")
    return wall


def _run_logged(cmd: list[str], cwd: Path, log_path: Path, show) -> tuple[int, deque]:
    """Run a YADE command in its environment: every line into ``log_path``, the lines for which
    ``show(line)`` returns text printed; return (exit status, the last 20 lines)."""
    tail = deque(maxlen=20)
    with open(log_path, "w") as log:
        log.write("$ " + " ".join(cmd) + "\n")
        # its own process group: an interrupted tdem (Ctrl-C, SIGTERM) stops YADE and the jobs
        # of yade-batch with it instead of leaving them running (issue 28)
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, env=yade_environment(),
                                cwd=cwd, text=True, bufsize=1, start_new_session=True)
        try:
            for line in proc.stdout:
                log.write(line)
                log.flush()
                line = line.rstrip()
                tail.append(line)
                text = show(line)
                if text is not None:
                    print(text, flush=True)
            return proc.wait(), tail
        except BaseException:
            _stop_group(proc)
            raise


def _stop_group(proc: subprocess.Popen) -> None:
    """Terminate a YADE process group (SIGTERM, then SIGKILL after 5 s)."""
    import signal
    for sig, wait in ((signal.SIGTERM, 5.0), (signal.SIGKILL, 5.0)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            return
        try:
            proc.wait(timeout=wait)
            return
        except subprocess.TimeoutExpired:
            continue


def _is_banner(line: str) -> bool:
    # (YADE's start-up lines, and its warning that NewtonIntegrator.densityScaling adjusted the
    # time stepper - which is what the density-scaled path asks for; both stay in yade.log)
    return line.startswith(("TCP python prompt", "XMLRPC info provider", "Running script",
                            "Welcome to Yade", "Yade version", "Using python version")) \
        or "set_densityScaling" in line


def yade_batch_executable() -> str:
    exe = shutil.which("yade-batch", path=yade_environment()["PATH"])
    if exe is None:
        raise YadeError("yade-batch: not found on PATH; install Debian's YADE "
                        "(`apt-get install -y yade`, which `make demo` does)")
    return exe


BATCH_GENERATORS = ("dense",)      # scripts that read their params.json from a batch table


def run_batch(generator: str, params_list: list[dict], out_dirs: list[Path], *, jobs: int = 2,
              quiet: bool = False) -> float:
    """Run independent packings (e.g. one per seed) as one ``yade-batch`` table: one job per
    line, ``jobs`` at a time, one log per job (``<out_dir>/yade.log``); return wall seconds.

    Each job's parameters are its own ``params.json``; the table names them in a
    ``params_json`` column that the generator reads with YADE's readParamsFromTable. YADE's
    threads stay 1 per job (deterministic); the jobs run in parallel."""
    if generator not in BATCH_GENERATORS:
        raise YadeError(f"--seeds: the {generator!r} generator runs one YADE process per "
                        f"scene (yade-batch tables: {', '.join(BATCH_GENERATORS)})")
    batch_dir = Path(out_dirs[0]).parent
    lines = ["description params_json"]
    for params, out_dir in zip(params_list, out_dirs):
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        path = (out_dir / "params.json").resolve()
        if any(c.isspace() for c in str(path)):
            raise YadeError(f"{path}: yade-batch tables split on blanks: use an output folder "
                            "without spaces")
        write_text_atomic(path, json.dumps(dict(params, output_dir=str(out_dir.resolve())),
                                           indent=1, sort_keys=True))
        lines.append(f"{out_dir.name} '{path}'")      # values are Python literals
    table = batch_dir / "batch.table"
    write_text_atomic(table, "\n".join(lines) + "\n")
    script = YADE_SCRIPTS / SCRIPTS[generator]
    cmd = [yade_batch_executable(), "--jobs", str(jobs), "--job-threads", "1",
           "--log", str(batch_dir.resolve() / "@" / "yade.log"), str(table), str(script)]
    start = time.perf_counter()
    log_path = batch_dir / "yade-batch.log"
    _run_logged(cmd, batch_dir, log_path, lambda line: "  yade-batch | " + line
                if not quiet and line.lstrip().startswith("#") else None)
    wall = time.perf_counter() - start
    failed = []
    for out_dir in out_dirs:
        job_log = Path(out_dir) / "yade.log"
        text = job_log.read_text(errors="replace") if job_log.exists() else ""
        errors = [line for line in text.splitlines() if line.startswith("error:")]
        if errors or not (Path(out_dir) / "packing.h5").exists():
            failed.append(f"{Path(out_dir).name}: " + (errors[-1] if errors else
                                                       f"no packing.h5 (log: {job_log})"))
    if failed:
        raise YadeError(f"yade-batch: {len(failed)} of {len(out_dirs)} job(s) failed: "
                        + "; ".join(failed) + f" (batch log: {log_path})")
    return wall
