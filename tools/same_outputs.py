"""Same outputs before and after a refactoring (issue 26): snapshot what the campaign and post
write, then diff two snapshots.

    python tools/same_outputs.py snap DIR [small] [seeds] [campaign_7500]
    python tools/same_outputs.py diff DIR_BEFORE DIR_AFTER            (exit 1 when they differ)

``snap`` writes into DIR, for each instance asked (all three by default):
- ``small``: a campaign (laws pipe, bob) run on the two committed 300-sphere beds of tests/data;
- ``seeds``: the same with ``seeds = [3, 5]`` (the beds stand in for each seed's series);
- ``campaign_7500``: report.md, results.csv and the figures re-written (``write_report``) from
  the 21 case summaries of ``runs/out/campaign_7500`` (when present), nothing run again;
its report.md, results.csv, contact_angles.csv, the three figures (PNG bytes) and every case's
summary.json, with what changes from run to run masked: the seconds in report.md's first lines,
the wall-time columns and keys, post_sha256. Take the "before" snapshot with the old code, e.g.
``git worktree add /tmp/base <commit>`` and ``PYTHONPATH=/tmp/base python tools/same_outputs.py
snap /tmp/before`` (this file's code is the same in both; it calls only the campaign's entry
points: run_campaign, write_report, read_campaign, target_pressure).
"""
from __future__ import annotations

import filecmp
import io
import json
import re
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
WALL = ("case_wall_seconds", "thermal_wall_seconds", "run_wall_seconds", "post_sha256")
INSTANCES = ("small", "seeds", "campaign_7500")


def _keep(out: Path, dest: Path, mask_wall: bool) -> None:
    import pandas as pd
    dest.mkdir(parents=True)
    for name in ("report.md", "results.csv", "contact_angles.csv"):
        if not (out / name).exists():
            continue
        text = re.sub(r"; \d+ s in all", "; N s in all", (out / name).read_text())
        if name == "results.csv" and mask_wall:
            table = pd.read_csv(io.StringIO(text), keep_default_na=False, dtype=str)
            for col in WALL:
                if col in table.columns:
                    table[col] = "X"
            text = table.to_csv(index=False)
        (dest / name).write_text(text)
    for name in ("gamma_p.png", "tau_p.png", "contact_angles.png"):
        if (out / name).exists():
            shutil.copy(out / name, dest / name)
    for path in sorted(out.rglob("post/summary.json")):
        data = json.loads(path.read_text())
        for key in WALL:
            data.pop(key, None)
        rel = str(path.relative_to(out)).replace("/", "__")
        (dest / rel).write_text(json.dumps(data, indent=1))


def _campaign(work: Path, extra: str, laws='["pipe", "bob"]') -> Path:
    from tdem import campaign as camp
    from test_campaign import BEDS, NO_PACK
    build = camp.build_packings
    camp.build_packings = lambda *a, **k: BEDS
    try:
        path = work / "c.toml"
        path.write_text(NO_PACK.replace('["pipe"]', laws).replace("n_bins = 5", extra)
                        + "theta = 0.5\n")
        camp.run_campaign(path, work / "out", threads=1, quiet=True)
    finally:
        camp.build_packings = build
    return work / "out"


def _campaign_7500(work: Path) -> Path | None:
    """report.md etc. of runs/out/campaign_7500 re-written from its case summaries."""
    from tdem import campaign as camp
    out = ROOT / "runs" / "out" / "campaign_7500"
    toml = ROOT / "runs" / "campaign_7500.toml"
    if not (out / "cases").is_dir():
        return None
    conf, _ = camp.read_campaign(toml)
    pressures = json.loads((out / "packings" / "params.json").read_text())["pressures_pa"]
    cases = []
    for p in pressures:
        packing = out / "packings" / f"packing_{p:.4g}Pa.h5"
        for law in conf["laws"]:
            path = out / "cases" / f"{packing.stem.removeprefix('packing_')}_{law}" / "post" \
                / "summary.json"
            try:        # the records (issue 26; their module was tdem.campaign_record first)
                try:
                    from tdem_post.campaign_record import CaseRow, CaseSummary
                except ImportError:
                    from tdem.campaign_record import CaseRow, CaseSummary
                from tdem_post.records import record_from_json
                s = record_from_json(CaseSummary, path)
                cases.append((s, CaseRow.from_summary(
                    s, camp.target_pressure(packing, s.pressure_pa))))
            except ImportError:     # the code before them: the summaries as dicts
                s = json.loads(path.read_text())
                s["pressure_target_pa"] = camp.target_pressure(packing, s["pressure_pa"])
                cases.append(s)
    (work / "out").mkdir(parents=True)
    camp.write_report(work / "out", toml, conf, cases, 58.0)
    return work / "out"


def snap(dest: Path, instances) -> None:
    dest = Path(dest)
    if dest.exists():
        raise SystemExit(f"{dest}: exists; give a new folder")
    # one fixed work folder: the summaries name their thermal.h5 by its absolute path
    work = Path(tempfile.gettempdir()) / "tdem_same_outputs"
    for name in instances:
        shutil.rmtree(work, ignore_errors=True)
        work.mkdir()
        try:
            out = (_campaign(work, "n_bins = 5") if name == "small" else
                   _campaign(work, "n_bins = 5\nseeds = [3, 5]", laws='["pipe"]')
                   if name == "seeds" else _campaign_7500(work))
            if out is None:
                print(f"{name}: runs/out/campaign_7500 not here, skipped")
                continue
            _keep(out, dest / name, mask_wall=name != "campaign_7500")
        finally:
            shutil.rmtree(work, ignore_errors=True)
    print(f"snapshot in {dest}")


def diff(a: Path, b: Path) -> int:
    """Print the files that differ or exist on one side only; 1 if any."""
    bad = []

    def walk(cmp, rel=""):
        bad.extend(f"{rel}{n}: only in {a}" for n in cmp.left_only)
        bad.extend(f"{rel}{n}: only in {b}" for n in cmp.right_only)
        _, mismatch, errors = filecmp.cmpfiles(cmp.left, cmp.right, cmp.common_files,
                                               shallow=False)
        bad.extend(f"{rel}{n}: differs" for n in mismatch + errors)
        for n, sub in cmp.subdirs.items():
            walk(sub, f"{rel}{n}/")
    walk(filecmp.dircmp(a, b))
    print("\n".join(bad) if bad else f"same outputs: {a} and {b}")
    return 1 if bad else 0


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) >= 2 and argv[0] == "snap":
        snap(Path(argv[1]), argv[2:] or INSTANCES)
        return 0
    if len(argv) == 3 and argv[0] == "diff":
        return diff(Path(argv[1]), Path(argv[2]))
    print(__doc__.split("\n\n")[1], file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
