"""How much the fitted gamma depends on the output times (issue 15, docs/campaign.md).

003 fits gamma to profiles at t = 0.2-7 s (Fig. 6 and 8); on its own bed, with Table 1's
material, L^2/alpha is 10^3-10^4 s, so those profiles only see the layers next to the walls.
``window_fit(case_dir)`` runs a campaign case again (the scene stored in its thermal.h5, its
packing and law) with outputs at
the paper's times and post-processes it exactly as the campaign does (tdem_post.post_run): the
fitted gamma on the paper's window beside the case's own (outputs 30-30,000 s).

    tdem window CASE_DIR [CASE_DIR ...] [--times 0.2,0.5,...] [--dt 0.02]

(``python -m tdem_post.window`` the same) writes ``CASE_DIR/window/thermal.h5``,
``CASE_DIR/window/post/`` and ``CASE_DIR/window.json`` (kept: a case whose window.json exists
is not run again) and prints one line per case.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

PAPER_TIMES = (0.2, 0.5, 1.0, 2.0, 3.5, 5.0, 7.0)       # 003 Fig. 6b (Fig. 8: 0.2-2 s)


def window_fit(case_dir, times=PAPER_TIMES, dt: float | None = None, threads: int = 1) -> dict:
    """The case of ``case_dir`` (its thermal.h5: the scene as it ran and its packing, checked
    against the stored content hash; and post/summary.json) run with outputs at ``times`` (s;
    end time the last one; implicit, the case's scheme, ``dt`` = times[0]/10 by default) and
    fitted like the case. Returns the two fits side by side."""
    from thermal_kernel.output import read_run_packing, read_thermal
    from thermal_kernel.run import run_scene
    from thermal_kernel.atomic import write_text_atomic
    from .post_run import analyse, write_post

    case_dir = Path(case_dir)
    done = case_dir / "window.json"
    if done.exists():
        return json.loads(done.read_text())
    case = json.loads((case_dir / "post" / "summary.json").read_text())
    times = tuple(sorted(float(t) for t in times))
    run = read_thermal(case_dir / "thermal.h5", data=False)
    read_run_packing(run)               # refused in one line if it changed since the case ran
    solver = dataclasses.replace(run.scene.solver, method="implicit", end_time=times[-1],
                                 output_times=times,
                                 dt=float(dt) if dt else times[0] / 10)
    scene = dataclasses.replace(run.scene, solver=solver,
                                output=case_dir / "window" / "thermal.h5")
    t0 = time.time()
    result = run_scene(scene, run.packing_path, quiet=True, threads=threads,
                       run_args=dict(command="tdem_post.window", case=str(case_dir)))
    post = analyse(result.output, n_bins=case["n_bins"])
    window = write_post(post, plots=True)
    flags = post.run.flags
    out = {
        "case": str(case_dir), "law": case["law"], "pressure_pa": case["pressure_pa"],
        "solid_fraction": case["solid_fraction"], "times_s": list(times), "dt_s": solver.dt,
        "gamma_window": window["gamma"], "gamma_window_ci95": window["gamma_ci95"],
        "gamma_paper_window": window["gamma_paper"],
        "gamma_window_residual_rms_k": window["gamma_residual_rms_k"],
        "gamma_window_per_time": window["gamma_per_time"],
        "gamma_case": case["gamma"], "gamma_case_ci95": case["gamma_ci95"],
        "gamma_paper_case": case.get("gamma_paper"),
        "gamma_case_per_time": case.get("gamma_per_time"),
        "gamma_steady": case["gamma_steady"], "tau_s": case["tau_s"],
        "flags": flags, "post_flags": window["post_flags"],
        "not_measurable": window["not_measurable"], "wall_seconds": time.time() - t0,
    }
    write_text_atomic(done, json.dumps(out, indent=1))
    return out


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``tdem window`` (one home: the subcommand and ``main`` both take them)."""
    parser.add_argument("cases", nargs="+", help="campaign case folders (cases/<p>Pa_<law>/)")
    parser.add_argument("--times", default=",".join(f"{t:g}" for t in PAPER_TIMES),
                        help="output times, s (default: 003's, 0.2-7 s)")
    parser.add_argument("--dt", type=float, default=None, help="time step, s (default t1/10)")
    parser.add_argument("--threads", type=int, default=1)


def command(args) -> int:
    """``tdem window``: each case fitted on the window (or read from its window.json), one line
    per case."""
    times = [float(x) for x in args.times.split(",") if x.strip()]
    print("p (bar)  law    gamma(case window)  gamma(window)  gamma_paper(window)  "
          "gamma_steady")
    def num(value, width):      # a gamma the window cannot give (not measurable): said so
        return f"{value:{width}.4g}" if value is not None else f"{'n/m':>{width}}"

    for case in args.cases:
        r = window_fit(case, times, args.dt, args.threads)
        print(f"{r['pressure_pa'] / 1e5:7.3g}  {r['law']:<6} {num(r['gamma_case'], 18)}  "
              f"{num(r['gamma_window'], 13)}  {num(r['gamma_paper_window'], 19)}  "
              f"{r['gamma_steady']:12.4g}"
              + "".join(f"\n    {k} not measurable: {v}"
                        for k, v in (r.get("not_measurable") or {}).items()), flush=True)
    return 0


def main(argv=None) -> int:
    """``python -m tdem_post.window``: the same as ``tdem window``."""
    parser = argparse.ArgumentParser(prog="python -m tdem_post.window", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    add_arguments(parser)
    return command(parser.parse_args(argv))


if __name__ == "__main__":
    from thermal_kernel.threading_layer import prefer_openmp
    prefer_openmp()             # an entry point: OpenMP first, NUMBA_THREADING_LAYER* wins
    raise SystemExit(main())
