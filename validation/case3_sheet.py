"""Case 3 of docs/validation.md: Terreros's sheet heated by a moving source (000 sec. 5.2,
Tables 3-5), against our own continuum reference (tdem_post.continuum) at check-points A, B, C.

Sheet x in [0, 50], y in [-15, 15], z in [0, 2] mm, aluminium (lambda 134, rho 2790, c 880),
25 C initially, adiabatic everywhere; a cylindrical source of radius 4 mm through the whole
depth (2 mm), 1e11 W/m^3, its axis on y = 0, from x = 20 mm at 3.3 mm/s (Table 4). Check-points
(Table 5): A (9.5, -0.5), B (31.0, 0.0), C (41.5, -9.5) mm. The source spans the whole thickness
and every face is adiabatic, so the continuum field does not depend on z: the reference is the
2-D finite-volume solve (one cell through the thickness), refined three times with dt halved each
time (Crank-Nicolson, Rannacher start), its error estimated by Richardson extrapolation.

DEM: 1,000 / 5,000 / 20,000 spheres x 5 seeds (000: "five domains of each type"), sheets carved
from one 2,000-sphere periodic cell per seed (validation/packings_000.py) and scaled to
50 x 30 x 2 mm; law haddad with C_t calibrated in the plane of each sheet (steady flux tests along
x and y, held-plane length, mean of the two); the source as tdem runs it (`kind = "source"`: a
sphere whose centre is inside receives q x the continuum volume it represents,
thermal_kernel.boundaries.MovingSource). A check-point's DEM temperature is the mean over the
conducting spheres whose centre lies within 1 mm of it in the plane (the nearest one if none);
the reference there is the continuum interpolated at the same centres and averaged alike, so the
comparison is not blurred by the probe's size.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tdem_post import continuum as fv
from tdem_post.records import to_dict
from thermal_kernel.packing import read_packing
from thermal_kernel.run import run_in_memory

from . import framework as fw
from . import packings_000 as P
from .framework import CaseInfo, CaseResult, Context
from .framework import FIGURE_8, Judgement, dress, figure_csv, figure_md, fit_order, md_table, \
    numbers_reader

CASE = CaseInfo(number=3, title="sheet heated by a moving source",
                paper="000 sec. 5.2, Tables 3–5, Fig. 11–14", paper_n="1,000–20,000 × 5",
                paper_error="FEM comparison (Fig. 12–14); dispersion Fig. 11")

LAMBDA, RHO, CAP = 134.0, 2790.0, 880.0                    # 000 Table 3
RHO_C = RHO * CAP
T0 = 298.15                                                # 25 C
LX, LY, LZ = P.SHEET_SIZE_M
Y0 = -LY / 2                                               # the sheet spans y in [-15, 15] mm
Q, R_SRC, V_SRC, X_SRC = 1e11, 4e-3, 3.3e-3, 20e-3          # Table 4
POINTS = {"A": (9.5e-3, -0.5e-3), "B": (31.0e-3, 0.0), "C": (41.5e-3, -9.5e-3)}  # Table 5
T_END, T_OUT = 12.0, 0.05                                  # s: the source leaves at 10.3 s
PROBE_RADIUS = 1e-3
# continuum grids: cells of 1, 0.5 (the paper's FEM), 0.25, 0.125 mm with dt 0.05 ... 0.00625 s
GRIDS = ((50, 0.05), (100, 0.025), (200, 0.0125), (400, 0.00625))
QUICK_GRIDS = ((25, 0.05), (50, 0.025), (100, 0.0125))
QUICK_CELL = fw.DATA / "dense_periodic.h5"


def source_field(grid: fv.Grid, sub: int = 4):
    """q(t) on the grid: the disc's cell-averaged indicator times Q, evaluated only in the cells
    near the disc (its bounding box), sub x sub samples per cell."""
    h = grid.spacing
    xc_all, yc_all = grid.centres(0), grid.centres(1)
    offs = (np.arange(sub) + 0.5) / sub - 0.5

    def q(t):
        out = np.zeros(grid.shape)
        xs = X_SRC + V_SRC * t
        ix = np.flatnonzero(np.abs(xc_all - xs) <= R_SRC + h[0])
        iy = np.flatnonzero(np.abs(yc_all) <= R_SRC + h[1])
        if ix.size == 0 or iy.size == 0:
            return out
        X, Y = np.meshgrid(xc_all[ix], yc_all[iy], indexing="ij")
        acc = np.zeros(X.shape)
        for ox in offs:
            for oy in offs:
                acc += ((X + ox * h[0] - xs) ** 2 + (Y + oy * h[1]) ** 2) <= R_SRC ** 2
        out[np.ix_(ix, iy)] = (Q / sub ** 2 * acc)[:, :, None]
        return out
    return q


def continuum_reference(points_xy, grids=GRIDS, times=None):
    """The sheet on each grid of ``grids`` ((nx, dt): ny = 0.6 nx, one cell through the depth).
    Returns (times, list of (P, K) probe temperatures per grid, list of wall seconds, Richardson
    estimate over the last three grids)."""
    times = np.arange(1, int(round(T_END / T_OUT)) + 1) * T_OUT if times is None else times
    pts = np.column_stack([np.asarray(points_xy, float), np.full(len(points_xy), LZ / 2)])
    fields, secs = [], []
    for nx, dt in grids:
        g = fv.make_grid((0.0, Y0, 0.0), (LX, Y0 + LY, LZ), (nx, int(round(nx * LY / LX)), 1))
        t0 = time.perf_counter()
        res = fv.solve_transient(g, LAMBDA, RHO_C, {}, T0, times, dt, source=source_field(g),
                                 theta=0.5, source_points=2, probes=pts, fields=False)
        secs.append(time.perf_counter() - t0)
        ledger = np.max(np.abs(res.ledger_residual_j())) / np.max(res.stored_energy_j)
        assert ledger < 1e-9, ledger
        fields.append(res.probe_temperature.T)
    est = fv.richardson(fields[-3:], 2.0)
    return times, fields, secs, est


def source_energy_exact(t_end: float = T_END, samples: int = 20001) -> float:
    """Heat the continuum's source puts into the sheet over [0, t_end] (J): Q x depth x the
    time integral of the disc's area inside x <= LX (a circular segment once it reaches the
    edge; y is never cut), by the trapezoid rule on a fine time grid."""
    t = np.linspace(0.0, t_end, samples)
    d = np.clip(LX - (X_SRC + V_SRC * t), -R_SRC, R_SRC)     # centre to the edge
    area = R_SRC ** 2 * np.arccos(-d / R_SRC) + d * np.sqrt(R_SRC ** 2 - d ** 2)
    return float(Q * LZ * np.trapezoid(area, t))


def output_times(times=None) -> np.ndarray:
    """The run's output times (s): every T_OUT to T_END, or ``times``."""
    return np.arange(1, int(round(T_END / T_OUT)) + 1) * T_OUT if times is None else times


