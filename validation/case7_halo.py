"""Case 7 of docs/validation.md: the scatter of the particle heat flux and its Halo smoothing
(002 sec. 3, eq. 20-23, Fig. 10-11) on tdem packings.

The cube of case 4 at steady state (two faces normal to x held at 25 C and 35 C, adiabatic
sides; 002 sec. 3 uses "the same thermal conditions as 2.2", lambda 33 W/m/K), law haddad. The
flux of each particle: eq. 20 (raw) and the Halo average of eq. 22-23 over the particles whose
centre lies within ratio x R_p of p's (tdem_post.flux). The CoV (std / mean) of |q| over the
particles whose whole halo lies inside the cube (and, raw, over the free particles at least one
radius inside), against the halo/DE radius ratio, at several N: the paper's Fig. 10 (CoV 27 %
raw, 5 % at ratio ~4, 2 % at ~11, "not influenced by the density of particles": 1e5 and 5e5).
The paper's curve is not digitised: its three values quoted in the text are plotted.

The CoV does not depend on C_t (it scales every flux alike); fluxes are normalised by the
macroscopic flux Q / A through the held faces (the paper's 3,300 W/m^2 = lambda dT / L when C_t
is calibrated), so Fig. 11's "mean close to the analytical value" is mean |q| / (Q/A) ~ 1.

  .venv/bin/python -m validation.run 7
  .venv/bin/python validation/case7_halo.py [--quick]
"""
from __future__ import annotations

import csv
import json
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from thermal_kernel.atomic import open_atomic, savefig_atomic, write_text_atomic
from tdem_post.flux import contact_moments, halo_flux
from thermal_kernel.calibrate import cross_section
from thermal_kernel.network import assemble
from thermal_kernel.packing import read_packing
from thermal_kernel.problem import build_problem
from thermal_kernel.scene import load_scene
from thermal_kernel.solvers.steady import solve_steady
from validation.case4_slab import scene_text as slab_scene_text
from validation.framework import ROOT, CaseInfo, CaseResult, Context, pack_seconds, \
    register_packing

CASE = CaseInfo(number=7, title="Halo CoV vs halo/DE radius ratio",
                paper="002 sec. 3, eq. 20-23, Fig. 10-11", paper_n="1e5, 5e5",
                paper_error="CoV 27 % raw, 5 % at ratio ~4, 2 % at ~11, independent of N",
                target="CoV ≤ 5 % at ratio 4 and ≤ 2 % at 11, at 1e5 and 5e5")

LAMBDA, RHO, CAP = 33.0, 7800.0, 0.9                # 002 Tab. 1
T1, T2 = 298.15, 308.15
RATIOS = (0.0, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 11.0, 14.0)
PAPER = ((1.0, 27.0), (4.0, 5.0), (11.0, 2.0))      # (ratio, CoV %) from the text, "raw" at 1
MAX_EVAL = 20_000           # particles evaluated per ratio (a seeded random subset above it)
MIN_EVAL = 200              # fewer particles with the halo inside: no point
VERSION = 2

CELL400 = ROOT / "tests" / "data" / "dense_periodic.h5"
SIZES = {10_000: "box_tiled_10000", 100_000: "box_1e5", 500_000: "box_5e5",
         1_000_000: "box_1e6"}
QUICK = {2_000: "box_2000_cell400"}
for _n, _b in SIZES.items():
    register_packing(_b, "runs/dense_box_1e5.toml", dict(n_particles=_n))
for _n, _b in QUICK.items():
    register_packing(_b, "runs/dense_box_1e5.toml", dict(
        n_particles=_n, method="tiled", cell_particles=400, cell_packing=str(CELL400)))

SCENE_PATH = ROOT / "validation" / "case7_scene.toml"        # named in messages only


def scene_text(packing: str, ct: float = 0.806) -> str:
    """Case 4's slab scene (the cube between two held x faces, 002 Tab. 1 material)."""
    return slab_scene_text(packing, ct)


