#!/usr/bin/env python3
"""Every scene of runs/ in-process and on 1, 2 and 3 MPI ranks: the same answers? (issue 25)

Issue 25's target "same answers": every scene of ``runs/`` gives, on the PETSc backend
(``tdem run --ranks R``, ``tdem campaign --ranks R``), the in-process kernel's answer: explicit
within 1e-12, implicit and steady within 1e-10 (the solver tolerance), flags (maximum principle,
ledger) identical, on 1, 2 and 3 ranks. This script runs each scene four times into a scratch
folder (default ``bench/out/ranks/``, ignored by git) and compares each ``thermal.h5`` with the
in-process one:

- the temperature history (every output time, every particle): max |T - T_in-process| over the
  run's temperature change (the span of its initial and output temperatures; the tests' measure,
  ``tests/test_petsc_backend.py``), and the same over max |T| for reference;
- the boundary heat flows and the ledger's arrays (``boundary_heat_flow``, ``boundary_energy``,
  ``source_energy``, ``stored_energy_change``): max difference over each array's max |value|;
- the flags (maximum principle, ledger, network), the counts (steps, conducting contacts,
  rattlers, floating clusters), dt and its bound, the maximum-principle bounds and the
  neighbour choice: identical.

Which packing each scene runs on (never written under ``runs/out``):

- a ``[pack]`` scene: the packing(s) under ``runs/out/`` whose ``params.json`` equals the scene's
  ``[pack]`` table (``tdem.pack.built_packings``: ``runs/out/<scene>/`` first, then any other
  folder of ``runs/out`` built from the same table, e.g. the demo's series for bed_small); when
  none exists, one packing of the scene's own generator at a reduced size (``n_particles`` at most
  ``--max-n``, a copy of the scene with that one line changed under the scratch folder,
  ``tdem pack --threads 1``, one YADE build at a time). A pressure series: its lowest and highest
  pressure (``--all-pressures``: every one).
- a campaign (``[campaign]``): run by ``tdem campaign`` (in-process) and ``tdem campaign --ranks
  R`` on a copy of the campaign under the scratch folder that lists its packings
  (``[campaign] packings``, the lowest and highest pressure of its series, every law): the
  series under ``runs/out/`` built from the same ``[pack]`` table (for a campaign over seeds, the
  first seed's series: ``seeds`` is dropped); a LIGGGHTS campaign's own packings list, when its
  packings exist under ``runs/out/liggghts`` (``sh runs/liggghts/run.sh``), else skipped.

    .venv/bin/python bench/ranks_same_answers.py            # make bench-ranks
    .venv/bin/python bench/ranks_same_answers.py --scenes dense_box,demo --fresh

Writes bench/results/ranks_same_answers.md (``--md``): the summary table (a row per scene and
number of ranks, the worst of its runs) and the table of every run. Runs already in the scratch
folder are reused (``--fresh``: remove the scene's scratch runs first).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
TDEM = ROOT / ".venv" / "bin" / "tdem"
TOL = {"explicit": 1e-12, "implicit": 1e-10, "steady": 1e-10}
RANKS = (1, 2, 3)
ARRAYS = ("boundary_heat_flow", "boundary_energy", "source_energy", "stored_energy_change",
          "capacity")
SAME_ATTRS = ("flags", "method", "steps", "n_conducting_contacts", "n_rattlers",
              "n_floating_clusters", "max_principle_checked", "max_principle_bounds_k",
              "n_particles", "packing_sha256")
CLOSE_ATTRS = ("dt", "dt_max", "dt_paper")     # the same bound: compared relative, 1e-12
ENV = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1",
           NUMBA_NUM_THREADS="1")


# ---------------------------------------------------------------------------------------------
# which scenes, on which packings

def _pressure(path: Path) -> float:
    """A series packing's nominal pressure from its name (0 when it has none)."""
    from tdem.campaign import target_pressure
    return target_pressure(path, 0.0)


def _ends(packings: list, every: bool) -> list:
    """A series' lowest and highest pressure (all with ``every``), or the one packing."""
    packings = sorted(packings, key=_pressure)
    if every or len(packings) <= 2:
        return packings
    return [packings[0], packings[-1]]


