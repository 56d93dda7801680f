"""Benchmark of the explicit kernel's data layout (not a test; the numbers go to docs/solvers.md).

    .venv/bin/python bench/bench_explicit.py                  # N = 1e5 and 1e6, 1 and 2 threads
    .venv/bin/python bench/bench_explicit.py --n 1e6 --steps 100
    .venv/bin/python bench/bench_explicit.py --memory 1e6     # peak RSS of explicit and steady

A seeded packing-like network: N uniform random points in a cube, contacts between points
closer than the distance that gives a mean coordination of 6 (Poisson: ~0.25 % rattlers),
particles renumbered in Morton (Z-curve) order and contacts sorted, so neighbours are close in
memory as in a dump sorted for locality. Conductances and capacities are random (seeded).

Layouts timed, counting each contact once per step (contact-updates/s = M x steps / s):
  csr-gather     the production kernel (thermal_kernel.solvers.explicit._step_plain): each
                 particle sums its CSR row; indices are scipy's int32 arrays viewed as uint32
                 (numba then skips the negative-index test); no atomics; any thread count gives
                 the same bits;
  csr-gather-signed  the same kernel on the signed int32 arrays;
  edge-scatter   edge list (i, j, H): f = H (T_j - T_i), acc_i += f, acc_j -= f, then update;
                 serial (a parallel scatter needs atomics or colouring, and atomics make the sum
                 order, hence the bits, depend on the threads);
  edge-scatter-2buf  the edge list split into 2 fixed halves, each scattering into its own
                 accumulator, then summed: parallel and deterministic, at the cost of 2 N-vectors.
Also the full run_explicit step (kernel + ledger + two Dirichlet faces).
"""
from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import time

import numba
import numpy as np
from numba import njit, prange

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from thermal_kernel.network import assemble, make_problem  # noqa: E402
from thermal_kernel.solvers.explicit import _step_plain, _unsigned  # noqa: E402


def morton_order(x: np.ndarray, bits: int = 10) -> np.ndarray:
    """Permutation sorting points in [0, 1)^3 along a Z-curve of 2^bits cells per axis."""
    cell = np.minimum((x * (1 << bits)).astype(np.int64), (1 << bits) - 1)
    code = np.zeros(x.shape[0], dtype=np.int64)
    for b in range(bits):
        for a in range(3):
            code |= ((cell[:, a] >> b) & 1) << (3 * b + a)
    return np.argsort(code, kind="stable")


def packing_like(n: int, seed: int = 1, z: float = 6.0):
    from scipy.spatial import cKDTree
    rng = np.random.default_rng(seed)
    x = rng.random((n, 3))
    x = x[morton_order(x)]
    r = (z / (n * 4.0 / 3.0 * np.pi)) ** (1.0 / 3.0)
    pair = cKDTree(x).query_pairs(r, output_type="ndarray").astype(np.int64)
    pair.sort(axis=1)
    pair = pair[np.lexsort((pair[:, 1], pair[:, 0]))]
    h = rng.uniform(0.5, 2.0, pair.shape[0])
    c = rng.uniform(1.0, 3.0, n)
    return x, pair, h, c


@njit(cache=True)
def _scatter(ei, ej, hval, inv_c, dt, t_old, acc, t_new):
    acc[:] = 0.0
    for e in range(ei.shape[0]):
        i, j = ei[e], ej[e]
        f = hval[e] * (t_old[j] - t_old[i])
        acc[i] += f
        acc[j] -= f
    for p in range(t_old.shape[0]):
        t_new[p] = t_old[p] + (dt * inv_c[p]) * acc[p]


