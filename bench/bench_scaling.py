"""The PETSc backend against the in-process solvers, N x ranks x solver (issue 25; not a test).

    .venv/bin/python bench/bench_scaling.py                      # 1e5 and 1e6, prints the table
    .venv/bin/python bench/bench_scaling.py --write docs/scaling.md   # `make bench-scaling`
    .venv/bin/python bench/bench_scaling.py --n 1e5,1e6,4e6 --solvers steady

Each case is its own process (a fresh peak RSS): the in-process solvers in .venv, the PETSc
backend under ``mpirun -n R`` in .venv-mpi (thermal_kernel.solvers.mpi_launch). The network is the
packing-like one of bench/bench_explicit.py (N random centres in a cube, contacts closer than
the distance that gives a mean coordination of 6, random conductances and capacities, seeded)
between two held faces (x < 0.02 at 1 K above, x > 0.98 at 0); every process builds the same one.

Measured per case: wall of the solve (explicit: the steps; implicit: setup + steps; steady: the
solve), CG iterations, the peak RSS of each rank (ru_maxrss) and what the solve adds to it
(RSS after the solve minus RSS before: the part the ranks divide), the contacts the Morton blocks
cut. Ratios are quoted side by side (the machine is shared; its load, from /proc/loadavg, is in
the table's heading). The cost model of docs/scaling.md is fitted on these rows.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

EXPLICIT_STEPS = 50
IMPLICIT_STEPS = 5
IMPLICIT_DT_OVER_BOUND = 100.0     # backward Euler far above the explicit bound: a stiff step


def network(n: int, seed: int = 1, z: float = 6.0):
    """(centres, pair, H, C) of bench_explicit's packing-like network (scipy's cKDTree)."""
    from scipy.spatial import cKDTree
    rng = np.random.default_rng(seed)
    x = rng.random((n, 3))
    r = (z / (n * 4.0 / 3.0 * np.pi)) ** (1.0 / 3.0)
    pair = cKDTree(x).query_pairs(r, output_type="ndarray").astype(np.int64)
    pair.sort(axis=1)
    h = rng.uniform(0.5, 2.0, pair.shape[0])
    c = rng.uniform(1.0, 3.0, n)
    return x, pair, h, c


def problem(n: int):
    from thermal_kernel.network import make_problem
    x, pair, h, c = network(n)
    hot, cold = np.flatnonzero(x[:, 0] < 0.02), np.flatnonzero(x[:, 0] > 0.98)
    fixed = (np.concatenate([hot, cold]), np.concatenate([np.ones(hot.size),
                                                         np.zeros(cold.size)]),
             np.concatenate([np.zeros(hot.size, np.int32), np.ones(cold.size, np.int32)]))
    return x, make_problem(c, pair, h, fixed=fixed, boundary_names=("hot", "cold"))


def rss_gb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6     # kB -> GB


def current_rss_gb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e9


# ----------------------------------------------------------------------------- workers
def worker_inprocess(n, solver, threads):
    import numba

    from thermal_kernel.network import assemble
    from thermal_kernel.solvers import run_explicit, run_implicit, solve_steady
    numba.set_num_threads(threads)
    t0 = time.perf_counter()
    _, prob = problem(n)
    net = assemble(prob)
    build = time.perf_counter() - t0
    before = current_rss_gb()
    T0 = np.zeros(n)
    its = 0
    cpu0 = time.process_time()
    if solver == "steady":
        r = solve_steady(net, T0)
        wall = r.wall_seconds
        its = int(np.sum(r.info.get("cg_iterations") or [0]))
    elif solver == "explicit":
        dt = 0.9 * net.dt_max_s
        r = run_explicit(net, T0, [EXPLICIT_STEPS * dt], dt=dt, threads=threads)
        wall = r.info["step_seconds"]
    else:
        dt = IMPLICIT_DT_OVER_BOUND * net.dt_max_s
        r = run_implicit(net, T0, [IMPLICIT_STEPS * dt], dt=dt, method="amg")
        wall = r.wall_seconds
        its = int(np.sum(r.info.get("cg_iterations") or [0]))
    cpu = time.process_time() - cpu0
    return dict(backend="in-process", threads=threads, n=n, solver=solver, ranks=1,
                wall_s=wall, cpu_s=cpu, build_s=build, iterations=its, rss_max_gb=rss_gb(),
                rss_solve_gb=max(rss_gb() - before, 0.0), cut=0,
                contacts=int(net.n_active_contacts), T=r.temperature_k[-1])


def worker_petsc(n, solver, pc):
    import petsc4py
    petsc4py.init([sys.argv[0]])
    from petsc4py import PETSc

    from thermal_kernel.network import assemble
    from thermal_kernel.solvers import petsc_backend as backend
    comm = PETSc.COMM_WORLD.tompi4py()
    t0 = time.perf_counter()
    x = net = None
    if comm.rank == 0:              # as thermal_kernel/mpi_run.py: rank 0 builds, sends rows
        x, prob = problem(n)
        net = assemble(prob)
    build = time.perf_counter() - t0
    before = current_rss_gb()
    dist = backend.DistributedNetwork(net, x)
    T0 = np.zeros(n)
    its = 0
    cpu0 = time.process_time()
    if solver == "steady":
        r = backend.solve_steady(dist, T0, pc=pc)
        key = "wall"
    elif solver == "explicit":
        dt = 0.9 * comm.bcast(net.dt_max_s if net is not None else None)
        r = backend.run_explicit(dist, T0, [EXPLICIT_STEPS * dt], dt=dt)
        key = "step"
    else:
        dt = IMPLICIT_DT_OVER_BOUND * comm.bcast(net.dt_max_s if net is not None else None)
        r = backend.run_implicit(dist, T0, [IMPLICIT_STEPS * dt], dt=dt, pc=pc)
        key = "wall"
    cpu = comm.gather(time.process_time() - cpu0, root=0)
    rss = comm.gather(rss_gb(), root=0)
    grown = comm.gather(max(rss_gb() - before, 0.0), root=0)
    if comm.rank != 0:
        return None
    wall = r.info["step_seconds"] if key == "step" else r.wall_seconds
    its = int(np.sum(r.info.get("cg_iterations") or [0]))
    return dict(backend="petsc", pc=pc if solver != "explicit" else "-", n=n, solver=solver,
                ranks=comm.size, wall_s=wall, cpu_s=max(cpu), build_s=build, iterations=its,
                rss_max_gb=max(rss), rss_solve_gb=max(grown), rss_ranks_gb=rss,
                cut=int(dist.cut),
                contacts=int(net.n_active_contacts), T=r.temperature_k[-1])


def _emit(row, out):
    if row is None:
        return
    T = row.pop("T")
    np.save(out, T)
    print("ROW " + json.dumps(row), flush=True)


# ----------------------------------------------------------------------------- driver
def _run(cmd, env=None):
    done = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=ROOT)
    rows = [json.loads(line[4:]) for line in done.stdout.splitlines() if line.startswith("ROW ")]
    if done.returncode or not rows:
        sys.stderr.write(done.stdout[-2000:] + done.stderr[-3000:])
        raise SystemExit(f"bench_scaling: {' '.join(cmd[:6])} ... failed ({done.returncode})")
    return rows[0]


def cut_table():
    """Contacts cut by the ranks' blocks on the 100,000-sphere dense box (if built) and the
    300-sphere bed: the packing's own order against the Morton order."""
    from thermal_kernel.packing import read_packing
    from thermal_kernel.solvers.partition import (block_starts, cut_contacts,
                                                  owner_of_particle, particle_order)
    rows = []
    for path in (ROOT / "runs/out/dense_box_1e5/packing.h5",
                 ROOT / "tests/data/bed_small_4.05e+07Pa.h5"):
        if not path.exists():
            continue
        p = read_packing(path)
        h = np.ones(len(p.pair))
        for ranks in (2, 4, 8, 64):
            row = {"packing": path.relative_to(ROOT).as_posix(), "n": p.n_particles,
                   "contacts": len(p.pair), "ranks": ranks}
            for kind in ("index", "morton"):
                owner = owner_of_particle(particle_order(p.position, kind),
                                          block_starts(p.n_particles, ranks))
                row[kind] = cut_contacts(p.pair, h, owner) / len(p.pair)
            rows.append(row)
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--worker", choices=("inprocess", "petsc"))
    ap.add_argument("--n", default="1e5,1e6")
    ap.add_argument("--solvers", default="steady,explicit,implicit")
    ap.add_argument("--ranks", default="1,2")
    ap.add_argument("--pcs", default="gamg,hypre")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--pc", default="gamg")
    ap.add_argument("--out")
    ap.add_argument("--write", help="markdown file to write (docs/scaling.md)")
    ap.add_argument("--json", default=str(ROOT / "bench/results/scaling.json"))
    ap.add_argument("--no-inprocess", action="store_true",
                    help="PETSc rows only (no in-process reference: its diff column is nan)")
    ap.add_argument("--from-json", action="store_true",
                    help="no runs: write --write from the rows stored in --json")
    a = ap.parse_args()
    if a.from_json:
        Path(a.write).write_text(document(json.loads(Path(a.json).read_text())))
        print(f"wrote {a.write}")
        return
    if a.worker == "inprocess":
        _emit(worker_inprocess(int(float(a.n)), a.solvers, a.threads), a.out)
        return
    if a.worker == "petsc":
        _emit(worker_petsc(int(float(a.n)), a.solvers, a.pc), a.out)
        return

    from thermal_kernel.solvers.mpi_launch import MPIRUN_LOCAL, mpi_env, mpi_python
    tmp = ROOT / "bench/out/scaling"
    tmp.mkdir(parents=True, exist_ok=True)
    load = [open("/proc/loadavg").read().split()[:3]]
    rows = []
    me = [sys.executable, str(Path(__file__).resolve())]
    for n in [int(float(v)) for v in a.n.split(",")]:
        for solver in a.solvers.split(","):
            ref_path = tmp / f"inprocess_{n}_{solver}_1.npy"
            cases = [] if a.no_inprocess else [
                ("in-process", t, None, 1) for t in ((1, 2) if solver == "explicit" else (1,))]
            pcs = ["-"] if solver == "explicit" else a.pcs.split(",")
            cases += [("petsc", None, pc, r) for pc in pcs for r in map(int, a.ranks.split(","))]
            for kind, threads, pc, ranks in cases:
                if kind == "in-process":
                    out = tmp / f"inprocess_{n}_{solver}_{threads}.npy"
                    row = _run(me + ["--worker", "inprocess", "--n", str(n), "--solvers", solver,
                                     "--threads", str(threads), "--out", str(out)])
                else:
                    out = tmp / f"petsc_{n}_{solver}_{pc}_{ranks}.npy"
                    row = _run(["mpirun", "-n", str(ranks), *MPIRUN_LOCAL, "-x",
                                "OMP_NUM_THREADS", "-x", "NUMBA_NUM_THREADS", str(mpi_python()),
                                str(Path(__file__).resolve()), "--worker", "petsc", "--n",
                                str(n), "--solvers", solver, "--pc",
                                "gamg" if pc == "-" else pc, "--out", str(out)], env=mpi_env())
                row["diff_vs_inprocess"] = float("nan")
                if ref_path.exists() and not a.no_inprocess:
                    T, ref = np.load(out), np.load(ref_path)
                    row["diff_vs_inprocess"] = float(np.abs(T - ref).max() /
                                                     max(np.abs(ref).max(), 1e-300))
                rows.append(row)
                print(_line(row), flush=True)
    load.append(open("/proc/loadavg").read().split()[:3])
    cuts = cut_table()
    Path(a.json).parent.mkdir(parents=True, exist_ok=True)
    synthetic_cuts = synthetic_cut_table(max(int(float(v)) for v in a.n.split(",")))
    data = {"rows": rows, "cuts": cuts, "synthetic_cuts": synthetic_cuts, "load": load,
            "mpirun_options": " ".join(MPIRUN_LOCAL),
            "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "uptime": subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()}
    Path(a.json).write_text(json.dumps(data, indent=1))
    print(f"wrote {a.json}")
    if a.write:
        Path(a.write).write_text(document(data))
        print(f"wrote {a.write}")


def synthetic_cut_table(n):
    """Contacts cut by the Morton blocks of the bench's network at N for 2 .. 4096 ranks (the
    partition only: nothing is solved), for the cost model's halo."""
    from thermal_kernel.solvers.partition import (block_starts, cut_contacts,
                                                  owner_of_particle, particle_order)
    x, pair, h, _ = network(n)
    order = particle_order(x)
    out = []
    for ranks in (2, 8, 64, 512, 4096):
        owner = owner_of_particle(order, block_starts(n, ranks))
        out.append({"n": n, "ranks": ranks, "contacts": int(len(pair)),
                    "cut": cut_contacts(pair, h, owner)})
    return out


# ----------------------------------------------------------------------------- the document
# Assumed for the projection (not measured here): a cluster node of 64 cores and 256 GB, an
# InfiniBand-class network of 10 GB/s per node and 2 us latency; 1 rank per core.
NODE_CORES, NODE_GB, LINK_GB_S, LATENCY_S = 64, 256.0, 10.0, 2e-6


def _fit(rows):
    """The cost model's constants from the largest N measured on 1 rank (and the 2-rank rows
    for the measured speed-up). Returns a dict of per-solver constants."""
    big = max(r["n"] for r in rows)
    model = {"n": big}
    for solver in ("steady", "explicit", "implicit"):
        sel = [r for r in rows if r["n"] == big and r["solver"] == solver
               and r["backend"] == "petsc" and r["pc"] in ("gamg", "-")]
        one = [r for r in sel if r["ranks"] == 1]
        two = [r for r in sel if r["ranks"] == 2]
        if not one:
            continue
        one, two = one[0], (two[0] if two else None)
        steps = EXPLICIT_STEPS if solver == "explicit" else 1
        # CPU seconds, not wall: on the shared machine the wall was up to 6x the CPU time
        # of a 1-rank run (other jobs held the cores); the CPU time is the work
        model[solver] = {
            "s_per_particle": one["cpu_s"] / (big * steps),       # per step (explicit)
            "its": one["iterations"], "speedup_2": (one["wall_s"] / two["wall_s"]) if two
            else float("nan"),
            "cpu_ratio_2": (one["cpu_s"] / two["cpu_s"]) if two else float("nan"),
            "solve_bytes_per_particle": one["rss_solve_gb"] * 1e9 / big,
            "whole_bytes_per_particle": (one["rss_max_gb"] - one["rss_solve_gb"]) * 1e9 / big}
    return model


def _its_at(rows, solver, n_target):
    """GAMG iterations at n_target from the two largest N measured (log-linear in N)."""
    pts = sorted({(r["n"], r["iterations"]) for r in rows if r["solver"] == solver and
                  r["backend"] == "petsc" and r.get("pc") == "gamg" and r["ranks"] == 1})
    if len(pts) < 2:
        return pts[-1][1] if pts else float("nan")
    (n1, i1), (n2, i2) = pts[-2], pts[-1]
    slope = (i2 - i1) / np.log(n2 / n1)
    return max(i2 + slope * np.log(n_target / n2), i2)


def _halo(cuts, n, ranks):
    """Values a rank receives per mat-vec: kappa (N/R)^(2/3), kappa fitted on the measured
    Morton cuts (cut contacts x 2 / R is the mean halo per rank)."""
    ks = [2 * c["cut"] / c["ranks"] / (c["n"] / c["ranks"]) ** (2 / 3) for c in cuts
          if c["ranks"] >= 8]
    kappa = max(ks) if ks else 6.0
    return kappa * (n / ranks) ** (2 / 3), kappa


def projection(data):
    rows, model = data["rows"], _fit(data["rows"])
    out = []
    _, kappa = _halo(data["synthetic_cuts"], 1, 1)
    for n in (1e8, 1e9):
        for solver in ("explicit", "steady"):
            m = model.get(solver)
            if m is None:
                continue
            solve_gb_total = m["solve_bytes_per_particle"] * n / 1e9
            whole_gb_rank = m["whole_bytes_per_particle"] * n / 1e9
            # nodes: the distributed part must fit in the nodes' memory at half of it
            nodes = max(1, int(np.ceil(solve_gb_total / (0.5 * NODE_GB))))
            # at most 2e6 particles a rank (the largest block measured per rank here)
            nodes = max(nodes, int(np.ceil(n / 2e6 / NODE_CORES)))
            ranks = nodes * NODE_CORES
            halo = _halo(data["synthetic_cuts"], n, ranks)[0]
            comm = LATENCY_S * 26 + 8 * halo / (LINK_GB_S * 1e9 / NODE_CORES)
            if solver == "explicit":
                step = m["s_per_particle"] * n / ranks + comm
                compute = m["s_per_particle"] * n / ranks
                what = (f"{step * 1e3:.3g} ms per step (compute {compute * 1e3:.3g} ms, halo "
                        f"{comm * 1e3:.2g} ms)")
                minutes = step * 1e5 / 60
                extra = f"1e5 steps: {minutes:.3g} min"
            else:
                its = _its_at(rows, "steady", n)
                per_it = m["s_per_particle"] / max(m["its"], 1) * n / ranks
                solve = its * (per_it + 2 * comm + 3 * LATENCY_S * np.log2(ranks))
                what = f"{solve:.3g} s for one solve (~{its:.0f} CG iterations)"
                extra = ""
            out.append(dict(n=n, solver=solver, nodes=nodes, ranks=ranks,
                            solve_gb_total=solve_gb_total, whole_gb_rank=whole_gb_rank,
                            what=what, extra=extra, kappa=kappa))
    return model, out


# the largest steady solves measured here (not part of make bench-scaling): each file is one
# run of the command beside it; the last is the largest, what the cost model's text quotes
LARGEST_RUNS = tuple(
    (ROOT / f"bench/results/{name}.json",
     f"bench/bench_scaling.py --n {n} --solvers steady --ranks 2 --pcs hypre --no-inprocess "
     f"--json bench/results/{name}.json")
    for n, name in (("8e6", "scaling_largest_8e6"), ("1.6e7", "scaling_largest")))
LARGEST = LARGEST_RUNS[-1][0]


BUILD = ROOT / "bench/results/rank_build_memory.json"
# bench/bench_rank_build.py --stages: each rank's traced memory, step by step of the build
BUILD_STAGES = ROOT / "bench/results/rank_build_stages.json"
# what each step of rank_build.build_on_ranks does (the stages table's second column)
STEP_WORDS = {
    "read_packing_on_ranks": "each rank reads and checks its block of the file's particles "
                             "(the reader's checks, the first fault agreed on)",
    "morton_blocks_on_ranks": "the Morton order sorted on the ranks",
    "Routes": "the ways between the blocks of the order and the file's order",
    "_bulk_flags": "a [neighbours] scene's bulk flags (none here)",
    "_contacts_to_owners": "each rank reads its slice of the contacts, checks them, sends "
                           "each to its particles' owners",
    "_owner_block": "each rank fetches its particles and evaluates the law's capacities on "
                    "them",
    "_conducting_contacts": "each rank evaluates the law on its contacts",
    "_rank_rows": "each rank's rows of the matrix",
    "_owner_problem": "each rank runs the boundary kinds on its particles; the summary's "
                      "parts reduced",
    "_clusters_on_ranks": "each rank's components of its contacts, joined on rank 0 (an array "
                          "of the components)",
    "run_explicit": "the run after the build: the explicit steps, the output times' sums, "
                    "the temperatures gathered on rank 0",
    "_untied_rows": "the untied particles' rows to rank 0 (a steady solve fills them there)",
    "_explicit_bound": "the explicit bound, each rank's over its rows, the least on rank 0",
    "_root_summary": "rank 0's NetworkSummary from its parts (no array of every particle)",
}
# bench/bench_output_memory.py's rows: a long run's memory against its output times
OUTPUT_MEMORY = ROOT / "bench/results/output_memory.json"
# the section "Every scene of runs/ on 1, 2 and 3 ranks": make bench-ranks' command and its
# output (bench/ranks_same_answers.py), kept beside its table
RANKS_SECTION = ROOT / "bench/results/ranks_same_answers_section.md"


def build_fit(build):
    """Peak RSS of the explicit runs against N and R, least squares, bytes: a + whole N +
    divided N / R for rank 0 before (it built the whole network), rank 0 after (each rank
    builds its own part) and the other ranks after (the largest; rows with R >= 2)."""
    out = {}
    for which, key, pick, ranks in (("before", "rss_before_gb", lambda v: v[0], 1),
                                    ("after", "rss_after_gb", lambda v: v[0], 1),
                                    ("after_other", "rss_after_gb", lambda v: max(v[1:]), 2)):
        rows = [r for r in build["rows"] if r["solver"] == "explicit" and r["ranks"] >= ranks]
        A = np.array([[1.0, r["n"], r["n"] / r["ranks"]] for r in rows])
        y = np.array([pick(r[key]) * 1e9 for r in rows])
        out[which] = dict(zip(("a", "whole", "divided"), np.linalg.lstsq(A, y, rcond=None)[0]))
    return out


def build_memory_section(build) -> str:
    fit = build_fit(build)
    a, b = fit["after"], fit["before"]
    L = ["### Memory of the build on the ranks\n",
         f"Peak RSS of every rank over a whole `tdem run` on the ranks ({build['date']}; "
         "`bench/bench_rank_build.py`, not part of `make bench-scaling`; memory only: RSS "
         "figures measured on this machine under load (load "
         f"{' / '.join(' '.join(x) for x in build['load'])}, other agents' YADE runs), which "
         "the load does not change; no wall time is recorded). Before: the code of "
         f"{build['before']}, rank 0 reading the packing and building the whole network; "
         f"after: {build['after']}, each rank building its own rows. Haddad's law, every dumped "
         "row conducting, two held faces; libraries included (~0.16 GB a rank before any "
         "array).\n",
         "| packing | N | contacts | solver | ranks | before: rank 0 GB | before: other ranks "
         "GB | after: rank 0 GB | after: other ranks GB | sum over ranks before / after GB |",
         "|---|---|---|---|---|---|---|---|---|---|"]
    def others(v):
        return " / ".join(f"{x:.2f}" for x in v[1:]) or "-"

    for r in build["rows"]:
        bf, af = r["rss_before_gb"], r["rss_after_gb"]
        L.append(f"| {r['packing']} | {r['n']} | {r['contacts']} | {r['solver']} | "
                 f"{r['ranks']} | {bf[0]:.2f} | {others(bf)} | {af[0]:.2f} | {others(af)} | "
                 f"{sum(bf):.2f} / {sum(af):.2f} |")
    L.append("")
    o = fit["after_other"]
    L.append(f"Fitted on the explicit rows (the build dominates their peak; a + w N + d N / R): "
             f"before, rank 0 needed w = {b['whole']:.0f} B per particle, not divided by the "
             f"ranks (the whole network), + d = {b['divided']:.0f} B per particle / R; after, "
             f"rank 0 needs w = {a['whole']:.0f} B per particle"
             + (" (zero within the fit's noise: the start, the temperatures and the capacities "
                "the output gathers are a few tens of B per particle, the table below)"
                if a["whole"] < 16 else " (what the output gathers: the start, the "
                "temperatures, the capacities)")
             + f" + d = {a['divided']:.0f} / R, the "
             f"other ranks w = {o['whole']:.0f} + d = {o['divided']:.0f} / R (their particles, "
             "contacts, the law's inputs on them, their rows: no rank holds an array of every "
             "particle during the build; two N and three R do not separate w from d well), "
             "about "
             f"{a['a'] / 1e9:.2f} GB of libraries apart. The steady rows add the solver's share "
             "(and, on rank 0, the gathered temperatures and the output).\n")
    return "\n".join(L) + "\n"


def document(data) -> str:
    """docs/scaling.md from the measured rows (``data``: bench/results/scaling.json), with
    the largest solve and the build's memory where their files exist: its sections in
    order, each written by a ``_doc_*`` step."""
    model, proj = projection(data)
    largest = json.loads(LARGEST.read_text()) if LARGEST.exists() else None
    build = json.loads(BUILD.read_text()) if BUILD.exists() else None
    bfit = build_fit(build) if build else None
    L = _doc_running() + _doc_agreement() + _doc_measured(data)
    if largest:
        L += _doc_largest(largest)
    if build:
        L.append(build_memory_section(build))
    if BUILD_STAGES.exists():
        L += _doc_build_stages(json.loads(BUILD_STAGES.read_text()))
    if OUTPUT_MEMORY.exists():
        L += _doc_output_memory(json.loads(OUTPUT_MEMORY.read_text()))
    L += _doc_cuts(data)
    L += _doc_cost_model(model, proj, largest, build)
    L += _doc_projection(proj, build, bfit)
    text = "\n".join(L) + "\n"
    if RANKS_SECTION.exists():      # make bench-ranks' section (its own run, its own file)
        text += "\n" + RANKS_SECTION.read_text()
    return text


def _doc_running() -> list[str]:
    """The title and how to run on ranks (text only)."""
    L = []
    w = L.append
    w("# Scaling: the PETSc backend on MPI ranks (issue 25)\n")
    w("Written by `make bench-scaling` (`bench/bench_scaling.py --write docs/scaling.md`; the rows "
      "are in `bench/results/scaling.json`); edit the script, not this file.\n")
    w("## Running on ranks\n")
    w("```\nmake test                                   # or: make .venv-mpi/.installed\n"
      "tdem run runs/dense_box_1e5.toml --ranks 2   # or [solver] backend = \"petsc\"\n"
      "PETSC_OPTIONS=\"-pc_type hypre\" tdem run SCENE --ranks 2   # BoomerAMG, not GAMG\n"
      "```\n")
    w("`tdem run --ranks N` starts `mpirun -n N .venv-mpi/bin/python -m thermal_kernel.mpi_run "
      "SCENE` (`thermal_kernel/solvers/mpi_launch.py`). The particles are ordered along a "
      "Morton curve of their centres and the order cut into equal blocks "
      "(`thermal_kernel/solvers/partition.py`); each rank builds its own rows "
      "(`thermal_kernel/rank_build.py`): rank r reads the r-th block of the file's "
      "particles, the ranks sort the Morton order together (a sample sort of the blocks' "
      "keys, the whole sort's order bit for bit: `tests/mpi_partition_check.py`, 1-4 ranks) "
      "and rank r takes the r-th block of it; every value between the ranks' blocks and "
      "rank 0 goes in the file's order through the particles' directories "
      "(`partition.Routes`: no rank holds the order); rank r reads the r-th slice of the "
      "file's contact rows, checks the rows against their "
      "spheres as the in-process reader does, and sends each contact to the ranks owning its "
      "two particles; a scene's `[neighbours]` criterion (e.g. the gap giving a target bulk "
      "coordination, chosen over every bulk contact) is chosen with collectives over the "
      "ranks' slices (`thermal_kernel.neighbours.choose_neighbours_on_ranks`: each rank "
      "marks the bulk particles of its block; a bisection over the float bits of "
      "d/(r_i + r_j), the ranks' summed bulk weights gathered a step, finds the whole "
      "build's gap bit for bit), no rank holding every contact; each rank evaluates the "
      "scene's law (the one registry) on the contacts it then holds (H = 0 on the rows the "
      "criterion leaves out) and puts its rows into a PETSc MPIAIJ matrix; each rank runs the "
      "boundary kinds (the one registry) on its own particles, and rank 0 joins the ranks' "
      "components into the in-process clusters. Each rank's rows and boundary rows, its "
      "source's powers, rank 0's clusters, bound and flags equal the whole build's bit for "
      "bit (the summary's sums to 1e-14), and so do a `[neighbours]` scene's gap, rows "
      "kept and bulk coordinations "
      "(`tests/mpi_rank_build_check.py`, 2 and 3 ranks). A scene given `--whole-build` "
      "(`thermal_kernel.mpi_run`'s option, for comparison: the table 'Memory of the build "
      "on the ranks') is built whole on rank 0, which sends each rank its rows. The "
      "explicit step is a distributed mat-vec with "
      "the in-process dt and bound; the implicit schemes (theta, Rannacher, TR-BDF2) and the "
      "steady solve use CG with GAMG (default) or hypre BoomerAMG to a relative true residual "
      "of 1e-12. Rank 0 writes the ordinary `thermal.h5` (the in-process attributes, flags and "
      "checks, plus `backend`, `ranks`, `cut_contacts`, `linear_solver`, `run_seconds`), so "
      "`tdem post` takes it unchanged. On a cluster, with a hostfile:\n")
    w("```\nmpirun --hostfile hosts -n 256 -x OMP_NUM_THREADS=1 -x NUMBA_NUM_THREADS=1 \\\n"
      "    .venv-mpi/bin/python -m thermal_kernel.mpi_run SCENE.toml --out runs/out/big \\\n"
      "    --checkpoint-every 10   # a transient run; after a batch system's time limit, "
      "the same line with --resume\n```\n")
    return L


def _doc_agreement() -> list[str]:
    """Agreement with the in-process solvers, what is still whole on rank 0, what works as
    in-process, validation on ranks and the backend's limits (text only)."""
    L = []
    w = L.append
    w("Agreement with the in-process solvers (`tests/test_petsc_backend.py`, 1, 2 and 3 ranks, "
      "`make test`): explicit within 1e-12 of the temperature change, implicit and steady "
      "within 1e-10, boundary flows and ledger alike, flags identical; the last column of the "
      "table below is the same comparison at bench scale (relative to max abs(T)).\n")
    w("**What is whole on rank 0**: no array of every particle, during the build or the "
      "run, but what a single output file needs. Each rank reads and checks its block of the "
      "file's particles with the in-process reader's checks and the same first fault "
      "(`thermal_kernel.packing_ranks.read_packing_on_ranks`, every rank agreeing after "
      "each stage; the walls and wall contacts, a surface's worth, on every rank; "
      "`tests/test_packing_ranks.py`, 1-3 ranks, 20 good and bad files), finds a "
      "`[neighbours]` scene's bulk flags of its block, fetches its own particles, evaluates "
      "the law's capacities on them and runs the boundary kinds (the one registry) on them, "
      "seeing the whole packing through reductions (`boundaries.base.Whole`: a count, a "
      "flag, a sum in packing order, the phases present, the lowest particle; a refusal is "
      "the in-process line: `test_a_boundary_refused_on_the_ranks_is_the_in_process_line`); "
      "a source is built over each rank's block. Rank 0 joins the ranks' components "
      "into the clusters (an array of the components: one entry per cluster and rattler) and "
      "makes the network's `NetworkSummary` (counts, bounds, flags, the boundaries' constant "
      "powers, the steady reference, the maximum principle's inputs, the untied particles' "
      "rows) from the ranks' reductions. During the run the ranks set a transient run's "
      "start on their rows and, at each output time, sum the boundaries' heat flows and the "
      "stored energy over their rows (`DistributedNetwork.output_terms`); a steady solve's "
      "floating clusters and rattlers are filled on rank 0 from the untied particles' rows "
      "(`tests/mpi_steady_check.py`). What rank 0 holds of every particle is the output's: "
      "the start T0 and one output time's temperatures while it writes them into "
      "`thermal.h5` (a run's history of them goes to disk when it is large: the table "
      "'Memory of a long run's output' below), and the capacities gathered at the end.\n")
    w("As in-process: `--checkpoint-every K` and `--resume` (rank 0 gathers the state after "
      "every K output times and writes the in-process checkpoint; either kind resumes on "
      "either), rank 0 shows the in-process progress bar, and `tdem campaign` runs each case "
      "on the ranks when the scene says `backend = \"petsc\"` (1 rank) or `--ranks N` is "
      "given (`tests/test_petsc_backend.py`: a run resumed on 2 ranks from an in-process "
      "checkpoint, and a campaign on the backend, give the in-process answers).\n")
    w("`tdem validate CASE --ranks N` runs every scene a validation case runs (through "
      "`thermal_kernel.run.run_in_memory`, which takes `ranks=N` too, and honours a scene's "
      "`backend = \"petsc\"` with 1 rank) on the ranks: `mpi_run` through the launcher into a "
      "temporary folder, its `thermal.h5` read back into the in-process `SceneRun` (the "
      "problem, network and neighbour choice are the in-process build's, made beside it and "
      "checked to agree with the ranks'; a transient run's final state comes from rank 0, "
      "`mpi_run --state-out`; `assemble_seconds` is all but the ranks' solve). The packing "
      "goes as it is in memory, written to a temporary file (case 3 scales its sheet, cases "
      "8-10 set the phases); a start per particle and a conductance factor per dumped row as "
      "`.npy` files (`mpi_run --initial-temperature`, `--conductance-factor`, each rank "
      "reading its contacts' rows); a run continued from another's state (`start_state`, "
      "case 2's second stage) as the checkpoint the ranks resume from. Refused, in one line: "
      "a scene changed after it was read (the ranks read its text). The flux tests of "
      "`calibrate` in a case (case 6 whole, the C_t of cases 2-5) run on the ranks too, as "
      "`tdem calibrate SCENE --ranks N` does (`thermal_kernel.calibrate.flux_test` through "
      "`run_in_memory`: its scene is the case's text with the two faces held and a steady "
      "solve, the faces 300 K higher when the test's colder one is at 0 K, which a scene "
      "refuses; the in-process test is unchanged, bit for bit), and without `--ranks` every "
      "case runs in-process whatever a scene's "
      "`backend`; runs on ranks are cached apart (`<stem>.ranksN.json`). "
      "`tests/test_petsc_backend.py`: case 4's quick slab (explicit and steady) on 2 ranks "
      "gives the in-process case's numbers (the profile within 1e-12 of ΔT, the steady "
      "profile within 1e-10), a run with a start, factors and flipped phases the in-process "
      "run (1e-12, flags identical), a Rannacher run continued from its state the in-process "
      "two stages (1e-10, the same steps). The quick instances of cases 2 to 10 on 2 ranks, "
      "their flux tests on the ranks too, gave their in-process numbers (every number of "
      "each case's record compared: the errors against the papers' solutions and "
      "references, C_t, CoV, k, T within 7.1e-12 relative, C_t within 1.6e-13, but for "
      "case 4's profile errors, 1.4e-11 of an error of 0.8 % (1e-13 of ΔT), and case 9's "
      "Halo flux errors against the FE values, 1.2e-11; the differences of two runs, the "
      "dt checks of cases 2 and 3, within 3.8e-11 and 9.1e-9 of themselves; heat-balance "
      "residuals and a zero flux at round-off, <= 1e-12; seconds apart; 2026-12-02 after "
      "dd4e1a7, by hand, not in the suite).\n")
    w("Limits of the backend today: the preconditioner is GAMG unless PETSC_OPTIONS says "
      "`-pc_type hypre` (hypre was faster here, the table; GAMG stays the default because it "
      "is part of every PETSc build, hypre an optional package).\n")
    return L


def _doc_measured(data) -> list[str]:
    """The measured rows: load, network, the table."""
    L = []
    w = L.append
    rows = data["rows"]
    w(f"## Measured ({data['date']}, this machine: 2 cores, shared)\n")
    w(f"Load while it ran: {' / '.join(' '.join(x) for x in data['load'])} (1/5/15-min load "
      f"averages at start and end; `{data['uptime']}`). A load above 2 means other jobs (here "
      "other agents' YADE runs) wanted the 2 cores too: the wall times measure them as well, "
      "and 2 ranks, which wait for each other at every halo exchange and every CG "
      "reduction, lose most (a rank descheduled for a time slice stalls the other). The "
      "CPU column is the work; the cost model is fitted on it. The probe of issue 25, on a "
      "quieter machine, measured 1.82x for the 1e5 steady solve on 2 ranks (GAMG). The ranks "
      "run with `mpirun --bind-to none --mca mpi_yield_when_idle 1` (`MPIRUN_LOCAL` of "
      "`mpi_launch.py`, also what `tdem run --ranks` uses): under a load of ~4.5 a 3e5 "
      "steady solve on 2 ranks took 4.7 s with it against 8.6 s with Open MPI's default "
      "(polling, bound to a core); 1 rank 2.6-3.6 s.\n")
    w("Network: bench_explicit's packing-like one (N random centres in a cube, mean "
      "coordination 6, random H and C, seeded), two held faces. wall: the steps (explicit, "
      f"{EXPLICIT_STEPS} steps at 0.9 of the bound), setup + {IMPLICIT_STEPS} backward-Euler "
      f"steps at {IMPLICIT_DT_OVER_BOUND:g} x the bound (implicit; in-process: pyamg AMG-CG), "
      "the solve (steady; in-process: pyamg AMG-CG to 1e-12). CPU: the solve call's CPU "
      "seconds on its busiest rank (waiting ranks poll, so it counts some waiting). RSS: "
      "peak per process; the bench's network is made in memory (no packing file), so rank 0 "
      "holds it whole and sends the others their rows (the path of `--whole-build`; a "
      "packing file's run is built on the ranks: the next table); solve+: what the solve "
      "added to the largest (the part ranks divide).\n")
    w("| N | solver | backend | threads / pc | ranks | wall s | vs 1 rank | CPU s (busiest "
      "rank) | iterations | peak RSS rank 0 GB | peak RSS other ranks GB | solve+ GB | "
      "B / particle / rank (solve part) | cut contacts | max abs(T - T_in-process) / max "
      "abs(T) |")
    w("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        ref = [q for q in rows if q["n"] == r["n"] and q["solver"] == r["solver"] and
               q["backend"] == r["backend"] and q.get("pc") == r.get("pc") and q["ranks"] == 1
               and q.get("threads") == r.get("threads")]
        ratio = f"{ref[0]['wall_s'] / r['wall_s']:.2f}x" if ref and r["ranks"] > 1 else ""
        tp = f"{r['threads']} thr" if r["backend"] == "in-process" else r["pc"]
        bpp = r["rss_solve_gb"] * 1e9 / (r["n"] / r["ranks"])
        w(f"| {r['n']:.0e} | {r['solver']} | {r['backend']} | {tp} | {r['ranks']} | "
          f"{r['wall_s']:.3g} | {ratio} | {r['cpu_s']:.3g} | {r['iterations'] or ''} | "
          f"{(r.get('rss_ranks_gb') or [r['rss_max_gb']])[0]:.2f} | "
          f"{max(r.get('rss_ranks_gb', [])[1:], default=float('nan')):.2f} | "
          f"{r['rss_solve_gb']:.2f} | {bpp:.0f} | {r['cut'] or ''} | "
          f"{r['diff_vs_inprocess']:.1e} |")
    w("")
    return L


def _doc_largest(largest) -> list[str]:
    """The largest steady solves (LARGEST_RUNS' files that exist; ``largest`` the last)."""
    L = []
    w = L.append
    runs = [(json.loads(path.read_text()), cmd) for path, cmd in LARGEST_RUNS if path.exists()]
    w("The largest steady solves measured here (each a command of its own, not part of "
      "`make bench-scaling`: a few minutes, most of them making the network in memory on "
      "rank 0, the bench's path without a packing file; mpirun "
      f"{largest.get('mpirun_options') or 'with Open MPI defaults (polling, bound)'}; the "
      "load is the 1/5/15-min averages at the start and the end):\n")
    w("| N | ranks | pc | wall s | CPU s (busiest rank) | iterations | peak RSS rank 0 GB | "
      "peak RSS other ranks GB | measured | load | command |")
    w("|---|---|---|---|---|---|---|---|---|---|---|")
    for run, cmd in runs:
        load = " / ".join(" ".join(x) for x in run["load"])
        for r in run["rows"]:
            w(f"| {r['n']:.2g} | {r['ranks']} | {r['pc']} | {r['wall_s']:.3g} | "
              f"{r['cpu_s']:.3g} | {r['iterations']} | {r['rss_ranks_gb'][0]:.2f} | "
              f"{max(r['rss_ranks_gb'][1:], default=float('nan')):.2f} | {run['date']} | "
              f"{load} | `{cmd}` |")
    w("")
    return L


def stage_peaks(row) -> list[dict]:
    """Each rank's peak per step of one --stages row: {step: bytes per particle above the
    rank's traced memory before the first step}."""
    out = []
    for steps in row["steps"]:
        base = steps[0]["start"] if steps else 0
        out.append({s["step"]: (s["peak"] - base) / row["n"] for s in steps})
    return out


def stages_whole(st) -> dict:
    """Rank 0's part of each step not divided by the ranks, bytes per particle: peak = w + d / R
    solved from the 2- and 3-rank rows of bench_rank_build.py --stages ({} without both)."""
    by_r = {r["ranks"]: stage_peaks(r)[0] for r in st["rows"]}
    if 2 not in by_r or 3 not in by_r:
        return {}
    p2, p3 = by_r[2], by_r[3]
    return {k: 3 * p3[k] - 2 * p2[k] for k in p2 if k in p3}


def _doc_build_stages(st) -> list[str]:
    """Each rank's traced memory, step by step of the build (bench_rank_build.py --stages):
    what rank 0 holds beyond the others, and where."""
    rows = st["rows"]
    by_r = {r["ranks"]: r for r in rows}
    timed = all("seconds" in s for r in rows for s in r["steps"][0])
    head = "| step | what it does | " + " | ".join(
        f"{r['ranks']} ranks: rank 0 | {r['ranks']} ranks: other ranks" for r in rows) + " |"
    if timed:
        head += "".join(f" {r['ranks']} ranks: rank 0's wall s |" for r in rows)
    L = ["### What rank 0 holds, step by step of the build\n",
         f"Traced memory (tracemalloc: numpy's arrays and Python's objects, not the libraries "
         f"or the allocator's slack) of each rank at the peak of each step of "
         f"`rank_build.build_on_ranks` and of the run after it (`petsc_backend.run_explicit`: "
         "its traced memory at the start is what the rank keeps for the run), in bytes per "
         "particle above the rank's traced memory "
         f"before the first step ({st['date']}, the code of {st['commit']}; "
         "`bench/bench_rank_build.py --stages`, not part of `make bench-scaling`; memory "
         f"only). {rows[0]['packing']}: {rows[0]['n']} particles, {rows[0]['contacts']} "
         "contacts, explicit, Haddad's law, two held faces. '-': a step rank 0 makes alone."
         + (" Wall seconds: rank 0's, per step, the best of three runs without tracemalloc "
            f"(load {' / '.join(' '.join(x) for x in st['load'])}); the ranks share this "
            "machine's 2 cores." if timed else "") + "\n",
         head, "|---|---|" + "---|---|" * len(rows) + ("---|" * len(rows) if timed else "")]

    per = {r["ranks"]: stage_peaks(r) for r in rows}
    for name in [s["step"] for s in rows[0]["steps"][0]]:
        cells = []
        for r in rows:
            p = per[r["ranks"]]
            other = [q[name] for q in p[1:] if name in q]
            cells += [f"{p[0][name]:.0f}", f"{max(other):.0f}" if other else "-"]
        if timed:
            cells += [f"{next(s['seconds'] for s in r['steps'][0] if s['step'] == name):.3g}"
                      for r in rows]
        L.append(f"| `{name}` | {STEP_WORDS.get(name, '')} | " + " | ".join(cells) + " |")
    L.append("")
    if 2 in by_r and 3 in by_r:
        p2, p3 = per[2][0], per[3][0]
        top2 = max(p2, key=p2.get)
        whole = stages_whole(st)
        late = [k for k in ("_owner_problem", "_clusters_on_ranks", "_untied_rows",
                            "_root_summary", "run_explicit") if k in whole]
        wl = max(late, key=whole.get) if late else None
        first = rows[0]["steps"][0][0]["step"]
        L.append(f"Read: on 2 and 3 ranks rank 0's highest step is `{top2}` ({p2[top2]:.0f} "
                 f"and {p3[top2]:.0f} B per particle), where every rank holds its contacts. "
                 "Written as peak = w + d / R from the two rows, rank 0's part not divided by "
                 f"the ranks is w = {whole[top2]:.0f} B per particle there, "
                 f"w = {whole[first]:.0f} in `{first}`"
                 + (f" and w = {whole[wl]:.0f} in `{wl}`, the largest of the later steps "
                    f"({STEP_WORDS.get(wl, '')})" if wl else "")
                 + ". Every rank reads, checks and builds its own particles: what rank 0 "
                 "holds beyond its block is the components' arrays (one entry per cluster "
                 "and rattler, to join them), the untied particles' rows and, in the run, "
                 "the temperatures it gathers at an output time. Two rows (R = 2, 3) of "
                 "traced memory are noisy at a few B per particle: a w near 0 means no array "
                 "of every particle.\n")
    if timed and rows[0].get("root_alone"):
        r = rows[0]
        alone = [s for s in r["steps"][0] if s["step"] in r["root_alone"]]
        total = sum(s["seconds"] for s in alone)
        L.append("Time: the steps rank 0 makes while the other ranks wait ("
                 + ", ".join(f"`{s['step']}`" for s in alone)
                 + f") took {total:.3g} s on {r['ranks']} ranks, {total / r['n'] * 1e9:.0f} "
                 "ns per particle, not divided by the ranks: at 1e9 particles about "
                 f"{total / r['n'] * 1e9 / 60:.2g} min of the build on rank 0 alone, "
                 "before the first step of the solve.\n")
    return L


def _doc_output_memory(om) -> list[str]:
    """A long run's memory against its output times (bench/bench_output_memory.py)."""
    L = []
    w = L.append
    load = " / ".join(" ".join(x) for x in om["load"])
    w("### Memory of a long run's output\n")
    w(f"Peak anonymous memory (RssAnon, sampled every 10 ms by each process; {om['date']}; "
      f"`bench/bench_output_memory.py`, not part of `make bench-scaling`; load {load}) of "
      "an explicit `tdem run` of the dense box with 50 and 500 output times, in-process "
      f"(one thread) and on 2 ranks. Before: the code of {om['before']}, which held the "
      "temperatures of every output time in memory (on rank 0: gathered there) and built "
      f"thermal.h5's image beside them; after: {om['after']}, where a history over 256 MiB "
      "is a memory map of an unnamed file beside the output and thermal.h5 is written on "
      "disk into room reserved first (below 256 MiB both stay in memory, as before).\n")
    w("| packing | N | output times | history GB | ranks | before: GB per process | "
      "after: GB per process |")
    w("|---|---|---|---|---|---|---|")
    for r in om["rows"]:
        before = " / ".join(f"{v:.2f}" for v in r["anon_before_gb"])
        after = " / ".join(f"{v:.2f}" for v in r["anon_after_gb"])
        w(f"| {r['packing']} | {r['n']} | {r['output_times']} | {r['history_gb']:.2f} | "
          f"{r['ranks'] or 'in-process'} | {before} | {after} |")
    w("")
    return L


def _doc_cuts(data) -> list[str]:
    """The contacts cut by the ranks' blocks: packings, then the bench's network."""
    L = []
    w = L.append
    w("### Contacts cut by the ranks' blocks\n")
    w("Each cut contact is a value the mat-vec sends between two ranks, every step. The "
      "packing's own order against the Morton order (`partition.py`):\n")
    w("| packing | N | contacts | ranks | cut, packing order | cut, Morton order |")
    w("|---|---|---|---|---|---|")
    for c in data["cuts"]:
        w(f"| {c['packing']} | {c['n']} | {c['contacts']} | {c['ranks']} | "
          f"{100 * c['index']:.2f} % | {100 * c['morton']:.2f} % |")
    w("")
    w("The bench's network (its centres are random, so its own order cuts ~all contacts; "
      "the Morton order):\n")
    w("| N | ranks | contacts | cut | cut / contacts | halo per rank (2 cut / R) |")
    w("|---|---|---|---|---|---|")
    for c in data["synthetic_cuts"]:
        w(f"| {c['n']:.0e} | {c['ranks']} | {c['contacts']} | {c['cut']} | "
          f"{100 * c['cut'] / c['contacts']:.2f} % | {2 * c['cut'] / c['ranks']:.0f} |")
    w("")
    return L


def _doc_cost_model(model, proj, largest, build) -> list[str]:
    """The cost model fitted on the 1-rank rows, this machine's largest, the model's terms."""
    L = []
    w = L.append
    w("## Cost model and what 1e8 and 1e9 particles need\n")
    big = model["n"]
    w(f"Fitted on the CPU time of the 1-rank PETSc rows at N = {big:.0e} (GAMG; CPU, not "
      "wall, because the wall of this shared machine measured the other jobs too), the halo "
      "on the Morton cuts above:\n")
    for solver in ("explicit", "steady", "implicit"):
        m = model.get(solver)
        if m is None:
            continue
        unit = {"explicit": "per particle per step", "steady": "per particle per solve",
                "implicit": f"per particle for the setup and {IMPLICIT_STEPS} steps"}[solver]
        w(f"- {solver}: {m['s_per_particle'] * 1e9:.3g} ns {unit}"
          + (f" ({m['its']} CG iterations)" if m["its"] else "")
          + f"; solver memory {m['solve_bytes_per_particle']:.0f} B per particle (divided by "
          f"the ranks); the whole network rank 0 holds when it builds it (the bench's path; "
          f"with the Python, numba and PETSc libraries, ~0.2 GB) "
          f"{m['whole_bytes_per_particle']:.0f} B per particle (not divided); measured here "
          f"on 2 ranks: wall {m['speedup_2']:.2f}x, CPU of the busiest rank "
          f"{m['cpu_ratio_2']:.2f}x of 1 rank's.")
    w("")
    st = model.get("steady")
    if st:
        per = st["whole_bytes_per_particle"] + st["solve_bytes_per_particle"]
        w(f"On this 24 GB machine (all ranks on it), a steady solve with rank 0 building the "
          f"whole network needs ~{per:.0f} B per particle in all (rank 0's whole network + the "
          f"solver, whatever the ranks): the largest it holds with 10 % to spare is "
          f"~{0.9 * 24e9 / per:.1e} particles"
          + (" (measured: the last row of that table, {:.2g} particles, the sum of its "
             "ranks' peaks {:.1f} GB)."
             .format(largest["rows"][0]["n"], sum(largest["rows"][0]["rss_ranks_gb"]))
             if largest else ".")
          + (" Built on the ranks, the sum of the ranks' peaks is lower (the table 'Memory of "
             "the build on the ranks': 1e6 steady on 2 ranks)." if build else "") + "\n")
    kappa = proj[0]["kappa"] if proj else float("nan")
    w(f"Model: time per step or per CG iteration on R ranks = a N / R + halo, with halo = "
      f"26 latencies + 8 B x h / bandwidth, h = {kappa:.2f} (N/R)^(2/3) values per rank (the "
      "largest fit on the Morton cuts at 8-4096 ranks); a CG iteration adds 3 allreduces "
      f"(latency x log2 R). Assumed cluster (not measured here): nodes of {NODE_CORES} cores and "
      f"{NODE_GB:g} GB, {LINK_GB_S:g} GB/s per node, {LATENCY_S * 1e6:g} us latency, one rank "
      "per core; GAMG iterations extrapolated log-linearly in N from the two largest N "
      "measured.\n")
    return L


def _doc_projection(proj, build, bfit) -> list[str]:
    """What 1e8 and 1e9 particles need, and how to read it."""
    L = []
    w = L.append
    # rank 0's bytes per particle not divided by the ranks: the larger of the RSS fit and the
    # traced step-by-step part (bench_rank_build.py --stages), the stricter reading
    fit_pp = bfit["after"]["whole"] if build else float("nan")
    whole = stages_whole(json.loads(BUILD_STAGES.read_text())) if BUILD_STAGES.exists() else {}
    step_pp = max(whole.values()) if whole else float("nan")
    step = max(whole, key=whole.get) if whole else ""
    root_pp = float(np.nanmax([fit_pp, step_pp])) if build else float("nan")
    w("| N | solver | nodes (64 cores) | solver memory, all ranks | + on rank 0: the whole "
      "network (whole build) | + on rank 0: the per-particle arrays (per-rank build) | time |")
    w("|---|---|---|---|---|---|---|")
    for p in proj:
        w(f"| {p['n']:.0e} | {p['solver']} | {p['nodes']} ({p['ranks']} ranks) | "
          f"{p['solve_gb_total']:.0f} GB | {p['whole_gb_rank']:.0f} GB | "
          f"{root_pp * p['n'] / 1e9:.0f} GB | {p['what']}"
          + (f"; {p['extra']}" if p["extra"] else "") + " |")
    w("")
    if proj:
        top = {(p["n"], p["solver"]): p for p in proj}
        s8 = top.get((1e8, "steady"))
        s9 = top.get((1e9, "steady"))
        if s8 and s9 and bfit:
            w(f"Read: the distributed part of a steady solve needs {s8['solve_gb_total']:.0f} GB "
              f"in all at 1e8 ({s8['nodes']} node(s)) and {s9['solve_gb_total']:.0f} GB at 1e9 "
              f"({s9['nodes']} nodes). Built whole on rank 0, rank 0's node must also hold "
              f"the whole network on its own ({s8['whole_gb_rank']:.0f} GB at 1e8, "
              f"{s9['whole_gb_rank']:.0f} GB at 1e9): a few 1e8 particles on a 256 GB node, "
              "not 1e9. Built on the ranks (every packing file's run, a `[neighbours]` "
              "criterion included), no rank holds an array of every particle during the "
              "build; rank 0 holds, beyond its share, what the single output file needs (the "
              "start, one output time's temperatures while it writes them, the capacities "
              f"at the end; the last-but-one column: {root_pp:.0f} B per particle, the larger "
              f"of the fit on the build's measured peaks, {fit_pp:.0f}, and rank 0's traced "
              f"part in `{step}`, {step_pp:.0f}, the table 'What rank 0 holds, step by step': "
              f"{root_pp * 1e8 / 1e9:.0f} GB at 1e8, {root_pp * 1e9 / 1e9:.0f} GB at 1e9): "
              "1e9 then needs rank 0 on a node with that much memory beside its share (fewer "
              "ranks on its node); a writer in parallel HDF5 (h5py-mpi) would divide that "
              "column by the ranks too.\n")
    return L


def _line(r):
    how = f"threads={r.get('threads')}" if r["backend"] == "in-process" else f"pc={r['pc']}"
    return (f"N={r['n']:.0e} {r['solver']:8s} {r['backend']:10s} {how:12s}"
            f" ranks={r['ranks']} wall={r['wall_s']:.3f}s cpu={r['cpu_s']:.3f}s "
            f"its={r['iterations']} "
            f"rss_max={r['rss_max_gb']:.2f}GB solve+={r['rss_solve_gb']:.2f}GB cut={r['cut']} "
            f"diff={r['diff_vs_inprocess']:.1e}")


if __name__ == "__main__":
    main()
