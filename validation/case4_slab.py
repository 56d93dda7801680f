"""Case 4 of docs/validation.md: Haddad's cube slab (002 sec. 2.2, eq. 17) on tdem packings.

The cube between two held faces normal to x (T = 25 C at xmin, 35 C at xmax, 25 C initially,
adiabatic sides), material of 002 Tab. 1 (rho 7800, lambda 33, c 0.9), law haddad with C_t
calibrated on the same packing by the steady flux test with the HELD-PLANE length (the distance
between the mean centre planes of the two held sets, the slab of the analytical solution, as
`tdem post` uses); the domain-length C_t (`tdem calibrate`, the paper's convention) is printed
beside it. The geometry is not rescaled to L = 10 cm: conduction depends only on the Fourier
number, so the outputs are at the paper's Fo = alpha t / L^2 with alpha = 33 / (7800 * 0.9) and
L = 10 cm at t = 0.05, 0.1, 0.2 s, i.e. Fo = 0.0235, 0.0470, 0.0940, with our L.

Forward Euler (as the paper) at 0.9 x the exact positivity bound. Profile: partial-volume
weighted means over n_bins equal bins of [0, L] (rattlers excluded), against the bin mean of
the slab series (tdem_post.analytic.slab_mean_temperature). Also the STEADY profile on the same
network against the linear one (20 bins, % of dT): the calibration makes the heat flow exact,
not the profile linear; a boundary resistance of the held layers bends it.

`tdem validate 4` runs it over INSTANCES (the default ones built when missing, the others when
their packing is on the machine; the rows of the rest are carried over); `--quick` runs
:func:`slab_case` on the committed 400-sphere box, the function every row runs.
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tdem_post.records import column, from_dict, to_dict
from thermal_kernel.atomic import write_text_atomic

from .framework import (ROOT, CaseInfo, CaseResult, Context, case_scene, optional_packing,
                        previous_numbers, today)
from .framework import Action, Judgement, cell_cost_text, figure_csv, fit_order, \
    held_plane_ct, held_planes, judged, md_table, rebuild_saved, scene_toml

CASE = CaseInfo(number=4, title="cube slab, eq. 17", paper="002 sec. 2.2", paper_n="1e5",
                paper_error="max rel. error 0.7 %",
                target="≤ 0.5 % of ΔT (max over the finest bins), N 1e5")
RHO, LAMBDA, CAP = 7800.0, 33.0, 0.9          # 002 Tab. 1
ALPHA = LAMBDA / (RHO * CAP)
T1, T2 = 298.15, 308.15                         # 25 C at x = 0, 35 C at x = L
PAPER_L, PAPER_TIMES = 0.1, (0.05, 0.1, 0.2)
FOURIER = tuple(ALPHA * t / PAPER_L ** 2 for t in PAPER_TIMES)
PAPER_ERROR = 0.007                             # 002 Fig. 5b, max relative error at 1e5
STEADY_BINS = 20
N_BINS = 10                                     # the profile's bins (slab_case's default)
DENSE_400 = ROOT / "tests" / "data" / "dense_box.h5"
WALLED, TILED = "walled (YADE box)", "tiled (cut cube)"
# key (row name), label, family (None: not in the convergence figure), packing, default
INSTANCES = [
    ("dense_box_400", "tests/data/dense_box.h5 (walled, 400)", None, None, True),
    ("ds_2000_s1", "walled ds, seed 1", WALLED, "box_2000", True),
    ("ds_2000_s2", "walled ds, seed 2", WALLED, "box_2000_s2", False),
    ("ds_2000_s3", "walled ds, seed 3", WALLED, "box_2000_s3", False),
    ("ds_10000_s1", "walled ds", WALLED, "box_1e4", False),
    ("ds_1e5_s1", "walled ds", WALLED, "box_1e5_walled", False),
    ("tiled_10000_s1", "tiled (2,000 cell), seed 1", TILED, "box_1e4_tiled_s1", False),
    ("tiled_10000_s2", "tiled (2,000 cell), seed 2", TILED, "box_1e4_tiled_s2", False),
    ("tiled_10000_s3", "tiled (2,000 cell), seed 3", TILED, "box_1e4_tiled_s3", False),
    ("tiled_1e5", "tiled (10,000 cell)", TILED, "box_1e5", True),
    ("tiled_1e6", "tiled (10,000 cell)", TILED, "box_1e6", True),
]
SPEC = {k: (lab, fam) for k, lab, fam, _, _ in INSTANCES}
HOW = "tdem validate 4"


# Haddad's coordination with gaps in the bulk (002 sec. 2.1: Z ~ 7.5): the scene picks the gap that
# gives it on each packing from the dumped neighbours (thermal_kernel.neighbours, issue 23)
TARGET_Z = 7.5


def scene_text(packing: str, ct: float, target_z: float | None = None,
               solver: dict | None = None) -> str:
    """The slab's scene: the steady solve unless ``solver`` (a [solver] table) says otherwise."""
    return scene_toml(
        packing, "haddad", law_params=dict(ct=ct),
        neighbours=None if target_z is None else dict(target_z_with_gaps=float(target_z)),
        material=dict(conductivity=LAMBDA, density=RHO, heat_capacity=CAP),
        initial=dict(temperature=T1),
        boundary=[dict(kind="temperature", name="cold", on="xmin", value=T1),
                  dict(kind="temperature", name="hot", on="xmax", value=T2)],
        solver=solver or dict(method="steady"))