def _candidate_dirs() -> list:
    out = ROOT / "runs" / "out"
    dirs = []
    for pattern in ("*", "*/packings", "*/seed_*/packings", "*/seed_*"):
        dirs += sorted(p for p in out.glob(pattern) if p.is_dir())
    return dirs


def _same_table(scene: Path, params_override: dict | None = None):
    """(folder, packings) under runs/out built from the scene's [pack] table (with
    ``params_override`` applied, e.g. a seed), runs/out/<scene>/ first; None when none is."""
    from tdem.pack import read_pack_table
    generator, params = read_pack_table(scene)
    params = dict(params, **(params_override or {}))
    want = {k: v for k, v in params.items() if k != "output_dir"}
    own = ROOT / "runs" / "out" / scene.stem
    dirs = [own, own / "packings"]
    dirs += [d for d in _candidate_dirs() if d not in dirs]
    for d in dirs:
        done = d / "params.json"
        made = sorted(d.glob("packing*.h5"))
        if not done.exists() or not made:
            continue
        try:
            old = json.loads(done.read_text())
        except json.JSONDecodeError:
            continue
        old.pop("output_dir", None)
        if old == want:
            return d, made
    return None


def _stale_keys(scene: Path, folder: Path) -> list:
    """The [pack] keys in which ``folder/params.json`` differs from the scene's table."""
    from tdem.pack import read_pack_table
    _, params = read_pack_table(scene)
    try:
        old = json.loads((folder / "params.json").read_text())
    except (FileNotFoundError, json.JSONDecodeError):
        return ["params.json"]
    return sorted(k for k in set(params) | set(old)
                  if k != "output_dir" and params.get(k, None) != old.get(k, None))


def _reduced_packing(scene: Path, scratch: Path, max_n: int, log) -> tuple[list, str]:
    """One packing of the scene's generator with n_particles at most ``max_n``: a copy of the
    scene with that line changed, ``tdem pack --threads 1`` into the scratch folder."""
    text = scene.read_text()
    n = tomllib.loads(text)["pack"]["n_particles"]
    small = min(int(n), max_n)
    folder = scratch / "packs" / scene.stem
    copy = folder / f"{scene.stem}_n{small}.toml"
    folder.mkdir(parents=True, exist_ok=True)
    new, k = re.subn(r"(?m)^n_particles\s*=\s*\d+", f"n_particles = {small}", text, count=1)
    if k != 1:
        raise RuntimeError(f"{scene}: no n_particles line to change")
    if not copy.exists() or copy.read_text() != new:
        copy.write_text(new)
    from tdem.pack import built_packings
    made = built_packings(copy, folder)
    if not made:
        log(f"  tdem pack {copy.relative_to(ROOT)} --out {folder.relative_to(ROOT)} "
            f"--threads 1 (n_particles {n} -> {small})")
        t = time.time()
        _call([str(TDEM), "pack", str(copy), "--out", str(folder), "--threads", "1", "--quiet"],
              folder / "pack.log")
        log(f"  packed in {time.time() - t:.0f} s")
        made = built_packings(copy, folder)
    note = (f"made here: `tdem pack` of the scene with n_particles {small}"
            + (f" (the scene: {n})" if small != n else "") + f", {folder.relative_to(ROOT)}/")
    return made, note


def plan_scenes(args, scratch: Path, log) -> tuple[list, list]:
    """(plans, skipped): a plan per scene that runs, (scene, reason) per scene that does not."""
    scenes = sorted((ROOT / "runs").glob("*.toml")) + sorted((ROOT / "runs").glob("*/*.toml"))
    if args.scenes:
        wanted = set(args.scenes.split(","))
        scenes = [s for s in scenes if s.stem in wanted or _label(s) in wanted]
    campaign_ranks = "--ranks" in subprocess.run([str(TDEM), "campaign", "--help"],
                                                 capture_output=True, text=True).stdout
    plans, skipped = [], []
    for scene in scenes:
        data = tomllib.loads(scene.read_text())
        label = _label(scene)
        if "campaign" in data:
            if not campaign_ranks:
                skipped.append((label, "a campaign and `tdem campaign` has no --ranks"))
                continue
            plan, why = _campaign_plan(scene, data, scratch, args)
        else:
            plan, why = _scene_plan(scene, data, scratch, args, log)
        if plan is None:
            skipped.append((label, why))
        else:
            plans.append(plan)
    return plans, skipped


