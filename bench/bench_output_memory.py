"""Peak memory of a long transient run against its number of output times, before and after the
history left memory (issue 25; the section "Memory of a long run's output" of docs/scaling.md).

    .venv/bin/python bench/bench_output_memory.py [--before COMMIT] [--json PATH]

A `tdem run` of the committed dense box of 1e5 spheres (runs/out/dense_box_1e5/packing.h5,
`tdem pack runs/dense_box_1e5.toml`) between two held faces, explicit, with 50 and with 500
output times (a history of 0.04 and 0.4 GB), in-process (one thread) and on 2 ranks. Each
process samples its own peak anonymous memory (``RssAnon`` of /proc/self/status, every 10 ms:
``ru_maxrss`` would count the pages of a memory-mapped history, which the kernel may drop), so
the figures do not depend on the machine's load. "before" runs the code of ``--before``
(default 40456fb, the last commit that held the history in memory and built thermal.h5's image
beside it), extracted with ``git archive`` and put first on PYTHONPATH; "after" the checkout's
own. ``bench/bench_scaling.py --from-json --write docs/scaling.md`` puts the rows into the doc.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench_rank_build import THERMAL as RANK_BUILD_THERMAL  # noqa: E402 (bench/ on sys.path)

BEFORE = "40456fb"
OUT = ROOT / "bench/out/output_memory"
PACKING = ROOT / "runs/out/dense_box_1e5/packing.h5"
JSON = ROOT / "bench/results/output_memory.json"
OUTPUT_TIMES = (50, 500)
INTERVAL_S = 1e-3        # one output every ms (the explicit bound of this box is ~ms: 1-2 steps)

# the dense box between two held faces, haddad's law (bench_rank_build's scene), explicit
THERMAL = RANK_BUILD_THERMAL + 'method = "explicit"\n'
# each process samples its own anonymous memory and reports the peak at exit
SAMPLER = '''import atexit, os, runpy, sys, threading, time
peak = [0]
def sample():
    while True:
        for line in open("/proc/self/status"):
            if line.startswith("RssAnon:"):
                peak[0] = max(peak[0], int(line.split()[1]))
        time.sleep(0.01)
threading.Thread(target=sample, daemon=True).start()
atexit.register(lambda: os.write(2, (f"ANON_PEAK {os.environ.get('OMPI_COMM_WORLD_RANK', 0)} "
                                     f"{peak[0]}\\n").encode()))
module, sys.argv = sys.argv[1], [sys.argv[1]] + sys.argv[2:]
runpy.run_module(module, run_name="__main__", alter_sys=True)
'''


def scene(n_times: int) -> Path:
    times = ", ".join(f"{INTERVAL_S * k:.6g}" for k in range(1, n_times + 1))
    path = OUT / f"box_{n_times}.toml"
    path.write_text(f'packing = "{PACKING}"\n{THERMAL}end_time = {INTERVAL_S * n_times:.6g}\n'
                    f"output_times = [{times}]\n")
    return path


def run(code_root: Path, scene_path: Path, ranks: int, tag: str) -> list[float]:
    """Peak RssAnon (GB) of each process of one `tdem run` (in-process when ``ranks`` is 0)."""
    from thermal_kernel.solvers.mpi_launch import MPIRUN_LOCAL, mpi_env, mpi_python
    wrapper = OUT / "anon_sampler.py"
    wrapper.write_text(SAMPLER)
    out = OUT / tag
    if ranks == 0:
        cmd = [sys.executable, str(wrapper), "tdem.cli", "run", str(scene_path), "--out",
               str(out), "--threads", "1", "--quiet"]
        env = dict(os.environ, PYTHONPATH=str(code_root))
    else:
        cmd = ["mpirun", "-n", str(ranks), *MPIRUN_LOCAL, "-x", "PYTHONPATH", "-x",
               "OMP_NUM_THREADS", "-x", "NUMBA_NUM_THREADS", str(mpi_python()), str(wrapper),
               "thermal_kernel.mpi_run", str(scene_path), "--out", str(out), "--quiet"]
        env = dict(mpi_env(), PYTHONPATH=str(code_root))
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=OUT)
    peaks = {int(r): int(kb) * 1024 / 1e9
             for r, kb in re.findall(r"ANON_PEAK (\d+) (\d+)", done.stderr)}
    if done.returncode or len(peaks) != max(ranks, 1):
        raise SystemExit(f"{tag}: exited with {done.returncode}: {done.stderr[-2000:]}")
    return [peaks[r] for r in range(max(ranks, 1))]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", default=BEFORE)
    ap.add_argument("--json", default=str(JSON))
    a = ap.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    from thermal_kernel.packing import read_packing
    n = read_packing(PACKING, contacts=False).n_particles
    load = [open("/proc/loadavg").read().split()[:3]]
    rows = []
    with tempfile.TemporaryDirectory(prefix="tdem-before-") as tmp:
        archive = Path(tmp) / "before.tar"
        subprocess.run(["git", "archive", "-o", str(archive), a.before, "thermal_kernel",
                        "tdem", "tdem_post", "validation", "yade_scripts"], check=True, cwd=ROOT)
        with tarfile.open(archive) as t:
            t.extractall(tmp)
        for n_times in OUTPUT_TIMES:
            path = scene(n_times)
            for ranks in (0, 2):
                row = dict(packing=str(PACKING.relative_to(ROOT)), n=n, output_times=n_times,
                           history_gb=8 * n * n_times / 1e9, ranks=ranks)
                for which, code in (("before", Path(tmp)), ("after", ROOT)):
                    row[f"anon_{which}_gb"] = run(code, path, ranks,
                                                  f"{which}_{n_times}_{ranks}")
                rows.append(row)
                print(json.dumps(row), flush=True)
    load.append(open("/proc/loadavg").read().split()[:3])
    Path(a.json).write_text(json.dumps(dict(
        rows=rows, before=a.before, load=load,
        after=subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                             text=True, cwd=ROOT).stdout.strip(),
        date=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())), indent=1))
    print(f"wrote {a.json}")


if __name__ == "__main__":
    main()
