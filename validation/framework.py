"""The validation framework of docs/validation.md (issue 14): one registry of cases, one home for
the packings they share, resumable runs, and the document assembled from what ran.

A case is a module ``validation/caseN_<name>.py`` exposing

    CASE = CaseInfo(number=N, title="...", paper="002 sec. 2.2, eq. 17", paper_n="1e5",
                    paper_error="max rel. error 0.7 %")
    def run(ctx: Context) -> CaseResult
    ACTIONS = {"rebuild": Action(step, "help")}     (optional: `tdem validate N --action NAME`)

``run`` does the work (packings through ``ctx.packing(name)``, outputs under ``ctx.out``, figures
as ``ctx.figure(stem)`` -> docs/img/validation_caseN_<stem>.png with a CSV of the plotted numbers
beside it) and returns the summary row and the markdown of its section. ``ctx.quick`` asks for the
smallest instance (a few thousand spheres), used by tests/test_validation_small.py; the full run
is ``tdem validate N`` / ``make validate``. Results are saved as validation/results/caseN.json
(committed: the document is rebuilt from them) and docs/validation.md is assembled from them by
``validation.run.assemble``.
"""
from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from thermal_kernel.errors import UserError
from thermal_kernel.atomic import write_text_atomic

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "validation" / "out"            # large outputs (gitignored)
RESULTS = ROOT / "validation" / "results"    # small JSON per case (committed)
IMG = ROOT / "docs" / "img"
DATA = ROOT / "tests" / "data"               # the committed small packings of quick instances
# a field a saved result may lack (written before it existed): read as absent, not refused
_MAY_LACK = {"optional": True}


@dataclass(frozen=True)
class CaseInfo:
    number: int
    title: str
    paper: str          # where in which paper, e.g. "002 sec. 2.2, eq. 17"
    paper_n: str        # the paper's number of spheres, as text ("1e5", "19,465")
    paper_error: str    # the paper's result / error, as text
    # issue 23: what tdem must reach at the paper's own N, by the paper's measure (or the stricter
    # reading where the paper leaves the measure open), as text; the verdict is judged on it
    target: str = field(default="", metadata=_MAY_LACK)


@dataclass
class CaseResult:
    our_n: str                  # the N we ran (largest, and the range), as text
    our_error: str              # our error in the paper's measure (and stricter ones), as text
    wall_time: str              # "packing + thermal" as text with units
    verdict: str                # in words: met / not met / why
    section_md: str             # the case's section of docs/validation.md (markdown, no heading)
    # machine-readable values (tests read them)
    numbers: dict = field(default_factory=dict, metadata=_MAY_LACK)
    command: str = field(default="", metadata=_MAY_LACK)    # the command that reproduces it
    # issue 23, the column the verdict is judged on: tdem at the paper's own N by the paper's
    # measure (the stricter reading where the paper's is undefined, named), e.g.
    # "N 100,031: 0.58 % of ΔT (max over 10 bins; 0.17 % of T in °C beside it)"
    at_paper_n: str = field(default="", metadata=_MAY_LACK)
    # the N and wall time tdem needs to reach the paper's error (or "not reached up to N ...")
    speed_vs_error: str = field(default="", metadata=_MAY_LACK)
    # judged on at_paper_n against CaseInfo.target
    target_met: bool | None = field(default=None, metadata=_MAY_LACK)


@dataclass(frozen=True)
class Judgement:
    """Issue 23's columns of one case, from its saved ``numbers``: tdem at the paper's own N by
    the paper's measure (the verdict is judged on it), the N and time needed to reach the
    paper's error, and whether CaseInfo.target is met (None: the paper gives no number)."""
    at_paper_n: str
    speed_vs_error: str
    target_met: bool | None
    verdict: str = ""       # judged on at_paper_n; "" keeps the case's own


def judged(result: CaseResult, judgement: Judgement) -> CaseResult:
    """``result`` with the issue-23 columns of ``judgement`` filled in (and its verdict, when
    the judgement gives one)."""
    return dataclasses.replace(result, at_paper_n=judgement.at_paper_n,
                               speed_vs_error=judgement.speed_vs_error,
                               target_met=judgement.target_met,
                               verdict=judgement.verdict or result.verdict)


