"""``tdem campaign CAMPAIGN.toml``: from pressures to conclusions (issue 4).

A campaign file is a bed scene with a ``[pack]`` table (the pressure series) and a
``[campaign]`` table::

    [campaign]
    laws = ["pipe", "bob"]       # each packing is run with each law
    n_bins = 8                   # profile bins between the two held walls

Steps, each kept so that an interrupted campaign resumes where it stopped:
1. packings: YADE builds the settled bed and every pressure in one process
   (``<out>/packings/``); reused when ``params.json`` there equals the campaign's parameters and
   every ``packing_<p>Pa.h5`` exists;
2. cases (pressure x law): the thermal scene runs on the packing (``<out>/cases/<p>Pa_<law>/
   thermal.h5``) and is post-processed (``post/summary.json``); a case whose summary exists is
   not recomputed;
3. ``results.csv`` (one row per case), ``gamma_p.png``/``tau_p.png`` (+ CSV) and ``report.md``
   with the power-law fits next to the paper's curves (003, Fig. 7 and 10) and the mean-field
   predictions; each case's ``flags`` (the attribute of its ``thermal.h5``: maximum principle,
   energy ledger, solver flags) is a column of both, and flagged runs are listed. Every file is written to a temporary name and renamed.
"""
from __future__ import annotations

import json
import re
import time
import tomllib
from pathlib import Path

import numpy as np

from .errors import UserError
from thermal_kernel.atomic import replacing
from tdem_post.files import savefig_atomic, write_text_atomic

PAPER_TAU = dict(a=1.945, b=0.1084, c=-1.332)       # 003 Fig. 10: tau = a p^b + c (p in bar)
# flags of a run's thermal.h5 that make its numbers suspect (the others, e.g. rattlers or
# floating_clusters, describe the network); "unknown": a run written before flags existed
SUSPECT_FLAGS = ("max_principle", "energy_ledger", "dt_above_bound", "non_finite",
                 "no_steady_state_in_floating_cluster", "unknown")


def read_campaign(path: Path) -> tuple[dict, str]:
    path = Path(path)
    try:
        text = path.read_text()
        data = tomllib.loads(text)
    except FileNotFoundError:
        raise UserError(f"{path}: file not found") from None
    except tomllib.TOMLDecodeError as e:
        raise UserError(f"{path}: not valid TOML ({e})") from None
    camp = data.get("campaign")
    if not isinstance(camp, dict):
        raise UserError(f"{path}: campaign: missing [campaign] table (laws = [...])")
    unknown = set(camp) - {"laws", "n_bins"}
    if unknown:
        raise UserError(f"{path}: campaign.{sorted(unknown)[0]}: unknown key (known: laws, n_bins)")
    laws = camp.get("laws")
    from thermal_kernel.laws import LAWS
    if not (isinstance(laws, list) and laws and all(isinstance(x, str) for x in laws)):
        raise UserError(f"{path}: campaign.laws: expected a list of law names")
    for law in laws:
        if law not in LAWS:
            raise UserError(f"{path}: campaign.laws: unknown law {law!r} (known: "
                            f"{', '.join(LAWS)})")
    n_bins = camp.get("n_bins", 8)
    if not (isinstance(n_bins, int) and n_bins >= 3):
        raise UserError(f"{path}: campaign.n_bins: expected an integer >= 3")
    if "packing" in data:
        raise UserError(f"{path}: packing: a campaign builds its packings from [pack]")
    return dict(laws=laws, n_bins=n_bins), text


def _scene_text(campaign_text: str, packing: Path, law: str) -> str:
    """The campaign file without its [pack] and [campaign] tables and top-level law, for one
    packing and one law."""
    out, skip = [], False
    for line in campaign_text.splitlines():
        header = re.match(r"^\s*\[\[?\s*([A-Za-z0-9_.]+)\s*\]\]?", line)
        if header:
            skip = header.group(1) in ("pack", "campaign")
        elif not skip and re.match(r"^\s*law\s*=", line):
            continue
        if not skip:
            out.append(line)
    return f'packing = "{packing}"\nlaw = "{law}"\n' + "\n".join(out) + "\n"