@njit(parallel=True, cache=True)
def _scatter_2buf(ei, ej, hval, inv_c, dt, t_old, acc2, t_new):
    m = ei.shape[0]
    half = (m + 1) // 2
    for part in prange(2):
        a = acc2[part]
        a[:] = 0.0
        for e in range(part * half, min(m, (part + 1) * half)):
            i, j = ei[e], ej[e]
            f = hval[e] * (t_old[j] - t_old[i])
            a[i] += f
            a[j] -= f
    for p in prange(t_old.shape[0]):
        t_new[p] = t_old[p] + (dt * inv_c[p]) * (acc2[0, p] + acc2[1, p])


def timed(fn, steps, repeats=3):
    """Best of ``repeats`` wall times for ``steps`` calls, and the CPU/wall ratio of that
    repeat (about the number of busy threads: 2 means both cores worked)."""
    fn()  # warm (JIT)
    best, ratio = np.inf, np.nan
    for _ in range(repeats):
        c0 = os.times()
        t0 = time.perf_counter()
        for _ in range(steps):
            fn()
        wall = time.perf_counter() - t0
        c1 = os.times()
        if wall < best:
            best = wall
            ratio = (c1.user + c1.system - c0.user - c0.system) / wall
    return best, ratio


def bench(n: int, steps: int, threads=(1, 2)):
    t0 = time.perf_counter()
    x, pair, h, c = packing_like(n)
    m = pair.shape[0]
    gen = time.perf_counter() - t0
    lo = np.flatnonzero(x[:, 0] < 0.02)
    hi = np.flatnonzero(x[:, 0] > 0.98)
    prob = make_problem(c, pair, h, fixed=(np.r_[lo, hi], np.r_[np.full(lo.size, 300.0),
                                                                 np.full(hi.size, 400.0)],
                                           np.r_[np.zeros(lo.size), np.ones(hi.size)]),
                        boundary_names=("cold", "hot"))
    t0 = time.perf_counter()
    net = assemble(prob)
    asm = time.perf_counter() - t0
    print(f"N = {n:,}  contacts M = {m:,} (active {net.n_active_contacts:,}, mean Z "
          f"{2 * m / n:.2f})  generate {gen:.1f} s  assemble {asm:.1f} s  "
          f"dt_max {net.dt_max_s:.3g}  clusters: {net.clusters.summary()}")
    a = net.adjacency
    inv_c = 1.0 / c
    held = net.held
    no_held = np.zeros(n, dtype=bool)
    dt = 0.5 * net.dt_max_s
    rng = np.random.default_rng(2)
    T = 300.0 + 100.0 * rng.random(n)
    Tn = np.empty_like(T)
    uptr, uind = _unsigned(a.indptr), _unsigned(a.indices)
    ei32, ej32 = pair[:, 0].astype(np.uint32), pair[:, 1].astype(np.uint32)
    acc = np.zeros(n)
    acc2 = np.zeros((2, n))
    rows = []
    for nt in threads:
        numba.set_num_threads(nt)
        cases = {
            "csr-gather": lambda: _step_plain(uptr, uind, a.data, inv_c, no_held, dt, T, Tn),
            "csr-gather-signed": lambda: _step_plain(a.indptr, a.indices, a.data, inv_c,
                                                     no_held, dt, T, Tn),
            "edge-scatter": lambda: _scatter(ei32, ej32, h, inv_c, dt, T, acc, Tn),
            "edge-scatter-2buf": lambda: _scatter_2buf(ei32, ej32, h, inv_c, dt, T, acc2, Tn),
        }
        for name, fn in cases.items():
            if name == "edge-scatter" and nt > 1:
                continue   # serial by construction
            s, cpu = timed(fn, steps)
            rows.append((name, nt, m * steps / s, s / steps, cpu))
        from thermal_kernel.solvers import run_explicit
        run_explicit(net, T, [dt * 2], dt=dt, threads=nt)    # warm
        r = run_explicit(net, T, [dt * steps], dt=dt, threads=nt)
        rows.append(("run_explicit (kernel+ledger)", nt, r.contact_updates_per_second,
                     r.info["step_seconds"] / r.steps, np.nan))
    numba.set_num_threads(max(threads))
    # Check the two gathers and the scatter agree (to round-off) and 1 == 2 threads bitwise.
    out = {}
    for nt in threads:
        numba.set_num_threads(nt)
        _step_plain(uptr, uind, a.data, inv_c, held, dt, T, Tn)
        out[nt] = Tn.copy()
    _scatter(ei32, ej32, h, inv_c, dt, T, acc, Tn)
    Tn[held] = T[held]
    print(f"  gather 1 vs 2 threads bit-identical: {np.array_equal(out[1], out[max(threads)])};"
          f" gather vs scatter max diff {np.abs(out[1] - Tn).max():.2e} K")
    for name, nt, cups, per_step, cpu in rows:
        print(f"  {name:30s} threads {nt}: {cups:10.3e} contact-updates/s  "
              f"({per_step * 1e3:7.2f} ms/step, cpu/wall {cpu:4.2f})")
    return rows