def scene_text(packing: str, ct: float, dt: float = 0.01, times=None) -> str:
    """The sheet's scene: Crank-Nicolson with a backward-Euler start (Rannacher) in steps of
    ``dt`` (s) to each output time (:func:`output_times`)."""
    return fw.scene_toml(
        packing, "haddad", law_params=dict(ct=ct),
        material=dict(conductivity=LAMBDA, density=RHO, heat_capacity=CAP),
        initial=dict(temperature=T0),
        boundary=[dict(kind="source", name="source", shape="cylinder", value=Q,
                       centre_m=[X_SRC, -Y0, LZ / 2], radius_m=R_SRC, depth_m=LZ,
                       axis=[0, 0, 1], velocity_m_s=[V_SRC, 0, 0])],
        solver=dict(method="implicit", end_time=T_END, dt=dt, scheme="rannacher",
                    output_times=[float(t) for t in output_times(times)]))


def load_sheet(packing_path):
    """The packing scaled to the 50 x 30 x 2 mm sheet (its box has the sheet's aspect)."""
    packing = read_packing(str(packing_path))
    size = packing.domain_hi - packing.domain_lo
    factor = LX / float(size[0])
    if not np.allclose(size * factor, P.SHEET_SIZE_M, rtol=1e-6):
        raise ValueError(f"{packing_path}: domain {size} does not have the sheet's aspect")
    return P.scaled(packing, factor)


