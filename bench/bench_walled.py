"""Benchmark of walled packings at scale (issue 24). Measures, does not assert.

    .venv/bin/python bench/bench_walled.py [--build] [--only LABEL ...]

Two paths make a walled box of Haddad's cube (runs/dense_box.toml's [pack]: Gaussian radii σ/μ 0.3,
steel, 1 bar, gap_tolerance 0.1):

  direct  the whole domain relaxed with its walls (method = "direct", YADE's density scaling),
          the reference; three seeds through one yade-batch table (``tdem pack --seeds``)
  shell   a relaxed 10,000-sphere periodic cell tiled and carved, then walls pressed onto a
          shell of 6 mean diameters along them (method = "shell", yade_scripts/shell.py;
          variants: the carve's cut depth, the walls' speed in the soft stage, the outer 1.5 or
          3 mean diameters grown again against the walls (shell_cloud_diameters), a 3-diameter
          shell)

Each packing is a ``tdem pack`` run of its own (whole-process wall time and CPU seconds of the
process tree from /usr/bin/time, peak resident memory, DEM steps from the packing), and its
statistics: bulk φ and touching Z of the non-rattlers (tdem_post/packing_compare.py), the
near-wall profiles φ(distance) and Z by layer over the first 5 mean diameters and the wall
contacts per area (tdem_post/wall_layers.py), the steady γ = k_eff/k_p of the force-based pipe
law and the calibrated C_t of the haddad law between the two held x walls. One JSON per packing
in bench/results/walled_cases/ (committed: the tables are rebuilt from them), the table
bench/results/walled.md and the profiles figure docs/img/walled_profiles.png, which
docs/packings.md quotes. With --build the missing packings are built first (hours in all: the
direct reference takes ~4 CPU min per seed at 1e4; the shell boxes 1e5 and 1e6 are the timed
targets).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from thermal_kernel.atomic import savefig_atomic, write_text_atomic  # noqa: E402
from thermal_kernel.packing import read_packing  # noqa: E402
from tdem_post.packing_compare import packing_stats  # noqa: E402
from tdem_post.wall_layers import layer_centres, wall_layers  # noqa: E402
from validation.framework import scene_with_pack  # noqa: E402

OUT = ROOT / "bench" / "out" / "walled"
RESULTS = ROOT / "bench" / "results"
CASES_DIR = RESULTS / "walled_cases"
FIGURE = ROOT / "docs" / "img" / "walled_profiles.png"
BASE = ROOT / "runs" / "dense_box.toml"
TDEM = ROOT / ".venv" / "bin" / "tdem"
# cells relaxed by earlier runs (10,000 spheres, seeds 1-3): a shell box at 1e4 copies the cell
# of its seed when there is one, so the comparison with the reference costs only the shell
CELL_DIRS = [ROOT / "runs" / "out" / "dense_box_1e5", ROOT / "validation" / "out" / "packings"]

# (label, path, N, seeds, own cell?, extra [pack] keys): the reference and the shell boxes at 1e4
# are compared (the shell's defaults; spheres kept only when wholly inside the carved faces, as
# before 2026-12-02; walls pressed 5x slower once loaded in the soft stage); the shell at 1e5 and
# 1e6 are the timed sizes (each copies the 10,000 cell of its seed when one exists)
CASES = [
    ("direct_10000", "direct", 10_000, (1, 2, 3), False, {}),
    ("direct_20000", "direct", 20_000, (1,), False, {}),
    ("shell_10000", "shell", 10_000, (1, 2, 3), False, {}),
    ("shell_wholecut_10000", "shell", 10_000, (2,), False, dict(shell_cut_depth=1.0)),
    ("shell_loaded_slow_10000", "shell", 10_000, (1, 2), False,
     dict(shell_loaded_step=0.002)),
    ("shell_cloud_10000", "shell", 10_000, (1, 2, 3), False, dict(shell_cloud_diameters=1.5)),
    ("shell_cloud3_10000", "shell", 10_000, (1, 2, 3), False, dict(shell_cloud_diameters=3.0)),
    ("shell_thin_10000", "shell", 10_000, (1,), False, dict(shell_diameters=3.0)),
    ("direct_100000", "direct", 100_000, (1,), False, {}),
    ("shell_cloud3_100000", "shell", 100_000, (1,), False, dict(shell_cloud_diameters=3.0)),
    ("shell_100000", "shell", 100_000, (1,), False, {}),
    ("shell_1000000", "shell", 1_000_000, (1,), False, {}),
]
LABELS = [case[0] for case in CASES]
# the shell boxes compared with the direct reference statistic by statistic
# (shell case, its direct reference of the same N): at 1e5 one seed each, the profiles judged
# against the 1e4 reference seeds' scatter (the only one measured)
COMPARED = [(label, f"direct_{n}") for label, method, n, *_ in CASES if method == "shell"]


def scene_text(method: str, n: int, seed: int, cell: Path | None, keys: dict) -> str:
    """runs/dense_box.toml with this case's [pack] values."""
    extra = dict(method=method, n_particles=n, seed=seed, max_seconds=14400.0, **keys)
    if cell is not None:
        extra["cell_packing"] = str(cell)
    return scene_with_pack(BASE, extra)


