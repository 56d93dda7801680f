"""Benchmark of the dense packing paths (issue: packings at scale). Measures, does not assert.

    .venv/bin/python bench/bench_packings.py [--cases CASES] [--reuse]

Each case builds a dense box (runs/dense_box.toml's [pack]: Gaussian radii sigma/mean 0.3, 1 bar,
steel, gap_tolerance 0.1) with one path at one N and seed by running ``tdem pack`` as a separate
process, and records its whole-process wall time, the peak resident memory of the process tree
(YADE included), the DEM steps of the relaxation and the comparison statistics of
``tdem_post/packing_compare.py`` (bulk phi, Z of the non-rattlers, Z with gaps, rattlers,
fabric, RDF) plus the steady gamma = k_eff/k_p of the force-based ``pipe`` law in a flux test along
x. Results go to bench/results/packings.csv and packings.md (quoted by docs/packings.md) and
the RDF figure packings_rdf.png. With --reuse a case whose packing exists is not built again (its
time and memory are read from the case's bench.json): the benchmark resumes case by case.

Paths:
  reference  method direct, time_step p_wave (the generator before 2026-11: 0.5 x the P-wave
             step of the smallest sphere)
  ds         method direct, time_step density_scaling (YADE's GlobalStiffnessTimeStepper with
             per-sphere density scaling)
  tiled      method tiled: a periodic cell of cell_particles spheres relaxed with density
             scaling, copied side by side and carved to the box
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from thermal_kernel.atomic import savefig_atomic, write_text_atomic  # noqa: E402
from tdem_post.packing_compare import as_row, packing_stats, rdf_distance  # noqa: E402
from thermal_kernel.packing import read_packing  # noqa: E402

OUT = ROOT / "bench" / "out" / "packings"
RESULTS = ROOT / "bench" / "results"
# one small JSON per measured case (its table row and RDF), committed: the tables are rebuilt
# from them, so a case measured once (the reference takes ~1 h per seed) need not be rebuilt on a
# new machine, where bench/out/ (the packings, gitignored) is empty
CASES_DIR = RESULTS / "packings_cases"
BASE_SCENES = {shape: ROOT / "runs" / f"dense_{shape}.toml"
               for shape in ("box", "cylinder", "sphere")}

PATHS = {
    "reference": dict(method="direct", time_step="p_wave"),
    "ds": dict(method="direct", time_step="density_scaling"),
    "tiled": dict(method="tiled", time_step="density_scaling"),
}


def parse_case(text: str) -> dict:
    """'path:N:seed[:cell[:shape]]' -> case dict (shape: box, cylinder or sphere; the
    cylinder and the sphere take runs/dense_cylinder.toml / dense_sphere.toml's [pack])."""
    parts = text.split(":")
    path, n, seed = parts[0], int(float(parts[1])), int(parts[2])
    cell = int(float(parts[3])) if len(parts) > 3 and parts[3] else None
    shape = parts[4] if len(parts) > 4 else "box"
    if path not in PATHS:
        raise SystemExit(f"bench_packings: unknown path {path!r} (known: {', '.join(PATHS)})")
    if shape not in BASE_SCENES:
        raise SystemExit(f"bench_packings: unknown shape {shape!r} "
                         f"(known: {', '.join(BASE_SCENES)})")
    label = (f"{path}_{n}_s{seed}" + (f"_c{cell}" if cell else "")
             + ("" if shape == "box" else f"_{shape}"))
    return dict(path=path, n=n, seed=seed, cell=cell, shape=shape, label=label)


DEFAULT_CASES = (
    [f"reference:2000:{s}" for s in (1, 2, 3)] + [f"ds:2000:{s}" for s in (1, 2, 3)]
    + [f"reference:10000:{s}" for s in (1, 2, 3)] + [f"ds:10000:{s}" for s in (1, 2, 3)]
    + [f"tiled:10000:{s}:2000" for s in (1, 2, 3)]
    # the walled curved containers against the box (the "same as the box +- 50 %")
    + [f"ds:2000:{s}::{shape}" for shape in ("cylinder", "sphere") for s in (1, 2, 3)]
    + ["tiled:100000:1:10000", "tiled:1000000:1:10000", "tiled:8000000:1:10000",
       "tiled:100000:1:10000:cylinder", "tiled:100000:1:10000:sphere"]
)


def scene_text(case: dict, cell_packing: Path | None = None) -> str:
    """runs/dense_<shape>.toml with the case's [pack] values."""
    text = BASE_SCENES[case["shape"]].read_text()
    extra = dict(PATHS[case["path"]], n_particles=case["n"], seed=case["seed"],
                 max_seconds=14400.0)
    if case["cell"]:
        extra["cell_particles"] = case["cell"]
    if cell_packing is not None:
        extra["cell_packing"] = str(cell_packing)
    lines = []
    in_pack = False
    for line in text.splitlines():
        if line.startswith("["):
            in_pack = line.strip() == "[pack]"
            lines.append(line)
            if in_pack:
                lines += [f"{k} = {json.dumps(v)}" for k, v in extra.items()]
            continue
        if in_pack and line.split("=")[0].strip() in extra:
            continue
        lines.append(line)
    return "\n".join(lines) + "\n"


def reusable_cell(case: dict, cell_dirs: list[Path]) -> Path | None:
    """A cell.h5 (written by an earlier tiled run) of this case's seed and cell size."""
    if case["path"] != "tiled":
        return None
    import h5py
    for d in cell_dirs:
        path = Path(d) / "cell.h5"
        if path.exists():
            with h5py.File(path, "r") as f:
                if int(f.attrs["seed"]) == case["seed"] and \
                        len(f["particles/radius"]) == case["cell"]:
                    return path.resolve()
    return None


def build(case: dict, reuse: bool, cell_dirs: list[Path]) -> dict:
    """Run tdem pack for one case (or reuse it); return its timing record. A tiled case whose
    cell was relaxed by an earlier run copies that cell (cell_packing); its relaxation time is
    then recorded as ``cell_reused_seconds`` and counted in the path's total."""
    folder = OUT / case["label"]
    record_path = folder / "bench.json"
    if reuse and record_path.exists() and (folder / "packing.h5").exists():
        return json.loads(record_path.read_text())
    folder.mkdir(parents=True, exist_ok=True)
    scene = folder / "scene.toml"
    cell = reusable_cell(case, cell_dirs)
    write_text_atomic(scene, scene_text(case, cell))
    cmd = [str(ROOT / ".venv" / "bin" / "tdem"), "pack", str(scene), "--out", str(folder),
           "--quiet"]
    # /usr/bin/time reports the peak RSS and CPU of the tdem pack process tree (YADE
    # included); the rusage of a child forked straight from this process would start with this
    # process's own (large) resident pages.
    timing = folder / "time.txt"
    cmd = ["/usr/bin/time", "-f", "%M %U %S", "-o", str(timing)] + cmd
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    output, _ = proc.communicate()
    wall = time.perf_counter() - start
    status = proc.returncode
    write_text_atomic(folder / "tdem_pack.log", output)
    if status != 0:
        raise SystemExit(f"bench_packings: {case['label']} failed: "
                         f"{output.strip().splitlines()[-1]}")
    max_kb, user_s, sys_s = (float(x) for x in timing.read_text().split()[-3:])
    record = dict(case, wall_seconds=wall, peak_rss_mb=max_kb / 1024.0,
                  cpu_seconds=user_s + sys_s,
                  load_at_start=os.getloadavg()[0], cell_packing=str(cell or ""),
                  cell_reused_seconds=0.0)
    if cell is not None:
        import h5py
        with h5py.File(cell, "r") as f:
            record["cell_reused_seconds"] = float(f.attrs["compression_seconds"])
            record["cell_reused_steps"] = int(f.attrs.get("compression_steps", 0))
        record["cell_reused_cpu_seconds"] = float(json.loads(
            (cell.parent / "cell_cpu.json").read_text())["cpu_seconds"]) \
            if (cell.parent / "cell_cpu.json").exists() else record["cell_reused_seconds"]
    write_text_atomic(record_path, json.dumps(record, indent=1))
    return record


def pipe_gamma(packing_path: Path, shape: str) -> tuple[float, float]:
    """Steady gamma = k_eff/k_p of the pipe law (003 eq. 40; force-based) on the packing, flux
    test along x between the two x faces (thermal_kernel/calibrate.flux_test)."""
    from thermal_kernel.calibrate import flux_test
    from thermal_kernel.scene import load_scene
    scene_path = packing_path.parent / "pipe_scene.toml"
    write_text_atomic(
        scene_path,
        'packing = "packing.h5"\nlaw = "pipe"\n[material]\nconductivity = 33.0\ndensity = 7800.0\n'
        'heat_capacity = 460.0\nyoung_pa = 2.1e11\npoisson = 0.3\n[initial]\n'
        'temperature = 0.5\n[solver]\nmethod = "steady"\n')
    scene = load_scene(scene_path)
    if shape == "sphere":
        return float("nan"), float("nan")     # no two opposite faces
    from thermal_kernel.problem import boundary_particles
    packing = read_packing(packing_path)
    axis = "z" if shape == "cylinder" else "x"
    test = flux_test(scene, packing, axis)
    # the slab between the mean centre planes of the two held sets (where the Dirichlet
    # condition acts; tdem post's convention) instead of the domain length
    k = "xyz".index(axis)
    hot = boundary_particles(scene, packing, f"{axis}min", "hot")
    cold = boundary_particles(scene, packing, f"{axis}max", "cold")
    held_length = float(packing.position[cold, k].mean() - packing.position[hot, k].mean())
    gamma = test.effective_w_mk / 33.0
    return gamma, gamma * held_length / test.length_m


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="*", default=DEFAULT_CASES,
                        help="path:N:seed[:cell_particles], e.g. tiled:100000:1:10000")
    parser.add_argument("--reuse", action="store_true",
                        help="do not rebuild a case whose packing and bench.json exist")
    parser.add_argument("--skip-build", action="store_true",
                        help="only tabulate the cases already built")
    parser.add_argument("--cell-from", nargs="*", default=[str(ROOT / "runs" / "out" /
                                                               "dense_box_1e5")],
                        help="folders with a cell.h5 that tiled cases of the same seed and cell "
                             "size copy instead of relaxing a new cell (default: the one of "
                             "runs/dense_box_1e5.toml)")
    args = parser.parse_args(argv)
    for text in args.cases:
        case = parse_case(text)
        folder = OUT / case["label"]
        if args.skip_build and not (folder / "bench.json").exists():
            continue
        if args.reuse and not (folder / "packing.h5").exists() and \
                (CASES_DIR / f"{case['label']}.json").exists():
            print(f"bench_packings: {case['label']} measured before "
                  f"({CASES_DIR.name}/{case['label']}.json)", flush=True)
            continue
        print(f"bench_packings: {case['label']} ...", flush=True)
        record = build(case, reuse=args.reuse or args.skip_build,
                       cell_dirs=[Path(d) for d in args.cell_from])
        packing = read_packing(folder / "packing.h5")
        st = packing_stats(packing)
        row = dict(label=case["label"], path=case["path"], shape=case["shape"],
                   n_target=case["n"],
                   seed=case["seed"], cell_particles=case["cell"] or 0,
                   wall_seconds=record["wall_seconds"] + record.get("cell_reused_seconds", 0.0),
                   cell_reused_seconds=record.get("cell_reused_seconds", 0.0),
                   cpu_seconds=record.get("cpu_seconds", float("nan"))
                   + record.get("cell_reused_cpu_seconds", 0.0),
                   peak_rss_mb=record["peak_rss_mb"],
                   compression_steps=int(packing.attrs.get("compression_steps",
                                                           record.get("compression_steps", -1)))
                   + int(record.get("cell_reused_steps", 0)),
                   **as_row(st))
        row["gamma_pipe"], row["gamma_pipe_held"] = \
            pipe_gamma(folder / "packing.h5", case["shape"]) if st.n_particles <= 2_000_000 \
            else (float("nan"), float("nan"))
        save_case(row, st)
        print(f"  {row['n_particles']} spheres, {row['wall_seconds']:.0f} s, "
              f"{row['peak_rss_mb']:.0f} MB, phi_bulk {row['solid_fraction_bulk']:.4f}, "
              f"Z_nr {row['z_nonrattler']:.3f}, Z_gaps {row['z_with_gaps']:.3f}, rattlers "
              f"{100 * row['rattler_fraction']:.1f} %, gamma_pipe {row['gamma_pipe']:.4g}",
              flush=True)
    rows, stats = load_cases()
    if not rows:
        return 0
    import pandas as pd
    table = pd.DataFrame(rows)
    RESULTS.mkdir(parents=True, exist_ok=True)
    write_text_atomic(RESULTS / "packings.csv", table.to_csv(index=False))
    write_text_atomic(RESULTS / "packings.md", summary_markdown(table, stats))
    plot_rdf(stats, RESULTS / "packings_rdf.png")
    print(f"bench_packings: {RESULTS / 'packings.md'}")
    return 0