def probe_sets(packing, conducting):
    """Indices of the spheres that make each check-point's temperature."""
    xy = packing.position[:, :2] - np.array([0.0, -Y0])
    sets = {}
    for name, (x, y) in POINTS.items():
        d = np.hypot(xy[:, 0] - x, xy[:, 1] - y)
        d = np.where(conducting, d, np.inf)
        near = np.flatnonzero(d <= PROBE_RADIUS)
        sets[name] = near if near.size else np.array([int(np.argmin(d))])
    return sets


@dataclass(frozen=True, kw_only=True)
class SheetRun:
    """One DEM sheet (:func:`sheet_dem`, kept in memory): C_t (held planes, the mean of x and
    y and each), the output times (s), each check-point's probe temperatures (K, per time),
    probe centres (m) and probe size, the source's heat (J), the ledger's residual over the
    stored heat, the steps and the seconds."""
    packing: str
    n_particles: int
    ct: float
    ct_xy: list
    times_s: object                     # (K,) array
    probe_t_k: dict                     # point -> (K,) array
    probe_xy_m: dict                    # point -> (n, 2) array
    probe_count: dict[str, int]
    source_energy_j: float
    ledger_relative: float
    steps: int
    calibration_seconds: float
    run_seconds: float
    mean_radius_m: float


@dataclass(frozen=True, kw_only=True)
class PointCompare:
    """One sheet at one check-point against the continuum: the reference history (K), the
    error (K), the reference's peak rise (K) and the max |error| over it."""
    ref: object
    error: object
    rise: float
    max_error_over_rise: float


def sheet_dem(packing_path, dt: float = 0.01, times=None) -> SheetRun:
    """One DEM sheet: calibrate C_t in the plane, run the moving source, probe A, B, C."""
    packing_path = str(Path(packing_path).resolve())
    packing = load_sheet(packing_path)
    where = Path("validation/case3_scene.toml")
    c0 = time.perf_counter()
    scene = fw.case_scene(scene_text(packing_path, 0.806, dt, times), where)
    cts = [fw.held_plane_ct(scene, packing, axis, 0.806, LAMBDA)[2] for axis in "xy"]
    ct = float(np.mean(cts))
    scene = fw.case_scene(scene_text(packing_path, ct, dt, times), where)
    calib_s = time.perf_counter() - c0
    times = output_times(times)
    r0 = time.perf_counter()
    run = run_in_memory(scene, packing)
    res = run.result
    run_s = res.wall_seconds                # the solver's; the network's build is set up
    calib_s += time.perf_counter() - r0 - run_s
    sets = probe_sets(packing, run.conducting)
    probe_t = {k: res.temperature_k[:, v].mean(axis=1) for k, v in sets.items()}
    xy = {k: packing.position[v, :2] + np.array([0.0, Y0]) for k, v in sets.items()}
    ledger = float(np.max(np.abs(res.ledger_residual_j())) / np.max(np.abs(res.stored_energy_j)))
    return SheetRun(packing=packing_path, n_particles=int(packing.n_particles), ct=ct,
                    ct_xy=cts, times_s=times, probe_t_k=probe_t, probe_xy_m=xy,
                    probe_count={k: int(v.size) for k, v in sets.items()},
                    source_energy_j=float(res.source_energy_j[-1]), ledger_relative=ledger,
                    steps=int(res.steps), calibration_seconds=calib_s, run_seconds=run_s,
                    mean_radius_m=float(packing.radius.mean()))


def compare(dem: SheetRun, times, ref_fields, point_index) -> dict[str, PointCompare]:
    """Reference at each check-point (the continuum averaged over the DEM probe's centres) and
    errors relative to the reference's peak rise there."""
    out = {}
    for name in POINTS:
        idx = point_index[(dem.packing, name)]
        ref = ref_fields[idx].mean(axis=0)                  # (K,)
        rise = float(np.max(ref - T0))
        err = dem.probe_t_k[name] - ref
        out[name] = PointCompare(ref=ref, error=err, rise=rise,
                                 max_error_over_rise=float(np.max(np.abs(err)) / rise))
    return out