def seed_cell(seed: int) -> Path | None:
    """A relaxed 10,000-sphere periodic cell of this seed made by an earlier run, if any."""
    import h5py
    for d in CELL_DIRS:
        for path in sorted(Path(d).glob("**/cell.h5")):
            with h5py.File(path, "r") as f:
                if int(f.attrs["seed"]) == seed and len(f["particles/radius"]) == 10_000 and \
                        float(f.attrs["confining_pressure_pa"]) == 1e5:
                    return path.resolve()
    return None


def build(label: str, method: str, n: int, seed: int, own_cell: bool, keys: dict) -> Path:
    """One ``tdem pack`` under /usr/bin/time; returns the folder (packing.h5, time.txt)."""
    folder = OUT / f"{label}_s{seed}"
    if (folder / "packing.h5").exists():
        return folder
    folder.mkdir(parents=True, exist_ok=True)
    cell = None if own_cell or method == "direct" else seed_cell(seed)
    scene = folder / "scene.toml"
    write_text_atomic(scene, scene_text(method, n, seed, cell, keys))
    cmd = ["/usr/bin/time", "-f", "%M %U %S %e", "-o", str(folder / "time.txt"), str(TDEM),
           "pack", str(scene), "--out", str(folder), "--quiet"]
    print(f"bench_walled: {folder.name}: {' '.join(cmd[5:])}", flush=True)
    proc = subprocess.run(cmd, capture_output=True, text=True)
    write_text_atomic(folder / "tdem_pack.log", proc.stdout + proc.stderr)
    if proc.returncode != 0:
        raise SystemExit(f"bench_walled: {folder.name} failed: "
                         f"{(proc.stdout + proc.stderr).strip().splitlines()[-1]}")
    return folder


def flux_numbers(packing, packing_path: Path) -> tuple[float, float]:
    """(γ of the pipe law, calibrated C_t of the haddad law), steady, x walls held."""
    from thermal_kernel.calibrate import calibrate_ct, flux_test
    from thermal_kernel.scene import load_scene

    def scene(law: str, extra: str = ""):
        path = packing_path.parent / f"{law}_scene.toml"
        write_text_atomic(path, f'packing = "{packing_path.name}"\nlaw = "{law}"\n' + extra
                          + '[material]\nconductivity = 33.0\ndensity = 7800.0\n'
                            'heat_capacity = 460.0\nyoung_pa = 2.1e11\npoisson = 0.3\n'
                            '[initial]\ntemperature = 0.5\n[solver]\nmethod = "steady"\n')
        return load_scene(path)
    gamma = flux_test(scene("pipe"), packing, "x").effective_w_mk / 33.0
    ct = calibrate_ct(scene("haddad", "[law_params]\nct = 0.806\n[neighbours]\n"
                                      "target_z_with_gaps = 7.5\n"), packing, "x").ct
    return gamma, ct


