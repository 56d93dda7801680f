"""OpenBLAS threads and the sparse solves (docs/solvers.md, "Sparse solves run with one OpenBLAS
thread"): pyamg's smoothed-aggregation setup and an AMG-CG solve on 19,683 unknowns (a 27^3
lattice Laplacian plus a small shift), each mode in its own process:

    none           OpenBLAS's default thread count
    blas_threads   thermal_kernel.solvers.blas_threads(1) (threadpoolctl), what the solvers use
    ctypes         the ctypes scan of /proc/self/maps that blas_threads replaced (2026-12-01),
                   kept here only to compare

    .venv/bin/python bench/bench_blas_threads.py [--repeat 2]
"""
import argparse
import subprocess
import sys
import time

MODES = ("none", "blas_threads", "ctypes")


def _ctypes_limit(n):
    import ctypes
    with open("/proc/self/maps") as f:
        paths = {line.split()[-1] for line in f if "openblas" in line.lower() and ".so" in line}
    for path in sorted(p for p in paths if p.startswith("/")):
        lib = ctypes.CDLL(path)
        for prefix in ("scipy_openblas", "openblas"):
            for suffix in ("64_", "_64_", ""):
                s = getattr(lib, f"{prefix}_set_num_threads{suffix}", None)
                if s is not None:
                    s.argtypes = [ctypes.c_int]
                    s(n)
                    break
            else:
                continue
            break


def one(mode):
    import numpy as np
    import pyamg
    import scipy.sparse as sp
    from threadpoolctl import threadpool_info

    from thermal_kernel.solvers import blas_threads
    n1 = 27
    e = np.ones(n1)
    d1 = sp.diags([-e[:-1], 2 * e, -e[:-1]], [-1, 0, 1])
    eye = sp.identity(n1)
    a = (sp.kron(sp.kron(d1, eye), eye) + sp.kron(sp.kron(eye, d1), eye)
         + sp.kron(sp.kron(eye, eye), d1) + 1e-3 * sp.identity(n1 ** 3)).tocsr()
    b = np.random.default_rng(0).standard_normal(a.shape[0])
    ctl = blas_threads(1 if mode == "blas_threads" else None)
    ctl.__enter__()
    if mode == "ctypes":
        _ctypes_limit(1)
    threads = [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]
    t0 = time.perf_counter()
    ml = pyamg.smoothed_aggregation_solver(a, symmetry="symmetric", max_coarse=500)
    t1 = time.perf_counter()
    ml.solve(b, tol=1e-10, accel="cg", maxiter=1000)
    t2 = time.perf_counter()
    ctl.__exit__(None, None, None)
    print(f"{mode:13s} unknowns {a.shape[0]}  BLAS threads {threads}  AMG setup {t1 - t0:.3f} s"
          f"  AMG-CG solve {t2 - t1:.3f} s", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--mode", choices=MODES, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.mode:
        one(args.mode)
        return
    import os
    print(f"load average {os.getloadavg()}")
    for _ in range(args.repeat):
        for mode in MODES:
            subprocess.run([sys.executable, __file__, "--mode", mode], check=True)


if __name__ == "__main__":
    main()
