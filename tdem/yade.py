"""Running the YADE generators (``yade_scripts/``) from tdem: environment, progress, errors."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from collections import deque
from pathlib import Path

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


def load_schema(generator: str) -> dict:
    """The parameter schema of a generator, read from ``yade_scripts/<generator>_params.py``."""
    params = _load_params_module()
    return params.load_schema(generator)


def _load_params_module():
    import importlib.util
    spec = importlib.util.spec_from_file_location("tdem_yade_params",
                                                  YADE_SCRIPTS / "params.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def resolve_params(generator: str, table: dict) -> dict:
    """Defaults filled in and every key checked; raises ValueError('key: ...')."""
    params = _load_params_module()
    return params.resolve(params.load_schema(generator), table)


def run_generator(generator: str, params: dict, out_dir: Path, *, threads: int = 1,
                  quiet: bool = False) -> float:
    """Run one generator under YADE with ``params`` (already resolved); return wall seconds.

    Writes ``out_dir/params.json`` and ``out_dir/yade.log``; YADE's output is streamed to
    stdout (unless quiet). A non-zero exit raises YadeError with the script's last error line.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    params = dict(params, output_dir=str(out_dir.resolve()))
    params_path = out_dir / "params.json"
    tmp = params_path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(params, indent=1, sort_keys=True))
    os.replace(tmp, params_path)
    script = YADE_SCRIPTS / SCRIPTS[generator]
    cmd = [yade_executable(), "-n", f"-j{threads}", "-x", str(script), str(params_path)]
    log_path = out_dir / "yade.log"
    tail = deque(maxlen=20)
    start = time.perf_counter()
    with open(log_path, "w") as log:
        log.write("$ " + " ".join(cmd) + "\n")
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, env=yade_environment(),
                                cwd=out_dir, text=True, bufsize=1)
        for line in proc.stdout:
            log.write(line)
            log.flush()
            tail.append(line.rstrip())
            if not quiet and not _is_banner(line):
                print("  yade | " + line.rstrip(), flush=True)
        rc = proc.wait()
    wall = time.perf_counter() - start
    if rc != 0:
        errors = [l for l in tail if l.startswith("error:")]
        last = errors[-1] if errors else next((l for l in reversed(tail) if l.strip()), "")
        raise YadeError(f"{script.name} failed (exit {rc}): {last.strip()} (full log: {log_path})")
    return wall


def _is_banner(line: str) -> bool:
    return line.startswith(("TCP python prompt", "XMLRPC info provider", "Running script",
                            "Welcome to Yade", "Yade version"))
