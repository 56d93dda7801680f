"""Benchmark of the compressed-bed generator (yade_scripts/compressed_bed.py): wall time per stage
and packing statistics of a pressure series, for several generator versions / parameter sets
side by side ("same packings, only faster").

    .venv/bin/python bench/bench_bed.py                       # old vs new, bed_small, seeds 1 2 3
    .venv/bin/python bench/bench_bed.py --scene runs/bed_7500.toml --seeds 1
    .venv/bin/python bench/bench_bed.py --variant old=0c04f14 --variant new=worktree \
        --variant sf10=worktree:'{"stiffen_factor": 10}'

A variant is NAME=SOURCE[:JSON]: SOURCE is ``worktree`` (yade_scripts/ as it is now), an
absolute folder holding a copy of yade_scripts/ and thermal_kernel/ (a candidate), or a git
commit (its yade_scripts/ and thermal_kernel/ are extracted with ``git archive``, so an old
generator runs with its own defaults); JSON holds parameter overrides on top of the scene's
[pack] table. The first variant is the reference of the comparison.

Runs are serial (one YADE process, one thread, at a time) and go to
runs/out/bench_bed/<variant>/<scene>_s<seed>/; a run whose folder already holds every packing of
its series (and the same params.json) is not run again (--force runs it again). Writes
bench/results/bed_series.csv (one row per variant, seed and stage) and
bench/results/bed_series.md (wall times per stage and the statistics side by side, with the
tolerances: phi within 0.005, Z of the non-rattlers within 3 %, rattler fraction within
2 points). Everything above the line ``<!-- bench_bed.py output below -->`` of an existing
bed_series.md is kept (the write-up).

Stage times are the dumps' own ``stage_wall_seconds`` (settled.h5: ``wall_seconds``, from the
script's start, cloud included); "total" is the last dump's ``wall_seconds`` (YADE's start-up of
about 1 s is not in it). Wall times depend on the host and its load: compare variants only
within one benchmark run.
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tdem.yade import yade_environment, yade_executable  # noqa: E402
from thermal_kernel.atomic import open_atomic, write_text_atomic  # noqa: E402
from thermal_kernel.scene import read_toml  # noqa: E402

OUT = ROOT / "runs" / "out" / "bench_bed"
RESULTS = ROOT / "bench" / "results"
MARKER = "<!-- bench_bed.py output below -->"
TOL_PHI = 0.005          # absolute
TOL_Z = 0.03             # relative, Z of the non-rattlers
TOL_RATTLERS = 0.02      # absolute (fraction)
# the generator as it was before this benchmark's speed-ups
DEFAULT_VARIANTS = ["old=0c04f14", "new=worktree"]


def parse_variant(text):
    name, _, rest = text.partition("=")
    source, _, overrides = rest.partition(":")
    if not name or not source:
        raise SystemExit(f"--variant {text!r}: expected NAME=SOURCE[:JSON]")
    return name, source, json.loads(overrides) if overrides else {}


def scripts_for(source):
    """Folder holding compressed_bed.py of a source ('worktree' or a git commit)."""
    if source == "worktree":
        return ROOT / "yade_scripts"
    if source.startswith("/"):              # a folder holding yade_scripts/ (a candidate)
        return Path(source) / "yade_scripts"
    commit = subprocess.run(["git", "rev-parse", "--short=12", source], cwd=ROOT, check=True,
                            capture_output=True, text=True).stdout.strip()
    dest = OUT / f"_scripts_{commit}"
    if not (dest / "yade_scripts" / "compressed_bed.py").exists():
        dest.mkdir(parents=True, exist_ok=True)
        archive = subprocess.run(["git", "archive", commit, "yade_scripts", "thermal_kernel"],
                                 cwd=ROOT, check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(dest)], input=archive, check=True)
    return dest / "yade_scripts"


def pressure_name(p):
    return f"packing_{p:.4g}Pa.h5"


def run_one(scripts, params, out_dir, force):
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "params.json"
    wanted = [out_dir / pressure_name(p) for p in params["pressures_pa"]]
    def same(a, b):     # a run folder may have been moved: output_dir does not count
        return ({k: v for k, v in a.items() if k != "output_dir"}
                == {k: v for k, v in b.items() if k != "output_dir"})

    if (not force and path.exists() and same(json.loads(path.read_text()), params)
            and all(f.exists() for f in wanted)):
        print(f"  {out_dir.relative_to(ROOT)}: done before, not run again", flush=True)
        return
    for f in out_dir.glob("*.h5"):
        f.unlink()
    write_text_atomic(path, json.dumps(params, indent=1, sort_keys=True))
    cmd = [yade_executable(), "-n", "-j1", "-x", str(scripts / "compressed_bed.py"), str(path)]
    start = time.perf_counter()
    with open(out_dir / "yade.log", "w") as log:
        rc = subprocess.run(cmd, cwd=out_dir, env=yade_environment(), stdout=log,
                            stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL).returncode
    wall = time.perf_counter() - start
    write_text_atomic(out_dir / "process_wall_seconds.txt", f"{wall:.2f}\n")
    print(f"  {out_dir.relative_to(ROOT)}: exit {rc}, {wall:.1f} s", flush=True)
    if rc != 0:
        raise SystemExit(f"YADE failed, see {out_dir / 'yade.log'}")


def statistics(path):
    """phi, Z (touching) of the non-rattlers, rattler fraction and the dump's attributes."""
    with h5py.File(path, "r") as f:
        a = dict(f.attrs)
        n = len(f["particles/radius"])
        pair = f["contacts/pair"][()]
        overlap = f["contacts/overlap"][()]
        wp = f["wall_contacts/particle"][()]
        wo = f["wall_contacts/overlap"][()]
    pair = pair[overlap > 0]
    count = np.bincount(pair.reshape(-1), minlength=n)
    wall = np.bincount(wp[wo > 0], minlength=n)
    rattler = (count + wall) == 0
    return dict(phi=float(a["solid_fraction"]), z=2.0 * len(pair) / n,
                z_nr=float(count[~rattler].mean()), rattlers=float(rattler.mean()),
                pressure_pa=float(a["pressure_pa"]), unbalanced=float(a["unbalanced_force_ratio"]),
                inertial=float(a["inertial_number"]), young_used=float(a["young_pa_used"]),
                young=float(a["young_pa"]), steps=int(a["stage_steps"]),
                stage_s=float(a["stage_wall_seconds"]), wall_s=float(a["wall_seconds"]))