# ---------------------------------------------------------------------------- the case
@dataclass(frozen=True, kw_only=True)
class PointError:
    """The DEM against the continuum at one check-point, over the seeds of one N: errors and
    dispersion are fractions of the point's peak rise, the rise in K."""
    err_mean_of_seeds: float        # mean over the seeds of each seed's max |error|
    err_max: float                  # the worst seed's
    err_of_seed_mean: float         # of the seeds' mean history
    dispersion: float               # the seeds' standard deviation, time mean
    rise_k: float


@dataclass(frozen=True, kw_only=True)
class SheetRow:
    """One N of the case (means over its seeds): the three check-points of 000 Table 5, the
    source's energy against the exact one, the thermal seconds of a seed."""
    n: float                        # mean number of spheres
    A: PointError
    B: PointError
    C: PointError
    source_energy_ratio: float
    source_energy_ratio_range: tuple[float, ...]        # (min, max) over the seeds
    seconds: float                  # calibration + run, mean over the seeds

    def at(self, point: str) -> PointError:
        return getattr(self, point)


@dataclass(frozen=True, kw_only=True)
class SheetResult:
    """Case 3's saved ``numbers``: a row per N, the convergence rows (N, the error at A, B, C,
    their dispersion, seconds) and order, the continuum's own convergence (fractions of the
    rise at A, B, C; seconds per grid), the DEM's time-step error, the rises (K) and C_t."""
    table: tuple[SheetRow, ...]
    convergence: tuple[tuple[float, ...], ...]
    order: float
    continuum_richardson_over_rise: tuple[float, ...]
    continuum_order: float
    continuum_seconds: tuple[float, ...]
    continuum_grid_vs_finest: tuple[tuple[float, ...], ...]
    dem_dt_error: dict[str, float]
    rise_k: tuple[float, ...]
    ct: tuple[float, ...]
    worst_error_largest_n: float


read_numbers = numbers_reader(SheetResult, 3)


def judge(numbers: dict) -> Judgement:
    """Issue 23's columns: 000 compares with FEM by figure only (Fig. 12–14), so the stricter
    reading is used: the worst seed's error at A, B, C (% of the peak rise) at the paper's
    largest N (20,000), the mean over seeds beside it. No numeric target."""
    if not numbers.get("table"):
        return Judgement("not measured", "", None)
    m = read_numbers(numbers)
    top = max(m.table, key=lambda r: r.n)
    pts = list(POINTS)
    at = (f"N {int(top.n):,}: worst seed " + " / ".join(
        f"{k} {100 * top.at(k).err_max:.2f}" for k in pts) + " % of the peak rise (mean of 5 "
          "seeds " + " / ".join(f"{100 * top.at(k).err_mean_of_seeds:.2f}" for k in pts) + " %)")
    conv = m.convergence
    speed = (f"error ∝ N^{m.order:.2f}; thermal {conv[-1][-1]:.0f} s a seed at "
             f"{int(conv[-1][0]):,}" if conv else "")
    verdict = ("no number in the paper to meet (FEM by figure); the worst seed within "
               f"{100 * max(top.at(k).err_max for k in pts):.1f} % of the peak rise at the "
               "paper's largest N, against a continuum converged to 0.01 %")
    return Judgement(at_paper_n=at, speed_vs_error=speed, target_met=None, verdict=verdict)


def run(ctx: Context) -> CaseResult:
    pack_s = 0.0
    if ctx.quick:
        name = "sheet_quick_1000"
        fw.register_packing(name, "runs/dense_box.toml", dict(
            shape="box", aspect=[25.0, 15.0, 1.0], n_particles=1000, method="tiled",
            cell_particles=400, cell_packing=str(QUICK_CELL), seed=1))
        sizes = {1000: [str(fw.packing(name))]}
        seeds, grids = [1], QUICK_GRIDS
    else:
        P.register()
        sizes = {}
        for n in P.SHEET_NS:
            sizes[n] = []
            for s in P.SEEDS:
                name = P.sheet_name(n, s)
                ctx.progress(f"packing {name}")
                sizes[n].append(P.build(name))
                pack_s += fw.pack_seconds(name) or 0.0
        seeds, grids = list(P.SEEDS), GRIDS
    dems = {}
    for n, paths in sizes.items():
        for s, path in zip(seeds, paths):
            d = sheet_dem(path)
            dems[(n, s)] = d
            ctx.progress(f"N {d.n_particles} seed {s}: C_t {d.ct:.4f}, "
                         f"{d.run_seconds:.1f} s")
    # dt check of the DEM: the first sheet of the largest N at dt / 2
    big = max(sizes)
    dt_check = sheet_dem(sizes[big][0], dt=0.005)
    # the continuum at the check-points and at every probe sphere's centre
    pts, point_index = [np.array(v) for v in POINTS.values()], {}
    for d in list(dems.values()) + [dt_check]:
        for name in POINTS:
            start = sum(len(p) if p.ndim == 2 else 1 for p in pts)
            pts.append(d.probe_xy_m[name])
            point_index[(d.packing, name)] = np.arange(start, start + len(d.probe_xy_m[name]))
    allpts = np.vstack([np.atleast_2d(p) for p in pts])
    ctx.progress(f"continuum reference at {len(allpts)} points on {len(grids)} grids")
    times, fields, cont_s, est = continuum_reference(allpts, grids)
    ref = fields[-1]
    return _report(ctx, sizes, seeds, dems, dt_check, times, fields, cont_s, est, ref,
                   point_index, grids, pack_s)