def check_case_scenes(campaign_path: Path, conf: dict, text: str, out_dir: Path) -> None:
    """Load the case scene of every law as the campaign will write it (the packing not built
    yet), so that a typo in [solver], [material], [[boundary]] or [law_params] is one line
    naming the campaign file and key before any packing is built (issue 16 sec. 3). What needs
    the packing itself (walls named by a boundary, the explicit bound) is checked when a case
    runs."""
    from thermal_kernel.laws import LAWS
    from thermal_kernel.scene import SceneError, load_scene
    placeholder = out_dir / "packings" / "packing.h5"
    for law in conf["laws"]:
        try:
            load_scene(campaign_path, known_laws=LAWS, out_dir=out_dir / "cases" / law,
                       text=_scene_text(text, placeholder.resolve(), law))
        except SceneError as e:
            raise UserError(f"{e} (in the case scene for law {law!r}; checked before any "
                            "packing is built)") from None


def build_packings(campaign_path: Path, out_dir: Path, *, threads: int, quiet: bool) -> list:
    from .pack import build, built_packings, read_pack_table
    generator, params = read_pack_table(campaign_path)
    if generator != "bed":
        raise UserError(f"{campaign_path}: pack.generator: a pressure campaign needs the bed "
                        "generator")
    pdir = out_dir / "packings"
    expected = [pdir / f"packing_{p:.4g}Pa.h5" for p in params["pressures_pa"]]
    if built_packings(campaign_path, pdir) and all(p.exists() for p in expected):
        print(f"tdem campaign: reusing the {len(expected)} packings in {pdir}/", flush=True)
        return expected
    build(campaign_path, pdir, threads=threads, quiet=quiet)
    missing = [p for p in expected if not p.exists()]
    if missing:
        raise UserError(f"{campaign_path}: pack: YADE did not write {missing[0].name}")
    return expected


def run_campaign(campaign_path, out_dir=None, *, threads: int = 2, yade_threads: int = 1,
                 quiet: bool = False, repost: bool = False) -> dict:
    """Packings (YADE, ``yade_threads``; 1 keeps them bit-reproducible for a seed: YADE's
    parallel force summation order varies between runs), then thermal cases (numba, ``threads``).
    Finished cases are kept; with ``repost`` their thermal runs are kept and post-processed anew
    (after a change of the post-processing)."""
    from thermal_kernel.laws import LAWS
    from thermal_kernel.run import run_scene
    from thermal_kernel.scene import load_scene
    from tdem_post.post_run import post_run
    from .pack import default_out_dir

    campaign_path = Path(campaign_path)
    conf, text = read_campaign(campaign_path)
    out_dir = Path(out_dir) if out_dir else default_out_dir(campaign_path)
    check_case_scenes(campaign_path, conf, text, out_dir)     # before YADE builds anything
    out_dir.mkdir(parents=True, exist_ok=True)
    start = time.time()
    packings = build_packings(campaign_path, out_dir, threads=yade_threads, quiet=quiet)
    cases = [(p, law) for p in packings for law in conf["laws"]]
    rows = []
    for k, (packing, law) in enumerate(cases, 1):
        name = f"{packing.stem.removeprefix('packing_')}_{law}"
        case_dir = out_dir / "cases" / name
        summary_path = case_dir / "post" / "summary.json"
        thermal_path = case_dir / "thermal.h5"
        if summary_path.exists() and repost and thermal_path.exists():
            old = json.loads(summary_path.read_text())
            t0 = time.time()
            summary = post_run(thermal_path, n_bins=conf["n_bins"])
            for key in ("case_wall_seconds", "thermal_wall_seconds"):
                summary[key] = old.get(key, float("nan"))
            summary["flags"] = run_flags(thermal_path)
            write_text_atomic(summary_path, json.dumps(summary, indent=1))
            print(f"[{k}/{len(cases)}] {name}: thermal run kept, post-processed again: gamma "
                  f"{old['gamma']:.4g} -> {summary['gamma']:.4g} ({time.time() - t0:.1f} s)",
                  flush=True)
        elif summary_path.exists():
            summary = json.loads(summary_path.read_text())
            summary["flags"] = run_flags(thermal_path, summary.get("flags"))
            print(f"[{k}/{len(cases)}] {name}: done before (gamma {summary['gamma']:.4g}), kept"
                  + (f"; flags: {summary['flags']}" if summary["flags"] else ""), flush=True)
        else:
            case_dir.mkdir(parents=True, exist_ok=True)
            scene_path = case_dir / "scene.toml"
            write_text_atomic(scene_path, _scene_text(text, packing.resolve(), law))
            scene = load_scene(scene_path, known_laws=LAWS, out_dir=case_dir)
            t0 = time.time()
            result = run_scene(scene, packing, quiet=True, threads=threads)
            run_seconds = time.time() - t0
            summary = post_run(result.output, n_bins=conf["n_bins"])
            summary["case_wall_seconds"] = time.time() - t0
            summary["thermal_wall_seconds"] = run_seconds
            summary["flags"] = run_flags(result.output)
            write_text_atomic(summary_path, json.dumps(summary, indent=1))
            print(f"[{k}/{len(cases)}] {name}: gamma {summary['gamma']:.4g} "
                  f"[{summary['gamma_ci95'][0]:.4g}, {summary['gamma_ci95'][1]:.4g}], steady "
                  f"{summary['gamma_steady']:.4g}, tau {summary['tau_s']:.4g} s "
                  f"({summary['case_wall_seconds']:.1f} s)"
                  + (f"; flags: {summary['flags']}" if summary["flags"] else ""), flush=True)
        rows.append(summary)
    report = write_report(out_dir, campaign_path, conf, rows, time.time() - start)
    return report