def measure(label: str, method: str, folder: Path) -> dict:
    """The row of one packing (also saved as bench/results/walled_cases/<folder>.json)."""
    path = folder / "packing.h5"
    packing = read_packing(path)
    st = packing_stats(packing)
    layers = wall_layers(packing)
    # touching Z 5-7 d̄ from the walls: where the shell path's free shell meets its frozen band
    # (6 d̄ by default) - outside the 5 d̄ profiles, but in series with the flux
    deep = wall_layers(packing, depth_d=10.0)
    deep_d = layer_centres(10.0)
    seam = (deep_d > 5.0) & (deep_d < 7.0)
    touching = packing.overlap > 0
    z = np.bincount(packing.pair[touching].reshape(-1), minlength=packing.n_particles)
    nonrattler = z > 0
    if (folder / "time.txt").exists():
        peak_kb, user_s, sys_s, wall_s = (float(x) for x in
                                          (folder / "time.txt").read_text().split()[-4:])
    else:   # built in a yade-batch table (tdem pack --seeds): the packing's own wall time
        peak_kb, user_s, sys_s = float("nan"), float("nan"), 0.0
        wall_s = float(packing.attrs.get("wall_seconds", float("nan")))
    gamma, ct = flux_numbers(packing, path)
    attrs = packing.attrs
    row = dict(
        label=label, method=method, seed=int(attrs["seed"]), n_particles=packing.n_particles,
        wall_seconds=wall_s, cpu_seconds=user_s + sys_s, peak_rss_mb=peak_kb / 1024.0,
        cell_reused=bool(attrs.get("cell_packing", "")),
        compression_steps=int(attrs.get("compression_steps", 0)),
        shell_steps=int(attrs.get("shell_steps", 0)),
        cell_seconds=float(attrs.get("compression_seconds", 0.0))
        - float(attrs.get("shell_seconds", 0.0)),
        solid_fraction=float(attrs["solid_fraction"]),
        solid_fraction_bulk=st.solid_fraction_bulk,
        z_nonrattler_bulk=st.z_nonrattler,
        z_nonrattler=float(z[nonrattler].mean()),
        rattler_fraction=float(1.0 - nonrattler.mean()),
        wall_contacts_per_d2=layers.wall_contacts_per_d2,
        gamma_pipe=gamma, ct_haddad=ct,
        seam_z_touching=float(np.mean(deep.z_touching[seam])),
        profile_distance_d=layers.distance_over_d.tolist(),
        profile_phi=layers.solid_fraction.tolist(),
        layer_distance_d=layer_centres().tolist(),
        layer_z_with_gaps=layers.z_with_gaps.tolist(),
        layer_z_touching=layers.z_touching.tolist(),
        wall_pressure_pa=float(attrs.get("pressure_pa", float("nan"))),
        unbalanced=float(attrs.get("unbalanced_force_ratio", float("nan"))))
    CASES_DIR.mkdir(parents=True, exist_ok=True)
    write_text_atomic(CASES_DIR / f"{folder.name}.json", json.dumps(row, indent=1))
    return row


SCALARS = [("solid_fraction_bulk", "φ bulk", "{:.4f}"), ("z_nonrattler", "Z non-rattlers",
                                                         "{:.3f}"),
           ("rattler_fraction", "rattlers", "{:.3f}"),
           ("wall_contacts_per_d2", "wall contacts per d̄²", "{:.3f}"),
           ("gamma_pipe", "γ pipe", "{:.5f}"), ("ct_haddad", "C_t haddad", "{:.4f}"),
           ("seam_z_touching", "touching Z 5-7 d̄", "{:.2f}")]


