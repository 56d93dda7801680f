"""Same outputs before and after a refactoring (issue 26): snapshot what the campaign, post and
validation write, then diff two snapshots.

    python tools/same_outputs.py snap DIR [small] [seeds] [campaign_7500] [validation]
                                          [validation_quick[=1,2,11]]
                                          [validation_full=5,7] [validation_rebuild=4,6,8,10]
    python tools/same_outputs.py diff DIR_BEFORE DIR_AFTER            (exit 1 when they differ)

``snap`` writes into DIR, for each instance asked (the campaign's three by default):
- ``small``: a campaign (laws pipe, bob) run on the two committed 300-sphere beds of tests/data;
- ``seeds``: the same with ``seeds = [3, 5]`` (the beds stand in for each seed's series);
- ``campaign_7500``: report.md, results.csv and the figures re-written (``write_report``) from
  the 21 case summaries of ``runs/out/campaign_7500`` (when present), nothing run again;
its report.md, results.csv, contact_angles.csv, the three figures (PNG bytes) and every case's
summary.json, with what changes from run to run masked: the seconds in report.md's first lines,
the wall-time columns and keys, post_sha256.

Take the "before" snapshot with the old code, e.g.
``git worktree add /tmp/base <commit>`` and ``PYTHONPATH=/tmp/base python tools/same_outputs.py
snap /tmp/before`` (this file's code is the same in both; it calls only the campaign's entry
points: run_campaign, write_report, read_campaign, target_pressure).

Validation (docs/validation.md, ``tdem validate``):
- ``validation``: what the current code makes of the saved results, nothing measured: every
  validation/results/caseN.json (its ``finished`` date and ``run_seconds`` masked), each case's
  ``numbers`` read by the case's own records and written back (``records_caseN.json``: its
  ``read_numbers`` or ``read_rows`` and ``records.to_dict``, when it has one), the summary's
  columns from each case's ``judge(numbers)``, docs/validation.md's generated parts as
  ``validation.run.assemble_text`` rebuilds them from the saved results (dates and seconds
  masked), the committed docs/validation.md as it is, and every docs/img/validation_*.csv (the
  figures' numbers). Run the cases' ``--action rebuild`` (or a case itself) first to include
  what they rewrite;
- ``validation_quick[=N,N,...]``: the quick instance of each case named (1, 2, 11 by default;
  3 needs its 1,000-sphere sheet under validation/out, built by YADE once) run again with a
  deterministic clock (``time.perf_counter`` a counter): its result (judged) and its figures
  with their CSVs (under validation/out/caseN_quick; the PNG bytes too: matplotlib writes the
  same bytes for the same figure here).
- ``validation_full=N,N,...``: the full instance of each case named, run again the same way
  but from the runs cached under validation/out/caseN (nothing measured when every run is
  cached there and every packing built; otherwise it measures): its result (judged) and its
  figures with their CSVs, the figures written into the snapshot instead of docs/img.
- ``validation_rebuild=N,N,...``: each case's ``--action rebuild`` (nothing measured: the
  section, figures and summary made again from its saved result) run on a copy of
  validation/results, with the figures written into the snapshot instead of docs/img: the
  rebuilt caseN.json (``finished`` masked), the figures (PNG bytes) and their CSVs. Nothing
  committed is rewritten.
"""
from __future__ import annotations

import dataclasses
import filecmp
import io
import json
import re
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WALL = ("case_wall_seconds", "thermal_wall_seconds", "run_wall_seconds", "post_sha256")
INSTANCES = ("small", "seeds", "campaign_7500")
QUICK_CASES = (1, 2, 11)
MASKED = ("finished", "run_seconds")


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


