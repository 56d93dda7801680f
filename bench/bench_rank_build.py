"""Peak memory of each rank with the per-rank build against rank 0 building the whole network
(issue 25; the table "Memory of the build on the ranks" of docs/scaling.md).

    .venv/bin/python bench/bench_rank_build.py [--before COMMIT] [--json PATH]
    .venv/bin/python bench/bench_rank_build.py --stages [--json PATH]

Memory only: every rank's peak RSS (``ru_maxrss``, libraries included) over a whole `tdem run`
on the ranks (``python -m thermal_kernel.mpi_run``, as ``tdem run --ranks`` starts it), which
does not depend on the machine's load; the wall times of a loaded machine are not recorded.
"before" runs the code of ``--before`` (default cc9da6d, the last commit where rank 0 read the
packing and built the whole network), extracted with ``git archive`` and put first on the
ranks' PYTHONPATH; "after" the checkout's own. The packings: the committed dense box of 1e5
spheres (runs/out/dense_box_1e5/packing.h5, `tdem pack runs/dense_box_1e5.toml`) and a 1e6
tiled box made from the same relaxed cell (`tdem pack`, ~20 s when that cell exists, else the
cell is relaxed first), each between two held faces, haddad's law with every dumped row
conducting (no [neighbours] criterion: when these rows were measured a scene with one still
built whole on rank 0; it is built on the ranks now, not measured here).
``--stages``: each rank's traced memory (tracemalloc) over each step of the build
(rank_build.py's functions), the 1e6 box, explicit, on 2 and 3 ranks: what rank 0 holds
beyond the others, step by step (bench/results/rank_build_stages.json).
``bench/bench_scaling.py --from-json --write docs/scaling.md`` puts the rows into the doc.
"""
from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

BEFORE = "cc9da6d"
OUT = ROOT / "bench/out/rank_build"
P1E5 = ROOT / "runs/out/dense_box_1e5/packing.h5"
CELL = ROOT / "runs/out/dense_box_1e5/cell.h5"
JSON = ROOT / "bench/results/rank_build_memory.json"
# (N label, packing, solver, ranks)
CASES = [("1e5", "explicit", 2), ("1e5", "steady", 2),
         ("1e6", "explicit", 1), ("1e6", "explicit", 2), ("1e6", "explicit", 3),
         ("1e6", "steady", 2)]

THERMAL = '''law = "haddad"
[law_params]
ct = 0.806
[material]
conductivity = 33.0
density = 7800.0
heat_capacity = 460.0
[initial]
temperature = 298.15
[[boundary]]
kind = "temperature"
on = "xmin"
value = 308.15
[[boundary]]
kind = "temperature"
on = "xmax"
value = 298.15
[solver]
'''
SOLVER = {"steady": 'method = "steady"\n',
          "explicit": 'method = "explicit"\nend_time = 0.02\noutput_times = [0.02]\n'}
# each rank reports its peak at exit
RSS = '''import atexit, os, resource, runpy, sys
atexit.register(lambda: os.write(2, (f"RSS_PEAK {os.environ.get('OMPI_COMM_WORLD_RANK')} "
                                     f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss}\\n")
                                    .encode()))     # one write: the ranks' lines do not mix
sys.argv = ["thermal_kernel.mpi_run"] + sys.argv[1:]
runpy.run_module("thermal_kernel.mpi_run", run_name="__main__", alter_sys=True)
'''