def run_flags(thermal_path: Path, fallback: str | None = None) -> str:
    """The ``flags`` attribute of a run's ``thermal.h5`` (comma-separated: the solver's flags and
    the physics checks', ``max_principle`` / ``energy_ledger``; "" when the run is clean).
    ``fallback`` (or "unknown") when the file or the attribute is missing."""
    import h5py
    try:
        with h5py.File(thermal_path, "r") as f:
            value = f.attrs.get("flags")
    except (OSError, KeyError):
        value = None
    if value is None:
        return "unknown" if fallback is None else fallback
    return value.decode() if isinstance(value, bytes) else str(value)


def _fit(p_bar, y):
    from tdem_post.fits import fit_power_law
    if len(p_bar) < 4:
        return None
    try:
        return fit_power_law(p_bar, y)
    except (RuntimeError, ValueError):
        return None


def write_report(out_dir: Path, campaign_path: Path, conf: dict, rows: list, seconds: float):
    import pandas as pd
    from tdem_post.fits import PAPER_GAMMA, power_law

    table = pd.DataFrame([{
        "pressure_pa": r["pressure_pa"], "law": r["law"], "n_particles": r["n_particles"],
        "mean_coordination": r["mean_coordination"], "solid_fraction": r["solid_fraction"],
        "mean_normal_force_n": r["mean_normal_force_n"], "gamma": r["gamma"],
        "gamma_ci95_low": r["gamma_ci95"][0], "gamma_ci95_high": r["gamma_ci95"][1],
        "gamma_residual_rms_k": r["gamma_residual_rms_k"], "gamma_steady": r["gamma_steady"],
        "tau_s": r["tau_s"], "tau_series_s": r["tau_series_s"],
        **{f"gamma_mean_field_{k}": v for k, v in r["gamma_mean_field"].items()},
        "thermal_wall_seconds": r.get("thermal_wall_seconds", float("nan")),
        "case_wall_seconds": r.get("case_wall_seconds", float("nan")),
        # the run's thermal.h5 flags ("none": clean; see docs/solvers.md)
        "flags": r.get("flags", "unknown") or "none",
    } for r in rows]).sort_values(["law", "pressure_pa"])
    with replacing(out_dir / "results.csv") as tmp:
        table.to_csv(tmp, index=False)

    fits = {}
    for law, g in table.groupby("law"):
        p_bar = g["pressure_pa"].to_numpy() / 1e5
        fits[law] = dict(gamma=_fit(p_bar, g["gamma"].to_numpy()),
                         tau=_fit(p_bar, g["tau_s"].to_numpy()))
    _plots(out_dir, table, fits)

    lines = [f"# Pressure campaign: {campaign_path.name}", "",
             f"{table['n_particles'].iloc[0]} particles, pressures "
             f"{', '.join(f'{p / 1e5:.3g}' for p in sorted(table['pressure_pa'].unique()))} bar, "
             f"laws {', '.join(conf['laws'])}; {seconds:.0f} s in all. Files: `results.csv`, "
             "`gamma_p.png`, `tau_p.png`, `cases/<p>Pa_<law>/post/profiles.png`.", "",
             "γ = k_eff / k_p fitted to the binned profiles against the slab solution (95 % "
             "interval), γ_steady from the steady heat flow, γ_mf the mean-field estimate "
             "φ Z H̄ / (2π R̄ k_p) of each contact law on the same contacts; τ the characteristic "
             "time of the middle section (003 eq. 41).", "",
             "| p (bar) | law | Z | φ | mean F_n (N) | γ | 95 % CI | γ_steady | γ_mf bob | "
             "γ_mf argento | γ_mf pipe | τ (s) | flags |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for _, r in table.iterrows():
        lines.append(
            f"| {r.pressure_pa / 1e5:.3g} | {r.law} | {r.mean_coordination:.2f} | "
            f"{r.solid_fraction:.4f} | {r.mean_normal_force_n:.3g} | {r.gamma:.4g} | "
            f"{r.gamma_ci95_low:.4g}–{r.gamma_ci95_high:.4g} | {r.gamma_steady:.4g} | "
            f"{r.gamma_mean_field_bob:.4g} | {r.gamma_mean_field_argento:.4g} | "
            f"{r.gamma_mean_field_pipe:.4g} | {r.tau_s:.4g} | {r['flags']} |")
    suspect = [(r, [f for f in r["flags"].split(",") if f in SUSPECT_FLAGS])
               for _, r in table.iterrows()]
    suspect = [(r, f) for r, f in suspect if f]
    if suspect:
        lines += ["", f"**{len(suspect)} of {len(table)} runs flagged: their numbers are "
                      "suspect** (`flags` of their `thermal.h5`; `max_principle`: a "
                      "temperature outside the range of the initial and boundary values, "
                      "`energy_ledger`: heat in ≠ heat stored; docs/solvers.md): "
                  + "; ".join(f"{r['pressure_pa'] / 1e5:.3g} bar {r['law']}: {', '.join(f)}"
                              for r, f in suspect) + "."]
    else:
        lines += ["", "No run flagged by the maximum-principle and energy-ledger checks or the "
                      "solver (other flags, e.g. `rattlers`, are information; docs/solvers.md)."]
    lines += ["", "## Fits over pressure (p in bar)", ""]
    for law, f in fits.items():
        g = table[table.law == law]
        p_bar = g["pressure_pa"].to_numpy() / 1e5
        for what, fit in (("γ", f["gamma"]), ("τ", f["tau"])):
            if fit is None:
                lines.append(f"- {law}: {what}(p) not fitted (fewer than 4 pressures)")
            else:
                lines.append(f"- {law}: {what}(p) = {fit.a:.4g} (±{fit.stderr[0]:.2g}) "
                             f"p^{fit.b:.4g} (±{fit.stderr[1]:.2g}) {'−' if fit.c < 0 else '+'} {abs(fit.c):.4g} "
                             f"(±{fit.stderr[2]:.2g}), rms {fit.rms:.3g}")
        paper = power_law(p_bar, **PAPER_GAMMA)
        ratio = g["gamma"].to_numpy() / paper
        mf = g["gamma_mean_field_bob"].to_numpy() / g["gamma"].to_numpy()
        mfa = g["gamma_mean_field_argento"].to_numpy() / g["gamma"].to_numpy()
        steady = g["gamma_steady"].to_numpy() / g["gamma"].to_numpy()
        lines.append(f"- {law}: γ / paper's γ(p) (003 Fig. 7) = "
                     f"{', '.join(f'{x:.3g}' for x in ratio)} (from low to high pressure); "
                     f"γ_mf(bob) / γ = {', '.join(f'{x:.3g}' for x in mf)}; "
                     f"γ_mf(argento) / γ = {', '.join(f'{x:.3g}' for x in mfa)}; "
                     f"γ_steady / γ = {', '.join(f'{x:.3g}' for x in steady)}")
        trend = np.polyfit(np.log(p_bar), np.log(g["gamma"].to_numpy()), 1)[0] \
            if len(p_bar) > 1 else float("nan")
        lines.append(f"- {law}: log-log slope of γ(p) {trend:.3g} (the paper's curve falls, "
                     f"slope −0.29 at low p; contact mechanics, ζ ∝ F_n^(1/3) ∝ p^(1/3), "
                     "predicts a rising γ)")
    lines += ["", f"Paper (003): γ = {PAPER_GAMMA['a']} p^{PAPER_GAMMA['b']} + "
                  f"{PAPER_GAMMA['c']} (Fig. 7); τ = {PAPER_TAU['a']} p^{PAPER_TAU['b']} "
                  f"{PAPER_TAU['c']:+} s (Fig. 10).", ""]
    write_text_atomic(out_dir / "report.md", "\n".join(lines))
    print(f"tdem campaign: report {out_dir / 'report.md'}", flush=True)
    print(table[["pressure_pa", "law", "gamma", "gamma_steady", "tau_s", "flags"]].to_string(
        index=False, float_format=lambda x: f"{x:.4g}"), flush=True)
    return dict(table=table, fits=fits, report=out_dir / "report.md")


def _plots(out_dir, table, fits):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from tdem_post.fits import PAPER_GAMMA, power_law
    pmin = table.pressure_pa.min() / 1e5
    pmax = table.pressure_pa.max() / 1e5
    grid = np.geomspace(pmin, pmax, 100)
    for key, label, paper, fname in (
            ("gamma", "γ = k_eff / k_p", PAPER_GAMMA, "gamma_p"),
            ("tau_s", "τ (s), middle section", PAPER_TAU, "tau_p")):
        fig, ax = plt.subplots(figsize=(6, 4.2))
        for k, (law, g) in enumerate(table.groupby("law")):
            p = g.pressure_pa / 1e5
            if key == "gamma":
                ax.errorbar(p, g.gamma, yerr=[g.gamma - g.gamma_ci95_low,
                                              g.gamma_ci95_high - g.gamma], fmt="o",
                            color=f"C{k}", label=f"tdem {law}")
                ax.plot(p, g.gamma_steady, "x", color=f"C{k}", label=f"steady ETC {law}")
            else:
                ax.plot(p, g[key], "o", color=f"C{k}", label=f"tdem {law}")
            fit = fits[law]["gamma" if key == "gamma" else "tau"]
            if fit is not None:
                ax.plot(grid, fit(grid), "-", color=f"C{k}", lw=1)
        if key == "gamma":
            g0 = table[table.law == table.law.iloc[0]]
            ax.plot(g0.pressure_pa / 1e5, g0.gamma_mean_field_bob, "s", mfc="none", color="k",
                    label="mean field, bob")
            ax.plot(g0.pressure_pa / 1e5, g0.gamma_mean_field_argento, "^", mfc="none",
                    color="k", label="mean field, argento")
        ax.plot(grid, power_law(grid, **paper), "k--", label="paper (003)")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("plate pressure (bar)")
        ax.set_ylabel(label)
        ax.legend(fontsize=7)
        fig.tight_layout()
        savefig_atomic(fig, out_dir / f"{fname}.png", dpi=110)
        plt.close(fig)