def collect(variant, seed, out_dir, pressures):
    rows = []
    settled = out_dir / "settled.h5"
    if settled.exists():
        with h5py.File(settled, "r") as f:
            a = dict(f.attrs)
        rows.append(dict(variant=variant, seed=seed, stage="settle", target_pa="",
                         stage_s=float(a["wall_seconds"]), steps=int(a["steps"]),
                         phi=float(a["solid_fraction"])))
    last = 0.0
    for p in pressures:
        s = statistics(out_dir / pressure_name(p))
        rows.append(dict(variant=variant, seed=seed, stage=f"{p / 1e5:.4g} bar", target_pa=p,
                         **s))
        last = s["wall_s"]
    rows.append(dict(variant=variant, seed=seed, stage="total", target_pa="", stage_s=last))
    return rows


def fmt_s(x):
    return "" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.0f}"


def write_results(rows, variants, seeds, pressures, scene, stem):
    """bench/results/<stem>.csv (every row) and <stem>.md: below MARKER the wall times and time
    steps per stage, the speed-up, the statistics per pressure against the first variant and
    the reference's seed-to-seed range; the text above MARKER is kept."""
    RESULTS.mkdir(parents=True, exist_ok=True)
    _write_csv(rows, RESULTS / f"{stem}.csv")
    get = {(r["variant"], r["seed"], r["stage"]): r for r in rows}
    names = [v[0] for v in variants]
    stages = ["settle"] + [f"{p / 1e5:.4g} bar" for p in pressures] + ["total"]
    out = [MARKER, "",
           f"`bench/bench_bed.py`: scene `{scene}`, seeds {', '.join(map(str, seeds))}, "
           f"one YADE thread, one run at a time; variants "
           + "; ".join(f"**{n}** = {s}{(' ' + json.dumps(o)) if o else ''}"
                       for n, s, o in variants) + ".", ""]
    out += _wall_time_table(get, names, seeds, stages)
    out += _steps_table(get, names, seeds, stages)
    out += _speed_up(get, names, seeds)
    out += _statistics_table(get, names, seeds, pressures)
    out += _seed_spread(get, names[0], seeds, pressures)
    md = RESULTS / f"{stem}.md"
    head_text = ""
    if md.exists():
        old = md.read_text()
        if MARKER in old:
            head_text = old.split(MARKER)[0]
    write_text_atomic(md, head_text + "\n".join(out) + "\n")
    print(f"wrote {RESULTS / (stem + '.csv')} and {md}")