# --stages: each rank's traced numpy/Python memory (tracemalloc) over each step of the build
# (thermal_kernel/rank_build.py's functions, wrapped), reported at exit
STAGES = '''import atexit, json, os, runpy, sys, time, tracemalloc
if TRACE:
    tracemalloc.start()
import thermal_kernel.rank_build as rb
import thermal_kernel.solvers.petsc_backend as pb
steps = []
def wrap(name, module=rb):
    f = getattr(module, name)
    def g(*a, **k):
        if not TRACE:           # the wall seconds, without tracemalloc's cost
            t0 = time.perf_counter()
            out = f(*a, **k)
            steps.append(dict(step=name, seconds=time.perf_counter() - t0))
            return out
        start = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        out = f(*a, **k)
        end, peak = tracemalloc.get_traced_memory()
        steps.append(dict(step=name, start=start, peak=peak, end=end))
        return out
    setattr(module, name, g)
for name in STEPS:
    wrap(name)
for name in RUN_STEPS:        # the run after the build (mpi_run calls it through the module)
    wrap(name, pb)
rank = os.environ.get("OMPI_COMM_WORLD_RANK")
atexit.register(lambda: os.write(2, ("STAGES " + rank + " " + json.dumps(steps) + "\\n").encode()))
sys.argv = ["thermal_kernel.mpi_run"] + sys.argv[1:]
runpy.run_module("thermal_kernel.mpi_run", run_name="__main__", alter_sys=True)
'''
# the build's steps in the order build_on_ranks calls them (names in rank_build.py); those in
# ROOT_ALONE are rank 0's work while the other ranks wait (their wall time is serial)
STEPS = ["read_packing_on_ranks", "morton_blocks_on_ranks", "Routes", "_bulk_flags",
         "_contacts_to_owners", "_owner_block", "_conducting_contacts", "_rank_rows",
         "_owner_problem", "_clusters_on_ranks", "_untied_rows", "_explicit_bound",
         "_root_summary"]
# after the build: the run itself (petsc_backend's solver functions), what each rank holds
# for it and at its peak (the explicit cases of STAGE_CASES)
RUN_STEPS = ["run_explicit"]
ROOT_ALONE = ("_root_summary",)
STAGE_CASES = [("1e6", "explicit", 2), ("1e6", "explicit", 3)]
STAGES_JSON = ROOT / "bench/results/rank_build_stages.json"


def packing_1e6() -> Path:
    """The 1e6 tiled box (bench/out/rank_build/box1e6/packing.h5), made once by tdem pack."""
    out = OUT / "box1e6"
    if (out / "packing.h5").exists():
        return out / "packing.h5"
    scene = (ROOT / "runs/dense_box_1e5.toml").read_text()
    scene = scene.replace("n_particles = 100000", "n_particles = 1000000")
    start = scene.index("[neighbours]")
    scene = scene[:start] + scene[scene.index("[pack]"):]      # every dumped row conducts
    if CELL.exists():
        scene = scene.replace("cell_particles = 10000",
                              f'cell_particles = 10000\ncell_packing = "{CELL}"')
    path = OUT / "box1e6.toml"
    path.write_text(scene)
    subprocess.run([sys.executable, "-m", "tdem.cli", "pack", str(path), "--out", str(out),
                    "--quiet"], check=True, cwd=ROOT)
    return out / "packing.h5"