def _label(scene: Path) -> str:
    rel = scene.relative_to(ROOT / "runs")
    return str(rel.with_suffix("")) if rel.parent != Path(".") else scene.stem


def _scene_plan(scene, data, scratch, args, log):
    if "pack" not in data:
        return None, "no [pack] table and no packing of its own"
    found = _same_table(scene)
    own = sorted((ROOT / "runs" / "out" / scene.stem).glob("packing*.h5"))
    if found is None and own:       # the scene's own packing, its params.json older than [pack]
        found = (own[0].parent, own)
        stale = _stale_keys(scene, own[0].parent)
    else:
        stale = None
    if found is not None:
        d, made = found
        rel = d.relative_to(ROOT)
        note = (f"{rel}/ (its own)" if d in (ROOT / "runs/out" / scene.stem,
                                              ROOT / "runs/out" / scene.stem / "packings")
                else f"{rel}/ (built from the same [pack] table)")
        if stale:
            note += (f"; its params.json predates the [pack] keys {', '.join(stale)} (their "
                     "defaults now; `tdem run` would build it again, this bench uses it as it is)")
    else:
        made, note = _reduced_packing(scene, scratch, args.max_n, log)
    packings = _ends(made, args.all_pressures)
    if len(made) > len(packings):
        note += f"; {len(packings)} of its {len(made)} pressures (lowest, highest)"
    return dict(label=_label(scene), scene=scene, kind="run", packings=packings,
                note=note), None


def _campaign_plan(scene, data, scratch, args):
    camp = data["campaign"]
    label = _label(scene)
    if camp.get("packings"):
        made = [(scene.parent / p).resolve() for p in camp["packings"]]
        missing = [p for p in made if not p.exists()]
        if missing:
            return None, (f"its packings are not built ({missing[0].relative_to(ROOT)} missing: "
                          "they need LIGGGHTS, `sh runs/liggghts/run.sh`)")
        note = "its packings list: " + ", ".join(str(p.relative_to(ROOT)) for p in made[:1]) + " …"
    else:
        seeds = camp.get("seeds")
        found = _same_table(scene, None if not seeds else {"seed": seeds[0]})
        if found is None:
            return None, "no packing series under runs/out built from its [pack] table"
        d, made = found
        made = [p for p in made if p.name.startswith("packing_")]
        note = f"{d.relative_to(ROOT)}/" + (f" (seed {seeds[0]} of its seeds {seeds}: the same "
                                             "[pack] table)" if seeds else "")
    if label in args.lowest_only.split(","):
        packings = sorted(made, key=_pressure)[:1]
        note += (f"; 1 of its {len(made)} packings, the lowest pressure (--lowest-only: its "
                 f"cases are long on ranks)")
    else:
        packings = _ends(made, args.all_pressures)
        if len(made) > len(packings):
            note += (f"; {len(packings)} of its {len(made)} packings (the first and last of "
                     "the series)")
    note += f"; laws {', '.join(camp['laws'])}"
    folder = scratch / label
    folder.mkdir(parents=True, exist_ok=True)
    copy = folder / f"{scene.stem}_campaign.toml"
    text = _campaign_copy(scene.read_text(), camp, packings)
    if not copy.exists() or copy.read_text() != text:
        copy.write_text(text)
    return dict(label=label, scene=scene, kind="campaign", campaign=copy, packings=packings,
                note=note), None


def _campaign_copy(text: str, camp: dict, packings: list) -> str:
    """The campaign's text without its [pack] and [campaign] tables, and a [campaign] table that
    lists the packings (its laws and n_bins kept; seeds dropped)."""
    lines = text.splitlines()
    keep, drop = [], False
    for line in lines:
        header = re.match(r"^\s*\[([^\[\]]+)\]", line)
        if header:
            drop = header.group(1).strip() in ("pack", "campaign")
        if not drop:
            keep.append(line)
    table = ["", "[campaign]   # written by bench/ranks_same_answers.py",
             "laws = [" + ", ".join(json.dumps(x) for x in camp["laws"]) + "]"]
    if "n_bins" in camp:
        table.append(f"n_bins = {int(camp['n_bins'])}")
    table.append("packings = [" + ", ".join(json.dumps(str(p)) for p in packings) + "]")
    return "\n".join(keep + table) + "\n"