def _rows_by_n(sizes, seeds, dems, cmp, names):
    """Per N (means over the seeds): each point's errors, dispersion and rise, the source's
    energy against the exact, the seconds; (the rows, the convergence rows)."""
    table, conv = [], []
    exact = source_energy_exact()
    for n in sizes:
        points = {}
        for p in names:
            errs = [cmp[(n, s)][p].max_error_over_rise for s in seeds]
            temps = np.array([dems[(n, s)].probe_t_k[p] for s in seeds])   # (seeds, K)
            refs = np.array([cmp[(n, s)][p].ref for s in seeds])
            rise = float(np.mean([cmp[(n, s)][p].rise for s in seeds]))
            mean_err = float(np.max(np.abs(temps.mean(axis=0) - refs.mean(axis=0))) / rise)
            disp = float(np.mean(temps.std(axis=0, ddof=1)) / rise) if len(seeds) > 1 else 0.0
            points[p] = PointError(err_mean_of_seeds=float(np.mean(errs)),
                                   err_max=float(np.max(errs)), err_of_seed_mean=mean_err,
                                   dispersion=disp, rise_k=rise)
        energy = [dems[(n, s)].source_energy_j for s in seeds]
        row = SheetRow(
            n=float(np.mean([dems[(n, s)].n_particles for s in seeds])), **points,
            source_energy_ratio=float(np.mean(energy)) / exact,
            source_energy_ratio_range=(float(min(energy) / exact), float(max(energy) / exact)),
            seconds=float(np.mean([dems[(n, s)].run_seconds
                                   + dems[(n, s)].calibration_seconds for s in seeds])))
        table.append(row)
        conv.append((row.n, *[row.at(p).err_mean_of_seeds for p in names],
                     *[row.at(p).dispersion for p in names], row.seconds))
    return table, conv


def _figure_history(ctx, times, ref, sizes, seeds, dems, names):
    """Figure 1: T(t) at A, B, C (000 Fig. 12-14), the continuum and the DEM's seed means per
    N; its file."""
    rows = []
    for k, t in enumerate(times):
        r = [float(t)] + [float(ref[i, k]) for i in range(3)]
        for n in sizes:
            r += [float(np.mean([dems[(n, s)].probe_t_k[p][k] for s in seeds])) for p in names]
        rows.append(tuple(r))
    f_t = ctx.figure("history")
    with figure_csv(f_t, ["t_s"] + [f"ref_{p}_K" for p in names]
                    + [f"dem{n}_{p}_K" for n in sizes for p in names], **FIGURE_8) as (ax, csv):
        for i, p in enumerate(names):
            line, = ax.plot(times, ref[i] - 273.15, lw=1.2, label=f"{p}: continuum")
            for j, n in enumerate(sizes):
                ax.plot(times, np.mean([dems[(n, s)].probe_t_k[p] for s in seeds], axis=0)
                        - 273.15, ls=(":", "--", "-.")[j % 3], color=line.get_color(), lw=0.9,
                        label=f"{p}: DEM {n:,}" if i == 0 or j == len(sizes) - 1 else None)
        dress(ax, "t (s)", "T (°C)", legend=6, ncol=2)
        csv += rows
    return f_t