def run(code_root: Path, packing: Path, solver: str, ranks: int, tag: str,
        stages: bool = False, trace: bool = True):
    """Every rank's peak RSS (GB, rank order); ``stages``: every rank's steps instead (the
    traced memory at each step's start, peak and end, bytes; ``trace`` False: each step's
    wall seconds, untraced)."""
    from thermal_kernel.solvers.mpi_launch import MPIRUN_LOCAL, mpi_env, mpi_python
    scene = OUT / f"{tag}.toml"
    scene.write_text(f'packing = "{packing}"\n{THERMAL}{SOLVER[solver]}')
    wrapper = OUT / ("stages_wrapper.py" if stages else "rss_wrapper.py")
    wrapper.write_text(f"STEPS = {STEPS!r}\nRUN_STEPS = {RUN_STEPS!r}\nTRACE = {trace!r}\n"
                       + STAGES if stages else RSS)
    env = dict(mpi_env(), PYTHONPATH=str(code_root))
    done = subprocess.run(
        ["mpirun", "-n", str(ranks), *MPIRUN_LOCAL, "-x", "PYTHONPATH", "-x", "OMP_NUM_THREADS",
         "-x", "NUMBA_NUM_THREADS", str(mpi_python()), str(wrapper), str(scene), "--out",
         str(OUT / tag), "--quiet"], env=env, capture_output=True, text=True, cwd=OUT)
    if stages:
        got = {int(rank): json.loads(text)
               for rank, text in re.findall(r"STAGES (\d+) (.*)", done.stderr)}
        if done.returncode or len(got) != ranks:
            raise SystemExit(f"{tag}: mpirun exited with {done.returncode}: "
                             f"{done.stderr[-2000:]}")
        return [got[r] for r in range(ranks)]
    peaks = {int(rank): int(kb) * 1024 / 1e9
             for rank, kb in re.findall(r"RSS_PEAK (\d+) (\d+)", done.stderr)}
    if done.returncode or len(peaks) != ranks:
        raise SystemExit(f"{tag}: mpirun exited with {done.returncode}: {done.stderr[-2000:]}")
    return [peaks[r] for r in range(ranks)]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", default=BEFORE)
    ap.add_argument("--json", default=None)
    ap.add_argument("--stages", action="store_true",
                    help="each rank's traced memory step by step of the build (the checkout's "
                         "code; writes bench/results/rank_build_stages.json)")
    a = ap.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    packings = {"1e5": P1E5, "1e6": packing_1e6()}
    if a.stages:
        return stages(packings, Path(a.json or STAGES_JSON))
    a.json = a.json or str(JSON)
    from thermal_kernel.packing import read_packing
    sizes = {}
    for label, path in packings.items():
        p = read_packing(path, contacts=False)
        sizes[label] = dict(packing=str(path.relative_to(ROOT)), n=p.n_particles,
                            contacts=p.file_contacts)
    load = [open("/proc/loadavg").read().split()[:3]]
    rows = []
    with tempfile.TemporaryDirectory(prefix="tdem-before-") as tmp:
        archive = Path(tmp) / "before.tar"
        subprocess.run(["git", "archive", "-o", str(archive), a.before, "thermal_kernel"],
                       check=True, cwd=ROOT)
        with tarfile.open(archive) as t:
            t.extractall(tmp)
        for label, solver, ranks in CASES:
            row = dict(sizes[label], solver=solver, ranks=ranks)
            for which, code in (("before", Path(tmp)), ("after", ROOT)):
                row[f"rss_{which}_gb"] = run(code, packings[label], solver, ranks,
                                             f"{which}_{label}_{solver}_{ranks}")
            rows.append(row)
            print(json.dumps(row), flush=True)
    load.append(open("/proc/loadavg").read().split()[:3])
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True, cwd=ROOT).stdout.strip()
    data = dict(rows=rows, before=a.before, after=commit, load=load,
                date=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()))
    Path(a.json).write_text(json.dumps(data, indent=1))
    print(f"wrote {a.json}")


def stages(packings, path: Path):
    """--stages: each rank's traced memory (tracemalloc: numpy's arrays and Python's objects,
    not the libraries) at the start, peak and end of each step of the build, and each step's
    wall seconds in a second, untraced run (best of three), on the checkout's code, into
    ``path``."""
    from thermal_kernel.packing import read_packing
    rows = []
    load = [open("/proc/loadavg").read().split()[:3]]
    for label, solver, ranks in STAGE_CASES:
        p = read_packing(packings[label], contacts=False)
        tag = f"stages_{label}_{solver}_{ranks}"
        steps = run(ROOT, packings[label], solver, ranks, tag, stages=True)
        for _ in range(3):      # the wall seconds: best of three untraced runs, per step
            timed = run(ROOT, packings[label], solver, ranks, tag, stages=True, trace=False)
            for mine, other in zip(steps, timed):
                for s, t in zip(mine, other):
                    assert s["step"] == t["step"], (s, t)
                    s["seconds"] = min(s.get("seconds", float("inf")), t["seconds"])
        rows.append(dict(packing=str(packings[label].relative_to(ROOT)), n=p.n_particles,
                         contacts=p.file_contacts, solver=solver, ranks=ranks, steps=steps,
                         root_alone=list(ROOT_ALONE)))
        print(f"{label} {solver} {ranks} ranks: done", flush=True)
    load.append(open("/proc/loadavg").read().split()[:3])
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True, cwd=ROOT).stdout.strip()
    path.write_text(json.dumps(dict(rows=rows, commit=commit, load=load, date=time.strftime(
        "%Y-%m-%d %H:%M UTC", time.gmtime())), indent=1))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
