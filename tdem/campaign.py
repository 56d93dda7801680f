"""``tdem campaign CAMPAIGN.toml``: from pressures to conclusions (issue 4).

A campaign file is a bed scene with a ``[pack]`` table (the pressure series) and a
``[campaign]`` table::

    [campaign]
    laws = ["pipe", "bob"]       # each packing is run with each law
    n_bins = 8                   # profile bins between the two held walls

Steps, each kept so that an interrupted campaign resumes where it stopped:
1. packings: YADE builds the settled bed and every pressure in one process
   (``<out>/packings/``); reused when ``params.json`` there equals the campaign's parameters and
   every ``packing_<p>Pa.h5`` exists;
2. cases (pressure x law): the thermal scene runs on the packing (``<out>/cases/<p>Pa_<law>/
   thermal.h5``) and is post-processed (``post/summary.json``, which records the sha256 of the
   case's resolved scene and of the packing file's bytes); a case whose summary exists is kept
   when both hashes still match its inputs, recomputed (and said so) when either differs, and
   post-processed again from its thermal.h5 when only ``n_bins`` or the post-processing's code
   (tdem_post, its hash) changed. Every case is checked
   on its packing (the walls its boundaries name, the law's inputs) before any case runs;
3. ``campaign.json``, the campaign's record (:mod:`tdem_post.campaign_record`: a row per case and
   the fits over pressure), and from it ``results.csv`` (one row per case),
   ``gamma_p.png``/``tau_p.png`` (+ CSV) and ``report.md``
   with the power-law fits next to the paper's curves (003, Fig. 7 and 10) and the mean-field
   predictions; each case's ``flags`` (the attribute of its ``thermal.h5``: maximum principle,
   energy ledger, solver flags) is a column of both, and flagged runs are listed. Every file is
   written to a temporary name and renamed.
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import re
import sys
import time
from pathlib import Path

import numpy as np

from .errors import UserError
from thermal_kernel.atomic import savefig_atomic, write_text_atomic
from thermal_kernel.scene import read_toml

# flags of a run's thermal.h5 that make its numbers suspect (the others, e.g. rattlers or
# floating_clusters, describe the network); "unknown": a run written before flags existed
SUSPECT_FLAGS = ("max_principle", "energy_ledger", "dt_above_bound", "non_finite",
                 "no_steady_state_in_floating_cluster", "unknown")


def read_campaign(path: Path) -> tuple[dict, str]:
    path = Path(path)
    data, text = read_toml(path, error=UserError, what="a campaign TOML file")
    camp = data.get("campaign")
    if not isinstance(camp, dict):
        raise UserError(f"{path}: campaign: missing [campaign] table (laws = [...])")
    unknown = set(camp) - {"laws", "n_bins", "seeds", "packings"}
    if unknown:
        raise UserError(f"{path}: campaign.{sorted(unknown)[0]}: unknown key (known: laws, "
                        "n_bins, seeds, packings)")
    laws = camp.get("laws")
    from thermal_kernel.laws import LAWS
    if not (isinstance(laws, list) and laws and all(isinstance(x, str) for x in laws)):
        raise UserError(f"{path}: campaign.laws: expected a list of law names")
    for law in laws:
        if law not in LAWS:
            raise UserError(f"{path}: campaign.laws: unknown law {law!r} (known: "
                            f"{', '.join(LAWS)})")
    n_bins = camp.get("n_bins", 8)
    if not (isinstance(n_bins, int) and n_bins >= 3):
        raise UserError(f"{path}: campaign.n_bins: expected an integer >= 3")
    seeds = camp.get("seeds")
    from .pack import SEED_MAX
    if seeds is not None and not (
            isinstance(seeds, list) and seeds
            and all(isinstance(x, int) and not isinstance(x, bool) and 0 <= x <= SEED_MAX
                    for x in seeds)
            and len(set(seeds)) == len(seeds)):
        raise UserError(f"{path}: campaign.seeds: expected a list of distinct integers >= 0 "
                        f"and <= {SEED_MAX} (one packing series per seed; a seed is stored as "
                        f"a 64-bit integer), got {seeds!r}")
    if "packing" in data:
        raise UserError(f"{path}: packing: a campaign builds its packings from [pack]")
    packings = camp.get("packings")
    if packings is not None:        # existing packing files instead of [pack] (tdem/imported.py)
        from .imported import campaign_packings
        packings = campaign_packings(path, packings, "pack" in data, seeds)
    return dict(laws=laws, n_bins=n_bins, seeds=seeds, packings=packings,
                has_pack="pack" in data), text


def case_scenes(campaign_path: Path, conf: dict, text: str, out_dir: Path) -> dict:
    """{law: the campaign's thermal scene for that law}, parsed and checked by
    :func:`~thermal_kernel.scene.load_scene`: the campaign file's tables without [pack] and
    [campaign], with ``law`` set (the law's [law_params] checked for it) and a placeholder
    packing. The cases are variants of these (:func:`case_scene`, ``dataclasses.replace``):
    no rewriting of the TOML text. Each scene's ``text`` is the campaign file as read, its
    ``output`` relative to the case folder (thermal.h5, or [output] path)."""
    from thermal_kernel.laws import LAWS
    from thermal_kernel.scene import load_scene
    placeholder = (out_dir / "packings" / "packing.h5").resolve()
    scenes = {}
    for law in conf["laws"]:
        scenes[law] = load_scene(campaign_path, known_laws=LAWS, out_dir=Path("."), text=text,
                                 data=case_tables(campaign_path, text, law, placeholder))
    return scenes


def case_tables(campaign_path: Path, text: str, law: str, packing: Path) -> dict:
    """A case's scene as tables: the campaign file's without [pack] and [campaign], with
    ``law`` and ``packing`` set (what :func:`case_scenes` parses; the PETSc backend's ranks
    parse the same, :func:`_compute`)."""
    data = {k: v for k, v in read_toml(campaign_path, text, error=UserError)[0].items()
            if k not in ("pack", "campaign", "law")}
    return {"packing": str(packing), "law": law, **data}


def case_scene(base, packing: Path, case_dir: Path):
    """The scene of one case: ``base`` (:func:`case_scenes`) on ``packing``, its output in
    ``case_dir`` (where [output] path puts it, thermal.h5 by default)."""
    output = base.output if base.output.is_absolute() else Path(case_dir) / base.output
    return dataclasses.replace(base, packing=Path(packing).resolve(), output=output)


def check_case_scenes(campaign_path: Path, conf: dict, text: str, out_dir: Path) -> dict:
    """The case scene of every law (:func:`case_scenes`), checked before any packing is built,
    so that a typo in [solver], [material], [[boundary]] or [law_params] is one line naming
    the campaign file and key (issue 16 sec. 3). What needs the packing itself (walls named by
    a boundary, the explicit bound) is checked when a case runs."""
    from thermal_kernel.scene import SceneError
    scenes = {}
    for law in conf["laws"]:
        try:
            scenes.update(case_scenes(campaign_path, dict(conf, laws=[law]), text, out_dir))
        except SceneError as e:
            raise UserError(f"{e} (in the case scene for law {law!r}; checked before any "
                            "packing is built)") from None
    return scenes


def build_packings(campaign_path: Path, out_dir: Path, *, threads: int, quiet: bool,
                   seed: int | None = None) -> list:
    """The campaign's packing series in ``<out_dir>/packings/``: reused when ``params.json``
    there equals the [pack] table (with ``seed`` in place of its seed, when given) and every
    ``packing_<p>Pa.h5`` exists; built by YADE otherwise."""
    from .pack import build, built_packings, read_pack_table
    generator, params = read_pack_table(campaign_path)
    if generator != "bed":
        raise UserError(f"{campaign_path}: pack.generator: a pressure campaign needs the bed "
                        "generator")
    pdir = out_dir / "packings"
    expected = [pdir / f"packing_{p:.4g}Pa.h5" for p in params["pressures_pa"]]
    if seed is None:
        reusable = built_packings(campaign_path, pdir)
    else:
        params = dict(params, seed=seed)
        reusable = _same_params(pdir, params)
    if reusable and all(p.exists() for p in expected):
        print(f"tdem campaign: reusing the {len(expected)} packings in {pdir}/", flush=True)
        return expected
    if seed is None:
        build(campaign_path, pdir, threads=threads, quiet=quiet)
    else:
        _build_seed(campaign_path, generator, params, pdir, threads=threads, quiet=quiet)
    missing = [p for p in expected if not p.exists()]
    if missing:
        raise UserError(f"{campaign_path}: pack: YADE did not write {missing[0].name}")
    return expected


def _same_params(pdir: Path, params: dict) -> bool:
    """``pdir/params.json`` (written by the YADE run) equals ``params``, output folder aside."""
    try:
        old = json.loads((pdir / "params.json").read_text())
    except (FileNotFoundError, json.JSONDecodeError):
        return False
    old.pop("output_dir", None)
    return old == {k: v for k, v in params.items() if k != "output_dir"}


def _build_seed(campaign_path, generator, params, pdir, *, threads, quiet):
    from thermal_kernel.packing import format_statistics, packing_statistics, read_packing
    from . import yade
    pdir = Path(pdir).resolve()
    print(f"tdem campaign: building the series of seed {params['seed']} with YADE -> {pdir}/ "
          f"({threads} thread(s))", flush=True)
    try:
        wall = yade.run_generator(generator, params, pdir, threads=threads, quiet=quiet)
    except yade.YadeError as e:
        raise UserError(f"{campaign_path}: seed {params['seed']}: {e}") from None
    for p in sorted(pdir.glob("packing_*.h5")):
        print(f"{p}:", flush=True)
        print(format_statistics(packing_statistics(read_packing(p))), flush=True)
    print(f"tdem campaign: seed {params['seed']}: packings in {wall:.1f} s", flush=True)


def run_campaign(campaign_path, out_dir=None, *, threads: int = 2, yade_threads: int = 1,
                 quiet: bool = False, repost: bool = False, jobs: int = 1,
                 ranks: int | None = None, threads_given: bool = False) -> dict:
    """Packings (YADE, ``yade_threads``; 1 keeps them bit-reproducible for a seed: YADE's
    parallel force summation order varies between runs), then thermal cases (numba, ``threads``).
    Finished cases are kept while they match their inputs (the hashes of the case's scene and
    packing file, :func:`_run_case`; else recomputed, and said so); with ``repost`` their thermal
    runs are kept and post-processed anew (after a change of the post-processing). A refused
    campaign leaves no folder it made empty.

    With ``[campaign] seeds = [...]`` each seed has its own packing series and cases under
    ``<out>/seed_<s>/`` (``packings/``, ``cases/``) and the report gives mean +- sd over the
    seeds. ``jobs`` = 1: seed after seed, each series built and then its cases run (an
    interrupted campaign has whole seeds done); ``jobs`` > 1: the missing series are built first,
    ``jobs`` YADE processes at a time, then all the cases.

    ``[solver] backend = "petsc"`` (or ``ranks``) runs each case's thermal solve on ``ranks``
    MPI ranks (default 1) through PETSc, as ``tdem run --ranks`` (thermal_kernel/mpi_run.py):
    the same thermal.h5, so the same post-processing and report; ``threads_given`` (the
    user's ``--threads``) is then refused, each rank running one thread."""
    from .pack import default_out_dir, read_pack_table

    campaign_path = Path(campaign_path)
    conf, text = read_campaign(campaign_path)
    if jobs < 1:
        raise UserError(f"--jobs: expected a number of YADE series at a time >= 1, got {jobs}")
    out_dir = Path(out_dir) if out_dir else default_out_dir(campaign_path)
    scenes = check_case_scenes(campaign_path, conf, text, out_dir)   # before YADE builds
    ranks = _ranks(campaign_path, scenes, ranks, threads_given)      # before YADE builds too
    if conf["has_pack"]:                # [pack] checked before anything is made
        generator, _ = read_pack_table(campaign_path)
        if generator != "bed":
            raise UserError(f"{campaign_path}: pack.generator: a pressure campaign needs the "
                            "bed generator")
    if conf["packings"] is not None:    # the listed files: every case checked on its packing
        check_cases(campaign_path, scenes, conf["packings"])
    run_args = dict(command="campaign", campaign=str(campaign_path), out=str(out_dir),
                    threads=threads, repost=repost, **({} if ranks is None else
                                                       {"ranks": ranks}))
    made = _missing_folders(out_dir)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        return _run_series(campaign_path, conf, scenes, out_dir, threads=threads,
                           yade_threads=yade_threads, quiet=quiet, repost=repost, jobs=jobs,
                           run_args=run_args, ranks=ranks)
    except BaseException:
        _remove_empty(made)             # a refused campaign leaves no empty --out behind
        raise


def _ranks(campaign_path, scenes, ranks, threads_given=False):
    """The MPI ranks the cases run on (None: in-process): ``ranks``, else 1 when the scene's
    ``[solver] backend = "petsc"``; --threads refused with them, the PETSc venv and mpirun
    checked now (one line each)."""
    petsc = any(s.solver.backend == "petsc" for s in scenes.values())
    if ranks is None and not petsc:
        return None
    if ranks is not None:
        from thermal_kernel.solvers.mpi_launch import checked_ranks
        checked_ranks(ranks)
    if threads_given:
        raise UserError("--threads: not with --ranks (each rank runs one thread); expected an "
                        "in-process campaign for it" if ranks is not None else
                        f"{campaign_path}: solver.backend: \"petsc\" runs the cases on MPI "
                        "ranks of one thread each; expected no --threads with it (or backend "
                        "= \"in-process\")")
    ranks = 1 if ranks is None else int(ranks)
    from thermal_kernel.solvers.mpi_launch import missing
    why = missing()
    if why is not None:
        raise UserError(f"{campaign_path}: solver.backend: the PETSc backend cannot run here "
                        f"({why})")
    return ranks


def _missing_folders(path: Path) -> list[Path]:
    """``path`` and those of its parents that do not exist yet, innermost first."""
    made, d = [], Path(path).absolute()
    while not d.exists() and d != d.parent:
        made.append(d)
        d = d.parent
    return made


def _remove_empty(folders) -> None:
    """Remove the folders (innermost first) this campaign made, those still empty."""
    import contextlib
    for d in folders:
        if not d.is_dir():
            continue
        for sub in sorted((x for x in d.rglob("*") if x.is_dir()), reverse=True):
            with contextlib.suppress(OSError):      # (a folder with files stays)
                sub.rmdir()
        with contextlib.suppress(OSError):
            d.rmdir()


def _run_series(campaign_path, conf, scenes, out_dir, *, threads, yade_threads, quiet, repost,
                jobs, run_args, ranks=None):
    from tdem_post.campaign_record import CaseRow
    start = time.time()
    seeds = conf["seeds"]
    series = [(None, out_dir)] if seeds is None else [(s, out_dir / f"seed_{s}") for s in seeds]
    if seeds is not None and jobs > 1:
        from concurrent.futures import ThreadPoolExecutor
        with ThreadPoolExecutor(max_workers=jobs) as pool:
            list(pool.map(lambda sd: build_packings(campaign_path, sd[1], threads=yade_threads,
                                                    quiet=True, seed=sd[0]), series))
    cases, k = [], 0
    for seed, sdir in series:
        packings = conf["packings"]
        if packings is None:
            packings = build_packings(campaign_path, sdir, threads=yade_threads, quiet=quiet,
                                      seed=seed)
            check_cases(campaign_path, scenes, packings)
        hashes = {p: file_sha256(p) for p in packings}
        _say_duplicates(hashes)
        n_cases = len(series) * len(packings) * len(conf["laws"])
        for packing in packings:
            for law in conf["laws"]:
                k += 1
                summary = _run_case(scenes[law], conf, sdir, packing, repost, threads,
                                    run_args, packing_hash=hashes[packing], ranks=ranks,
                                    label=f"[{k}/{n_cases}] "
                                          + (f"seed {seed} " if seed is not None else ""))
                cases.append((summary, CaseRow.from_summary(
                    summary, target_pressure(packing, summary.pressure_pa), seed)))
    return write_report(out_dir, campaign_path, conf, cases, time.time() - start)


def check_cases(campaign_path: Path, scenes: dict, packings: list) -> None:
    """Every case (packing x law) built as it will run, before any case runs: each packing read
    by the validating reader, each boundary's wall or face found in it, the law's inputs made
    (:func:`~thermal_kernel.problem.build_problem`, no solve). A packing without a wall the
    scene holds was found only when its case ran, after the others (round 3)."""
    from thermal_kernel.network import NetworkError
    from thermal_kernel.packing import PackingError, read_packing
    from thermal_kernel.problem import build_problem
    from thermal_kernel.scene import SceneError
    for path in packings:
        try:
            packing = read_packing(path)
        except PackingError as e:
            raise UserError(f"{e} (a packing of {campaign_path}; checked before any case "
                            "runs)") from None
        for law, base in scenes.items():
            try:
                build_problem(dataclasses.replace(base, packing=Path(path).resolve()), packing)
            except (SceneError, PackingError, NetworkError) as e:
                raise UserError(f"{e} (case {_case_name(path, law)}; every case is checked on "
                                "its packing before any runs)") from None


def _case_name(packing: Path, law: str) -> str:
    return f"{Path(packing).stem.removeprefix('packing_')}_{law}"


def file_sha256(path: Path) -> str:
    """sha256 (hex) of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


@functools.cache
def post_sha256() -> str:
    """sha256 (hex) of the post-processing's code (the tdem_post modules' bytes): a case
    posted by other code is posted again from its thermal.h5 (its numbers are post's)."""
    import tdem_post
    h = hashlib.sha256()
    for path in sorted(Path(tdem_post.__file__).resolve().parent.glob("*.py")):
        h.update(path.name.encode() + b"\0" + path.read_bytes())
    return h.hexdigest()


def scene_sha256(scene_json: str) -> str:
    """sha256 (hex) of a case's resolved scene (:func:`~thermal_kernel.output.scene_to_json`)
    without what names files (its path, packing, output): what the thermal run computes from.
    The packing is hashed on its own (:func:`file_sha256`)."""
    data = json.loads(scene_json)
    for key in ("path", "packing", "output", "pack"):
        data.pop(key, None)
    return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()


def _say_duplicates(hashes: dict) -> None:
    """A warning line for packing files of one series with the same bytes (the same bed twice:
    its pressure counts once in the fits)."""
    first = {}
    for path, sha in hashes.items():
        if sha in first:
            print(f"tdem campaign: warning: {path} has the same content as {first[sha]}: the "
                  "same bed twice (its pressure counts once in the fits over pressure)",
                  file=sys.stderr, flush=True)
        else:
            first[sha] = path


def _read_summary(path: Path) -> dict | None:
    """A case's post/summary.json, or None when it is not a readable summary."""
    try:
        summary = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None
    return summary if isinstance(summary, dict) and "gamma" in summary else None


def _stale(summary: dict, thermal_path: Path, packing: Path, inputs: dict) -> list[str]:
    """What changed since the case ran: "scene", "packing file" (empty: it matches its
    ``inputs``, {scene_sha256, packing_sha256}). A summary written before the hashes were
    recorded is checked against its thermal.h5 (the scene it stored, the packing content hash
    it stored)."""
    if "scene_sha256" in summary and "packing_sha256" in summary:
        same_scene = summary["scene_sha256"] == inputs["scene_sha256"]
        same_packing = summary["packing_sha256"] == inputs["packing_sha256"]
    else:
        from thermal_kernel.checkpoint import packing_sha256
        from thermal_kernel.output import ThermalFileError, read_thermal
        from thermal_kernel.packing import PackingError, read_packing
        from thermal_kernel.scene import SceneError
        try:
            run = read_thermal(thermal_path, data=False)
            same_scene = bool(run.scene_json) and \
                scene_sha256(run.scene_json) == inputs["scene_sha256"]
            same_packing = packing_sha256(read_packing(packing)) == run.packing_sha256
        except (ThermalFileError, SceneError, PackingError, ValueError):
            return ["scene", "packing file"]    # nothing to check it against: not kept
    return ([] if same_scene else ["scene"]) + ([] if same_packing else ["packing file"])


def _run_case(scene, conf, series_dir, packing, repost, threads, run_args, label,
              packing_hash=None, ranks=None):
    """One pressure x law case in ``series_dir/cases/<p>Pa_<law>/``: kept when its
    ``post/summary.json`` exists and records the hashes of this case's scene and packing file
    (post-processed again, from its thermal.h5 alone, with ``repost``, another ``n_bins`` or
    other tdem_post code, :func:`post_sha256`);
    run otherwise: ``scene`` (the law's, :func:`case_scenes`) on ``packing``. A case that ran
    on other inputs is recomputed, and the line says which input changed."""
    from thermal_kernel.output import scene_to_json
    name = _case_name(packing, scene.law)
    case_dir = series_dir / "cases" / name
    summary_path = case_dir / "post" / "summary.json"
    thermal_path = case_dir / "thermal.h5"
    inputs = dict(scene_sha256=scene_sha256(scene_to_json(scene)),
                  packing_sha256=packing_hash or file_sha256(packing))
    post = post_sha256()
    old = _read_summary(summary_path) if summary_path.exists() else None
    why = None                      # why a case found done is recomputed
    if summary_path.exists() and old is None:
        why = "its post/summary.json is unreadable"
    elif old is not None:
        changed = _stale(old, thermal_path, packing, inputs)
        if changed:
            why = f"the {' and the '.join(changed)} changed since it ran"
    kept = None                     # the summary as the current record, if it reads as one
    if old is not None and why is None and not (repost or old.get("n_bins") != conf["n_bins"]
                                                or old.get("post_sha256") != post):
        kept = _read_case_summary(summary_path)
    if old is not None and why is None and kept is None:
        summary, why = _repost(old, thermal_path, conf, inputs, summary_path, label, name,
                               repost)
        if summary is not None:
            return summary
    elif kept is not None:
        summary = dataclasses.replace(kept, flags=run_flags(thermal_path, kept.flags))
        print(f"{label}{name}: done before (gamma {_g(summary.gamma)}), kept"
              + (f"; flags: {summary.flags}" if summary.flags else ""), flush=True)
        return summary
    if summary_path.exists():       # stale: never left beside a new run
        summary_path.unlink()
    summary = _compute(scene, conf, case_dir, packing, threads, run_args, name, inputs,
                       summary_path, ranks)
    ci = summary.gamma_ci95 or (None, None)
    print(f"{label}{name}: gamma {_g(summary.gamma)}"
          + (f" [{_g(ci[0])}, {_g(ci[1])}]" if summary.gamma is not None else "")
          + f", steady {_g(summary.gamma_steady)}, tau {_g(summary.tau_s)} s "
          f"({summary.case_wall_seconds:.1f} s)"
          + (f"; flags: {summary.flags}" if summary.flags else "")
          + (f"; recomputed: {why}" if why else ""), flush=True)
    return summary


def _g(value) -> str:
    """A number of a case's summary for its line; post's None: "not measurable" (post says why,
    summary.json's not_measurable)."""
    return "not measurable" if value is None else f"{value:.4g}"


def _read_case_summary(path: Path):
    """The case's post/summary.json as a :class:`~tdem_post.campaign_record.CaseSummary`, or None
    when it does not read as one (a key missing, unknown or of another type: it is posted
    again)."""
    from tdem_post.records import RecordError, record_from_json
    from tdem_post.campaign_record import CaseSummary
    try:
        return record_from_json(CaseSummary, path)
    except RecordError:
        return None


def _case_summary(posted: dict, summary_path: Path, **campaign):
    """The campaign's :class:`~tdem_post.campaign_record.CaseSummary` of a case: post's summary
    (``posted``, :func:`~tdem_post.post_run.write_post`) with the campaign's keys, written to
    ``summary_path``."""
    from tdem_post.records import from_dict, write_json
    from tdem_post.campaign_record import CaseSummary
    summary = from_dict(CaseSummary, dict(posted, **campaign), str(summary_path))
    summary_path.parent.mkdir(parents=True, exist_ok=True)
    write_json(summary_path, summary)
    return summary


def _compute(scene, conf, case_dir, packing, threads, run_args, name, inputs, summary_path,
             ranks=None):
    """Run the case and post-process it; its summary (with ``inputs``, the hashes) written.
    With ``ranks``, the thermal solve runs on MPI ranks (the PETSc backend), which parse the
    same case scene (:func:`case_tables`) and write the same thermal.h5."""
    from thermal_kernel.run import run_scene
    from tdem_post.post_run import analyse, write_post
    scene = case_scene(scene, packing, case_dir)
    t0 = time.time()
    if ranks is None:
        output = run_scene(scene, packing, quiet=True, threads=threads,
                           run_args=dict(run_args, case=name)).output
    else:
        from thermal_kernel.solvers.mpi_launch import run_on_ranks
        run_on_ranks(scene.path, ranks, packing=scene.packing, out=case_dir, quiet=True,
                     output=scene.output,
                     run_args=dict(run_args, case=name),
                     data=case_tables(scene.path, scene.text, scene.law, scene.packing))
        output = scene.output
    run_seconds = time.time() - t0
    post = analyse(output, n_bins=conf["n_bins"])
    posted = write_post(post)
    return _case_summary(posted, summary_path, case_wall_seconds=time.time() - t0,
                         thermal_wall_seconds=run_seconds, flags=post.run.flags, **inputs,
                         post_sha256=post_sha256())


def _repost(old, thermal_path, conf, inputs, summary_path, label, name, asked):
    """Post-process a kept case's thermal.h5 again: (summary, None); (None, why) when the file
    cannot be post-processed (missing, refused by its reader, a non-finite temperature): the
    case is then recomputed."""
    from thermal_kernel.network import NetworkError
    from thermal_kernel.output import ThermalFileError
    from thermal_kernel.packing import PackingError
    from thermal_kernel.scene import SceneError
    from tdem_post.post_run import analyse, write_post
    t0 = time.time()
    try:
        post = analyse(thermal_path, n_bins=conf["n_bins"])
        temperature = post.run.temperature
        if temperature is not None and not np.isfinite(temperature).all():
            raise ThermalFileError(f"{thermal_path}: temperature: expected finite values, got "
                                   f"{int(np.size(temperature) - np.isfinite(temperature).sum())}"
                                   " non-finite")
    except (ThermalFileError, PackingError, SceneError, NetworkError) as e:
        return None, f"its thermal.h5 could not be post-processed again ({e})"
    summary = _case_summary(
        write_post(post), summary_path,
        **{key: old.get(key, float("nan")) for key in ("case_wall_seconds",
                                                        "thermal_wall_seconds")},
        flags=post.run.flags, **inputs, post_sha256=post_sha256())    # (flags: analysed, the
    #                                                                    file is a complete run)
    what = ("post-processed again" if asked else
            f"n_bins {old.get('n_bins')} -> {conf['n_bins']}: post-processed again"
            if old.get("n_bins") != conf["n_bins"] else
            "the post-processing (tdem_post) changed since it was posted: post-processed again"
            if old.get("post_sha256") != post_sha256() else
            "its summary.json is not the current summary's record: post-processed again")
    print(f"{label}{name}: thermal run kept, {what}: gamma "
          f"{_g(old.get('gamma'))} -> {_g(summary.gamma)} ({time.time() - t0:.1f} s)",
          flush=True)
    return summary, None


def target_pressure(packing: Path, measured: float) -> float:
    """The series' nominal pressure of a packing, from its name (``packing_<p>Pa.h5``, as
    [pack].pressures_pa); the seeds of one pressure are grouped by it, since each series
    reaches the target within its own tolerance. ``measured`` when the name has none."""
    m = re.search(r"_([0-9.]+(?:[eE][+-]?[0-9]+)?)Pa$", Path(packing).stem)
    return float(m.group(1)) if m else float(measured)


def run_flags(thermal_path: Path, fallback: str | None = None) -> str:
    """The ``flags`` of a run's ``thermal.h5`` (comma-separated: the solver's flags and the
    physics checks', ``max_principle`` / ``energy_ledger``; "" when the run is clean), read by
    :func:`~thermal_kernel.output.read_thermal`. ``fallback`` (or "unknown") when the file is
    missing or not a complete run output."""
    from thermal_kernel.output import ThermalFileError, read_thermal
    from thermal_kernel.scene import SceneError
    try:
        return read_thermal(thermal_path, data=False).flags
    except (ThermalFileError, SceneError):
        return "unknown" if fallback is None else fallback


def n_distinct(p) -> int:
    """How many distinct pressures (relative difference above 1e-9) ``p`` holds: two copies
    of one bed, or two beds at one pressure, are one point of a fit over pressure."""
    p = np.sort(np.asarray(p, dtype=float))
    return int(len(p) > 0) + int(np.sum(np.diff(p) > 1e-9 * np.abs(p[1:])))


def _measured(p_bar, y):
    """The pairs (p, y) with y measured (finite and > 0: post's "not measurable" is NaN)."""
    p_bar, y = np.asarray(p_bar, dtype=float), np.asarray(y, dtype=float)
    ok = np.isfinite(p_bar) & np.isfinite(y) & (y > 0)
    return p_bar[ok], y[ok]


def _log_slope(p_bar, y):
    """The log-log slope of y(p) over the measured values, or None when fewer than two of
    their pressures are distinct."""
    p_bar, y = _measured(p_bar, y)
    if n_distinct(p_bar) < 2:
        return None
    return float(np.polyfit(np.log(p_bar), np.log(y), 1)[0])


def _no_slope(p_bar, y) -> str:
    p_bar = _measured(p_bar, y)[0]
    n, m = n_distinct(p_bar), len(p_bar)
    if m < 2:
        return f"not fitted: {m} measured value{'' if m == 1 else 's'}"
    return f"not fitted: {m} cases at {n} distinct pressure{'' if n == 1 else 's'} (a slope " \
        "needs two)"


def _fit(p_bar, y):
    from tdem_post.fits import fit_power_law
    p_bar, y = _measured(p_bar, y)
    if n_distinct(p_bar) < 4:
        return None
    try:
        return fit_power_law(p_bar, y)
    except (RuntimeError, ValueError):
        return None


def campaign_record(campaign_path: Path, conf: dict, rows: list, seconds: float):
    """The campaign's :class:`~tdem_post.campaign_record.CampaignRecord` from its cases' rows
    (:class:`~tdem_post.campaign_record.CaseRow`): the rows sorted by seed, law and pressure,
    and the fits over pressure per law (and seed)."""
    from tdem_post.fits import PAPER_GAMMA, power_law
    from tdem_post.paper_compare import PAPER_TAU     # 003 Fig. 10 (p in bar)
    from tdem_post.records import frame
    from tdem_post.campaign_record import CampaignRecord, LawFits
    seeded = any(c.seed is not None for c in rows)
    cases = sorted(rows, key=lambda c: ((c.seed,) if seeded else ()) + (c.law, c.pressure_pa))
    table = frame(cases)
    fits = []
    for key, g in table.groupby(["law", "seed"] if seeded else ["law"]):
        law, seed = (key[0], int(key[1])) if seeded else \
            (key[0] if isinstance(key, tuple) else key, None)
        p_bar = g["pressure_pa"].to_numpy() / 1e5
        fits.append(LawFits(
            law=law, seed=seed, gamma=_fit(p_bar, g["gamma"].to_numpy()),
            tau_s=_fit(p_bar, g["tau_s"].to_numpy()),
            gamma_loglog_slope=_log_slope(p_bar, g["gamma"].to_numpy()),
            gamma_paper_over_paper=tuple(float(v) for v in g["gamma_paper"].to_numpy()
                                         / power_law(p_bar, **PAPER_GAMMA))))
    seeds = sorted({c.seed for c in cases}) if seeded else None
    return CampaignRecord(campaign=Path(campaign_path).name, laws=tuple(conf["laws"]),
                          seeds=tuple(seeds) if seeded else None, wall_seconds=float(seconds),
                          paper_gamma=dict(PAPER_GAMMA), paper_tau_s=dict(PAPER_TAU),
                          fits=tuple(fits), rows=tuple(cases))


def write_report(out_dir: Path, campaign_path: Path, conf: dict, cases: list, seconds: float):
    """The campaign's record (campaign.json, :func:`campaign_record`), and from it results.csv,
    the figures and report.md. ``cases``: (CaseSummary, CaseRow) of each case, in run order."""
    from tdem_post.records import frame, write_csv, write_json
    from tdem_post.campaign_record import RECORD

    record = campaign_record(campaign_path, conf, [row for _, row in cases], seconds)
    write_json(out_dir / RECORD, record)
    write_csv(out_dir / "results.csv", record.rows)
    table = frame(record.rows)
    seeded = record.seeds is not None
    fits = {((f.law, f.seed) if seeded else f.law): dict(gamma=f.gamma, tau=f.tau_s)
            for f in record.fits}
    _plots(out_dir, table, fits, cases)
    _write_report_md(out_dir, record, table, fits)
    print(f"tdem campaign: report {out_dir / 'report.md'}", flush=True)
    print(table[(["seed"] if seeded else []) + ["pressure_pa", "law", "gamma",
                "gamma_steady", "tau_s", "flags"]].to_string(
        index=False, float_format=lambda x: f"{x:.4g}"), flush=True)
    return dict(table=table, fits=fits, record=record, report=out_dir / "report.md")


def _write_report_md(out_dir: Path, record, table, fits) -> None:
    """report.md from the campaign's record (``table``: its rows as a DataFrame, ``fits``: its
    fits by law, or by (law, seed)): the heading and table (:func:`_report_head`), the flagged
    runs (:func:`_report_flags`), the seeds' summary, the fits per law (:func:`_law_lines`)."""
    seeded = record.seeds is not None
    seeds = list(record.seeds) if seeded else [None]
    first = table[table.seed == seeds[0]] if seeded else table
    lines = _report_head(record, table, seeded, seeds) + _report_flags(table, seeded)
    if seeded:
        lines += _seed_summary(table, fits, seeds)
    lines += ["", "## Fits over pressure (p in bar)" + (f", seed {seeds[0]}" if seeded else ""),
              ""]
    for law, g in first.groupby("law"):
        lines += _law_lines(record, law, g, seeds[0])
    pg, pt = record.paper_gamma, record.paper_tau_s
    lines += ["", f"Paper (003): γ = {pg['a']} p^{pg['b']} + {pg['c']} (Fig. 7); "
                  f"τ = {pt['a']} p^{pt['b']} {pt['c']:+} s (Fig. 10).", ""]
    write_text_atomic(out_dir / "report.md", "\n".join(lines))


def _report_head(record, table, seeded, seeds) -> list[str]:
    """report.md's title, what was run, what each column means and the table of the cases."""
    from tdem_post.records import markdown_table
    p_col = "pressure_target_pa" if seeded else "pressure_pa"
    lines = [f"# Pressure campaign: {record.campaign}", "",
             f"{table['n_particles'].iloc[0]} particles, pressures "
             f"{', '.join(f'{p / 1e5:.3g}' for p in sorted(table[p_col].unique()))} bar"
             + (" (nominal)" if seeded else "") + ", "
             f"laws {', '.join(record.laws)}"
             + (f", packing seeds {', '.join(str(s) for s in seeds)} (one YADE series each, "
                "`seed_<s>/`)" if seeded else "")
             + f"; {record.wall_seconds:.0f} s in all. Files: `results.csv`, "
             "`gamma_p.png`, `tau_p.png`, `contact_angles.png`, "
             + ("`seed_<s>/cases/<p>Pa_<law>/post/profiles.png`." if seeded
                else "`cases/<p>Pa_<law>/post/profiles.png`."), "",
             "γ = k_eff / k_p fitted to the binned profiles against the slab solution with the "
             "run's own bed heat capacity (thermal.h5; φ ρ_p c_p for a law whose particles "
             "carry ρ_p c_p V_p) (95 % interval); γ_paper, the same fitted diffusivity in 003's "
             "convention α = γ_paper κ_p / (ρ_p c_p) (App. A; ρ is the "
             "particle density, Table 1) - the number to compare with the paper's γ(p); "
             "γ_steady = k_eff / k_p from the steady heat flow (no capacity enters: compare it "
             "with γ); γ_aff the affine (fabric-tensor) estimate k_zz / k_p = Σ H l_z² / (V k_p), "
             "an upper bound of γ_steady (Thomson); ⟨n_z²⟩ the mean squared axial cosine of the "
             "touching contacts (1/3 isotropic); γ_mf the isotropic mean field "
             "φ Z H̄ / (2π R̄ k_p) of each contact law on the same contacts; τ the characteristic "
             "time of the middle section (003 eq. 41) from the network, τ_slab = L² / (8 α) the "
             "slab's own with the fitted α.", "", *markdown_table(record.rows)]
    return lines


def _report_flags(table, seeded) -> list[str]:
    """report.md's paragraphs on the runs flagged suspect, not measurable or flagged by post."""
    lines = []
    suspect = [(r, [f for f in r["flags"].split(",") if f in SUSPECT_FLAGS])
               for _, r in table.iterrows()]
    suspect = [(r, f) for r, f in suspect if f]
    if suspect:
        lines += ["", f"**{len(suspect)} of {len(table)} runs flagged: their numbers are "
                      "suspect** (`flags` of their `thermal.h5`; `max_principle`: a "
                      "temperature outside the range of the initial and boundary values, "
                      "`energy_ledger`: heat in ≠ heat stored; docs/solvers.md): "
                  + "; ".join((f"seed {r['seed']} " if seeded else "")
                              + f"{r['pressure_pa'] / 1e5:.3g} bar {r['law']}: {', '.join(f)}"
                              for r, f in suspect) + "."]
    else:
        lines += ["", "No run flagged by the maximum-principle and energy-ledger checks or the "
                      "solver (other flags, e.g. `rattlers`, are information; docs/solvers.md)."]
    unmeasured = [r for _, r in table.iterrows() if r["not_measurable"]]
    if unmeasured:
        lines += ["", f"**Not measurable from {len(unmeasured)} of {len(table)} runs** (post "
                      "says why; their cells are nan, left out of the fits): "
                  + "; ".join((f"seed {r['seed']} " if seeded else "")
                              + f"{r['pressure_pa'] / 1e5:.3g} bar {r['law']}: "
                              f"{r['not_measurable']}" for r in unmeasured) + "."]
    post_flagged = [r for _, r in table.iterrows() if r["post_flags"]]
    if post_flagged:
        lines += ["", "Post-processing flags (docs/post.md): "
                  + "; ".join((f"seed {r['seed']} " if seeded else "")
                              + f"{r['pressure_pa'] / 1e5:.3g} bar {r['law']}: "
                              f"{r['post_flags']}" for r in post_flagged) + "."]
    return lines


def _law_lines(record, law, g, seed) -> list[str]:
    """report.md's lines of one law's fits over pressure and its ratios to the paper and to
    its own estimates (``g``: the law's rows of the first seed)."""
    from tdem_post.campaign_record import COMPARED_MEAN_FIELDS
    from tdem_post.fits import power_law
    lines = []
    law_fits = record.fits_of(law, seed)
    p_bar = g["pressure_pa"].to_numpy() / 1e5
    for what, fit in (("γ", law_fits.gamma), ("τ", law_fits.tau_s)):
        if fit is None:
            y = g["gamma" if what == "γ" else "tau_s"].to_numpy()
            lines.append(f"- {law}: {what}(p) not fitted (fewer than 4 distinct "
                         f"pressures with a measured {what}: "
                         f"{n_distinct(_measured(p_bar, y)[0])})")
        else:
            lines.append(f"- {law}: {what}(p) = {fit.a:.4g} (±{fit.stderr[0]:.2g}) "
                         f"p^{fit.b:.4g} (±{fit.stderr[1]:.2g}) "
                         f"{'−' if fit.c < 0 else '+'} {abs(fit.c):.4g} "
                         f"(±{fit.stderr[2]:.2g}), rms {fit.rms:.3g}")
    paper = power_law(p_bar, **record.paper_gamma)
    paper_tau = power_law(p_bar, **record.paper_tau_s)
    gamma = g["gamma"].to_numpy()

    def ratios(x):
        return ", ".join(f"{v:.3g}" for v in x)
    lines.append(
        f"- {law}: γ_paper / paper's γ(p) (003 Fig. 7, same convention) = "
        f"{ratios(law_fits.gamma_paper_over_paper)} (from low to high pressure); "
        + "".join(f"γ_mf({mf}) / γ = "
                  f"{ratios(g[f'gamma_mean_field_{mf}'].to_numpy() / gamma)}; "
                  for mf in COMPARED_MEAN_FIELDS)
        + f"γ_steady / γ = {ratios(g['gamma_steady'].to_numpy() / gamma)}; "
        f"γ_aff / γ_steady = {ratios(g['gamma_affine'].to_numpy() / g['gamma_steady'])}; "
        f"3 ⟨n_z²⟩ = {ratios(3 * g['fabric_nz2'].to_numpy())}; "
        f"τ / τ_slab = {ratios(g['tau_s'].to_numpy() / g['tau_slab_s'].to_numpy())}")
    trend = law_fits.gamma_loglog_slope
    lines.append(f"- {law}: log-log slope of γ(p) "
                 + (_no_slope(p_bar, gamma) if trend is None else f"{trend:.3g}")
                 + " (the paper's curve falls, slope −0.29 at low p; contact mechanics, "
                   "ζ ∝ F_n^(1/3) ∝ p^(1/3), predicts a rising γ)")
    # 003 App. A: tau_mid = L^2 rho_p c_p / (8 gamma_paper kappa_p); the paper's own fits
    # give tau gamma_paper = 0.0056-0.0067 s (docs/campaign.md)
    lines.append(f"- {law}: τ γ_paper (s) = {ratios(g['tau_s'].to_numpy() * g['gamma_paper'])}"
                 f"; the paper's fits give {ratios(paper_tau * paper)}")
    # App. A's own requirement, L^2 rho_p c_p / (8 kappa_p) = tau_slab gamma_paper (the slab's
    # mid-plane time of the fitted diffusivity), against the paper's fits; and the paper's
    # tau(p) read through App. A as a gamma_paper (> 1 would be k_eff > k_p: impossible)
    app_a = g["tau_slab_s"].to_numpy() * g["gamma_paper"].to_numpy()
    lines.append(f"- {law}: App. A requires τ γ_paper = L² ρ_p c_p/(8 κ_p) = {ratios(app_a)} s "
                 f"(L of these runs); that over the paper's fits = "
                 f"{ratios(app_a / (paper_tau * paper))}; the paper's τ(p) through "
                 f"App. A gives γ_paper = {ratios(app_a / paper_tau)}")
    return lines


def seed_statistics(table):
    """Mean, sample standard deviation and number of seeds of gamma, gamma_paper,
    gamma_steady, gamma_affine, <n_z^2>, Z, phi and tau per law and pressure."""
    cols = ["gamma", "gamma_paper", "gamma_steady", "gamma_affine", "fabric_nz2",
            "mean_coordination", "solid_fraction", "tau_s"]
    groups = table.groupby(["law", "pressure_target_pa"])
    g = groups[cols]
    out = g.mean().add_suffix("_mean").join(g.std(ddof=1).add_suffix("_std"))
    out["n_seeds"] = g.size()
    out["pressure_pa"] = groups["pressure_pa"].mean()      # the measured pressures' mean
    return out.reset_index()


def _seed_summary(table, fits, seeds):
    """Report lines: gamma and tau per pressure as mean +- standard deviation over the seeds,
    and the power-law exponents per seed with their mean and spread."""
    stats = seed_statistics(table)
    lines = ["", f"## Over the {len(seeds)} packing seeds (mean ± sample standard deviation)",
             "", "| law | p nominal (bar) | p measured, mean (bar) | seeds | Z | φ | γ | γ_paper | "
             "γ_steady | γ_aff | ⟨n_z²⟩ | τ (s) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for _, r in stats.iterrows():
        def pm(name, fmt=".4g", r=r):
            sd = r[f"{name}_std"]
            return f"{r[f'{name}_mean']:{fmt}} ± {sd:.2g}" if np.isfinite(sd) \
                else f"{r[f'{name}_mean']:{fmt}}"
        lines.append(f"| {r.law} | {r.pressure_target_pa / 1e5:.3g} | {r.pressure_pa / 1e5:.3g} | "
                     f"{r.n_seeds} | "
                     f"{pm('mean_coordination', '.3f')} | {pm('solid_fraction', '.4f')} | "
                     f"{pm('gamma')} | {pm('gamma_paper')} | {pm('gamma_steady')} | "
                     f"{pm('gamma_affine')} | {pm('fabric_nz2', '.4f')} | {pm('tau_s')} |")
    lines += ["", "Power-law fits y = a p^b + c per seed (p in bar):", ""]
    for law in sorted(table.law.unique()):
        for what, key in (("γ", "gamma"), ("τ", "tau")):
            b = [fits[(law, s)][key].b for s in seeds if fits.get((law, s), {}).get(key)]
            per = ", ".join(f"{s}: {fits[(law, s)][key].b:.4g}" for s in seeds
                            if fits.get((law, s), {}).get(key))
            if b:
                lines.append(f"- {law}: exponent b of {what}(p) = {np.mean(b):.4g} ± "
                             f"{np.std(b, ddof=1) if len(b) > 1 else float('nan'):.2g} over "
                             f"{len(b)} seeds (range {min(b):.4g} … {max(b):.4g}; per seed "
                             f"{per})")
            g = table[table.law == law]
            slopes = [_log_slope(x.pressure_pa.to_numpy() / 1e5,
                                 x[key if key == "gamma" else "tau_s"].to_numpy())
                      for _, x in g.groupby("seed")]
            slopes = [b for b in slopes if b is not None]
            if slopes:
                lines.append(f"- {law}: log-log slope of {what}(p) = {np.mean(slopes):.4g} ± "
                             f"{np.std(slopes, ddof=1) if len(slopes) > 1 else float('nan'):.2g}")
    return lines


def _plots(out_dir, table, fits, cases=()):
    """gamma_p.png and tau_p.png (per seed and mean +- sd when the campaign has seeds: each
    law's rows by :func:`_plot_law_seeds`, else :func:`_plot_law`), contact_angles.png (the
    contact-angle PDF per pressure, 003 Fig. 5)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from tdem_post.fits import PAPER_GAMMA, power_law
    from tdem_post.paper_compare import PAPER_TAU
    from tdem_post.campaign_record import COMPARED_MEAN_FIELDS
    seeded = "seed" in table.columns
    pmin = table.pressure_pa.min() / 1e5
    pmax = table.pressure_pa.max() / 1e5
    grid = np.geomspace(pmin, pmax, 100)
    for key, label, paper, fname in (
            ("gamma", "γ = k_eff / k_p", PAPER_GAMMA, "gamma_p"),
            ("tau_s", "τ (s), middle section", PAPER_TAU, "tau_p")):
        if seeded:      # a lower panel: each seed's deviation from the mean, per cent
            fig, (ax, dev) = plt.subplots(2, 1, figsize=(6, 5.6), sharex=True,
                                          gridspec_kw={"height_ratios": [3, 1.3]})
        else:
            fig, ax = plt.subplots(figsize=(6, 4.2))
        for k, (law, g) in enumerate(table.groupby("law")):
            if seeded:
                _plot_law_seeds(ax, dev, g, key, k, law, table.law.nunique())
            else:
                _plot_law(ax, g, key, k, law, fits[law]["gamma" if key == "gamma" else "tau"],
                          grid)
        if key == "gamma":
            g0 = table[table.law == table.law.iloc[0]]
            if seeded:
                g0 = g0[g0.seed == g0.seed.min()]
            for mf, marker in zip(COMPARED_MEAN_FIELDS, "s^v<>", strict=False):
                ax.plot(g0.pressure_pa / 1e5, g0[f"gamma_mean_field_{mf}"], marker, mfc="none",
                        color="k", label=f"mean field, {mf}")
        ax.plot(grid, power_law(grid, **paper), "k--", label="paper (003)")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_ylabel(label)
        ax.legend(fontsize=6)
        if seeded:
            dev.axhline(0, color="k", lw=0.6)
            dev.set_xscale("log")
            dev.set_ylabel("seed − mean (%)", fontsize=8)
            dev.set_xlabel("plate pressure (bar)")
            dev.legend(fontsize=6, ncol=3)
        else:
            ax.set_xlabel("plate pressure (bar)")
        fig.tight_layout()
        savefig_atomic(fig, out_dir / f"{fname}.png", dpi=110)
        plt.close(fig)
    _plot_contact_angles(out_dir, cases)


def _plot_law_seeds(ax, dev, g, key, k, law, n_laws):
    """One law's rows of a campaign with seeds on ``ax`` (each seed's dots, the mean ± sd per
    pressure; for γ the paper's convention and the steady ETC too) and each seed's deviation
    from the mean on ``dev``, the lower panel (per cent)."""
    mean = g.groupby("pressure_target_pa")[key].transform("mean")
    for m, (seed, gs) in enumerate(g.groupby("seed")):
        dev.plot(gs.pressure_pa / 1e5, 100 * (gs[key] / mean[gs.index] - 1),
                 "o-", ms=3, lw=0.8,
                 color=f"C{m}" if n_laws == 1 else f"C{k}",
                 label=f"seed {seed}" if k == 0 else None)
    stats = seed_statistics(g)
    p = stats.pressure_pa / 1e5
    ax.plot(g.pressure_pa / 1e5, g[key], ".", ms=3, alpha=0.5, color=f"C{k}")
    ax.errorbar(p, stats[f"{key}_mean"], yerr=stats[f"{key}_std"], fmt="o",
                capsize=3, color=f"C{k}",
                label=f"tdem {law}: mean ± sd of {int(stats.n_seeds.max())} seeds "
                      "(dots: each seed)")
    if key == "gamma":
        ax.errorbar(p, stats["gamma_paper_mean"], yerr=stats["gamma_paper_std"],
                    fmt="D", mfc="none", capsize=3, color=f"C{k}",
                    label=f"γ_paper = α ρ_p c_p/κ_p (003's convention), {law}")
        ax.plot(p, stats.gamma_steady_mean, "x", color=f"C{k}",
                label=f"steady ETC {law} (mean)")


def _plot_law(ax, g, key, k, law, fit, grid):
    """One law's rows of a campaign without seeds on ``ax``: each case (γ with its 95 %
    interval, the steady ETC and, for the first law, the paper's convention) and the fit over
    pressure on ``grid`` (bar)."""
    p = g.pressure_pa / 1e5
    if key == "gamma":
        ax.errorbar(p, g.gamma, yerr=[g.gamma - g.gamma_ci95_low,
                                      g.gamma_ci95_high - g.gamma], fmt="o",
                    color=f"C{k}", label=f"tdem {law}")
        ax.plot(p, g.gamma_steady, "x", color=f"C{k}", label=f"steady ETC {law}")
        if k == 0:
            ax.plot(p, g.gamma_paper, "D", mfc="none", color=f"C{k}",
                    label=f"γ_paper = α ρ_p c_p/κ_p (003's convention), {law}")
    else:
        ax.plot(p, g[key], "o", color=f"C{k}", label=f"tdem {law}")
    if fit is not None:
        ax.plot(grid, fit(grid), "-", color=f"C{k}", lw=1)


def _plot_contact_angles(out_dir, cases):
    """PDF of the angle between a contact normal and the bed's axis, per pressure (003 Fig. 5);
    with seeds, the mean over the seeds and its +- sd band. One law's rows are enough (the
    fabric is the packing's). ``cases``: (CaseSummary, CaseRow) pairs."""
    cases = [(s, row) for s, row in cases if s.contact_angle_pdf]
    if not cases:
        return
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    law = cases[0][1].law
    by_p = {}
    for s, row in cases:
        if row.law == law:
            by_p.setdefault(row.pressure_target_pa, []).append(np.asarray(s.contact_angle_pdf))
    edges = np.asarray(cases[0][0].contact_angle_edges)
    centres = 0.5 * (edges[1:] + edges[:-1])
    fig, ax = plt.subplots(figsize=(6, 4.2))
    lines = ["pressure_pa,n_seeds," + ",".join(f"pdf_{c:.4f}" for c in centres)]
    for k, (p, pdfs) in enumerate(sorted(by_p.items())):
        pdfs = np.array(pdfs)
        mean = pdfs.mean(axis=0)
        ax.plot(centres, mean, "-o", ms=3, color=plt.cm.viridis(k / max(len(by_p) - 1, 1)),
                label=f"{p / 1e5:.3g} bar" + (f" ({len(pdfs)} seeds)" if len(pdfs) > 1 else ""))
        if len(pdfs) > 1:
            sd = pdfs.std(axis=0, ddof=1)
            ax.fill_between(centres, mean - sd, mean + sd, alpha=0.2,
                            color=plt.cm.viridis(k / max(len(by_p) - 1, 1)))
        lines.append(f"{p},{len(pdfs)}," + ",".join(f"{v:.6g}" for v in mean))
    fine = np.linspace(0, np.pi / 2, 100)
    ax.plot(fine, np.sin(fine), "k--", label="isotropic: sin φ_c")
    for x in (np.pi / 6, np.pi / 3):
        ax.axvline(x, color="0.7", lw=0.8)
    ax.set_xlabel("φ_c, angle between contact normal and the bed axis (rad)")
    ax.set_ylabel("PDF")
    ax.legend(fontsize=7)
    fig.tight_layout()
    savefig_atomic(fig, out_dir / "contact_angles.png", dpi=110)
    plt.close(fig)
    write_text_atomic(out_dir / "contact_angles.csv", "\n".join(lines) + "\n")