@dataclass(frozen=True)
class Action:
    """An extra step of a case beside its run (rebuild the section from the saved result, add
    one more instance to it, ...): ``ACTIONS = {name: Action(step, help)}`` in the case's module,
    run by ``tdem validate N --action NAME`` with the case's :class:`Context`."""
    step: object            # Callable[[Context], object]
    help: str


@dataclass
class Context:
    number: int
    quick: bool = False
    threads: int = 1

    @property
    def out(self) -> Path:
        d = OUT / (f"case{self.number}" + ("_quick" if self.quick else ""))
        d.mkdir(parents=True, exist_ok=True)
        return d

    def figure(self, stem: str) -> Path:
        """docs/img/validation_case<N>_<stem>.png (quick runs write under ctx.out instead, so a
        test never overwrites the documented figures); put the CSV beside it (same stem)."""
        if self.quick:
            return self.out / f"validation_case{self.number}_{stem}.png"
        IMG.mkdir(parents=True, exist_ok=True)
        return IMG / f"validation_case{self.number}_{stem}.png"

    def packing(self, name: str) -> Path:
        return packing(name)

    def progress(self, text: str) -> None:
        print(f"  case {self.number}: {text}", flush=True)


# ---------------------------------------------------------------- shared packings
# name -> (scene TOML whose [pack] table is used, overrides of that table). Built once by
# `tdem pack` into validation/out/packings/<name>/packing.h5 and shared by every case. Tiled
# packings of seed 1 copy the relaxed 10,000-sphere cell of runs/dense_box_1e5.toml when it exists
# (cell_packing), so the 1e5 / 1e6 boxes, the cylinder and the sphere cost seconds after it.
CELL_1E5 = ROOT / "runs" / "out" / "dense_box_1e5" / "cell.h5"
PACKINGS: dict[str, tuple[str, dict]] = {
    "box_2000": ("runs/dense_box.toml", dict(n_particles=2000, seed=1)),
    "box_1e5": ("runs/dense_box_1e5.toml", {}),
    "box_1e6": ("runs/dense_box_1e5.toml", dict(n_particles=1_000_000)),
    "cylinder_1e5": ("runs/dense_cylinder.toml", dict(n_particles=100_000, method="tiled",
                                                      cell_particles=10_000)),
    "sphere_1e5": ("runs/dense_sphere.toml", dict(n_particles=100_000, method="tiled",
                                                  cell_particles=10_000)),
    # the cube at the paper's N with pressed walls (issue 24): the direct relaxation, ~1-2 h of
    # one YADE thread, so cases 4 and 8 take it only when built (bench_walled's direct_100000_s1
    # is the same scene)
    "box_1e5_walled": ("runs/dense_box.toml", dict(n_particles=100_000, seed=1, method="direct",
                                                   max_seconds=14400.0)),
}


# What the 10,000-sphere cell of the tiled boxes (runs/dense_box_1e5.toml, seed 1) cost: the
# packing benchmark's record of the tiled 1e5 box built from scratch (bench/bench_packings.py:
# the CPU of `tdem pack`'s process tree, YADE's relaxation of the cell and the copying).
CELL_1E5_RECORD = ROOT / "bench" / "results" / "packings_cases" / "tiled_100000_s1_c10000.json"