# ---------------------------------------------------------------------------------------------
# running

def _call(cmd, log_path: Path, timeout=3600):
    log_path.parent.mkdir(parents=True, exist_ok=True)
    with open(log_path, "w") as f:
        f.write("$ " + " ".join(cmd) + "\n")
        f.flush()
        r = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT, cwd=ROOT, env=ENV,
                           timeout=timeout)
    if r.returncode != 0:
        tail = log_path.read_text().splitlines()[-15:]
        raise RuntimeError(f"{' '.join(cmd)}: exit {r.returncode}\n" + "\n".join(tail))


def _variant(r):
    return "inprocess" if r == 0 else f"ranks{r}"


def run_plan(plan, scratch: Path, fresh: bool, log) -> dict:
    """Run the plan in-process and on each number of ranks; {ranks: {run name: thermal.h5}}."""
    base = scratch / plan["label"]
    out = {}
    for r in (0,) + RANKS:
        vdir = base / _variant(r)
        stamp = vdir / "bench_plan.json"     # what ran there: run again when the plan changed
        wanted = json.dumps({k: str(v) for k, v in plan.items() if k != "note"}, sort_keys=True)
        if vdir.exists() and (fresh or (plan["kind"] == "run" and (
                not stamp.exists() or stamp.read_text() != wanted))):
            shutil.rmtree(vdir)
        vdir.mkdir(parents=True, exist_ok=True)
        stamp.write_text(wanted)
        extra = ["--threads", "1"] if r == 0 else ["--ranks", str(r)]
        t = time.time()
        if plan["kind"] == "campaign":
            # the campaign resumes by itself: a case kept when its scene and packing hashes
            # still match, run otherwise; only the plan's cases (packing x law) are compared
            _call([str(TDEM), "campaign", str(plan["campaign"]), "--out", str(vdir),
                   "--quiet", *extra], vdir.with_suffix(".log"))
            laws = tomllib.loads(plan["campaign"].read_text())["campaign"]["laws"]
            names = [f"{p.stem.removeprefix('packing_')}_{law}" for p in plan["packings"]
                     for law in laws]        # tdem.campaign._case_name
            runs = {n: vdir / "cases" / n / "thermal.h5" for n in names}
            missing = [n for n, p in runs.items() if not p.exists()]
            if missing:
                raise RuntimeError(f"{plan['label']}: {_variant(r)}: no thermal.h5 for {missing}")
        else:
            runs = {}
            for p in plan["packings"]:
                name = p.stem
                rdir = vdir / name
                if not (rdir / "thermal.h5").exists():
                    _call([str(TDEM), "run", str(plan["scene"]), "--packing", str(p), "--out",
                           str(rdir), "--quiet", *extra], rdir.with_suffix(".log"))
                runs[name] = rdir / "thermal.h5"
        log(f"  {plan['label']}: {_variant(r)}: {len(runs)} run(s) ({time.time() - t:.0f} s)")
        out[r] = runs
    return out


# ---------------------------------------------------------------------------------------------
# comparing

def _attrs(f) -> dict:
    return {k: (v.decode() if isinstance(v, bytes) else v) for k, v in f.attrs.items()}


def _same(a, b) -> bool:
    if isinstance(a, str) or isinstance(b, str):
        if a == b:
            return True
        try:        # JSON texts (neighbours): the same values, key order aside
            return json.loads(a) == json.loads(b)
        except (TypeError, ValueError):
            return False
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and bool(np.array_equal(a, b, equal_nan=True))