def halo_cov(packing_path, ratios=RATIOS, max_eval=MAX_EVAL, seed=1):
    """Steady slab, then per halo ratio: CoV of |q| and of q_x over the particles whose halo
    lies inside the cube, their mean / min / max |q| over Q/A, and the seconds it took."""
    packing_path = str(Path(packing_path).resolve())
    packing = read_packing(packing_path)
    scene = load_scene(SCENE_PATH, text=scene_text(packing_path))
    s0 = time.perf_counter()
    problem, _ = build_problem(scene, packing)
    net = assemble(problem)
    res = solve_steady(net, np.full(packing.n_particles, 0.5 * (T1 + T2)))
    steady_s = time.perf_counter() - s0
    temp = res.temperature_k[-1]
    q_cold, q_hot = (float(q) for q in res.boundary_heat_flow_w[-1])
    area = cross_section(packing, 0)
    q_macro = q_hot / area                                   # W/m^2, from hot (xmax) to cold
    phi = float(packing.attrs["solid_fraction"])
    n = packing.n_particles
    moments = contact_moments(n, packing.pair, packing.branch, problem.conductance_w_k, temp)
    volume = 4.0 / 3.0 * np.pi * packing.radius ** 3
    free = (np.asarray(net.degree_w_k) > 0) & ~np.asarray(net.held)
    lo, hi = np.asarray(packing.domain_lo), np.asarray(packing.domain_hi)
    pos, rad = packing.position, packing.radius
    tree = cKDTree(pos)
    rng = np.random.default_rng(seed)
    rows = []
    for ratio in ratios:
        reach = max(ratio, 1.0) * rad[:, None]
        inside = free & np.all((pos - reach >= lo) & (pos + reach <= hi), axis=1)
        cand = np.flatnonzero(inside)
        if len(cand) < MIN_EVAL:
            continue
        pick = np.sort(rng.choice(cand, max_eval, replace=False)) if len(cand) > max_eval \
            else cand
        h0 = time.perf_counter()
        if ratio <= 0:
            q = phi * moments[pick] / (2.0 * volume[pick, None])
        else:
            q = halo_flux(pos, rad, moments, volume, phi, ratio, particles=pick, tree=tree)
        halo_s = time.perf_counter() - h0
        mag = np.linalg.norm(q, axis=1) / q_macro
        qx = -q[:, 0] / q_macro                               # along the imposed gradient
        rows.append({"ratio": ratio, "n_inside": int(len(cand)), "n_eval": int(len(pick)),
                     "cov_abs": float(mag.std() / mag.mean()),
                     "cov_x": float(qx.std() / qx.mean()),
                     "mean_abs": float(mag.mean()), "mean_x": float(qx.mean()),
                     "min_abs": float(mag.min()), "max_abs": float(mag.max()),
                     "seconds": halo_s, "seconds_per_particle": halo_s / len(pick)})
    return {"packing": packing_path, "n_particles": int(n), "steady_seconds": steady_s,
            "q_macro_w_m2": q_macro, "balance": abs(q_hot + q_cold) / q_hot,
            "solid_fraction": phi, "length_m": float(hi[0] - lo[0]), "rows": rows}


def _cached(path: Path, make):
    if path.exists():
        rec = json.loads(path.read_text())
        if rec.get("version") == VERSION:
            return rec
    rec = make()
    rec["version"] = VERSION
    write_text_atomic(path, json.dumps(rec, indent=1, default=float))
    return rec


def run(ctx: Context) -> CaseResult:
    sizes = QUICK if ctx.quick else SIZES
    recs = []
    for n, name in sizes.items():
        ctx.progress(f"N {n}: packing {name}")
        path = ctx.packing(name)
        ctx.progress(f"N {n}: steady slab and Halo fluxes at {len(RATIOS)} ratios")
        rec = _cached(ctx.out / f"halo_{name}.json", lambda path=path: halo_cov(path))
        rec.update(name=name, n_nominal=n)
        recs.append(rec)
    return _report(ctx, recs)


def _at(rec, ratio, key="cov_abs"):
    for r in rec["rows"]:
        if r["ratio"] == ratio:
            return r[key]
    return float("nan")