def slab_case(packing_path, n_bins: int = 10, threads: int = 1, ct_arb: float = 0.806,
              target_z: float | None = TARGET_Z):
    """One packing: (summary dict, profile rows (Fo, t, x/L, T_dem C, T_exact C, error K))."""
    from tdem_post.analytic import slab_mean_temperature
    from tdem_post.profiles import binned_profile
    from thermal_kernel.calibrate import cross_section
    from thermal_kernel.packing import read_packing
    from thermal_kernel.run import run_in_memory
    packing_path = str(Path(packing_path).resolve())
    scene_path = ROOT / "validation" / "case4_scene.toml"     # a name for messages only
    packing = read_packing(packing_path)
    scene = case_scene(scene_text(packing_path, ct_arb, target_z), scene_path)
    c0 = time.perf_counter()
    # held-plane slab: mean centre planes of the two held sets
    x0, x1 = held_planes(scene, packing, "x")
    length = x1 - x0
    domain_length = float(packing.domain_hi[0] - packing.domain_lo[0])
    # C_t from one steady flux test (002 eq. 8-9); lambda_e is proportional to the length used
    test, ct_domain, ct_held = held_plane_ct(scene, packing, "x", ct_arb, LAMBDA)
    area = cross_section(packing, 0)
    calib_s = time.perf_counter() - c0

    # forward Euler (as the paper) at the bound's default fraction to the paper's Fourier numbers
    times = [fo * length ** 2 / ALPHA for fo in FOURIER]
    r0 = time.perf_counter()
    run = run_in_memory(case_scene(scene_text(packing_path, ct_held, target_z, dict(
        method="explicit", end_time=times[-1], output_times=times)), scene_path), packing,
        threads=threads)
    run_s = time.perf_counter() - r0 - run.assemble_seconds      # the steps, not the build
    result, net, choice = run.result, run.network, run.neighbours
    conducting = np.asarray(net.conducting)
    x = packing.position[:, 0] - x0
    edges = np.linspace(0.0, length, n_bins + 1)
    prof = binned_profile(x, packing.radius, result.temperature_k, edges, weights=conducting)
    exact = np.array([slab_mean_temperature(edges[:-1], edges[1:], t, length, ALPHA, T1, T2, T1)
                      for t in times])
    err = prof - exact
    err_dt = np.abs(err) / (T2 - T1)                    # relative to the imposed difference
    err_c = np.abs(err) / (exact - 273.15)              # relative to T in C (the paper's, Fig. 5b)

    # the steady profile on the same network against the linear one (% of dT)
    s0 = time.perf_counter()
    steady_run = run_in_memory(case_scene(scene_text(packing_path, ct_held, target_z),
                                          scene_path), packing,
                               initial_temperature_k=0.5 * (T1 + T2), threads=threads)
    steady = steady_run.final_temperature_k
    sedges = np.linspace(0.0, length, STEADY_BINS + 1)
    sprof = binned_profile(x, packing.radius, steady, sedges, weights=conducting)
    linear = T1 + (T2 - T1) * 0.5 * (sedges[1:] + sedges[:-1]) / length
    steady_pct = 100 * (sprof - linear) / (T2 - T1)
    steady_s = time.perf_counter() - s0
    summary = {
        "packing": packing_path, "n_particles": int(packing.n_particles), "n_bins": n_bins,
        "neighbour_gap": choice.gap if choice else None,
        "bulk_z_with_gaps": choice.bulk_z if choice else None,
        "bulk_z_dumped": choice.bulk_z_dumped if choice else None,
        "length_held_m": length, "length_domain_m": domain_length,
        "ct_held_plane": ct_held, "ct_domain_length": ct_domain,
        "steady_balance": test.balance, "area_m2": area,
        "fourier": list(FOURIER), "times_s": times, "dt_s": result.dt, "steps": result.steps,
        "max_rel_error_celsius": float(err_c.max()),
        "max_rel_error_celsius_per_time": err_c.max(axis=1).tolist(),
        "max_error_over_dT": float(err_dt.max()),
        "max_error_over_dT_per_time": err_dt.max(axis=1).tolist(),
        "steady_minus_linear_pct_dT": steady_pct.tolist(),
        "calibration_seconds": calib_s, "run_seconds": run_s, "steady_seconds": steady_s,
        "threads": threads,
        # a tiled box: the periodicity of the cell it is copied from (its packing says it)
        "cell_size_m": (float(packing.attrs["cell_size_m"][0])
                        if "cell_size_m" in packing.attrs else None),
    }
    rows = []
    for k, t in enumerate(times):
        for b in range(n_bins):
            rows.append((FOURIER[k], t, 0.5 * (edges[b] + edges[b + 1]) / length,
                         prof[k, b] - 273.15, exact[k, b] - 273.15, err[k, b]))
    return summary, rows