def save_case(row: dict, st) -> None:
    """bench/results/packings_cases/<label>.json: the case's row and its bulk RDF."""
    record = dict(row, rdf_r_over_d=st.rdf_r_over_d.tolist(), rdf=st.rdf.tolist())
    record = {k: (v.item() if isinstance(v, np.generic) else v) for k, v in record.items()}
    CASES_DIR.mkdir(parents=True, exist_ok=True)
    write_text_atomic(CASES_DIR / f"{row['label']}.json", json.dumps(record, indent=0))


def load_cases() -> tuple[list[dict], dict]:
    """Every measured case (rows in label order) and, where stored, its statistics for the RDF
    comparison (cases measured before the RDF was stored have none)."""
    from tdem_post.packing_compare import PackingStats
    rows, stats = [], {}
    fields = [f.name for f in dataclasses.fields(PackingStats)]
    for path in sorted(CASES_DIR.glob("*.json")):
        record = json.loads(path.read_text())
        rdf = record.pop("rdf", None), record.pop("rdf_r_over_d", None)
        rows.append(record)
        if rdf[0] is not None:
            stats[record["label"]] = PackingStats(**{
                k: (np.asarray(rdf[0]) if k == "rdf" else np.asarray(rdf[1])
                    if k == "rdf_r_over_d" else record[k]) for k in fields})
    return rows, stats