def _report(ctx, recs) -> CaseResult:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    # --- figure 1: CoV against the ratio (Fig. 10)
    png = ctx.figure("cov")
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    slopes = {}
    for rec in recs:
        rr = [r for r in rec["rows"] if r["ratio"] > 0]
        x = np.array([max(r["ratio"], 1.0) for r in rr])
        y = 100 * np.array([r["cov_abs"] for r in rr])
        ax.loglog(x, y, "o-", ms=4, label=f"tdem, {rec['n_particles']:,} spheres, |q|")
        ax.loglog([1.0], [100 * _at(rec, 0.0)], "o", mfc="none", color=ax.lines[-1].get_color())
        fit = x >= 5
        if fit.sum() >= 2:
            slopes[rec["n_particles"]] = float(np.polyfit(np.log(x[fit]), np.log(y[fit]), 1)[0])
    main = next((r for r in recs if r["n_nominal"] == 100_000), recs[-1])
    rr = [r for r in main["rows"] if r["ratio"] > 0]
    ax.loglog([r["ratio"] for r in rr], [100 * r["cov_x"] for r in rr], "s:", ms=3, color="0.4",
              label=f"tdem, {main['n_particles']:,}, q_x (along the gradient)")
    ax.loglog([p[0] for p in PAPER], [p[1] for p in PAPER], "r*", ms=12,
              label="002 (values in its text; raw at ratio 1)")
    ax.set_xlabel("halo / DE radius ratio (open circles: raw, eq. 20, plotted at 1)")
    ax.set_ylabel("CoV of the particle flux (%)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    savefig_atomic(fig, png, dpi=110)
    plt.close(fig)
    with open_atomic(png.with_suffix(".csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["n_particles", "ratio", "n_inside", "n_eval", "cov_abs_pct", "cov_x_pct",
                    "mean_abs_over_QA", "mean_x_over_QA", "min_abs_over_QA", "max_abs_over_QA",
                    "halo_seconds"])
        for rec in recs:
            for r in rec["rows"]:
                w.writerow([rec["n_particles"], r["ratio"], r["n_inside"], r["n_eval"],
                            f"{100 * r['cov_abs']:.4f}", f"{100 * r['cov_x']:.4f}",
                            f"{r['mean_abs']:.5f}", f"{r['mean_x']:.5f}", f"{r['min_abs']:.5f}",
                            f"{r['max_abs']:.5f}", f"{r['seconds']:.3f}"])
        for p in PAPER:
            w.writerow(["paper_text", p[0], "", "", p[1], "", "", "", "", "", ""])

    # --- figure 2: mean / min / max (Fig. 11) at the main N
    png = ctx.figure("minmax")
    fig, ax = plt.subplots(figsize=(6, 4))
    rr = main["rows"]
    x = [max(r["ratio"], 1.0) for r in rr]
    ax.semilogx(x, [r["mean_abs"] for r in rr], "o-", label="mean |q|")
    ax.semilogx(x, [r["mean_x"] for r in rr], "s--", ms=3, label="mean q_x")
    ax.semilogx(x, [r["max_abs"] for r in rr], "^-", label="max |q|")
    ax.semilogx(x, [r["min_abs"] for r in rr], "v-", label="min |q|")
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_xlabel("halo / DE radius ratio (raw at 1)")
    ax.set_ylabel("flux / (Q / A)")
    ax.set_title(f"{main['n_particles']:,} spheres", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    savefig_atomic(fig, png, dpi=110)
    plt.close(fig)
    with open_atomic(png.with_suffix(".csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["n_particles", "ratio", "mean_abs_over_QA", "mean_x_over_QA",
                    "min_abs_over_QA", "max_abs_over_QA"])
        for r in rr:
            w.writerow([main["n_particles"], r["ratio"], f"{r['mean_abs']:.5f}",
                        f"{r['mean_x']:.5f}", f"{r['min_abs']:.5f}", f"{r['max_abs']:.5f}"])

    # --- figure 3: speed against error: seconds per evaluated particle vs CoV
    png = ctx.figure("speed_error")
    fig, ax = plt.subplots(figsize=(6, 4.5))
    with open_atomic(png.with_suffix(".csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["n_particles", "ratio", "cov_abs_pct", "microseconds_per_particle"])
        for rec in recs:
            rr = [r for r in rec["rows"] if r["ratio"] > 0]
            ax.loglog([100 * r["cov_abs"] for r in rr],
                      [1e6 * r["seconds_per_particle"] for r in rr], "o-", ms=4,
                      label=f"{rec['n_particles']:,} spheres")
            for r in rec["rows"]:
                w.writerow([rec["n_particles"], r["ratio"], f"{100 * r['cov_abs']:.4f}",
                            f"{1e6 * r['seconds_per_particle']:.3f}"])
    for r in [r for r in main["rows"] if r["ratio"] > 0]:
        ax.annotate(f"{r['ratio']:g}", (100 * r["cov_abs"], 1e6 * r["seconds_per_particle"]),
                    fontsize=6, xytext=(3, 3), textcoords="offset points")
    ax.set_xlabel("CoV of |q| (%)")
    ax.set_ylabel("Halo evaluation, µs per particle (1 thread)")
    ax.set_title("labels: halo / DE ratio", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    savefig_atomic(fig, png, dpi=110)
    plt.close(fig)
    return _summary(recs, main, slopes)


def _ratio_for(rec, level):
    """Halo ratio at which CoV(|q|) falls to ``level`` (log-log interpolation; nan if never)."""
    rr = [r for r in rec["rows"] if r["ratio"] >= 1]
    for a, b in zip(rr[:-1], rr[1:]):
        if a["cov_abs"] >= level > b["cov_abs"]:
            f = np.log(level / a["cov_abs"]) / np.log(b["cov_abs"] / a["cov_abs"])
            return float(np.exp(np.log(a["ratio"]) + f * np.log(b["ratio"] / a["ratio"])))
    return float("nan")


def _summary(recs, main, slopes) -> CaseResult:
    header = "| ratio | " + " | ".join(f"{r['n_particles']:,}" for r in recs) + " |"
    sep = "|---|" + "---|" * len(recs)
    lines = []
    for ratio in RATIOS:
        cells = []
        for rec in recs:
            v = _at(rec, ratio)
            n_in = _at(rec, ratio, "n_eval")
            cells.append("—" if np.isnan(v) else f"{100 * v:.2f} % ({int(n_in):,})")
        paper = {p[0]: p[1] for p in PAPER}
        note = f" (paper {paper[ratio]:g} %)" if ratio in paper and ratio > 1 else \
            (" (paper 27 %)" if ratio == 0 else "")
        lines.append(f"| {'raw' if ratio == 0 else f'{ratio:g}'}{note} | " + " | ".join(cells)
                     + " |")
    table = "\n".join([header, sep] + lines)
    r5 = {rec["n_particles"]: _ratio_for(rec, 0.05) for rec in recs}
    r2 = {rec["n_particles"]: _ratio_for(rec, 0.02) for rec in recs}
    ratio_lines = "\n".join(
        f"| {n:,} | {r5[n]:.2f} | {r2[n]:.2f} | {slopes.get(n, float('nan')):.2f} | "
        f"{rec['steady_seconds']:.1f} | {sum(r['seconds'] for r in rec['rows']):.1f} | "
        f"{_pack(rec['name'])} |"
        for n, rec in zip(r5, recs))
    n_main = main["n_particles"]
    raw, c4, c11 = (100 * _at(main, x) for x in (0.0, 4.0, 11.0))
    mean_x4 = _at(main, 4.0, "mean_x")
    us4, us11 = (1e6 * _at(main, x, "seconds_per_particle") for x in (4.0, 11.0))
    frac11 = 100 * _at(main, 11.0, "n_inside") / n_main
    section = f"""
Setup (002 sec. 3): the cube of case 4 at steady state (faces normal to x held at 25 and 35 °C,
adiabatic sides, λ 33 W/m/K, law haddad), on cubes carved from copies of the relaxed
10,000-sphere periodic cell (`tiled`; N = {', '.join(f"{r['n_particles']:,}" for r in recs)}).
The flux of each particle is 002 eq. 20 (raw) or its Halo average, eq. 22–23
(`tdem_post.flux.halo_flux`: the particles whose centre lies within ratio × R_p of p's). The CoV
(std/mean) of |q| is taken over the free particles whose whole halo lies inside the cube (raw:
at least one radius inside), a seeded random subset of {MAX_EVAL:,} where more qualify (the
count in brackets). The CoV does not depend on C_t; fluxes are normalised by the macroscopic
flux Q/A through the held faces. **The paper's curve is not digitised**: its three values stated
in the text (27 % raw, 5 % at ratio ≈ 4, 2 % at ≈ 11) are plotted as stars. Reproduce:
`.venv/bin/python -m validation.run 7`.

CoV of |q| against the halo/DE radius ratio:

{table}

At {n_main:,} spheres: raw {raw:.1f} % (paper 27 %), {c4:.2f} % at ratio 4 (paper 5 %),
{c11:.2f} % at 11 (paper 2 %). The component along the gradient (q_x, dotted) scatters as
|q| does. Our raw scatter is higher than the paper's (our packing: Gaussian radii σ/μ 0.3
truncated at ±2σ, Z with gaps ~8.5 against its 7.5) and our curve falls faster at large halos
(slope ≈ −3/2, the paper's 5 % → 2 % between 4 and 11 is a slope of −0.9): 2 % is reached at a
ratio of {r2.get(n_main, float('nan')):.1f}, not 11. Between ratios 3 and 4 the CoV drops by
3×; our reading (not measured further): below it the halos of the smallest spheres
(R_p ≈ 0.4 mean radius) hold few or no other spheres.
The Halo average keeps the mean: mean q_x / (Q/A) is the same at every ratio ≥ 4
({mean_x4:.4f} at {n_main:,}); it is above 1 by a 1/L amount (4.6 % at 1e4, 2.2 % at 1e5),
because the layers along the cube's adiabatic cut faces conduct less (neighbours missing beyond
the cut), so the interior carries more than the average flux Q/A.

![CoV of the particle flux against the halo ratio, with the paper's \
values](img/validation_case7_cov.png)

![mean, min and max flux against the halo ratio](img/validation_case7_minmax.png)

**Against N and the ratio** (ratios where the CoV crosses 5 % and 2 %, log-log interpolated; the
slope of log CoV against log ratio fitted for ratio ≥ 5; times on 1 thread of a shared machine):

| N | ratio at 5 % | ratio at 2 % | slope (ratio ≥ 5) | steady solve (s) | Halo, all ratios (s) | \
packing (s) |
|---|---|---|---|---|---|---|
{ratio_lines}

As the paper found, the curve hardly depends on N: it is a property of the packing's local
disorder (the cut faces only shift the mean, above), and a halo holding M ≈ φ ratio³ / (1 + 3σ²)
spheres averages M roughly independent fluxes, so the CoV falls about as ratio^(−3/2) — the fitted
slopes. There is no convergence in N to fit; N sets how many particles have a whole halo inside
the cube.

**Speed against error**: the Halo evaluation costs about the number of spheres in a halo per
particle (ratio³): {us4:.0f} µs per particle at ratio 4, {us11:.0f} µs at 11 (1 thread); the
steady solve itself is {main['steady_seconds']:.0f} s at {n_main:,}.

![speed against error of the Halo smoothing](img/validation_case7_speed_error.png)

What limits us: the cube's boundary layer of depth ratio × R_p is excluded (at ratio 11 the
evaluated particles are the inner ~40 % of the 1e5 cube), and large halos near a boundary would
need a truncated halo (eq. 23's volume counts only particles inside) — not studied here. At
ratio 11, {frac11:.0f} % of the {n_main:,} spheres have their halo inside the cube.
"""
    return CaseResult(
        our_n=f"{n_main:,}" + (" (also " + ", ".join(f"{r['n_particles']:,}" for r in recs
                                                      if r is not main) + ")"
                                 if len(recs) > 1 else ""),
        our_error=(f"CoV {raw:.1f} % raw, {c4:.2f} % at 4, {c11:.2f} % at 11; "
                   f"5 % at ratio {r5.get(n_main, float('nan')):.1f}, "
                   f"2 % at {r2.get(n_main, float('nan')):.1f}"),
        wall_time=(f"{_pack(main['name'])} + {main['steady_seconds']:.0f} s steady + "
                   f"{sum(r['seconds'] for r in main['rows']):.0f} s Halo (11 ratios)"),
        verdict=(f"the paper's shape and N-independence; raw scatter {raw:.0f} % (paper 27 %), "
                 f"5 % at ratio {r5.get(n_main, float('nan')):.1f} (paper ≈ 4), 2 % at "
                 f"{r2.get(n_main, float('nan')):.1f} (paper ≈ 11): ours falls as ratio^-3/2"),
        section_md=section,
        numbers={"n_particles": n_main, "cov_raw": raw / 100, "cov_ratio4": c4 / 100,
                 "cov_ratio11": c11 / 100, "ratio_at_5pct": r5, "ratio_at_2pct": r2,
                 "slopes": slopes,
                 "records": [{k: v for k, v in r.items()} for r in recs]},
        command=".venv/bin/python -m validation.run 7")


def _pack(name):
    s = pack_seconds(name)
    return "—" if s is None else f"{s:.0f} s"


def main(argv=None):
    import argparse
    from validation.framework import save_result
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    res = run(Context(CASE.number, quick=a.quick))
    print(res.our_n, "|", res.our_error, "|", res.verdict)
    if not a.quick:
        print(save_result(CASE, res, time.perf_counter() - t0))


if __name__ == "__main__":
    main()