# ---------------------------------------------------------------- the case
_LEGACY = column(optional=True)      # absent from the rows measured before issue 23


@dataclass(frozen=True, kw_only=True)
class SlabRow:
    """One packing of the case, measured by :func:`slab_case` (or carried over from the saved
    result): the record the figures, the section and the judge read. Errors are fractions (of
    T in °C, of ΔT), C_t dimensionless; rows measured before issue 23 lack the optional
    fields (their steady profile is the hand-read ``steady_legacy``)."""
    name: str
    label: str
    family: str | None                  # its series in the convergence figure (None: not in it)
    n_particles: int
    ct_held: float                      # C_t with the held-plane length
    ct_domain: float                    # C_t with the domain length (002 eq. 8)
    length_held_m: float | None = field(default=None, metadata=_LEGACY)
    max_err_over_T_celsius: float       # max |bin mean - exact| / T_exact(°C), bins x times
    max_err_over_dT: float              # the same over ΔT
    max_err_over_dT_per_time: tuple[float, ...] | None = field(default=None, metadata=_LEGACY)
    steps: int                          # forward-Euler steps
    run_seconds: float
    steady_pct: tuple[float, ...] | None = field(default=None, metadata=_LEGACY)  # % of ΔT
    # (Fo, t s, x/L, T_dem °C, T_exact °C, error K) per bin and time
    profile: tuple[tuple[float, ...], ...] | None = field(default=None, metadata=_LEGACY)
    bulk_z_with_gaps: float | None = field(default=None, metadata=_LEGACY)
    neighbour_gap: float | None = field(default=None, metadata=_LEGACY)
    # the tiled boxes: the periodicity (x) of the cell copied into them (the packing's cell_size_m)
    cell_size_m: float | None = field(default=None, metadata=_LEGACY)
    measured: str                       # the date
    how: str                            # what measured it
    steady_legacy: dict | None = field(default=None, metadata=_LEGACY)


def read_rows(numbers: dict) -> list[SlabRow]:
    """The rows of case 4's saved numbers as records (a missing or unknown field: RecordError)."""
    return [from_dict(SlabRow, r, f"case 4: rows[{k}]")
            for k, r in enumerate(numbers.get("rows", []))]


def _row(key: str, summary: dict, profile: list) -> SlabRow:
    label, family = SPEC.get(key, (key, None))
    return SlabRow(name=key, label=label, family=family, n_particles=summary["n_particles"],
                   ct_held=summary["ct_held_plane"], ct_domain=summary["ct_domain_length"],
                   length_held_m=summary["length_held_m"],
                   max_err_over_T_celsius=summary["max_rel_error_celsius"],
                   max_err_over_dT=summary["max_error_over_dT"],
                   max_err_over_dT_per_time=tuple(summary["max_error_over_dT_per_time"]),
                   steps=summary["steps"], run_seconds=summary["run_seconds"],
                   steady_pct=tuple(summary["steady_minus_linear_pct_dT"]),
                   profile=tuple(tuple(float(v) for v in r) for r in profile),
                   bulk_z_with_gaps=summary.get("bulk_z_with_gaps"),
                   neighbour_gap=summary.get("neighbour_gap"),
                   cell_size_m=summary.get("cell_size_m"), measured=today(), how=HOW)


