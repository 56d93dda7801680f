"""The figure of docs/campaign.md, *Why the paper's γ falls* (issue 15): γ_paper(p) and τ(p) of
003's fits beside a campaign (mean ± sd over its seeds), the same runs fitted on 003's output
times (tdem_post.window) and the diagnostic law's campaign, all in 003's convention
(γ_paper = γ/φ).

    tdem paper-compare CAMPAIGN_OUT [--diag DIAG_OUT] [--law pipe] -o FIG.png

(``python -m tdem_post.paper_compare`` the same). CAMPAIGN_OUT and DIAG_OUT are campaign
folders (``results.csv``; the window fits are read from
``[seed_<s>/]cases/<p>Pa_<law>/window.json`` where they exist).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

PAPER_TAU = dict(a=1.945, b=0.1084, c=-1.332)       # 003 Fig. 10 (p in bar)


def _load(out_dir, law):
    import pandas as pd
    table = pd.read_csv(Path(out_dir) / "results.csv", keep_default_na=False)
    return table[table.law == law]


def _key(table):
    """Seeds of one pressure share its nominal value (results.csv's pressure_target_pa)."""
    return "pressure_target_pa" if "pressure_target_pa" in table.columns else "pressure_pa"


def _windows(out_dir, law):
    rows = []
    for path in sorted(Path(out_dir).glob(f"**/cases/*_{law}/window.json")):
        rows.append(json.loads(path.read_text()))
    return rows


def plot(campaign_out, out_png, *, law="pipe", diag_out=None,
         diag_law="pipe_resistance_as_conductance"):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from thermal_kernel.atomic import savefig_atomic

    from .fits import PAPER_GAMMA, power_law     # scipy.stats: not at `tdem`'s start-up
    table = _load(campaign_out, law)
    g = table.groupby(_key(table))
    p = g["pressure_pa"].mean().to_numpy() / 1e5
    n_seeds = int(g.size().max())
    grid = np.geomspace(p.min(), p.max(), 100)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    for ax, key, paper, ylabel in ((axes[0], "gamma_paper", PAPER_GAMMA,
                                    "γ_paper = α ρ_p c_p / κ_p (003's convention)"),
                                   (axes[1], "tau_s", PAPER_TAU, "τ, middle section (s)")):
        ax.plot(grid, power_law(grid, **paper), "k--", label="003's fit (Fig. 7 / 10)")
        mean, sd = g[key].mean().to_numpy(), g[key].std(ddof=1).to_numpy()
        ax.errorbar(p, mean, yerr=sd if n_seeds > 1 else None, fmt="o", capsize=3, color="C0",
                    label=f"tdem {law}, outputs 30–30,000 s"
                          + (f" (mean ± sd, {n_seeds} seeds)" if n_seeds > 1 else ""))
        if key == "gamma_paper":
            win = _windows(campaign_out, law)
            if win:
                wp = np.array([w["pressure_pa"] for w in win]) / 1e5
                ax.plot(wp, [w["gamma_paper_window"] for w in win], "s", mfc="none",
                        color="C0", label=f"tdem {law}, fitted on 003's times 0.2–7 s")
        if diag_out is not None:
            d = _load(diag_out, diag_law)
            dg = d.groupby(_key(d))[key]
            nd = int(d.groupby(_key(d)).size().max())
            ax.errorbar(d.groupby(_key(d))["pressure_pa"].mean().to_numpy() / 1e5,
                        dg.mean().to_numpy(),
                        yerr=dg.std(ddof=1).to_numpy() if nd > 1 else None, fmt="^",
                        capsize=3, color="C3",
                        label="diagnostic: pipe resistance used as conductance, 0.2–7 s"
                              + (f" (mean ± sd, {nd} seeds)" if nd > 1 else ""))
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("plate pressure (bar)")
        ax.set_ylabel(ylabel)
        ax.legend(fontsize=6)
    fig.tight_layout()
    savefig_atomic(fig, Path(out_png), dpi=110)
    plt.close(fig)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``tdem paper-compare`` (one home: the subcommand and ``main``)."""
    parser.add_argument("campaign", help="the campaign's output folder (its results.csv)")
    parser.add_argument("--diag", default=None,
                        help="the diagnostic law's campaign folder (optional)")
    parser.add_argument("--law", default="pipe", help="the campaign's law shown (default pipe)")
    parser.add_argument("-o", "--out", required=True, help="the figure to write (.png)")


def command(args) -> int:
    """``tdem paper-compare``: the figure, and its path printed."""
    plot(args.campaign, args.out, law=args.law, diag_out=args.diag)
    print(f"wrote {args.out}")
    return 0


def main(argv=None) -> int:
    """``python -m tdem_post.paper_compare``: the same as ``tdem paper-compare``."""
    parser = argparse.ArgumentParser(prog="python -m tdem_post.paper_compare",
                                     description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    add_arguments(parser)
    return command(parser.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