def _figure_convergence(ctx, conv, order, const, names):
    """Figure 2: error and dispersion against N (000 Fig. 11); its file."""
    f_conv = ctx.figure("convergence")
    with figure_csv(f_conv, ["n_mean"] + [f"err_{p}" for p in names]
                    + [f"dispersion_{p}" for p in names] + ["thermal_seconds"],
                    **FIGURE_8) as (ax, csv):
        for i, p in enumerate(names):
            line, = ax.loglog(conv[:, 0], 100 * conv[:, 1 + i], "o-", label=f"{p}: error")
            ax.loglog(conv[:, 0], 100 * conv[:, 4 + i], "s--", color=line.get_color(),
                      label=f"{p}: dispersion")
        if np.isfinite(order):
            ax.loglog(conv[:, 0], 100 * const * conv[:, 0] ** order, "k:", lw=0.8,
                      label=f"worst error fit N^{order:.2f}")
        dress(ax, "N", "% of the peak rise at the point", legend=6, ncol=2)
        csv += [tuple(float(v) for v in r) for r in conv]
    return f_conv


def _figure_speed(ctx, conv, worst, cont_s, fields, est, rise_pt, grids):
    """Figure 3: speed against error, the DEM per N and the continuum per grid against its
    Richardson limit; its file."""
    cont_err = [float(max(np.max(np.abs(f[i] - est.extrapolated[i])) / rise_pt[i]
                          for i in range(3))) for f in fields]
    f_speed = ctx.figure("speed")
    with figure_csv(f_speed, "kind,n_or_cells,seconds,error", **FIGURE_8) as (ax, csv):
        ax.loglog(conv[:, -1], 100 * worst, "o-", label="DEM (worst of A, B, C; mean of seeds)")
        ax.loglog(cont_s, 100 * np.array(cont_err), "s-",
                  label="continuum FV vs its Richardson limit")
        dress(ax, "wall time (s, one thread)", "error (% of the peak rise)")
        csv += [("dem", float(c[0]), float(c[-1]), float(w)) for c, w in zip(conv, worst)]
        csv += [("continuum", float(g[0] * round(g[0] * LY / LX)), float(s), float(e))
                for g, s, e in zip(grids, cont_s, cont_err)]
    return f_speed


def _report(ctx, sizes, seeds, dems, dt_check, times, fields, cont_s, est, ref, point_index,
            grids, pack_s) -> CaseResult:
    """The rows per N (:func:`_rows_by_n`), the three figures, the section
    (:func:`_section_setup`, :func:`_section_results`) and the summary's columns."""
    names = list(POINTS)
    # continuum convergence at the check-points themselves (rows 0..2)
    rise_pt = np.array([np.max(ref[i] - T0) for i in range(3)])
    rich_pt = np.array([np.max(est.error[i]) for i in range(3)]) / rise_pt
    grid_diff = [[float(np.max(np.abs(f[i] - ref[i])) / rise_pt[i]) for i in range(3)]
                 for f in fields[:-1]]
    cmp = {k: compare(d, times, ref, point_index) for k, d in dems.items()}
    big = max(sizes)
    dt_err = {p: float(np.max(np.abs(dt_check.probe_t_k[p] - dems[(big, seeds[0])].probe_t_k[p]))
                       / cmp[(big, seeds[0])][p].rise) for p in names}
    table, conv = _rows_by_n(sizes, seeds, dems, cmp, names)
    conv = np.array(conv)
    worst = conv[:, 1:4].max(axis=1)
    order, const = fit_order(conv[:, 0], worst) if len(conv) > 1 else (float("nan"),) * 2

    f_t = _figure_history(ctx, times, ref, sizes, seeds, dems, names)
    f_conv = _figure_convergence(ctx, conv, order, const, names)
    f_speed = _figure_speed(ctx, conv, worst, cont_s, fields, est, rise_pt, grids)

    last = table[-1]
    worst_big = max(last.at(p).err_mean_of_seeds for p in names)
    cts = [d.ct for d in dems.values()]
    section = (_section_setup(rise_pt, grids, est, rich_pt, grid_diff, cts, dt_err)
               + _section_results(table, names, order, (f_t, f_conv, f_speed)))
    numbers = to_dict(SheetResult(
        table=tuple(table), convergence=tuple(tuple(c) for c in conv.tolist()), order=order,
        continuum_richardson_over_rise=tuple(rich_pt.tolist()),
        continuum_order=float(est.order), continuum_seconds=tuple(cont_s),
        continuum_grid_vs_finest=tuple(tuple(g) for g in grid_diff), dem_dt_error=dt_err,
        rise_k=tuple(rise_pt.tolist()), ct=tuple(cts), worst_error_largest_n=worst_big))
    thermal_s = sum(d.run_seconds + d.calibration_seconds for d in dems.values())
    return CaseResult(
        our_n=" / ".join(f"{row.n:,.0f}" for row in table) + f" × {len(seeds)} seeds",
        our_error=f"at {table[-1].n:,.0f}: A {100 * last.A.err_mean_of_seeds:.1f} %, "
                  f"B {100 * last.B.err_mean_of_seeds:.1f} %, C "
                  f"{100 * last.C.err_mean_of_seeds:.1f} % of the peak rise (vs our "
                  f"continuum, converged to {100 * rich_pt.max():.2f} %); dispersion "
                  + " / ".join(f"{100 * last.at(p).dispersion:.1f} %" for p in names),
        wall_time=f"{pack_s:.0f} s (carving; the cells are case 2's) + {thermal_s:.0f} s "
                  f"(continuum {sum(cont_s):.0f} s)",
        verdict=f"error falls as N^{order:.2f}; continuum reference converged",
        section_md=section, numbers=numbers, command="")


