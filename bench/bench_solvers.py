"""Speed against error of the three solvers on a YADE-made bed (not a test; docs/solvers.md
quotes its output, bench/results/solvers_speed_error.md).

    .venv/bin/python bench/bench_solvers.py [PACKING.h5] [--law pipe]

The scene is the pipe-model paper's transient (003, sec. 4.4): bottom wall 500 K, plate 400 K,
particles at 300 K, outputs at 0.2, 0.5, 1 and 2 s. Reference: Crank-Nicolson at dt = 1e-4 s
(second order; its own error is estimated by the difference to dt = 2e-4 s, printed). Error =
max over particles and output times of |T - T_ref|, in K (the temperature span is 200 K).
Steady: the error of the steady field against a backward-Euler run to t = 1e7 s.
Times are wall times of the solver alone (network assembled once, outside), best of 3.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from thermal_kernel.atomic import write_text_atomic  # noqa: E402
from thermal_kernel.network import assemble  # noqa: E402
from thermal_kernel.packing import read_packing  # noqa: E402
from thermal_kernel.problem import build_problem  # noqa: E402
from thermal_kernel.scene import load_scene  # noqa: E402
from thermal_kernel.solvers.explicit import run_explicit  # noqa: E402
from thermal_kernel.solvers.implicit import run_implicit  # noqa: E402
from thermal_kernel.solvers.steady import solve_steady  # noqa: E402
from tdem_post.speed_error import write_speed_error  # noqa: E402

# the paper's bed scene, shared with the tests
from tdem.committed_beds import BED_THERMAL  # noqa: E402

SCENE = 'packing = "{packing}"\nlaw = "{law}"\n' + BED_THERMAL + '[solver]\nmethod = "steady"\n'
TIMES = [0.2, 0.5, 1.0, 2.0]


def best_of(fn, repeat=3):
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("packing", nargs="?", default=str(ROOT / "tests/data/bed_small_4.05e+07Pa.h5"))
    ap.add_argument("--law", default="pipe")
    ap.add_argument("--out", default=str(ROOT / "bench/results/solvers_speed_error.md"))
    args = ap.parse_args()
    scene_path = Path("/tmp/bench_solvers_scene.toml")
    write_text_atomic(scene_path, SCENE.format(packing=Path(args.packing).resolve(), law=args.law))
    scene = load_scene(scene_path)
    packing = read_packing(args.packing)
    problem, _ = build_problem(scene, packing)
    net = assemble(problem)
    T0 = np.full(packing.n_particles, 300.0)
    ref = run_implicit(net, T0, TIMES, dt=1e-4, theta=0.5).temperature_k
    ref2 = run_implicit(net, T0, TIMES, dt=2e-4, theta=0.5).temperature_k
    rows = []
    run_explicit(net, T0, TIMES[:1], safety=0.9)          # numba compile outside the timing
    first = run_explicit(net, T0, TIMES, safety=0.9)
    dt_max = first.dt_max
    for safety in (0.9, 0.5, 0.2, 0.1, 0.05, 0.02):
        sec, r = best_of(lambda safety=safety: run_explicit(net, T0, TIMES, safety=safety))
        rows.append(("explicit", f"safety {safety} (dt {r.dt:.3g} s)", r.steps, sec,
                     np.abs(r.temperature_k - ref).max()))
    for theta, name in ((1.0, "backward Euler"), (0.5, "Crank-Nicolson")):
        for dt in (0.1, 0.05, 0.02, 0.01, 0.005, 0.002):
            sec, r = best_of(lambda dt=dt, theta=theta:
                             run_implicit(net, T0, TIMES, dt=dt, theta=theta))
            rows.append((name, f"dt {dt:g} s", r.steps, sec, np.abs(r.temperature_k - ref).max()))
    long = run_implicit(net, T0, [1e7], dt=1e5, theta=1.0).temperature_k[-1]
    steady_sec, st = best_of(lambda: solve_steady(net, T0))
    steady_err = np.abs(st.temperature_k[-1] - long).max()
    lines = [
        f"# Solvers: speed against error ({Path(args.packing).name}, law {args.law})",
        "",
        f"`.venv/bin/python bench/bench_solvers.py {args.packing} --law {args.law}`; "
        f"{packing.n_particles} particles, {net.n_active_contacts} conducting contacts; "
        f"exact explicit bound dt_max = {dt_max:.4g} s; load average at start "
        f"{os.getloadavg()[0]:.2f} (2 cores).",
        "",
        f"Reference: Crank-Nicolson dt = 1e-4 s (its difference to dt = 2e-4 s: "
        f"{np.abs(ref - ref2).max():.2e} K). Error: max |T - T_ref| over particles and the "
        "output times 0.2, 0.5, 1, 2 s (span 200 K).",
        "",
        "| solver | step | steps | wall (s) | max error (K) |",
        "|---|---|---|---|---|",
    ]
    for solver, step, steps, sec, err in rows:
        lines.append(f"| {solver} | {step} | {steps} | {sec:.4f} | {err:.3g} |")
    lines += ["", f"Steady solve: {steady_sec:.4f} s; max |T_steady - T(backward Euler, "
                  f"t = 1e7 s)| = {steady_err:.2e} K.", ""]
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    lines += [f"Figure: `{out.with_suffix('.png').name}`, data: `{out.with_suffix('.csv').name}`.",
              ""]
    write_text_atomic(out, "\n".join(lines))
    write_speed_error(rows, out.with_suffix(".csv"), out.with_suffix(".png"),
                      title=f"{Path(args.packing).name}, law {args.law}: speed against error "
                            "(labels: steps)")
    print("\n".join(lines))


if __name__ == "__main__":
    from thermal_kernel.threading_layer import prefer_openmp
    prefer_openmp()             # an entry point: OpenMP first, NUMBA_THREADING_LAYER* wins
    main()