def _rss_now() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def memory(path: str, what: str):
    """Peak RSS of assembling + one explicit run (20 steps, no stored temperatures) or one
    steady AMG solve, on a problem saved by the parent (so generation is not counted)."""
    d = np.load(path)
    n = d["c"].size
    fixed = d["fixed"]
    prob = make_problem(d["c"], d["pair"], d["h"],
                        fixed=(fixed, d["fixed_t"], d["fixed_b"]), boundary_names=("cold", "hot"))
    from thermal_kernel.solvers import run_explicit, solve_steady   # imports before baseline
    base = _rss_now()
    t0 = time.perf_counter()
    net = assemble(prob)
    if what == "explicit":
        run_explicit(net, 300.0, [net.dt_max_s * 20], keep_temperatures=False)
    else:
        r = solve_steady(net, 300.0, method="amg")
        print(f"steady: AMG-CG iterations {r.info['cg_iterations']}, heat balance "
              f"{r.info['heat_balance_relative']:.1e}")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print(f"{what}: N = {n:,}, M = {prob.pair.shape[0]:,}: problem arrays + interpreter "
          f"{base / 1e9:.2f} GB; peak {peak / 1e9:.2f} GB; solver side {(peak - base) / n:.0f} "
          f"B/particle, all {peak / n:.0f} B/particle; {time.perf_counter() - t0:.1f} s")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=float, nargs="*", default=[1e5, 1e6])
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--memory", type=float, default=None,
                    help="measure peak memory at this N (runs each case in a subprocess)")
    ap.add_argument("--memory-case", choices=("explicit", "steady"), default=None)
    ap.add_argument("--memory-file", default=None)
    args = ap.parse_args(argv)
    if args.memory_case:
        memory(args.memory_file, args.memory_case)
        return
    if args.memory:
        import tempfile
        n = int(args.memory)
        x, pair, h, c = packing_like(n)
        lo = np.flatnonzero(x[:, 0] < 0.02)
        hi = np.flatnonzero(x[:, 0] > 0.98)
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "problem.npz")
            np.savez(path, c=c, pair=pair, h=h, fixed=np.r_[lo, hi],
                     fixed_t=np.r_[np.full(lo.size, 300.0), np.full(hi.size, 400.0)],
                     fixed_b=np.r_[np.zeros(lo.size), np.ones(hi.size)])
            del x, pair, h, c
            for case in ("explicit", "steady"):
                subprocess.run([sys.executable, __file__, "--memory-file", path,
                                "--memory-case", case], check=True)
        return
    print(f"numba {numba.__version__}, threading layer after first parallel call below; "
          f"{os.cpu_count()} CPUs; load average {os.getloadavg()}")
    for n in args.n:
        bench(int(n), args.steps)
    print(f"numba threading layer: {numba.threading_layer()}; load average {os.getloadavg()}")


if __name__ == "__main__":
    from thermal_kernel.threading_layer import prefer_openmp
    prefer_openmp()             # an entry point: OpenMP first, NUMBA_THREADING_LAYER* wins
    main()