def _write_csv(rows, path):
    keys = ["variant", "seed", "stage", "target_pa", "stage_s", "steps", "phi", "z", "z_nr",
            "rattlers", "pressure_pa", "unbalanced", "inertial", "young_used", "young", "wall_s"]
    with open_atomic(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow(r)


def _stage_head(names, seeds):
    """The header of a table with one column per variant and seed, then each variant's mean."""
    return ["| stage | " + " | ".join(f"{n} s{s}" for n in names for s in seeds)
            + " | " + " | ".join(f"{n} mean" for n in names) + " |",
            "|---" * (1 + len(names) * (len(seeds) + 1)) + "|"]


def _wall_time_table(get, names, seeds, stages):
    out = ["### Wall time per stage (s)", ""] + _stage_head(names, seeds)
    for st in stages:
        cells, means = [], []
        for n in names:
            vals = [get[(n, s, st)]["stage_s"] for s in seeds if (n, s, st) in get]
            cells += [fmt_s(get[(n, s, st)]["stage_s"]) if (n, s, st) in get else ""
                      for s in seeds]
            means.append(fmt_s(float(np.mean(vals))) if vals else "")
        label = f"**{st}**" if st == "total" else st
        out.append(f"| {label} | " + " | ".join(cells + means) + " |")
    return out


def _steps_table(get, names, seeds, stages):
    # steps do not depend on the host's load: the load-free measure of the work per stage
    out = ["", "### Time steps per stage (thousands; independent of the host's load)", ""]
    out += _stage_head(names, seeds)
    for st in stages[:-1] + ["total"]:
        cells, means = [], []
        for n in names:
            if st == "total":
                vals = [sum(get[(n, s, x)]["steps"] for x in stages[:-1] if (n, s, x) in get)
                        for s in seeds if (n, s, "total") in get]
                cells += [f"{v / 1e3:.1f}" for v in vals] + [""] * (len(seeds) - len(vals))
            else:
                vals = [get[(n, s, st)]["steps"] for s in seeds if (n, s, st) in get]
                cells += [f"{get[(n, s, st)]['steps'] / 1e3:.1f}" if (n, s, st) in get else ""
                          for s in seeds]
            means.append(f"{np.mean(vals) / 1e3:.1f}" if vals else "")
        label = f"**{st}**" if st == "total" else st
        out.append(f"| {label} | " + " | ".join(cells + means) + " |")
    return out


def _speed_up(get, names, seeds):
    ref = names[0]
    tot = {n: [get[(n, s, "total")]["stage_s"] for s in seeds if (n, s, "total") in get]
           for n in names}
    if not tot[ref]:
        return []
    return ["", "Speed-up of the whole series (mean total of the reference / mean total): "
            + ", ".join(f"{n} {np.mean(tot[ref]) / np.mean(tot[n]):.2f}x"
                        for n in names if tot[n]) + "."]


def _statistics_table(get, names, seeds, pressures):
    """Each variant's statistics per pressure and seed (and their mean), the differences to
    the reference's, and how many (seed, pressure) pairs are within the tolerances."""
    ref = names[0]
    out = ["", "### Statistics per pressure", "",
           "phi = solid fraction, Z_nr = touching sphere-sphere contacts per non-rattler, "
           "ratt = rattlers (no contact at all, %), unb = unbalanced-force ratio at the dump, "
           "E = modulus the dump was relaxed at. Differences are to the reference "
           f"**{ref}** with the same seed; a cell is marked **!** where it misses the tolerance "
           f"(|dphi| <= {TOL_PHI}, |dZ_nr|/Z_nr <= {100 * TOL_Z:.0f} %, "
           f"|d ratt| <= {100 * TOL_RATTLERS:.0f} points).", ""]
    head = ["p", "seed"]
    for n in names:
        head += [f"{n} phi", f"{n} Z_nr", f"{n} ratt %", f"{n} unb", f"{n} E (Pa)"]
        if n != ref:
            head += [f"{n} dphi", f"{n} dZ_nr %", f"{n} d ratt"]
    out += ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    misses = {n: 0 for n in names}
    compared = {n: 0 for n in names}
    for p in pressures:
        st = f"{p / 1e5:.4g} bar"
        for s in seeds + ["mean"]:
            line = [st, str(s)]
            for n in names:
                cells, bad = _statistics_cells(get, n, ref, s, st, seeds)
                line += cells
                if bad is not None and s != "mean":
                    compared[n] += 1
                    misses[n] += any(bad)
            out.append("| " + " | ".join(line) + " |")
    out += [""]
    for n in names[1:]:
        out.append(f"- **{n}**: {compared[n] - misses[n]} of {compared[n]} (seed, pressure) "
                   f"pairs within all three tolerances of **{ref}**.")
    return out


def _statistics_cells(get, n, ref, s, st, seeds):
    """Variant n's cells at stage st for seed s (or "mean" over the seeds): its statistics and,
    but for the reference, the differences to the reference's; with the three tolerance
    misses, or None where nothing was compared."""
    if s == "mean":
        rs = [get[(n, x, st)] for x in seeds if (n, x, st) in get]
        if not rs:
            return [""] * (5 if n == ref else 8), None
        r = {k: float(np.mean([q[k] for q in rs])) for k in
             ("phi", "z_nr", "rattlers", "unbalanced", "young_used")}
    else:
        r = get.get((n, s, st))
        if r is None:
            return [""] * (5 if n == ref else 8), None
    cells = [f"{r['phi']:.4f}", f"{r['z_nr']:.3f}", f"{100 * r['rattlers']:.1f}",
             f"{r['unbalanced']:.1e}", f"{r['young_used']:.3g}"]
    if n == ref:
        return cells, None
    if s == "mean":
        rs0 = [get[(ref, x, st)] for x in seeds if (ref, x, st) in get]
        r0 = {k: float(np.mean([q[k] for q in rs0])) for k in
              ("phi", "z_nr", "rattlers")} if rs0 else None
    else:
        r0 = get.get((ref, s, st))
    if r0 is None:
        return cells + ["", "", ""], None
    dphi = r["phi"] - r0["phi"]
    dz = (r["z_nr"] - r0["z_nr"]) / r0["z_nr"]
    dr = r["rattlers"] - r0["rattlers"]
    bad = [abs(dphi) > TOL_PHI, abs(dz) > TOL_Z, abs(dr) > TOL_RATTLERS]
    return cells + [f"{dphi:+.4f}" + (" **!**" if bad[0] else ""),
                    f"{100 * dz:+.1f}" + (" **!**" if bad[1] else ""),
                    f"{100 * dr:+.1f}" + (" **!**" if bad[2] else "")], bad


def _seed_spread(get, ref, seeds, pressures):
    """The seed-to-seed range of the reference: what "the same statistics" can mean at this
    size (nothing with one seed)."""
    if len(seeds) <= 1:
        return []
    spread = []
    for p in pressures:
        st = f"{p / 1e5:.4g} bar"
        rs = [get[(ref, s, st)] for s in seeds if (ref, s, st) in get]
        if len(rs) > 1:
            spread.append(f"{st}: phi {min(r['phi'] for r in rs):.4f}-"
                          f"{max(r['phi'] for r in rs):.4f}, Z_nr "
                          f"{min(r['z_nr'] for r in rs):.3f}-{max(r['z_nr'] for r in rs):.3f}"
                          f", ratt {100 * min(r['rattlers'] for r in rs):.1f}-"
                          f"{100 * max(r['rattlers'] for r in rs):.1f} %")
    return ["", f"Seed-to-seed range of **{ref}** (the noise floor of a paired comparison): "
            + "; ".join(spread) + "."]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="runs/bed_small.toml")
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--variant", action="append",
                    help="NAME=SOURCE[:JSON] (repeatable; default: "
                         + " ".join(DEFAULT_VARIANTS) + ")")
    ap.add_argument("--stem", default="bed_series",
                    help="bench/results/<stem>.csv and .md (default bed_series)")
    ap.add_argument("--report-only", action="store_true",
                    help="do not run YADE; tabulate the runs already in runs/out/bench_bed")
    ap.add_argument("--force", action="store_true", help="run again even if done before")
    args = ap.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    variants = [parse_variant(v) for v in (args.variant or DEFAULT_VARIANTS)]
    scene_path = ROOT / args.scene
    table = dict(read_toml(scene_path)[0]["pack"])
    table.pop("generator", None)
    pressures = [float(p) for p in table["pressures_pa"]]
    rows = []
    for name, source, overrides in variants:
        scripts = None if args.report_only else scripts_for(source)
        for seed in seeds:
            out_dir = OUT / name / f"{scene_path.stem}_s{seed}"
            params = dict(table, **overrides, seed=seed, output_dir=str(out_dir))
            if not args.report_only:
                run_one(scripts, params, out_dir, args.force)
            if all((out_dir / pressure_name(p)).exists() for p in pressures):
                rows += collect(name, seed, out_dir, pressures)
            else:
                print(f"  {out_dir.relative_to(ROOT)}: incomplete, left out", flush=True)
    write_results(rows, variants, seeds, pressures, args.scene, args.stem)


if __name__ == "__main__":
    from thermal_kernel.threading_layer import prefer_openmp
    prefer_openmp()             # an entry point: OpenMP first, NUMBA_THREADING_LAYER* wins
    main()