def cell_cpu_seconds() -> float | None:
    """CPU seconds the 1e5 cell took to relax (and copy), from the packing benchmark's record
    (:data:`CELL_1E5_RECORD`), None when the record is not here: cases 4, 5 and 6 quote it."""
    try:
        return float(json.loads(CELL_1E5_RECORD.read_text())["cpu_seconds"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def cell_cost_text(fmt: str = "{:.0f} s", missing: str = "the cell's YADE time") -> str:
    """:func:`cell_cpu_seconds` in ``fmt`` (``missing`` when there is no record)."""
    cpu = cell_cpu_seconds()
    return missing if cpu is None else fmt.format(cpu)


def register_packing(name: str, scene: str, overrides: dict) -> None:
    """A case adds the packings only it needs (e.g. a beam, a sheet) under its own names."""
    PACKINGS.setdefault(name, (scene, overrides))


def scene_with_pack(scene: Path, overrides: dict) -> str:
    """The scene file's text with ``overrides`` written into its [pack] table."""
    lines, in_pack = [], False
    for line in scene.read_text().splitlines():
        if line.startswith("["):
            in_pack = line.strip() == "[pack]"
            lines.append(line)
            if in_pack:
                lines += [f"{k} = {json.dumps(v)}" for k, v in overrides.items()]
            continue
        if in_pack and line.split("=")[0].strip() in overrides:
            continue
        lines.append(line)
    return "\n".join(lines) + "\n"


def packing(name: str) -> Path:
    """validation/out/packings/<name>/packing.h5, built by `tdem pack` when missing."""
    if name not in PACKINGS:
        raise SystemExit(f"validation: unknown packing {name!r} (known: {', '.join(PACKINGS)})")
    folder = OUT / "packings" / name
    path = folder / "packing.h5"
    if path.exists():
        return path
    folder.mkdir(parents=True, exist_ok=True)
    import fcntl
    with open(folder / ".lock", "w") as lock:    # two cases asking at once: one builds
        fcntl.flock(lock, fcntl.LOCK_EX)
        if path.exists():
            return path
        return _build_packing(name, folder, path)


def _build_packing(name: str, folder: Path, path: Path) -> Path:
    scene_rel, overrides = PACKINGS[name]
    overrides = dict(overrides)
    if overrides.get("method", _pack_value(ROOT / scene_rel, "method")) == "tiled" \
            and overrides.get("seed", 1) == 1 and CELL_1E5.exists() \
            and overrides.get("cell_particles", 10_000) == 10_000:
        overrides.setdefault("cell_packing", str(CELL_1E5))
    scene = folder / "scene.toml"
    write_text_atomic(scene, scene_with_pack(ROOT / scene_rel, overrides))
    print(f"  packing {name}: tdem pack {scene.relative_to(ROOT)} ...", flush=True)
    t0 = time.perf_counter()
    tdem = Path(sys.executable).with_name("tdem")
    proc = subprocess.run([str(tdem), "pack", str(scene), "--out", str(folder), "--quiet"],
                          capture_output=True, text=True)
    write_text_atomic(folder / "tdem_pack.log", proc.stdout + proc.stderr)
    if proc.returncode != 0:
        last = (proc.stderr or proc.stdout).strip().splitlines()[-1:] or ["?"]
        raise SystemExit(f"validation: packing {name} failed: {last[0]}")
    write_text_atomic(folder / "pack_seconds.json", json.dumps(
        {"wall_seconds": time.perf_counter() - t0}))
    return path


def _pack_value(scene: Path, key: str):
    from thermal_kernel.scene import read_toml
    return read_toml(scene)[0].get("pack", {}).get(key)


def pack_seconds(name: str) -> float | None:
    """Wall seconds `tdem pack` took for a shared packing (None if it was not built here)."""
    p = OUT / "packings" / name / "pack_seconds.json"
    return json.loads(p.read_text())["wall_seconds"] if p.exists() else None


def pack_text(name: str) -> str:
    """:func:`pack_seconds` as a table cell: "12 s", "—" when not built here."""
    s = pack_seconds(name)
    return "—" if s is None else f"{s:.0f} s"


def packs_text(runs) -> str:
    """The packings' seconds of ``runs`` (each with ``name`` and ``pack_s``), "box_1e5 95 s,
    ...", those not built here left out."""
    return ", ".join(f"{r.name} {r.pack_s:.0f} s" for r in runs if r.pack_s)


def save_result(info: CaseInfo, result: CaseResult, seconds: float) -> Path:
    RESULTS.mkdir(parents=True, exist_ok=True)
    path = RESULTS / f"case{info.number}.json"
    record = dict(info=dataclasses.asdict(info), result=dataclasses.asdict(result),
                  run_seconds=seconds, finished=time.strftime("%Y-%m-%d %H:%M:%S"))
    return write_text_atomic(path, json.dumps(record, indent=1, default=float))


def rebuild_saved(info: CaseInfo, build) -> Path:
    """``tdem validate N --action rebuild``: the case's result made again by ``build(numbers)``
    from its saved record alone (section, figures, summary columns; nothing measured) and saved
    with the record's run seconds."""
    record = load_result(info.number)
    if record is None:
        raise UserError(f"validate: --action rebuild: case {info.number} has no saved result "
                        f"(`tdem validate {info.number}` measures it)")
    return save_result(info, build(record["result"]["numbers"]), record["run_seconds"])


# ---------------------------------------------------------------- helpers for the cases
def packing_built(name: str) -> bool:
    """True when the shared packing ``name`` is already on this machine (no YADE needed)."""
    return (OUT / "packings" / name / "packing.h5").exists()


class ResultError(UserError):
    """A saved validation/results/caseN.json that is not a record :func:`save_result` writes
    (truncated, empty, binary, a list, a field missing or of another type): one line naming the
    file, the field and what was expected, and how to write it again."""


def shown(path: Path) -> str:
    """``path`` relative to the checkout when it is inside it (as messages name files)."""
    try:
        return str(Path(path).relative_to(ROOT))
    except ValueError:
        return str(path)


@dataclass(frozen=True)
class SavedResult:
    """What :func:`save_result` writes as validation/results/caseN.json: the case's info, its
    result, the seconds the run took and when it finished (read back by :func:`load_result`)."""
    info: CaseInfo
    result: CaseResult
    run_seconds: float
    finished: str


def check_record(number: int, record, path: Path) -> dict:
    """``record`` if it is a :class:`SavedResult` of case ``number`` (every field there, none
    unknown, each of its type, run_seconds >= 0), else :class:`ResultError` in one line."""
    from tdem_post.records import RecordError, from_dict

    def fail(what):
        raise ResultError(f"{what}; expected a result as `tdem validate` saves it: the saved "
                          f"result is unreadable (`tdem validate {number} --force` runs case "
                          f"{number} again and rewrites it)")
    try:
        saved = from_dict(SavedResult, record, shown(path))
    except RecordError as e:
        fail(str(e))
    if not saved.run_seconds >= 0:
        fail(f"{shown(path)}: run_seconds: {saved.run_seconds!r} is not >= 0")
    if saved.info.number != number:
        fail(f"{shown(path)}: info: number: {saved.info.number}, not {number}")
    return record


def load_result(number: int) -> dict | None:
    """The saved record of case ``number`` (validation/results/caseN.json), or None when there
    is none; :class:`ResultError` (one line) when the file is not a readable record."""
    path = RESULTS / f"case{number}.json"
    if not path.exists():
        return None
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError as e:
        raise ResultError(f"{shown(path)}: expected JSON text (UTF-8), got byte "
                          f"0x{e.object[e.start]:02x} at offset {e.start}; the saved result is "
                          f"unreadable (`tdem validate {number} --force` runs case {number} "
                          "again and rewrites it)") from None
    except json.JSONDecodeError as e:
        got = "an empty file" if not e.doc.strip() else \
            f"invalid JSON ({e.msg}, line {e.lineno} column {e.colno})"
        raise ResultError(f"{shown(path)}: expected a JSON object as tdem validate saves it, "
                          f"got {got}; the saved result is unreadable (`tdem validate {number} "
                          f"--force` runs case {number} again and rewrites it)") from None
    except OSError as e:
        raise ResultError(f"{shown(path)}: {e.strerror or e}") from None
    return check_record(number, record, path)


def previous_numbers(number: int) -> dict:
    """``numbers`` of the last saved run of case ``number`` ({} if none, or if the saved file is
    unreadable: nothing to carry over): a case re-measures what it can and carries over, with
    their dates, the rows whose packings are not on this machine."""
    try:
        record = load_result(number)
    except ResultError:
        return {}
    return dict(record["result"].get("numbers", {})) if record else {}


def write_csv(path: Path, header, rows, digits: int | None = 10,
              line_end: str = "\r\n") -> Path:
    """A small CSV (the numbers of a figure or a table), written atomically by the csv module:
    ``header`` (a sequence, or its names comma-separated), then ``rows``, floats to ``digits``
    significant digits (as given when None), lines ended by ``line_end``."""
    import csv
    import io
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = io.StringIO(newline="")
    w = csv.writer(text, lineterminator=line_end)
    w.writerow(header.split(",") if isinstance(header, str) else list(header))
    for r in rows:
        w.writerow([f"{v:.{digits}g}" if digits and isinstance(v, float) else v for v in r])
    return write_text_atomic(path, text.getvalue())


def today() -> str:
    return time.strftime("%Y-%m-%d")


def scene_toml(packing, law: str, **tables) -> str:
    """A case's scene as the TOML text a user would write (docs/scenes.md), for
    :func:`case_scene`: ``packing`` and ``law``, then each of
    ``tables`` in the order given, a dict as a table ``[name]`` and a list of dicts as an array
    of tables ``[[name]]`` (``boundary=[...]``); a table that is None or empty is left out.
    Written by the kernel's one TOML writer (``thermal_kernel.scene.toml_text``)."""
    from thermal_kernel.scene import toml_text
    return toml_text({"packing": str(packing), "law": law,
                      **{name: table for name, table in tables.items() if table}})


def case_scene(text: str | None, where: Path):
    """A case's scene from its TOML text (:func:`scene_toml`), read and checked as ``tdem run``
    reads a scene file (``thermal_kernel.scene.load_scene``); ``where`` names it in messages
    and resolves relative paths (nothing is read there; ``text`` None: the scene file
    ``where``). The case then runs it as a user does, through
    ``thermal_kernel.run.run_in_memory``."""
    from thermal_kernel.scene import load_scene
    return load_scene(where, text=text)


def held_planes(scene, packing, axis: str) -> tuple[float, float]:
    """(lo, hi) along ``axis``: the mean centre coordinate of the particles held on the
    ``axis``min and ``axis``max faces (the boundary rule of ``scene``) - the held planes, whose
    distance is the slab length of cases 2-6 (docs/validation.md, "The slab length")."""
    import numpy as np

    from thermal_kernel.problem import boundary_particles
    k = "xyz".index(axis)
    lo, hi = (float(np.mean(packing.position[boundary_particles(
        scene, packing, f"{axis}{side}", "b")][:, k])) for side in ("min", "max"))
    return lo, hi


def held_plane_ct(scene, packing, axis: str, ct_used: float, conductivity_w_mk: float):
    """The steady flux test along ``axis`` (002 eq. 8-9) and C_t in both length conventions:
    (test, ct_domain, ct_held), ct_domain = ct_used λ / λ_e with the domain length (the
    paper's), ct_held = ct_domain × domain length / held-plane distance."""
    from thermal_kernel.calibrate import flux_test
    test = flux_test(scene, packing, axis)
    lo, hi = held_planes(scene, packing, axis)
    ct_domain = ct_used * conductivity_w_mk / test.effective_w_mk
    return test, ct_domain, ct_domain * test.length_m / (hi - lo)


def new_figure(*args, **kwargs):
    """``plt.subplots(*args, **kwargs)`` on matplotlib's Agg backend (no display): (fig, axes)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt.subplots(*args, **kwargs)


# a one-axes figure whose CSV has floats to 8 digits and "\n" line ends (cases 2 and 3, as
# committed)
FIGURE_8 = dict(figsize=(6.4, 4.2), digits=8, line_end="\n")


def dress(ax, xlabel: str | None = None, ylabel: str | None = None, title: str | None = None,
          legend: float | None = 7, grid: bool = False, title_size: float | None = 9,
          **legend_kw) -> None:
    """A case's axes labelled: ``xlabel``, ``ylabel``, ``title`` (at ``title_size``; None:
    matplotlib's), the log grid of the speed figures (``grid``), and the legend (of what is
    drawn so far: call it last) at ``legend`` points (None: no legend) with ``legend_kw``."""
    if xlabel is not None:
        ax.set_xlabel(xlabel)
    if ylabel is not None:
        ax.set_ylabel(ylabel)
    if title is not None:
        ax.set_title(title, **({} if title_size is None else dict(fontsize=title_size)))
    if grid:
        ax.grid(True, which="both", alpha=0.3)
    if legend is not None:
        ax.legend(fontsize=legend, **legend_kw)


@contextlib.contextmanager
def figure_csv(path: Path, header, *grid, figsize, dpi: int = 110, digits: int | None = 10,
               line_end: str = "\r\n"):
    """Every case's figure and the CSV of its numbers beside it, in one place::

        with figure_csv(ctx.figure("profiles"), ["x", "T_K"], 1, 2, figsize=(10, 4)) as (ax, csv):
            ...draw on ax (the axes of ``plt.subplots(*grid)``), append the plotted numbers...

    When the block ends the figure is laid out (tight), written to ``path`` atomically at
    ``dpi`` and closed, and ``rows`` go to ``path`` with the suffix .csv below ``header``
    (:func:`write_csv`: floats to ``digits`` significant digits, or as given; ``line_end``).
    The cases keep the number format and line ends their committed CSVs were written with
    (docs/img/validation_*.csv, byte for byte). An error in the block writes neither file."""
    import matplotlib.pyplot as plt

    from thermal_kernel.atomic import savefig_atomic
    fig, axes = new_figure(*grid, figsize=figsize)
    rows: list = []
    try:
        yield axes, rows
    except BaseException:
        plt.close(fig)
        raise
    fig.tight_layout()
    savefig_atomic(fig, path, dpi=dpi)
    plt.close(fig)
    write_csv(Path(path).with_suffix(".csv"), header, rows, digits=digits, line_end=line_end)


# ---------------------------------------------------------------- section text
def pct(v, digits: int = 2) -> str:
    """A fraction as a percentage, "12.34 %" ("—" when None or not finite)."""
    import math
    return "—" if v is None or not math.isfinite(v) else f"{100 * v:.{digits}f} %"


def outcome(met: bool | None) -> str:
    """The verdict's first words: "target met", "target missed", "quick run" (None)."""
    return "target met" if met else "target missed" if met is False else "quick run"


def numbers_reader(cls, number: int):
    """A case's ``read_numbers(numbers)``: its saved ``numbers`` as its record ``cls`` (a missing
    or unknown field: RecordError in one line, "case N: numbers: ...")."""
    from tdem_post.records import from_dict
    return lambda numbers: from_dict(cls, numbers, f"case {number}: numbers")


def read_records(cls, items, where: str) -> list:
    """``items`` (saved dicts, or ``cls`` records already) as ``cls`` records, each named
    ``where[k]`` in a RecordError (one line)."""
    from tdem_post.records import from_dict
    return [r if isinstance(r, cls) else from_dict(cls, r, f"{where}[{k}]")
            for k, r in enumerate(items)]


def md_table(header, rows) -> str:
    """A table of a case's section, the one home of its markdown: ``header`` (its cells; an
    empty one is ``| |``) over the rule ``|---|...|``, then ``rows`` (each a sequence of cells,
    written by ``str``), one line each, no newline after the last."""
    return "\n".join(["|" + "|".join(f" {h} " if h else " " for h in header) + "|",
                      "|" + "---|" * len(header)]
                     + ["| " + " | ".join(map(str, r)) + " |" for r in rows])


def figure_md(caption: str, path: Path) -> str:
    """A figure of a case's section with its numbers under it: ``![caption](link)``, an empty
    line and ``(data: `link.csv`)``, the links as :func:`doc_link` gives them."""
    return (f"![{caption}]({doc_link(path)})\n\n"
            f"(data: `{doc_link(Path(path).with_suffix('.csv'))}`)")


def doc_link(path: Path) -> str:
    """A figure's path as docs/validation.md links it (relative to docs/; a quick run's figure
    outside docs/ as it is)."""
    try:
        return str(Path(path).relative_to(ROOT / "docs"))
    except ValueError:
        return str(path)


def fit_order(n, err) -> tuple[float, float]:
    """Convergence order: (p, C) of |err| = C N^p by least squares in log-log, over the points
    with N > 0 and a finite |err| > 0 (NaN, NaN with fewer than two). The one fit of every
    case's observed order."""
    import numpy as np
    n, err = np.asarray(n, float), np.abs(np.asarray(err, float))
    ok = (n > 0) & (err > 0) & np.isfinite(n) & np.isfinite(err)
    if ok.sum() < 2:
        return float("nan"), float("nan")
    p, logc = np.polyfit(np.log(n[ok]), np.log(err[ok]), 1)
    return float(p), float(np.exp(logc))


def cached(path: Path, make, version: int, arrays: tuple[str, ...] = ()) -> dict:
    """A run's record from ``path`` (JSON) when it was made by this ``version`` of its case, else
    ``make()`` saved there with its version: a case resumes run by run. Keys starting with "_"
    stay out of the JSON; with ``arrays`` (names), the record's ``"_field"`` (a tuple of arrays)
    is kept in the .npz beside it under those names and read back. Under ``tdem validate
    --ranks R`` the record is ``<stem>.ranksR<suffix>``: runs on ranks are cached apart."""
    import numpy as np

    from thermal_kernel.atomic import replacing
    from thermal_kernel.run import ranks_in_effect
    path = Path(path)
    if ranks_in_effect():
        path = path.with_name(f"{path.stem}.ranks{ranks_in_effect()}{path.suffix}")
    npz = path.with_suffix(".npz")
    if path.exists():
        rec = json.loads(path.read_text())
        if rec.get("version") == version:
            if arrays and npz.exists():
                with np.load(npz) as z:
                    rec["_field"] = tuple(z[a] for a in arrays)
            return rec
    rec = make()
    rec["version"] = version
    if arrays and "_field" in rec:
        with replacing(npz, keep_suffix=True) as tmp:     # (numpy adds .npz to other names)
            np.savez_compressed(tmp, **dict(zip(arrays, rec["_field"])))
    write_text_atomic(path, json.dumps({k: v for k, v in rec.items() if not k.startswith("_")},
                                       indent=1, default=float))
    return rec


# The dense-box family of cases 4 and 6 below 1e5 and at 8e6 (docs/packings.md's paths: "ds" =
# walled, density-scaled; "reference" = walled, P-wave time step, ~1 h of YADE; "tiled" from a
# 2,000-sphere cell). A full run measures them only when they are built here (or with
# TDEM_VALIDATE_ALL_PACKINGS=1, which builds them: hours); otherwise a case carries over their
# last measured rows.
for _s in (2, 3):
    register_packing(f"box_2000_s{_s}", "runs/dense_box.toml", dict(n_particles=2000, seed=_s))
register_packing("box_1e4", "runs/dense_box.toml", dict(n_particles=10_000, seed=1))
register_packing("box_1e4_reference", "runs/dense_box.toml",
                 dict(n_particles=10_000, seed=1, time_step="p_wave"))
for _s in (1, 2, 3):
    register_packing(f"box_1e4_tiled_s{_s}", "runs/dense_box.toml",
                     dict(n_particles=10_000, seed=_s, method="tiled", cell_particles=2000))
register_packing("box_8e6", "runs/dense_box_1e5.toml", dict(n_particles=8_000_000))


def optional_packing(name: str, default: bool) -> Path | None:
    """The packing for one instance of a case: a default instance is built when missing; another
    one is used only when it is already built (or TDEM_VALIDATE_ALL_PACKINGS=1 asks to build it),
    else None (the case keeps its last measured row)."""
    if default or packing_built(name) or os.environ.get("TDEM_VALIDATE_ALL_PACKINGS") == "1":
        return packing(name)
    return None