def summary(rows: list[dict]) -> str:
    """The markdown tables: per case the mean ± seed std of every statistic, then the shell
    boxes at 1e4 against the reference (difference of the means, and for the profiles the
    largest difference over the slabs in units of the reference's seed-to-seed std)."""
    by = {}
    for r in rows:
        by.setdefault(r["label"], []).append(r)
    out = ["| case | method | seeds | N per seed | wall (s) | CPU (s) | peak RSS (MB) | DEM steps "
           "(shell) | " + " | ".join(name for _, name, _ in SCALARS) + " |",
           "|" + "---|" * (8 + len(SCALARS))]
    for label, rs in by.items():
        def cell(key, fmt, rs=rs):
            v = np.array([r[key] for r in rs], dtype=float)
            return fmt.format(v.mean()) + (f" ± {fmt.format(v.std(ddof=1))}" if len(v) > 1
                                           else "")
        steps = f"{np.mean([r['compression_steps'] for r in rs]):,.0f}" + (
            f" ({np.mean([r['shell_steps'] for r in rs]):,.0f})" if rs[0]["shell_steps"] else "")
        reused = " (cell reused)" if rs[0]["cell_reused"] else ""
        def num(key, rs=rs, reduce=np.mean):
            v = reduce([r[key] for r in rs])
            return f"{v:.0f}" if np.isfinite(v) else "—"
        counts = ", ".join(f"{r['n_particles']:,}" for r in rs)
        out.append(f"| {label} | {rs[0]['method']}{reused}"
                   f" | {len(rs)} | {counts} | "
                   f"{num('wall_seconds')} | {num('cpu_seconds')} | "
                   f"{num('peak_rss_mb', reduce=np.max)} | {steps} | "
                   + " | ".join(cell(k, f) for k, _, f in SCALARS) + " |")
    for new_label, ref_label in COMPARED:
        ref, new = by.get(ref_label), by.get(new_label)
        if not (ref and new):
            continue
        # the profiles' scale: the reference's own seed-to-seed std, else the 1e4 reference's
        spread = ref if len(ref) > 1 else by.get("direct_10000", [])
        size = f"1e{len(str(new[0]['n_particles'])) - 1}"
        out += ["", f"{new_label} against the direct reference at {size} ({ref_label}; difference "
                "of the means; the profiles: largest |difference| over the slabs / the "
                f"seed-to-seed std of {spread[0]['label'] if spread else '-'} in that slab, and "
                "the RMS of the differences against the RMS of that std):",
                "", "| statistic | reference | shell | difference | tolerance | met |",
                "|---|---|---|---|---|---|"]
        # the tolerances: (absolute or relative, limit)
        tol = {"solid_fraction_bulk": ("abs", 0.005), "z_nonrattler": ("rel", 0.03),
               "wall_contacts_per_d2": ("rel", 0.03), "gamma_pipe": ("rel", 0.01),
               "ct_haddad": ("rel", 0.01), "rattler_fraction": (None, None),
               "seam_z_touching": (None, None)}
        for key, name, fmt in SCALARS:
            a = np.mean([r[key] for r in ref])
            b = np.mean([r[key] for r in new])
            kind, limit = tol[key]
            if kind == "rel":
                diff, met = f"{100 * (b / a - 1):+.2f} %", abs(b / a - 1) <= limit
                limit_text = f"{100 * limit:g} %"
            else:
                diff, met = f"{b - a:+.4f}", kind is None or abs(b - a) <= limit
                limit_text = "-" if kind is None else f"{limit:g}"
            verdict = "-" if kind is None else ("yes" if met else "**no**")
            out.append(f"| {name} | {fmt.format(a)} | {fmt.format(b)} | {diff} | {limit_text} | "
                       f"{verdict} |")
        for key, name in (("profile_phi", "φ(distance), slabs of 0.1 d̄"),
                          ("layer_z_with_gaps", "Z with gaps by layer of 0.5 d̄"),
                          ("layer_z_touching", "touching Z by layer of 0.5 d̄")):
            a = np.array([r[key] for r in ref], dtype=float)
            b = np.array([r[key] for r in new], dtype=float)
            diff = b.mean(axis=0) - a.mean(axis=0)
            if len(spread) < 2:
                continue
            scatter = np.array([r[key] for r in spread], dtype=float).std(axis=0, ddof=1)
            ok = scatter > 0
            worst = float(np.max(np.abs(diff[ok]) / scatter[ok]))
            rms, rms_seed = np.sqrt(np.mean(diff ** 2)), np.sqrt(np.mean(scatter ** 2))
            out.append(f"| {name} | | | RMS difference {rms:.4f} (largest {worst:.1f} seed "
                       f"std) | the seeds' RMS std {rms_seed:.4f} | "
                       f"{'yes' if rms <= rms_seed else '**no**'} |")
    return "\n".join(out) + "\n"