def _section_setup(rise_pt, grids, est, rich_pt, grid_diff, cts, dt_err) -> str:
    """The section's first half: the setup, the continuum reference and its convergence, the
    DEM's sheets, law, source and time step. Text, hence its length."""
    return f"""\
Setup (000 sec. 5.2, Tables 3–5): sheet 50 × 30 × 2 mm (x in [0, 50], y in [−15, 15] mm),
aluminium (λ 134 W/m/K, ρ 2790 kg/m³, c 880 J/kg/K), 25 °C initially, adiabatic everywhere; a
cylindrical source of radius 4 mm through the whole 2 mm depth, 1e11 W/m³ (10.05 kW), its axis on
y = 0 moving from x = 20 mm at 3.3 mm/s (it leaves the sheet at t = 10.3 s; we run to {T_END:g} s,
output every {T_OUT:g} s — the paper's time axis is not in our text copy). Check-points (Table 5):
A (9.5, −0.5), B (31, 0), C (41.5, −9.5) mm. Peak rises of the reference: A {rise_pt[0]:.0f} K,
B {rise_pt[1]:.0f} K, C {rise_pt[2]:.0f} K (the paper notes the sheet would melt).

**Continuum reference** (`tdem_post/continuum.py`, tested in `tests/test_continuum.py`): the
source spans the thickness and all faces are adiabatic, so T does not depend on z and one cell
through the depth is exact. Finite volumes, cells of \
{', '.join(f'{1e3 * LX / g[0]:g}' for g in grids)} mm
(the paper's FEM: 0.5 mm) with dt = {', '.join(f'{g[1]:g}' for g in grids)} s (Crank–Nicolson,
Rannacher start; the source's disc sampled 4 × 4 per cell and integrated over each step at two
Gauss points). Observed order from the three finest: {float(est.order):.2f}; Richardson error of
the finest at A, B, C: \
**{100 * rich_pt[0]:.3f} / {100 * rich_pt[1]:.3f} / {100 * rich_pt[2]:.3f} %**
of the peak rise (the finest grid is converged to {100 * rich_pt.max():.3f} %); the paper's 0.5 mm
grid differs from the finest by \
{100 * max(grid_diff[1] if len(grid_diff) > 1 else grid_diff[0]):.2f} %.
Energy ledger exact to round-off on every grid.

**DEM.** Sheets of 1,000 / 5,000 / 20,000 spheres × 5 seeds carved from one 2,000-sphere periodic
cell per seed (`validation/packings_000.py`, the material of cases 4 and 6: Gaussian radii σ/μ
0.3, 1 bar) and scaled to the sheet (1,000 spheres: ~1.3 diameters through the 2 mm; 20,000:
~3.5). Law `haddad` with C_t calibrated in the plane of each sheet (flux tests along x and y,
held-plane length, mean: C_t {min(cts):.3f}–{max(cts):.3f}); the source is tdem's `kind = "source"`
(a sphere whose centre is inside receives q × the continuum volume it represents,
C_i/(ρc); `thermal_kernel/boundaries/source.py` `MovingSource`, its energy ledger tested in
`tests/test_solvers.py` and against this continuum in `tests/test_validation_case2_3.py`).
Implicit run (Rannacher CN, dt 0.01 s; at dt 0.005 s the probes move by at most
{100 * max(dt_err.values()):.3f} % of the rise). A check-point's DEM temperature: the mean over
the conducting spheres within 1 mm of it in the plane; the reference: the continuum at the same
centres, averaged alike.

"""