def summary_markdown(table, stats) -> str:
    """Per (path, N): mean and spread over seeds, and the differences to the reference at the
    same N with the issue's tolerances."""
    cols = ["solid_fraction_bulk", "z_nonrattler", "z_with_gaps", "rattler_fraction",
            "fabric_deviator", "gamma_pipe", "gamma_pipe_held", "wall_seconds", "cpu_seconds",
            "peak_rss_mb", "compression_steps",
            "n_particles"]
    groups = list(table.groupby(["shape", "n_target", "path", "cell_particles"], sort=True))
    out = ["| shape | N (target) | path | cell | seeds | N | wall (s) | CPU (s) | peak RSS (MB) | "
           "DEM steps | "
           "φ bulk | Z non-rattlers | Z with gaps | rattlers (%) | fabric dev. | γ pipe | "
           "γ pipe, held planes | "
           "RDF diff. to ref. |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for (shape, n_target, path, cell), g in groups:
        m = g[cols].mean(numeric_only=True)
        s = g[cols].std(numeric_only=True).fillna(0.0)
        ref = table[(table.n_target == n_target) & (table.path == "reference")
                    & (table["shape"] == shape)]
        rdf = ""
        if len(ref) and path != "reference":
            pairs = [rdf_distance(stats[a], stats[b]) for a in g.label for b in ref.label
                     if a in stats and b in stats]
            rdf = f"{np.mean(pairs):.3f}" if pairs else ""
        elif path == "reference" and len(g) > 1:
            labels = list(g.label)
            pairs = [rdf_distance(stats[a], stats[b]) for i, a in enumerate(labels)
                     for b in labels[i + 1:] if a in stats and b in stats]
            rdf = f"({np.mean(pairs):.3f} seed to seed)" if pairs else ""
        out.append(
            f"| {shape} | {n_target:,} | {path} | {cell or ''} | {len(g)} | {m.n_particles:,.0f} | "
            f"{m.wall_seconds:.0f} ± {s.wall_seconds:.0f} | {m.cpu_seconds:.0f} | "
            f"{m.peak_rss_mb:.0f} | "
            f"{m.compression_steps:,.0f} | "
            f"{m.solid_fraction_bulk:.4f} ± {s.solid_fraction_bulk:.4f} | "
            f"{m.z_nonrattler:.3f} ± {s.z_nonrattler:.3f} | {m.z_with_gaps:.3f} ± "
            f"{s.z_with_gaps:.3f} | {100 * m.rattler_fraction:.1f} ± "
            f"{100 * s.rattler_fraction:.1f} | {m.fabric_deviator:.4f} | "
            f"{m.gamma_pipe:.4g} ± {s.gamma_pipe:.2g} | {m.gamma_pipe_held:.4g} | {rdf} |")
    out += ["", "Differences to the reference at the same N (mean over seeds; the issue's "
            "tolerances: φ 0.005, Z non-rattlers 3 %, Z with gaps 2 %, rattlers 2 points, "
            "γ pipe 3 %):", "",
            "| shape | N | path | Δφ bulk | ΔZ non-rattlers | ΔZ with gaps | "
            "Δrattlers (points) | Δγ pipe | Δγ pipe, held planes | speed-up (CPU) | "
            "fewer DEM steps |",
            "|---|---|---|---|---|---|---|---|---|---|---|"]
    for (shape, n_target, path, cell), g in groups:
        ref = table[(table.n_target == n_target) & (table.path == "reference")
                    & (table["shape"] == shape)]
        if path == "reference" or not len(ref):
            continue
        a, b = g.mean(numeric_only=True), ref.mean(numeric_only=True)
        out.append(
            f"| {shape} | {n_target:,} | {path}{' c' + str(cell) if cell else ''} | "
            f"{a.solid_fraction_bulk - b.solid_fraction_bulk:+.4f} | "
            f"{100 * (a.z_nonrattler / b.z_nonrattler - 1):+.1f} % | "
            f"{100 * (a.z_with_gaps / b.z_with_gaps - 1):+.1f} % | "
            f"{100 * (a.rattler_fraction - b.rattler_fraction):+.1f} | "
            f"{100 * (a.gamma_pipe / b.gamma_pipe - 1):+.1f} % | "
            f"{100 * (a.gamma_pipe_held / b.gamma_pipe_held - 1):+.1f} % | "
            f"{b.cpu_seconds / a.cpu_seconds:.1f}× | "
            f"{b.compression_steps / max(a.compression_steps, 1):.1f}× |")
    return "\n".join(out) + "\n"


def plot_rdf(stats, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4))
    styles = {"reference": "-", "ds": "--", "tiled": ":"}
    for label, st in stats.items():
        ax.plot(st.rdf_r_over_d, st.rdf, styles.get(label.split("_")[0], "-"), lw=1,
                label=label)
    ax.set_xlabel("centre distance / mean diameter")
    ax.set_ylabel("g(r), bulk")
    ax.legend(fontsize=6, ncol=2)
    savefig_atomic(fig, path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
