"""Speed-against-error figure of the solvers (the benchmark's output, bench/bench_solvers.py):
wall time of each run against its maximum temperature error, one line per solver, so that the
cheapest solver for a given accuracy can be read off."""
from __future__ import annotations

import csv
from pathlib import Path

from thermal_kernel.atomic import open_atomic, savefig_atomic


def write_speed_error(rows, csv_path, png_path, title=""):
    """rows: (solver, step label, steps, wall seconds, max error K). Writes the CSV and the
    log-log figure (error on x, wall time on y)."""
    csv_path, png_path = Path(csv_path), Path(png_path)
    with open_atomic(csv_path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["solver", "step", "steps", "wall_seconds", "max_error_k"])
        w.writerows(rows)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for k, solver in enumerate(dict.fromkeys(r[0] for r in rows)):
        mine = sorted((r for r in rows if r[0] == solver), key=lambda r: r[4])
        ax.plot([r[4] for r in mine], [r[3] for r in mine], "o-", color=f"C{k}", label=solver)
        for r in mine:
            ax.annotate(str(r[2]), (r[4], r[3]), fontsize=6, xytext=(3, 3),
                        textcoords="offset points")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("max |T - T_ref| (K)")
    ax.set_ylabel("wall time of the solver (s)")
    ax.set_title(title or "speed against error (labels: steps)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    savefig_atomic(fig, png_path, dpi=110)
    plt.close(fig)