def plot(rows: list[dict]) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(11, 5))
    styles = {label: ("k" if label == "direct_10000" else f"C{k}", label.replace("_", " "))
              for k, label in enumerate(LABELS)}
    for label, (colour, name) in styles.items():
        rs = [r for r in rows if r["label"] == label]
        if not rs:
            continue
        x = np.array(rs[0]["profile_distance_d"])
        phi = np.array([r["profile_phi"] for r in rs])
        axes[0].plot(x, phi.mean(axis=0), color=colour, label=f"{name} ({len(rs)} seed(s))")
        if len(rs) > 1:
            axes[0].fill_between(x, phi.min(axis=0), phi.max(axis=0), color=colour, alpha=0.2)
        xl = np.array(rs[0]["layer_distance_d"])
        z = np.array([r["layer_z_with_gaps"] for r in rs])
        zt = np.array([r["layer_z_touching"] for r in rs])
        axes[1].plot(xl, z.mean(axis=0), "o-", color=colour, label=f"{name}, with gaps")
        axes[1].plot(xl, zt.mean(axis=0), "s--", color=colour, label=f"{name}, touching")
    axes[0].set_xlabel("distance from the wall / mean diameter")
    axes[0].set_ylabel("solid fraction φ (slabs of 0.1 d̄)")
    axes[0].legend(fontsize=8)
    axes[1].set_xlabel("distance of the centre from the wall / mean diameter")
    axes[1].set_ylabel("neighbours per sphere (layers of 0.5 d̄)")
    axes[1].legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.15), ncol=2)
    fig.suptitle("Near-wall layer of the walled box: direct relaxation vs the shell path")
    fig.tight_layout()
    savefig_atomic(fig, FIGURE, dpi=110)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--build", action="store_true", help="build the missing packings")
    parser.add_argument("--only", nargs="*", help="labels to build / measure (default: all)")
    parser.add_argument("--seeds", type=int, nargs="*", help="only these seeds (default: all)")
    args = parser.parse_args(argv)
    for label, method, n, seeds, own_cell, keys in CASES:
        if args.only and label not in args.only:
            continue
        for seed in seeds:
            if args.seeds and seed not in args.seeds:
                continue
            folder = OUT / f"{label}_s{seed}"
            if args.build:
                t0 = time.perf_counter()
                build(label, method, n, seed, own_cell, keys)
                print(f"bench_walled: {folder.name} built ({time.perf_counter() - t0:.0f} s)",
                      flush=True)
            if (folder / "packing.h5").exists():
                row = measure(label, method, folder)
                print(f"bench_walled: {folder.name}: phi_bulk {row['solid_fraction_bulk']:.4f}, "
                      f"gamma {row['gamma_pipe']:.5f}, C_t {row['ct_haddad']:.4f}", flush=True)
    # the cases of CASES only (a JSON left by an experiment is not a row of the table)
    rows = [row for p in sorted(CASES_DIR.glob("*.json"))
            if (row := json.loads(p.read_text()))["label"] in LABELS]
    rows.sort(key=lambda row: LABELS.index(row["label"]))
    if not rows:
        return 0
    write_text_atomic(RESULTS / "walled.md", summary(rows))
    plot(rows)
    print(f"bench_walled: {RESULTS / 'walled.md'}, {FIGURE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