def _section_results(table, names, order, figures) -> str:
    """The section's second half: the errors and dispersion per N (a table), the figures, the
    convergence, the source's energy, the errors in kelvin, speed against error and what limits
    us. Text, hence its length."""
    f_t, f_conv, f_speed = figures
    src_txt = "; ".join(f"{row.n:,.0f} spheres {row.source_energy_ratio:.4f} (seeds "
                        f"{row.source_energy_ratio_range[0]:.4f}–"
                        f"{row.source_energy_ratio_range[1]:.4f})" for row in table)
    tab = md_table(
        ["N (mean)"] + [f"{p}: {what}" for p in names for what in (
            "error (mean / max of seeds)", "error of the seed mean", "dispersion")]
        + ["thermal s"],
        [[f"{row.n:,.0f}"] + [cell for p in names for cell in (
            f"{100 * row.at(p).err_mean_of_seeds:.2f} / {100 * row.at(p).err_max:.2f} %",
            f"{100 * row.at(p).err_of_seed_mean:.2f} %", f"{100 * row.at(p).dispersion:.2f} %")]
         + [f"{row.seconds:.1f}"] for row in table])
    last = table[-1]
    return f"""\
**Errors** (max over time of |T_DEM − T_ref| / the reference's peak rise at the point) and
**dispersion** (Fig. 11: the standard deviation over the 5 seeds, averaged over time, / the peak
rise):

{tab}

{figure_md("case 3 temperature histories at A, B, C", f_t)}

**Convergence with N** (error, mean of the seeds, and dispersion): the worst of A, B, C falls as
N^{order:.2f}.

{figure_md("case 3 error and dispersion against N", f_conv)}

The heat the DEM's source puts in (spheres whose centre is inside the disc receive q × their
represented volume) against the disc's exact {source_energy_exact() / 1e3:.1f} kJ: {src_txt} —
at 1,000 spheres this sampling of the source is itself an error of a few %, which shows at late
times as the offset of the whole history (A and B, Fig. above).

The peak rises are large (the 10 kW source heats the whole adiabatic sheet by ~12,000 K by the
end), so in kelvin the errors at {last.n:,.0f} spheres are A \
{last.A.err_mean_of_seeds * last.A.rise_k:.0f} K,
B {last.B.err_mean_of_seeds * last.B.rise_k:.0f} K, C \
{last.C.err_mean_of_seeds * last.C.rise_k:.0f} K (means of the seeds); B, on the \
source's path,
is the hardest point (the disc passes over it, and its neighbourhood is sampled by the spheres the
disc switches on and off).

**Speed against error.** The DEM at N spheres against the continuum grid at the same wall time
(thermal runs only, one thread, a shared machine): for this pure-conduction problem a grid is
cheaper at equal error by one to two orders of magnitude — the DEM's reason to exist is the
mechanics it shares its particles with (000 sec. 1), not the conduction alone:

{figure_md("case 3 speed against error", f_speed)}

**What limits us.** The paper's N is small for this sheet: at 1,000 spheres the sheet is ~1.3
sphere diameters thick and the 4 mm source covers a few dozen spheres, so whether a sphere's
centre is inside the moving disc switches its whole power on and off (a sampling of the source
at the sphere scale), and a check-point's temperature is that of one or two spheres. Both fall
with N; at 20,000 the sphere size (mean radius ~0.28 mm) is still comparable to the paper's FEM
cell (0.5 mm).
"""