def _figures(ctx: Context, rows: list[dict]) -> dict:
    out = {}
    best = next((r for r in rows if r.name == "tiled_1e5" and r.profile),
                next((r for r in reversed(rows) if r.profile), None))
    if best is not None:
        prof = np.array(best.profile)
        png = ctx.figure("profiles")
        with figure_csv(png, ["fourier", "time_s", "x_over_L", "T_dem_C", "T_exact_C",
                              "error_K"], 1, 2, figsize=(10, 4), dpi=120) as ((a, b), csv):
            csv += [tuple(float(v) for v in r) for r in best.profile]
            for fo in sorted(set(prof[:, 0])):
                sel = prof[prof[:, 0] == fo]
                a.plot(sel[:, 2], sel[:, 4], "-", color="0.5")
                a.plot(sel[:, 2], sel[:, 3], "o", label=f"Fo = {fo:.4f}")
                b.plot(sel[:, 2], 100 * sel[:, 5] / sel[:, 4], "o-", label=f"Fo = {fo:.4f}")
            a.set_xlabel("x / L (held planes)")
            a.set_ylabel("T (°C)")
            a.set_title(f"cube slab, {best.n_particles:,} spheres: DEM (dots), eq. 17 (lines)")
            a.legend()
            b.axhline(100 * PAPER_ERROR, ls="--", color="r", label="Haddad's max 0.7 %")
            b.axhline(-100 * PAPER_ERROR, ls="--", color="r")
            b.set_xlabel("x / L")
            b.set_ylabel("(T_DEM − T_exact) / T_exact(°C)  (%)")
            b.legend()
        out["profiles"] = (png.name, best)

    png = ctx.figure("convergence")
    orders = {}
    with figure_csv(png, ["family", "name", "n_particles", "ct_held", "ct_domain",
                          "max_err_over_T_celsius", "max_err_over_dT", "steps", "run_seconds",
                          "measured"], figsize=(5.5, 4), dpi=120) as (ax, csv):
        for family in (WALLED, TILED):
            fam = sorted((r for r in rows if r.family == family), key=lambda r: r.n_particles)
            if not fam:
                continue
            ns = [r.n_particles for r in fam]
            ed = np.array([r.max_err_over_dT for r in fam])
            ec = np.array([r.max_err_over_T_celsius for r in fam])
            lab = f"{family}: |err|/ΔT"
            if len(set(ns)) >= 2:
                orders[family] = fit_order(ns, ed)[0]
                lab += f", order {orders[family]:.2f}"
            line, = ax.loglog(ns, 100 * ed, "o", label=lab)
            ax.loglog(ns, 100 * ec, "x", color=line.get_color(), label=f"{family}: |err|/T(°C)")
        ax.axhline(100 * PAPER_ERROR, ls="--", color="r", lw=0.8,
                   label="Haddad 1e5: 0.7 % (of T in °C)")
        ax.set_xlabel("N (spheres)")
        ax.set_ylabel("max relative error (%)")
        ax.legend(fontsize=7)
        csv += [(r.family or "", r.name, r.n_particles, r.ct_held, r.ct_domain,
                 r.max_err_over_T_celsius, r.max_err_over_dT, r.steps, r.run_seconds,
                 r.measured) for r in rows]
    out["convergence"] = png.name
    out["orders"] = orders
    return out


def judge(numbers: dict) -> Judgement:
    """Issue 23's columns: the paper's N is 1e5 and its "max relative error 0.7 %" is undefined;
    the stricter reading judges: max |bin mean - exact| / ΔT over the 10 bins and 3 times (the
    error of T in °C, origin-dependent and 3.3x laxer here, beside it)."""
    rows = read_rows(numbers)
    at_n = [r for r in rows if r.name == "tiled_1e5"]
    if not at_n:
        return Judgement("not measured", "", None)
    r = at_n[0]
    bins = N_BINS
    at = (f"N {r.n_particles:,}: {100 * r.max_err_over_dT:.3f} % of ΔT (max over {bins} "
          f"bins × 3 times; {100 * r.max_err_over_T_celsius:.2f} % of T in °C beside it)")
    walled = [x for x in rows if x.name == "ds_1e5_s1"]
    if walled:      # the paper's boundaries as made (pressed walls, issue 24) beside the cut cube
        at += (f"; walled YADE box, N {walled[0].n_particles:,}: "
               f"{100 * walled[0].max_err_over_dT:.3f} % of ΔT "
               f"({100 * walled[0].max_err_over_T_celsius:.2f} % of T in °C)")
    reached = sorted((x for x in rows if x.max_err_over_dT <= 0.007),
                     key=lambda x: x.n_particles)
    speed = (f"0.7 % of ΔT first at N {reached[0].n_particles:,} ({reached[0].label}, "
             f"{_z_cell(reached[0])}: thermal {reached[0].run_seconds:.1f} s + its packing)"
             if reached
             else "0.7 % of ΔT not reached")
    met = r.max_err_over_dT <= 0.005
    verdict = ("met at 1e5 in the stricter measure" if met else
               f"not met at 1e5: {100 * r.max_err_over_dT:.3f} % of ΔT, in the bins at the "
               "cut hot face (a boundary resistance of the held layer the calibrated C_t cannot "
               "absorb); the laxer reading (of T in °C) would pass, which is why it is not used")
    return Judgement(at_paper_n=at, speed_vs_error=speed, target_met=met, verdict=verdict)


def run(ctx: Context) -> CaseResult:
    if ctx.quick:        # the committed 400-sphere walled box: no YADE
        summary, profile = slab_case(DENSE_400, threads=ctx.threads)
        row = _row("dense_box_400", summary, profile)
        return CaseResult(our_n="400", our_error=f"{100 * row.max_err_over_T_celsius:.2f} % "
                          f"of T in °C, {100 * row.max_err_over_dT:.2f} % of ΔT",
                          wall_time=f"{row.run_seconds:.1f} s", verdict="quick instance",
                          section_md="", numbers=dict(rows=[to_dict(row)]))
    previous = {r.name: r for r in read_rows(previous_numbers(4))}
    rows = []
    for key, _label, _family, name, default in INSTANCES:
        path = DENSE_400 if name is None else optional_packing(name, default)
        if path is None:
            if key in previous:
                rows.append(previous[key])
                ctx.progress(f"{key}: {name} not built here, row of {previous[key].measured} "
                             "kept")
            continue
        ctx.progress(f"{key}: slab on {Path(path).relative_to(ROOT)} ...")
        summary, profile = slab_case(path, threads=ctx.threads)
        row = _row(key, summary, profile)
        rows.append(row)
        write_text_atomic(ctx.out / f"{key}.json", json.dumps(summary, indent=1))
        ctx.progress(f"{key}: N {row.n_particles}, "
                     f"max err {100 * row.max_err_over_T_celsius:.3f} "
                     f"% of T(C), {100 * row.max_err_over_dT:.3f} % of dT, {row.steps} "
                     f"steps, {row.run_seconds:.1f} s")
    figs = _figures(ctx, rows)
    return _result(rows, figs)