def _committed_beds():
    """BEDS and NO_PACK of this checkout's tdem/committed_beds.py, loaded by path: both
    snapshots run on the same inputs, the "before" one too (PYTHONPATH at a base, which may
    predate the module)."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("_committed_beds",
                                                  ROOT / "tdem" / "committed_beds.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.BEDS, module.NO_PACK


def _campaign(work: Path, extra: str, laws='["pipe", "bob"]') -> Path:
    from tdem import campaign as camp
    beds, no_pack = _committed_beds()
    build = camp.build_packings
    camp.build_packings = lambda *a, **k: beds
    try:
        path = work / "c.toml"
        path.write_text(no_pack.replace('["pipe"]', laws).replace("n_bins = 5", extra)
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


def _case_records(mod, numbers: dict):
    """The case's saved numbers read through its own records (``read_numbers(numbers)`` or
    ``read_rows(numbers)``) and written back by ``records.to_dict``; None when the case has
    neither (its ``judge`` still reads them): a reader that drops or renames a field shows as a
    difference."""
    from tdem_post.records import to_dict
    reader = getattr(mod, "read_numbers", None) or getattr(mod, "read_rows", None)
    if reader is None:
        return None
    got = reader(numbers)
    return [to_dict(r) for r in got] if isinstance(got, (list, tuple)) else to_dict(got)


def _validation(dest: Path) -> None:
    """The saved validation results as the current code reads, judges and assembles them."""
    from validation import framework as fw
    from validation import run as vrun
    dest.mkdir(parents=True)
    cases = vrun.discover()
    records = vrun._records()
    for n, rec in sorted(records.items()):
        data = {k: ("X" if k in MASKED else v) for k, v in rec.items()}
        (dest / f"case{n}.json").write_text(json.dumps(data, indent=1))
        mod = cases.get(n)
        if mod is None or isinstance(mod, vrun.Broken):
            continue
        numbers = rec["result"].get("numbers", {})
        read = _case_records(mod, numbers)
        if read is not None:
            (dest / f"records_case{n}.json").write_text(json.dumps(read, indent=1,
                                                                   default=float))
        if hasattr(mod, "judge"):
            j = mod.judge(numbers)
            (dest / f"judge_case{n}.json").write_text(json.dumps(
                dataclasses.asdict(j), indent=1, default=float))
    doc = fw.ROOT / "docs" / "validation.md"
    (dest / "validation.md").write_text(doc.read_text())
    rebuilt = vrun.assemble_text(doc.read_text(), cases, records)
    rebuilt = re.sub(r"last run [0-9-]+ [0-9:]+, \d+ s", "last run DATE, N s", rebuilt)
    (dest / "validation_assembled.md").write_text(rebuilt)
    img = dest / "img"
    img.mkdir()
    for path in sorted((fw.ROOT / "docs" / "img").glob("validation_*.csv")):
        shutil.copy(path, img / path.name)


def _validation_quick(dest: Path, numbers, quick: bool = True) -> None:
    """The quick (or, ``quick`` False, full) instances of cases ``numbers`` run again with a
    counter for a clock; a full instance's figures go to ``dest`` instead of docs/img."""
    import time

    from validation import framework as fw
    from validation import run as vrun
    dest.mkdir(parents=True)
    cases = vrun.discover()
    real, img = time.perf_counter, fw.IMG
    # a full instance's figures: one fixed folder (the section links them by path), then kept
    figures = Path(tempfile.gettempdir()) / "tdem_same_outputs_figures"
    shutil.rmtree(figures, ignore_errors=True)
    for n in numbers:
        tick = iter(range(10 ** 9))
        time.perf_counter = lambda tick=tick: float(next(tick))
        fw.IMG = img if quick else figures
        try:
            mod = cases[n]
            ctx = fw.Context(number=n, quick=quick)
            where = ctx.out if quick else figures
            for old in list(where.glob(f"validation_case{n}_*.csv")) + \
                    list(where.glob(f"validation_case{n}_*.png")):
                old.unlink()
            result = mod.run(ctx)
            if not result.at_paper_n and hasattr(mod, "judge"):
                result = fw.judged(result, mod.judge(result.numbers))
        finally:
            time.perf_counter, fw.IMG = real, img
        (dest / f"case{n}_{'quick' if quick else 'full'}.json").write_text(json.dumps(
            dataclasses.asdict(result), indent=1, default=float))
        if quick:
            for path in sorted(ctx.out.glob("validation_*.csv")) + \
                    sorted(ctx.out.glob("validation_*.png")):
                shutil.copy(path, dest / path.name)
    if not quick and figures.exists():
        shutil.copytree(figures, dest / "figures")
        shutil.rmtree(figures)


def _validation_rebuild(dest: Path, numbers) -> None:
    """Each case's ``rebuild`` action on a copy of validation/results, figures into ``dest``."""
    from validation import framework as fw
    from validation import run as vrun
    dest.mkdir(parents=True)
    cases = vrun.discover()
    # fixed folders: the rebuilt sections link the figures by path
    work = Path(tempfile.gettempdir()) / "tdem_same_outputs_rebuild"
    shutil.rmtree(work, ignore_errors=True)
    shutil.copytree(fw.RESULTS, work / "results")
    results, img = fw.RESULTS, fw.IMG
    fw.RESULTS, fw.IMG = work / "results", work / "figures"
    try:
        for n in numbers:
            cases[n].ACTIONS["rebuild"].step(fw.Context(number=n))
            rec = json.loads((fw.RESULTS / f"case{n}.json").read_text())
            rec["finished"] = "X"
            (dest / f"case{n}_rebuilt.json").write_text(json.dumps(rec, indent=1))
    finally:
        fw.RESULTS, fw.IMG = results, img
    if (work / "figures").exists():
        shutil.copytree(work / "figures", dest / "figures")
    shutil.rmtree(work)


def snap(dest: Path, instances) -> None:
    dest = Path(dest)
    if dest.exists():
        raise SystemExit(f"{dest}: exists; give a new folder")
    for name in [i for i in instances if i.startswith("validation")]:
        if name == "validation":
            _validation(dest / name)
        elif name.startswith("validation_rebuild="):
            _validation_rebuild(dest / "validation_rebuild",
                                [int(x) for x in name.partition("=")[2].split(",")])
        elif name.startswith("validation_full="):
            _validation_quick(dest / "validation_full",
                              [int(x) for x in name.partition("=")[2].split(",")], quick=False)
        else:
            picked = name.partition("=")[2]
            _validation_quick(dest / "validation_quick",
                              [int(x) for x in picked.split(",")] if picked else QUICK_CASES)
    instances = [i for i in instances if not i.startswith("validation")]
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
    walk(filecmp.dircmp(a, b, ignore=[]))
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