def _rel_array(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.shape != b.shape:
        return np.inf
    na, nb = ~np.isfinite(a), ~np.isfinite(b)
    if not np.array_equal(na, nb) or not np.array_equal(a[na], b[na], equal_nan=True):
        return np.inf
    if not (~na).any():
        return 0.0
    scale = np.abs(a[~na]).max()
    diff = np.abs(a[~na] - b[~na]).max()
    return float(diff / scale) if scale > 0 else float(diff)


_NUM = re.compile(r"[-+]?\d+(\.\d+)?(e[-+]?\d+)?")
POST_SKIP = ("seconds", "sha256", "thermal", "packing", "files")


def _leaves(x, key=""):
    if isinstance(x, dict):
        for k, v in x.items():
            if not any(s in k for s in POST_SKIP):
                yield from _leaves(v, f"{key}.{k}" if key else k)
    elif isinstance(x, (list, tuple)):
        for i, v in enumerate(x):
            yield from _leaves(v, f"{key}[{i}]")
    else:
        yield key, x


def compare_post(ref: Path, other: Path):
    """A campaign case's post/summary.json (γ, τ, steady γ, flux CoV, ...) against the
    in-process one: (max relative difference, its key); None without summaries. Informative:
    not part of the verdict (the fits' windows are thresholds on the temperatures)."""
    a, b = ref.parent / "post" / "summary.json", other.parent / "post" / "summary.json"
    if not (a.exists() and b.exists()):
        return None
    la, lb = dict(_leaves(json.loads(a.read_text()))), dict(_leaves(json.loads(b.read_text())))
    worst, key = 0.0, ""
    for k in sorted(set(la) | set(lb)):
        x, y = la.get(k, "missing"), lb.get(k, "missing")
        if isinstance(x, (int, float)) and isinstance(y, (int, float)) \
                and not isinstance(x, bool) and not isinstance(y, bool):
            if x == y or (x != x and y != y):
                continue
            d = abs(x - y) / abs(x) if x != 0 else abs(y)
        elif isinstance(x, str) and isinstance(y, str):      # a sentence: its words, not
            d = 0.0 if _NUM.sub("#", x) == _NUM.sub("#", y) else np.inf  # its round-off digits
        else:
            d = 0.0 if x == y else np.inf
        if d > worst:
            worst, key = d, k
    return worst, key


def compare(ref: Path, other: Path, ranks: int) -> dict:
    """The run ``other`` against the in-process run ``ref`` (the measures of the docstring);
    ``other`` must say it ran on the PETSc backend on ``ranks`` ranks, ``ref`` that it did not."""
    with h5py.File(ref, "r") as fa, h5py.File(other, "r") as fb:
        A, B = _attrs(fa), _attrs(fb)
        Ta, Tb = fa["temperature"][()], fb["temperature"][()]
        T0 = fa["initial_temperature"][()]
        arrays = {k: _rel_array(fa[k][()], fb[k][()]) for k in ARRAYS if k in fa and k in fb}
        missing = [k for k in ARRAYS if (k in fa) != (k in fb)]
    if Ta.shape != Tb.shape:
        dT_rel = T_rel = np.inf
    else:
        both = np.concatenate([Ta.ravel(), T0.ravel()])
        span = float(both.max() - both.min()) or float(np.abs(Ta).max())
        diff = float(np.abs(Ta - Tb).max())
        dT_rel, T_rel = diff / span, diff / float(np.abs(Ta).max())
    differ = [k for k in SAME_ATTRS if (k in A) != (k in B) or (k in A and not _same(A[k], B[k]))]
    differ += missing
    if (A.get("backend") == "petsc" or B.get("backend") != "petsc"
            or int(B.get("ranks", -1)) != ranks):
        differ.append(f"backend/ranks ({A.get('backend', 'in-process')} / "
                      f"{B.get('backend', 'in-process')} on {B.get('ranks', '?')})")
    if "neighbours" in A and not _same(A["neighbours"], B.get("neighbours")):
        differ.append("neighbours")
    for k in CLOSE_ATTRS:
        if k in A and k in B and _rel_array(A[k], B[k]) > 1e-12:
            differ.append(k)
    method = str(A.get("method", ""))
    kind = "steady" if method.startswith("steady") else (
        "explicit" if method.startswith("explicit") else "implicit")
    tol = TOL[kind]
    arr = max(arrays.values()) if arrays else 0.0
    ok = dT_rel <= tol and arr <= tol and not differ
    return dict(code=(A.get("git_hash", "?"), B.get("git_hash", "?")),
                post=compare_post(ref, other), method=method, kind=kind,
                n=int(A.get("n_particles", 0)), dT_rel=dT_rel,
                T_rel=T_rel, arrays=arr, worst_array=max(arrays, key=arrays.get) if arrays else "",
                array_rel=arrays, flags_ref=A.get("flags", ""), flags=B.get("flags", ""),
                flags_same=A.get("flags") == B.get("flags"), differ=differ, tol=tol, ok=ok,
                ledger=(A.get("ledger_residual_relative"), B.get("ledger_residual_relative")),
                backend=B.get("backend", ""), ranks=B.get("ranks", ""),
                linear_solver=B.get("linear_solver", ""))


# ---------------------------------------------------------------------------------------------
# tables

def _e(x) -> str:
    return "inf" if not np.isfinite(x) else ("0" if x == 0 else f"{x:.1e}")


def _post(p) -> str:
    return "-" if p is None else (f"{_e(p[0])} ({p[1]})" if p[0] > 0 else "0")


def summary_rows(results) -> list:
    rows = []
    for plan, per_rank in results:
        for r in RANKS:
            cs = list(per_rank.get(r, {}).values())
            if not cs:
                continue
            kinds = sorted({c["method"] for c in cs})
            ns = sorted({c["n"] for c in cs})
            rows.append(dict(
                scene=plan["label"], runs=len(cs),
                n=", ".join(str(n) for n in ns), solver=", ".join(kinds), ranks=r,
                dT=max(c["dT_rel"] for c in cs), T=max(c["T_rel"] for c in cs),
                arrays=max(c["arrays"] for c in cs),
                post=(max((c["post"] for c in cs if c["post"]), default=None)),
                flags="yes" if all(c["flags_same"] for c in cs) else "no",
                same="yes" if all(not c["differ"] for c in cs) else
                     "no: " + ", ".join(sorted({d for c in cs for d in c["differ"]})),
                tol=" / ".join(sorted({f"{c['tol']:.0e}" for c in cs})),
                ok="within" if all(c["ok"] for c in cs) else "**beyond**"))
    return rows


def markdown(results, skipped, command, started, load) -> str:
    head = ("| scene | runs | N | solver | ranks | max abs(T - T_in-process) / temperature change"
            " | the same / max abs(T) | flows, ledger, capacity: max rel diff | flags identical |"
            " counts, dt, bounds identical | tolerance | verdict | campaign's post (γ, τ, ...):"
            " max rel diff |\n"
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n")
    body = "".join(
        f"| {r['scene']} | {r['runs']} | {r['n']} | {r['solver']} | {r['ranks']} | {_e(r['dT'])} "
        f"| {_e(r['T'])} | {_e(r['arrays'])} | {r['flags']} | {r['same']} | {r['tol']} "
        f"| {r['ok']} | {_post(r['post'])} |\n" for r in summary_rows(results))
    lines = ["# Every scene of runs/ in-process and on 1, 2 and 3 ranks (issue 25)", "",
             f"Written by `{command}` ({started}; load {load}). Each scene run in-process "
             "(`tdem run --threads 1`, `tdem campaign --threads 1`) and with `--ranks 1`, `2`, "
             "`3`; every `thermal.h5` compared with the in-process one (a row: the worst of the "
             "scene's runs on that many ranks). Tolerance: explicit 1e-12, implicit and steady "
             "1e-10 of the run's temperature change (the tests' measure); the flows and ledger "
             "arrays relative to each array's max abs value, judged at the same tolerance; "
             "flags, steps, conducting contacts, rattlers, floating clusters, maximum-principle "
             "bounds, neighbour choice identical and dt, its bound within 1e-12. The last "
             "column, for the campaigns, compares the numbers `tdem post` made from each case "
             "(its `post/summary.json`: γ and its interval, steady γ, τ, flux CoV, ...; "
             "informative, not in the verdict).", "",
             head + body, "", "Packings:", ""]
    for plan, _ in results:
        lines.append(f"- {plan['label']}: {plan['note']}")
    codes = sorted({h for _, pr in results for cs in pr.values() for c in cs.values()
                    for h in c["code"]})
    lines += ["", "The code the runs ran (each thermal.h5's git_hash; `-dirty`: other files of "
              "the checkout were being edited): " + ", ".join(f"`{h}`" for h in codes) + "."]
    if skipped:
        lines += ["", "Skipped:", ""] + [f"- {s}: {why}" for s, why in skipped]
    lines += ["", "## Every run", "",
              "| scene | run | N | method | ranks | T diff / change | T diff / max T | "
              "worst array (rel) | "
              "flags (in-process) | flags (ranks) | differs | linear solver | verdict |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for plan, per_rank in results:
        for r in RANKS:
            for name, c in per_rank.get(r, {}).items():
                lines.append(
                    f"| {plan['label']} | {name} | {c['n']} | {c['method']} | {r} | "
                    f"{_e(c['dT_rel'])} | {_e(c['T_rel'])} | {c['worst_array']} "
                    f"({_e(c['arrays'])}) | {c['flags_ref'] or '-'} | {c['flags'] or '-'} | "
                    f"{', '.join(c['differ']) or '-'} | {c['linear_solver'] or '-'} | "
                    f"{'within' if c['ok'] else '**beyond**'} |")
    return "\n".join(lines) + "\n"


def console_table(results) -> str:
    rows = summary_rows(results)
    cols = [("scene", "scene"), ("runs", "runs"), ("N", "n"), ("solver", "solver"),
            ("ranks", "ranks"), ("dT rel", "dT"), ("T rel", "T"), ("arrays", "arrays"),
            ("flags same", "flags"), ("counts same", "same"), ("tol", "tol"), ("verdict", "ok"),
            ("post", "post")]
    cells = [[h for h, _ in cols]] + [[_e(r[k]) if k in ("dT", "T", "arrays") else
                                       _post(r[k]) if k == "post" else str(r[k])
                                       for _, k in cols] for r in rows]
    widths = [max(len(c[i]) for c in cells) for i in range(len(cols))]
    return "\n".join("  ".join(c[i].ljust(widths[i]) for i in range(len(cols))) for c in cells)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scratch", default=str(ROOT / "bench" / "out" / "ranks"))
    ap.add_argument("--md", default=str(ROOT / "bench" / "results" / "ranks_same_answers.md"),
                    help="markdown table to write ('' for none)")
    ap.add_argument("--scenes", default="", help="comma-separated scene names (default: all)")
    ap.add_argument("--max-n", type=int, default=1500,
                    help="n_particles of a packing made here when runs/out has none")
    ap.add_argument("--all-pressures", action="store_true",
                    help="every packing of a pressure series, not its lowest and highest")
    ap.add_argument("--lowest-only", default="",
                    help="comma-separated campaigns to run on their lowest pressure only (e.g. "
                         "campaign_7500: 6,000 Crank-Nicolson steps on 7,500 spheres a case)")
    ap.add_argument("--fresh", action="store_true", help="run again what the scratch holds")
    ap.add_argument("--plan-only", action="store_true",
                    help="say which scenes run on which packings (builds missing packings)")
    args = ap.parse_args(argv)
    scratch = Path(args.scratch).resolve()
    scratch.mkdir(parents=True, exist_ok=True)
    started = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    load0 = " ".join(f"{x:.2f}" for x in os.getloadavg())

    def log(msg):
        print(msg, flush=True)

    plans, skipped = plan_scenes(args, scratch, log)
    for p in plans:
        log(f"{p['label']}: {p['kind']} on {p['note']}")
    for s, why in skipped:
        log(f"{s}: skipped: {why}")
    if args.plan_only:
        return 0
    results = []
    for plan in plans:
        runs = run_plan(plan, scratch, args.fresh, log)
        per_rank = {}
        for r in RANKS:
            per_rank[r] = {name: compare(runs[0][name], path, r)
                           for name, path in runs[r].items() if name in runs[0]}
            lost = set(runs[0]) ^ set(runs[r])
            if lost:
                raise RuntimeError(f"{plan['label']}: ranks {r}: runs {sorted(lost)} not in both")
        results.append((plan, per_rank))
    load = f"{load0} / " + " ".join(f"{x:.2f}" for x in os.getloadavg())
    print(console_table(results))
    for s, why in skipped:
        print(f"skipped {s}: {why}")
    command = "python bench/ranks_same_answers.py" + (" " + " ".join(argv if argv is not None
                                                                     else sys.argv[1:])).rstrip()
    if args.md:
        from thermal_kernel.atomic import write_text_atomic
        write_text_atomic(Path(args.md), markdown(results, skipped, command.strip(), started,
                                                  load))
        print(f"wrote {args.md}")
    return 0 if all(c["ok"] for _, pr in results for cs in pr.values() for c in cs.values()) \
        else 1


if __name__ == "__main__":
    sys.exit(main())