def _z_cell(r: dict) -> str:
    """The neighbour criterion a row was measured with: Haddad's bulk Z 7.5 (the gap chosen on
    the packing), or every dumped pair (rows measured before issue 23)."""
    if r.bulk_z_with_gaps is None:
        return "every dumped pair"
    return f"{r.bulk_z_with_gaps:.2f} ({r.neighbour_gap:.3f})"


def _p(x, digits=2):
    return f"{100 * x:.{digits}f} %"


def _sg(x, digits=2):
    """A signed number with a typographic minus."""
    return f"{x:+.{digits}f}".replace("-", "−")


def _steady_cells(r):
    if r.steady_pct is not None:
        s = np.array(r.steady_pct)
        mid = s[len(s) // 2 - 2: len(s) // 2 + 2]
        mid_t = (_sg(mid.mean()) if np.ptp(mid) < 0.1 else f"{_sg(mid.max())} … {_sg(mid.min())}")
        hot = _sg(s[-1]) + (f" ({_sg(s[-2])} one bin in)" if abs(s[-2]) > abs(s[-1]) + 0.1
                            else "")
        return s[0], mid_t, s[-1], hot
    lg = r.steady_legacy
    hot = _sg(lg["hot"]) + (f" ({_sg(lg['hot_inner'])} one bin in)" if lg["hot_inner"] else "")
    return lg["cold"], lg["mid"], lg["hot"], hot


def _packing_table(rows: list[SlabRow]) -> str:
    """The section's table of packings (the 1e5 row bold, carried rows marked)."""
    cells = []
    for r in rows:
        b = "**" if r.name == "tiled_1e5" else ""
        t = f"{r.run_seconds:.1f}" if r.run_seconds < 100 else f"{r.run_seconds:.0f}"
        mark = " †" if r.how != HOW else ""
        cells.append((f"{b}{r.label}{b}{mark}", f"{b}{r.n_particles:,}{b}",
                      f"{r.ct_held:.4f} / {r.ct_domain:.4f}",
                      f"{b}{_p(r.max_err_over_T_celsius)}{b}", f"{b}{_p(r.max_err_over_dT)}{b}",
                      _z_cell(r), f"{r.steps:,}", t))
    return md_table(["packing", "N", "C_t (held planes / domain)", "max err / T(°C)",
                     "max err / ΔT", "bulk Z (gap)", "explicit steps", "thermal (s)"], cells)


def _steady_table(rows: list[SlabRow]) -> str:
    """The steady-profile table: its ends, mid-slab and shape per packing."""
    cells = []
    for r in rows:
        if r.steady_pct is None and r.steady_legacy is None:
            continue
        cold, mid, hot, hot_t = _steady_cells(r)
        if cold < 0 < hot:
            shape = ("steeper than linear inside, opposite jumps at the faces (the held layer "
                     "conducts a little better than the bulk)")
        elif cold > 0 > hot:
            shape = ("flatter than linear inside, jumps at the faces: a boundary resistance of the "
                     "held layers")
        else:
            shape = "ends of one sign"
        cells.append((f"{r.label}, {r.n_particles:,}", _sg(cold), mid, hot_t, shape))
    return md_table(["packing", "cold end", "mid-slab", "hot end", "shape"], cells)


def _where(b5: SlabRow | None, b6: SlabRow | None, n: dict) -> dict:
    """Where the error is, in words, from the 1e5 and 1e6 profiles (the 1e5 last bin's range
    added to ``n``)."""
    parts = {}
    if b5 and b5.profile:
        p = np.array(b5.profile)
        first = p[p[:, 0] == p[0, 0]]
        cold = np.abs(p[p[:, 2] < 0.5, 5]).max()
        last = p[p[:, 2] == p[:, 2].max(), 5]
        parts["where"] = (f"at 1e5 the error is < {cold:.3f} K over the cold half and grows "
                          f"towards the hot face, {_sg(last.max())} to {_sg(last.min())} K in "
                          "the last bin"
                          + (", the largest at the earliest time (the steepest gradient there)"
                             if abs(first[-1, 5]) >= np.abs(last).max() - 1e-12 else ""))
        n["error_1e5_last_bin_k"] = [float(last.min()), float(last.max())]
    else:
        parts["where"] = "the error is largest in the bins next to the hot face"
    if b6 and b6.profile:
        p = np.array(b6.profile)
        first = p[p[:, 0] == p[0, 0]]
        mid = p[np.abs(p[:, 2] - 0.5) < 0.11, 5]
        parts["1e6"] = (f"({_sg(mid.max(), 3)} to {_sg(mid.min(), 3)} K at mid-slab, "
                        f"{_sg(first[-1, 5])} K in the last bin at the first time)")
    else:
        parts["1e6"] = ("(−0.005 to −0.015 K at mid-slab, −0.07 K in the last bin at the first "
                        "time)")
    return parts


def _result(rows: list[SlabRow], figs: dict) -> CaseResult:
    """The case's result from its rows and figures: the section (:func:`_section_setup`,
    :func:`_section_where`, :func:`_section_steady`) and the summary's columns
    (:func:`_columns`)."""
    by = {r.name: r for r in rows}
    n = dict(rows=[to_dict(r) for r in rows], fitted_orders=figs["orders"])
    b5, b6 = by.get("tiled_1e5"), by.get("tiled_1e6")
    parts = _where(b5, b6, n)
    paper = _paper_text(b5, b6, n)
    falls = b5 and b6 and b6.max_err_over_dT < b5.max_err_over_dT    # from 1e5 to 1e6
    section = (_section_setup(rows, figs, b5) + _section_where(by, b5, b6, parts, falls)
               + _section_steady(rows, figs, b5, b6, paper, by.get("ds_1e5_s1")))
    return CaseResult(**_columns(rows, b5, b6, falls), section_md=section, numbers=n)


def _paper_text(b5, b6, n: dict) -> str:
    """The paragraph against the paper's 0.7 % (and the 1e5 errors into ``n``)."""
    if not b5:
        return ""
    e5c, e5d = b5.max_err_over_T_celsius, b5.max_err_over_dT
    text = (f"**Against the paper.** 002's \"max relative error 0.7 %\" does not say "
            "relative to what. Judged on the stricter reading, |bin mean − exact| / "
            f"ΔT (max over the 10 bins and 3 times): **{_p(e5d)} at 1e5** — the "
            "target ≤ 0.5 % is " + ("met" if e5d <= 0.005 else "not met") + ". "
            f"Relative to T in °C the same error is {_p(e5c)}, but that reading "
            "depends on the origin of the temperature scale (in kelvin it would be "
            f"~10× smaller again) and is {e5d / e5c:.1f}× laxer here, so it is "
            "shown, not judged on.")
    if b6:
        text += (f" At 1e6 {_p(b6.max_err_over_T_celsius)} "
                 f"({_p(b6.max_err_over_dT)} of ΔT); the paper gives no 1e6 slab.")
    n.update(err_1e5_celsius=e5c, err_1e5_dT=e5d)
    return text


def _section_setup(rows, figs, b5) -> str:
    """The section's setup, the two measures, the profiles figure and the packings' table.
    Text, hence its length."""
    carried = sorted({r.measured for r in rows if r.how != HOW})
    table = _packing_table(rows)
    ratios = [r.max_err_over_dT / r.max_err_over_T_celsius for r in rows]
    lbl = f"held-plane distance, {1e3 * b5.length_held_m:.1f} mm at 1e5" \
        if b5 and b5.length_held_m else "the held-plane distance"
    prof_png = figs.get("profiles")
    return f"""\
Setup (as the paper, 002 sec. 2.2 and Tab. 1): two faces normal to x held, T = 25 °C at xmin and
35 °C at xmax from t = 0, 25 °C initially, adiabatic sides; ρ = 7800 kg/m³, λ = 33 W/m/K,
c = 0.9 J/kg/K (the paper's value; α = 4.70e-3 m²/s); law haddad with C_t calibrated on the same
packing (case 6, x axis, held-plane length{f": {b5.ct_held:.4f} at 1e5" if b5 else ""}).
**Not rescaled to L = 10 cm**: the solution depends on the Fourier number only, so the outputs are
at the paper's Fo = α t / L² for L = 10 cm and t = 0.05 / 0.1 / 0.2 s, i.e.
Fo = {FOURIER[0]:.4f} / {FOURIER[1]:.4f} / {FOURIER[2]:.4f}, with our L (the {lbl} — close to the
paper's 10 cm anyway). Forward Euler (as the paper) at 0.9 × its exact positivity bound. Profile:
10 equal bins of [0, L], each particle weighted by its partial volume in the bin (rattlers
excluded), against the bin mean of eq. 17 (`tdem_post.analytic.slab_mean_temperature`, the slab
series/images summed to 1e-12).

Two error measures: **|T − T_exact| / T_exact with T in °C** (our reading of the paper's
Fig. 5b: the paper does not define its relative error, and plots T in °C; 0.7 % of ~30 °C is
~0.2 K) and |T − T_exact| / ΔT (ΔT = 10 K, independent of the temperature scale's origin,
{min(ratios):.1f}–{max(ratios):.1f}× stricter).

One packing by hand: `slab_case(PACKING)` of `validation/case4_slab.py`, what every row runs
(`tdem validate 4 --quick` runs it on the committed 400-sphere box).
""" + (f"""
![case 4 profiles at {prof_png[1].n_particles:,}](img/{prof_png[0]})

(data: `img/{Path(prof_png[0]).with_suffix('.csv').name}`)
""" if prof_png else "") + f"""
{table}
""" + (f"""
† Measured {', '.join(carried)} (through every dumped pair: before the scene's neighbour
criterion of issue 23) and carried over: those packings are not on this machine;
`TDEM_VALIDATE_ALL_PACKINGS=1 tdem validate 4 --force` builds and measures them again.
""" if carried else "")


def _section_where(by, b5, b6, parts, falls) -> str:
    """Where the error is: the held face's boundary resistance, and from 1e5 to 1e6."""
    b4 = by.get("ds_10000_s1")
    tiled4 = [by[k] for k in ("tiled_10000_s1", "tiled_10000_s2", "tiled_10000_s3") if k in by]
    seeds = ""
    if tiled4 and b4:
        v = [r.max_err_over_dT for r in tiled4]
        seeds = (f" ({100 * np.mean(v):.1f} ± {100 * np.std(v, ddof=1):.1f} % against "
                 f"{_p(b4.max_err_over_dT)} of ΔT)")
    l6 = b6.length_held_m if b6 else None
    cell_m = next((r.cell_size_m for r in (b5, b6) if r and r.cell_size_m), None)
    cell_txt = "" if cell_m is None else (
        f"\n({1e3 * cell_m:.0f} mm" + (f", {100 * cell_m / l6:.0f} % of L at 1e6" if l6 else "")
        + ")")
    return f"""
**Where the error is.** Not in the bulk: {parts['where']}. The DEM lags the solution next to the
held face: on the tiled boxes the held layer of a cut face is joined to the bulk by fewer links
than a bulk layer, a boundary resistance (measured on the steady profile below; the walled boxes
show the opposite, smaller jump). The steady calibration folds that resistance into C_t (one
number for bulk and boundary), so the bulk is slightly over-conductive and the face
under-conductive; in steady state the heat flow is exact, in the transient the two do not
cancel. This is why the error falls with N from 400 to 1e5 and why the tiled 1e4 boxes — cut
from 2,000-sphere cells, only ~12 diameters periodic — are worse than the walled 1e4 box of the
same N{seeds}: their held layers are sparser.
""" + (f"""
**From 1e5 to 1e6 the error {'falls' if falls else 'does not fall'}** ({_p(b5.max_err_over_dT)} →
{_p(b6.max_err_over_dT)} of ΔT; {_p(b5.max_err_over_T_celsius)} →
{_p(b6.max_err_over_T_celsius)} of T in °C). At 1e6 the deficit is no longer confined to the
hot face: it spreads smoothly over the hot half {parts['1e6']}, as if the slab near the hot face
conducted or stored heat slightly differently from the slab as a whole. A boundary resistance
alone would make the error fall like 1/L, so something else sets a floor for these packings. Our
hypothesis, not tested: the tiled boxes are copies of ONE relaxed 10,000-sphere \
cell{cell_txt}, so their
local density and coordination fluctuations repeat instead of averaging out; the steady
calibration matches the harmonic mean along x, the transient near the hot face sees the first
cells only. Tiling from several independently relaxed cells, or seeds of the 1e5/1e6 boxes, would
test it.
""" if b5 and b6 else "")


def _remedies(walled, tiled) -> str:
    """The two remedies of the cut face's resistance, and what the walled box measured."""
    if walled is None or tiled is None:
        return ("Held-plane positions that include the jump (an effective plane found from the "
                "steady profile), or faces pressed by walls, are the two remedies to try.")
    return (f"Faces pressed by walls, measured (issue 24): the walled YADE box of "
            f"{walled.n_particles:,} spheres has {_p(walled.max_err_over_dT)} of ΔT against "
            f"{_p(tiled.max_err_over_dT)} on the tiled box of {tiled.n_particles:,}, "
            f"{tiled.max_err_over_dT / walled.max_err_over_dT:.1f}× less. Held-plane positions "
            "that include the jump (an effective plane found from the steady profile) are the "
            "other remedy, not tried.")


def _section_steady(rows, figs, b5, b6, paper, walled=None) -> str:
    """The steady profile, the paper, the convergence and the speed. Text, hence its length."""
    steady = _steady_table(rows)
    orders = figs["orders"]
    order_text = ", ".join(f"{'walled' if f == WALLED else 'tiled'} {_sg(o)}"
                           for f, o in orders.items())
    at_1e6 = (f"; at 1e6 {b6.run_seconds:.0f} s ({b6.steps:,} steps) for "
              f"{_p(b6.max_err_over_dT)}" if b6 else "")
    return f"""
The steady profile says where the floor comes from (steady T minus the linear profile, % of ΔT,
{STEADY_BINS} bins from the cold to the hot held plane, computed by `slab_case` on the same
network). The calibration makes the heat flow exact, not the profile linear:

{steady}

So the cut (tiled) faces carry a boundary resistance that the single calibrated C_t cannot
absorb; at 1e5 and 1e6 it bends the steady profile by a few tenths of a per cent of ΔT, and the
transient error at the hot face (largest at the earliest time, where the face flux is largest) is
its transient counterpart. {_remedies(walled, b5)} Fitted orders
(max err / ΔT against N, log-log least squares): {order_text or '—'}
(walled: 2,000 → 10,000; tiled: 10,000 → 1e6, not a clean power law).

{paper}

![case 4 convergence with N](img/{figs['convergence']})

(data: `img/{Path(figs['convergence']).with_suffix('.csv').name}`; the fitted order is that of
max err / ΔT against N over each family, least squares in log-log.)
""" + (f"""
**Speed against error.** The thermal part is cheap next to the packing: at 1e5,
{b5.run_seconds:.0f} s of explicit stepping (one thread) for {_p(b5.max_err_over_dT)} of ΔT,
after {cell_cost_text()} of YADE for the cell{at_1e6}.
""" if b5 else "") + """
**Test.** `tests/test_validation_small.py` runs `slab_case` on the committed 400-sphere box
(`tests/data/dense_box.h5`) and asserts the errors measured there with a ~20 % margin (1.5 % of T
in °C, 5 % of ΔT) and the C_t conversion; `tdem validate 4 --quick` runs the same instance."""


def _columns(rows, b5, b6, falls) -> dict:
    """The summary's columns: our N, our error, the wall time and the verdict."""
    big = max(rows, key=lambda r: r.n_particles)
    head = b5 or big
    best = min(rows, key=lambda r: r.max_err_over_dT)
    our_error = (f"{_p(head.max_err_over_dT)} of ΔT ({_p(head.max_err_over_T_celsius)} of "
                 "T in °C)"
                 + (f"; at 1e6 {_p(b6.max_err_over_dT)} / {_p(b6.max_err_over_T_celsius)}"
                    if b6 else "")
                 + f"; lowest {_p(best.max_err_over_dT)} of ΔT ({best.label}, "
                   f"{best.n_particles:,})")
    verdict = ("goal ≤ 0.5 % " + ("met" if head.max_err_over_T_celsius <= 0.005 else "not met")
               + " in the paper's measure, "
               + ("met" if head.max_err_over_dT <= 0.005 else "not quite")
               + " in the stricter one"
               + ("; does not keep falling from 1e5 to 1e6 (one periodic cell, see case 4)"
                  if b5 and b6 and not falls else ""))
    return dict(
        our_n=f"{head.n_particles:,} (also {min(r.n_particles for r in rows):,} … "
              f"{big.n_particles:,})",
        our_error=our_error,
        wall_time=(f"{cell_cost_text()} CPU + {head.run_seconds:.0f} s (explicit, "
                   f"{head.steps:,} steps, 1 thread)"
                   + (f"; 1e6: + {b6.run_seconds:.0f} s" if b6 else "")),
        verdict=verdict)


def _judged_result(ctx: Context, rows: list[SlabRow]) -> CaseResult:
    """Figures, section and judged summary of ``rows``."""
    result = _result(rows, _figures(ctx, rows))
    return judged(result, judge(result.numbers))


def _rebuild(ctx: Context) -> None:
    """The section, figures and summary again from the saved rows (no slab is run)."""
    print(rebuild_saved(CASE, lambda numbers: _judged_result(ctx, read_rows(numbers))))


def _add_walled(ctx: Context) -> None:
    """Measure the walled 1e5 box (instance ds_1e5_s1; its packing built when missing, ~1-2 h
    of YADE) and rebuild the saved result with its row, the other rows kept as saved."""
    key, _label, _family, name, _default = next(i for i in INSTANCES if i[0] == "ds_1e5_s1")
    ctx.progress(f"{key}: slab on {name} ...")
    summary, profile = slab_case(ctx.packing(name), threads=ctx.threads)
    write_text_atomic(ctx.out / f"{key}.json", json.dumps(summary, indent=1))
    new = _row(key, summary, profile)

    def build(numbers):
        order = [i[0] for i in INSTANCES]
        return _judged_result(ctx, sorted([r for r in read_rows(numbers) if r.name != key]
                                          + [new], key=lambda r: order.index(r.name)))
    print(rebuild_saved(CASE, build))


ACTIONS = {"rebuild": Action(_rebuild, "section, figures and summary again from the saved "
                                       "result (no solve)"),
           "walled": Action(_add_walled, "measure the walled 1e5 YADE box (issue 24) and add "
                                         "its row to the saved result")}
