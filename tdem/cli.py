"""The ``tdem`` command line. Subcommands import their code lazily."""
from __future__ import annotations

import argparse
import os
import re
import signal
import sys
from pathlib import Path

from thermal_kernel.threading_layer import prefer_openmp

from .errors import UserError

RUNS = Path(__file__).resolve().parent.parent / "runs"


def _out_dir(args, flag="--out"):
    """``--out`` as a Path (None when not given); refused when it names an existing file."""
    if not getattr(args, "out", None):
        return None
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UserError(f"{out}: {flag}: expected a folder (made if missing), got an existing "
                        "file")
    return out


def _threads(args, default=None):
    """``--threads`` checked against the numba threads this process has (NUMBA_NUM_THREADS,
    default: the CPUs); ``default`` when not given, capped at that number."""
    if args.threads is None and default is None:
        return None
    import numba
    most = numba.config.NUMBA_NUM_THREADS
    if args.threads is None:
        return min(default, most)
    if not 1 <= args.threads <= most:
        raise UserError(f"--threads: expected an integer from 1 to {most} (the numba threads "
                        f"available: NUMBA_NUM_THREADS or the CPUs), got {args.threads}")
    return args.threads


def _positive(args, name):
    """An integer option that counts threads or jobs: refused below 1, in one line."""
    value = getattr(args, name)
    if value < 1:
        raise UserError(f"--{name.replace('_', '-')}: expected an integer >= 1, got {value}")
    return value


def _text_file(path, what):
    """Refuse a scene/campaign path that is missing, a folder or not UTF-8, in one line."""
    path = Path(path)
    if not path.exists():
        raise UserError(f"{path}: file not found")
    if path.is_dir():
        raise UserError(f"{path}: is a folder; expected a {what} TOML file")
    try:
        path.read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise UserError(f"{path}: not UTF-8 text (byte 0x{e.object[e.start]:02x} at offset "
                        f"{e.start}); expected a {what} TOML file") from None
    return path


def _cmd_pack(args):
    from .pack import build, build_seeds, parse_seeds
    _text_file(args.scene, "scene")
    _positive(args, "threads")
    _positive(args, "jobs")
    out = _out_dir(args)
    if args.seeds is not None:
        seeds = parse_seeds(args.seeds)
        if args.threads != 1:
            raise UserError("--threads: yade-batch runs each seed on one YADE thread "
                            "(deterministic); use --jobs for parallel seeds")
        build_seeds(Path(args.scene), seeds, out, jobs=args.jobs, quiet=args.quiet)
        return
    build(Path(args.scene), out, threads=args.threads, quiet=args.quiet)


def _cmd_run(args):
    from thermal_kernel.run import run_scene
    from thermal_kernel.scene import load_scene
    threads = _threads(args)
    scene = load_scene(args.scene, out_dir=_out_dir(args))
    packing = Path(args.packing) if args.packing else None
    if packing is None and scene.pack is not None:
        from .pack import build, built_packings, default_out_dir
        pack_dir = Path(args.out) if args.out else default_out_dir(Path(args.scene))
        made = built_packings(Path(args.scene), pack_dir)
        if made:
            print(f"tdem run: using {', '.join(map(str, made))} (made by tdem pack from this "
                  "[pack] table)", flush=True)
        else:
            made = build(Path(args.scene), pack_dir, quiet=args.quiet)
        if len(made) != 1:
            raise UserError(f"{args.scene}: pack: the [pack] table made {len(made)} packings; "
                            "a scene runs on one (use `tdem campaign` for a pressure series)")
        packing = made[0]
    if args.checkpoint_every < 0:
        raise UserError(f"--checkpoint-every: expected a number of output times >= 0, got "
                        f"{args.checkpoint_every}")
    if args.ranks is not None or scene.solver.backend == "petsc":
        # the PETSc backend on MPI ranks (issue 25, docs/scaling.md); --ranks implies it
        from thermal_kernel.solvers.mpi_launch import checked_ranks, run_on_ranks
        ranks = 1 if args.ranks is None else checked_ranks(args.ranks)
        if args.threads:
            raise UserError("--threads: not with the PETSc backend (--ranks, or solver.backend"
                            " = \"petsc\"); expected an in-process run for it")
        run_on_ranks(Path(args.scene), ranks, packing=packing, out=args.out,
                     quiet=args.quiet, checkpoint_every=args.checkpoint_every,
                     resume=args.resume, output=scene.output,
                     run_args={k: v for k, v in vars(args).items() if k != "func"})
        return
    run_scene(scene, packing, quiet=args.quiet, threads=threads,
              checkpoint_every=args.checkpoint_every, resume=args.resume,
              run_args={k: v for k, v in vars(args).items() if k != "func"})


def _scene_and_packing(args):
    """The scene (laws known) and its packing, or --packing: for commands on a built packing."""
    from thermal_kernel.laws import LAWS
    from thermal_kernel.packing import read_packing
    from thermal_kernel.scene import load_scene
    from .pack import default_out_dir
    scene = load_scene(args.scene, known_laws=LAWS)
    path = Path(args.packing) if args.packing else scene.packing
    if path is None:       # a [pack] scene: the packing `tdem pack SCENE` wrote
        path = default_out_dir(Path(args.scene)) / "packing.h5"
    if not Path(path).exists():
        raise UserError(f"{path}: file not found (run `tdem pack {args.scene}` first)")
    return scene, path, read_packing(path)


def _cmd_calibrate(args):
    from thermal_kernel.calibrate import calibrate_axes
    from thermal_kernel.laws import get_law
    from thermal_kernel.problem import law_params
    scene, path, packing = _scene_and_packing(args)
    if args.ranks is None:
        results, skipped, ct = calibrate_axes(scene, packing, args.axis)
    else:       # each flux test's steady solve on MPI ranks (issue 25, docs/scaling.md)
        from thermal_kernel.run import ranks_of_run_in_memory
        from thermal_kernel.solvers.mpi_launch import checked_ranks
        with ranks_of_run_in_memory(checked_ranks(args.ranks)):
            results, skipped, ct = calibrate_axes(scene, packing, args.axis)
    mean_radius = law_params(scene, get_law(scene.law))["mean_radius"]   # with the default
    print(f"tdem calibrate: {args.scene} on {path} ({packing.n_particles} particles), law haddad"
          f" (R_m {mean_radius} mean), lambda = {results[0].conductivity_w_mk:.6g} W/m/K (002, "
          "eq. 8-9: one steady solve)")
    for r in results:
        print(f"  axis {r.axis}: faces {r.n_hot} / {r.n_cold} particles, L = {r.length_m:.6g} m, "
              f"A = {r.area_m2:.6g} m^2, Q = {r.heat_flow_w:.6g} W at C_t = {r.ct_used:.6g} "
              f"(balance {r.balance:.1e}) -> lambda_e = {r.effective_w_mk:.6g} W/m/K, "
              f"C_t = {r.ct:.6f}")
    for axis, why in skipped.items():
        print(f"  axis {axis}: skipped ({why})")
    if results[0].neighbours is not None:          # the same packing on every axis: one gap
        print(f"  {results[0].neighbours.line()}")
    print(f"  put this in the scene:\n[law_params]\nct = {ct:.6f}")


def _cmd_laws(args):
    from thermal_kernel.laws import LAWS
    physical = [n for n, law in LAWS.items() if not law.diagnostic]
    diagnostic = [n for n, law in LAWS.items() if law.diagnostic]
    for group in (physical, diagnostic):
        if group is diagnostic and group:
            print("\ndiagnostic laws: hypothesis tools, not physical laws (docs/campaign.md, "
                  "issue 15)")
        width = max((len(n) for n in group), default=0)
        for name in group:
            law = LAWS[name]
            params = ", ".join(f"{k} = {v!r}" for k, v in law.defaults.items())
            print(f"{name:<{width}}  {law.formula}")
            print(f"{'':<{width}}  source: {law.reference}" + (f"; parameters: {params}"
                                                              if params else ""))


def _cmd_demo(args):
    from .campaign import run_campaign
    scene = RUNS / "demo.toml"
    print(f"tdem demo: the default campaign {scene}", flush=True)
    run_campaign(scene, _out_dir(args), threads=_threads(args, default=2),
                 yade_threads=_positive(args, "yade_threads"), quiet=args.quiet)


def _cmd_campaign(args):
    from .campaign import run_campaign
    _text_file(args.campaign, "campaign")
    run_campaign(Path(args.campaign), _out_dir(args),
                 threads=_threads(args, default=2), yade_threads=_positive(args, "yade_threads"),
                 quiet=args.quiet,
                 repost=args.repost, jobs=_positive(args, "jobs"), ranks=args.ranks,
                 threads_given=args.threads is not None)


def _cmd_post(args):
    """tdem_post.post_run.command: the post folder built whole or not at all, the report lines
    (each quantity or why the run cannot give it), its own Ctrl-C handling."""
    from tdem_post.post_run import command
    return command(args.run, n_bins=args.bins, halo_ratio=args.halo,
                   halo_radius=args.halo_radius)


def _floats(text, what):
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise UserError(f"{what}: expected comma-separated numbers, got {text!r}") from None
    if not values or any(not v > 0 for v in values):
        raise UserError(f"{what}: expected positive numbers, got {text!r}")
    return values


def _cmd_etc(args):
    import csv
    from thermal_kernel.atomic import open_atomic
    from tdem_post.etc_sweep import etc_sweep, plot_etc
    from .pack import default_out_dir
    contrasts = _floats(args.contrasts, "--contrasts")
    fractions = _floats(args.fractions, "--fractions")
    if any(f >= 1 for f in fractions + (args.single_fraction,)):
        raise UserError("--fractions/--single-fraction: expected volume fractions below 1")
    scene, path, packing = _scene_and_packing(args)
    out = _out_dir(args) or default_out_dir(Path(args.scene)) / "etc"
    print(f"tdem etc: {args.scene} on {path} ({packing.n_particles} particles), law "
          f"{scene.law}, steady flux tests along {args.axis} (002 sec. 4-5)", flush=True)
    print(f"  {'case':<11s}{'contrast':>9s}{'f':>8s}{'k/k_m':>9s}{'Maxwell':>9s}"
          f"{'Bruggeman':>10s}{'HS low':>9s}{'HS up':>9s}", flush=True)

    def show(r):
        print(f"  {r['case']:<11s}{r['contrast']:>9.3g}{r['fraction']:>8.4f}"
              f"{r['k_over_km']:>9.4f}{r['maxwell']:>9.4f}{r['bruggeman']:>10.4f}"
              f"{r['hs_lower']:>9.4f}{r['hs_upper']:>9.4f}", flush=True)

    rows, k_m = etc_sweep(scene, packing, contrasts=contrasts, single_fraction=args.single_fraction,
                          fractions=fractions, dispersion_contrast=args.dispersion_contrast,
                          diameter_over_length=args.diameter_over_length, seed=args.seed,
                          axis=args.axis, progress=show)
    out.mkdir(parents=True, exist_ok=True)
    with open_atomic(out / "etc.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    plot_etc(rows, out / "etc.png", title=f"{Path(args.scene).name}: {packing.n_particles} "
             f"particles, law {scene.law}, k_m = {k_m:.4g} W/m/K in the flux test")
    print(f"  k_m (single phase) = {k_m:.6g} W/m/K; wrote {out}/etc.csv and etc.png")


def _cmd_info(args):
    from thermal_kernel.packing import format_statistics, packing_statistics, read_packing
    from thermal_kernel.packing_stats import describe_recheck, recheck
    packing = read_packing(args.packing)
    print(f"{args.packing}: format {packing.attrs['format']} v{packing.attrs['format_version']},"
          f" generator {packing.attrs['generator']}, seed {packing.attrs['seed']}")
    print(format_statistics(packing_statistics(packing)))
    if packing.wall_name:
        print("  walls                " + ", ".join(
            f"{n} ({k})" for n, k in zip(packing.wall_name, packing.wall_kind)))
    again = recheck(packing)        # the importers' own statistics, from the file's arrays
    if again is not None:
        print(f"  re-derived           {describe_recheck(again)}")
    _print_provenance(packing.attrs)


def _print_provenance(attrs):
    """What an imported packing's importer inferred, and its force-law check (docs/import.md)."""
    from thermal_kernel.contact_check import describe
    if attrs.get("source"):
        print(f"  source               {attrs['source']}")
    if attrs.get("inferred") not in (None, "", "none"):
        for k, item in enumerate(str(attrs["inferred"]).split("; ")):
            print(("  inferred             " if k == 0 else " " * 23) + item)
    line = describe(attrs)
    if line:
        print(f"  force law check      {line}")


def _cmd_import_liggghts(args):
    from thermal_kernel.contact_check import is_mismatch
    from thermal_kernel.packing import format_statistics, packing_statistics
    from .liggghts import import_liggghts
    packing = import_liggghts(args.atoms, args.pairs, args.walls_dump, args.output,
                              walls=args.walls, young=args.young, poisson=args.poisson,
                              density=args.density, pressure=args.pressure_pa, seed=args.seed,
                              timestep=args.timestep, law=args.law)
    print(f"tdem import: wrote {args.output} ({packing.attrs['source']})")
    print(format_statistics(packing_statistics(packing)))
    if packing.wall_name:
        print("  walls                " + ", ".join(packing.wall_name))
    _print_provenance(dict(packing.attrs, source=None))
    if is_mismatch(packing.attrs):
        print(f"tdem import: warning: {args.output}: force-law MISMATCH: F / F_law median "
              f"{packing.attrs['force_law_ratio_median']:.4g}, 95 % of |F / F_law - 1| below "
              f"{packing.attrs['force_law_mismatch_p95']:.3g} (written; recorded in force_law_*)",
              file=sys.stderr)


def _cmd_yade_path(args):
    from .yade import YADE_SCRIPTS
    print(Path(YADE_SCRIPTS).resolve())


def _output_file(args, suffix):
    """``-o`` (default: the packing's name with ``suffix``): a file name ending in ``suffix``
    whose folder exists."""
    out = Path(args.output) if args.output else Path(args.packing).with_suffix(suffix)
    if out.suffix.lower() != suffix:
        raise UserError(f"{out}: -o: expected a file name ending in {suffix}")
    if out.is_dir():
        raise UserError(f"{out}: -o: is a folder; expected a {suffix} file name")
    if not out.parent.is_dir():
        raise UserError(f"{out}: -o: the folder {out.parent} does not exist")
    return out


def _cmd_export(args):
    from thermal_kernel.output import read_run_packing, read_thermal
    from thermal_kernel.packing import read_packing
    from .export import packing_to_vtk
    temps = None
    if args.thermal:        # the run's temperatures, on the packing it was made on (its hash)
        run = read_thermal(args.thermal)
        packing = read_run_packing(run, args.packing)
        temps = (run.times, run.temperature)
    else:
        packing = read_packing(args.packing)
    out = _output_file(args, ".vtu")
    packing_to_vtk(packing, out, temps)
    print(f"wrote {out} ({packing.n_particles} particles, {packing.n_contacts} contacts"
          + (f", temperatures at {len(temps[0])} output times" if temps else "") + ")")


def _cmd_plot(args):
    from thermal_kernel.packing import read_packing
    from tdem_post.packing_plots import plot_packing
    packing = read_packing(args.packing)
    out = _output_file(args, ".png")
    plot_packing(packing, out)
    print(f"wrote {out}")


def _cmd_validate(args):
    from validation.run import validate
    return validate(args.cases, force=args.force, quick=args.quick, list_only=args.list_only,
                    threads=_threads(args), action=args.action, ranks=args.ranks)


def _cmd_window(args):
    from tdem_post.window import command
    return command(args)


def _cmd_paper_compare(args):
    from tdem_post.paper_compare import command
    return command(args)


def _cmd_fft_reference(args):
    from tdem_post.fft_conductivity import command
    return command(args)


def _module_command(sub, name, module, help, func, description=None):
    """``tdem NAME``: a command whose options and work live in ``module`` (its
    ``add_arguments`` and ``command``, which its own ``python -m`` entry takes too); its
    description the module's docstring unless given."""
    import importlib
    mod = importlib.import_module(module)
    p = sub.add_parser(name, help=help, description=description or mod.__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    mod.add_arguments(p)
    p.set_defaults(func=func)


def _add_pack(sub):
    p = sub.add_parser("pack", help="build packing(s) with YADE from a scene's [pack] table")
    p.add_argument("scene", help="scene TOML file with a [pack] table")
    p.add_argument("--out", help="output folder (default: runs/out/<scene name>/ beside the scene)")
    p.add_argument("--threads", type=int, default=1,
                   help="YADE threads (-j), default 1 (more is not deterministic)")
    p.add_argument("--seeds", help="comma-separated seeds: one packing each, in <out>/seed_<s>/, "
                                   "run as one yade-batch table (dense generator)")
    p.add_argument("--jobs", type=int, default=2,
                   help="with --seeds: YADE jobs at a time (yade-batch -j), default 2")
    p.add_argument("--quiet", action="store_true", help="do not stream YADE's output")
    p.set_defaults(func=_cmd_pack)


def _add_run(sub):
    p = sub.add_parser("run", help="run a thermal scene (TOML) and write thermal.h5")
    p.add_argument("scene")
    p.add_argument("--packing", help="packing.h5 to use instead of the scene's")
    p.add_argument("--out", help="output folder (default: runs/out/<scene name>/)")
    p.add_argument("--threads", type=int, default=None, help="numba threads (default: all)")
    p.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    p.add_argument("--checkpoint-every", type=int, default=0, metavar="K",
                   help="write a checkpoint every K output times (transient runs)")
    p.add_argument("--resume", action="store_true",
                   help="continue from the checkpoint of an interrupted run (same bits)")
    p.add_argument("--ranks", type=int, default=None, metavar="N",
                   help="solve on N MPI ranks with PETSc (solver.backend = \"petsc\"; needs "
                        ".venv-mpi, docs/scaling.md)")
    p.set_defaults(func=_cmd_run)


def _add_calibrate_laws_demo(sub):
    p = sub.add_parser("calibrate", help="calibrate the haddad law's C_t on a packing by a "
                                         "steady flux test (002, eq. 8-9)")
    p.add_argument("scene", help="scene TOML with law = \"haddad\" and its material")
    p.add_argument("--packing", help="packing.h5 to use instead of the scene's")
    p.add_argument("--axis", default="all", choices=["x", "y", "z", "all"],
                   help="direction of the flux test (default: all: every axis whose cross-section "
                        "is a box face or a cylinder along it, averaged; the others skipped)")
    p.add_argument("--ranks", type=int, default=None, metavar="N",
                   help="each flux test's steady solve on N MPI ranks with PETSc (needs "
                        ".venv-mpi, docs/scaling.md)")
    p.set_defaults(func=_cmd_calibrate)

    p = sub.add_parser("laws", help="list the conductance laws with formula and reference")
    p.set_defaults(func=_cmd_laws)

    p = sub.add_parser("demo", help="run the default scene (runs/demo.toml) end to end")
    p.add_argument("--out", help="output folder (default: runs/out/demo/)")
    p.add_argument("--threads", type=int, default=None,
                   help="numba threads, default 2 (at most the threads available)")
    p.add_argument("--yade-threads", type=int, default=1,
                   help="YADE threads (-j), default 1: reproducible packings for a seed")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=_cmd_demo)


def _add_campaign(sub):
    p = sub.add_parser("campaign", help="pressure campaign: packings, thermal runs, post, "
                                        "report (resumes where it stopped)")
    p.add_argument("campaign", help="campaign TOML ([pack] + [campaign] + thermal scene)")
    p.add_argument("--out", help="output folder (default: runs/out/<campaign name>/)")
    p.add_argument("--threads", type=int, default=None,
                   help="numba threads, default 2 (at most the threads available)")
    p.add_argument("--yade-threads", type=int, default=1,
                   help="YADE threads (-j), default 1: reproducible packings for a seed")
    p.add_argument("--quiet", action="store_true", help="do not stream YADE's output")
    p.add_argument("--repost", action="store_true",
                   help="keep finished thermal runs but post-process them again")
    p.add_argument("--jobs", type=int, default=1,
                   help="with [campaign] seeds: YADE series built at a time, default 1 (seed "
                        "after seed, each one's cases run before the next is built)")
    p.add_argument("--ranks", type=int, default=None, metavar="N",
                   help="each case's thermal solve on N MPI ranks with PETSc (solver.backend = "
                        "\"petsc\" runs on 1 without it; needs .venv-mpi, docs/scaling.md)")
    p.set_defaults(func=_cmd_campaign)


def _add_post(sub):
    p = sub.add_parser("post", help="post-process a run: profiles, gamma, tau, mean field, "
                                    "flux field")
    p.add_argument("run", help="run folder (with thermal.h5) or a thermal.h5")
    p.add_argument("--bins", type=int, default=10, help="profile bins, default 10")
    p.add_argument("--halo", type=float, default=3.0,
                   help="Halo radius over the particle radius for the flux field (002 eq. 22), "
                        "default 3")
    p.add_argument("--halo-radius", default="common", choices=["common", "own"],
                   help="Halo radius: halo x the packing's mean radius for every particle "
                        "(common, default: 002's halo of a pre-defined number of DE) or halo x "
                        "each particle's own radius (own)")
    p.set_defaults(func=_cmd_post)


def _add_etc(sub):
    p = sub.add_parser("etc", help="ETC of a composite vs contrast and volume fraction "
                                   "(steady flux tests, 002 sec. 4-5) with Maxwell, HS, Bruggeman")
    p.add_argument("scene", help="scene TOML (law, [material] of the matrix) with its packing")
    p.add_argument("--packing", help="packing.h5 to use instead of the scene's")
    p.add_argument("--out", help="output folder (default: runs/out/<scene name>/etc/)")
    p.add_argument("--axis", default="x", choices=["x", "y", "z"])
    p.add_argument("--contrasts", default="0.01,0.1,0.5,2,10,100",
                   help="single-inclusion contrasts k_i/k_m (default 0.01,0.1,0.5,2,10,100)")
    p.add_argument("--single-fraction", type=float, default=0.1551,
                   help="volume fraction of the single centred inclusion (default 0.1551: a = L/3)")
    p.add_argument("--fractions", default="0.05,0.1,0.15,0.2,0.25",
                   help="volume fractions of the random dispersion (default 0.05 ... 0.25)")
    p.add_argument("--dispersion-contrast", type=float, default=7.7,
                   help="contrast of the dispersion (default 7.7: silica in epoxy, 002 sec. 5)")
    p.add_argument("--diameter-over-length", type=float, default=1 / 6,
                   help="inclusion diameter over the box length (default 1/6, 002 sec. 5)")
    p.add_argument("--seed", type=int, default=0, help="seed of the dispersion (default 0)")
    p.set_defaults(func=_cmd_etc)


def _add_info(sub):
    p = sub.add_parser("info", help="validate a packing.h5 and print its statistics")
    p.add_argument("packing")
    p.set_defaults(func=_cmd_info)


def _add_import_yade_path(sub):
    p = sub.add_parser("import", help="import a packing made by another DEM code "
                                      "(docs/import.md)")
    isub = p.add_subparsers(dest="source", required=True)
    p = isub.add_parser("liggghts", help="LIGGGHTS dumps (dump custom atoms, dump local of "
                                         "pair/gran/local and wall/gran/local) -> packing.h5")
    p.add_argument("atoms", help="dump custom file: id type x y z radius")
    p.add_argument("pairs", help="dump local of compute pair/gran/local id force_normal delta")
    p.add_argument("walls_dump", nargs="?", metavar="walls",
                   help="dump local of compute wall/gran/local id force_normal delta (optional)")
    p.add_argument("--walls", default="",
                   help="the meshes of fix wall/gran in order, as planes: NAME[:SIDE][=COORD],... "
                        "e.g. zmin,plate:zmax (SIDE xmin ... zmax; COORD in m, else inferred)")
    p.add_argument("--young", type=float, help="Young's modulus of the spheres, Pa (required)")
    p.add_argument("--poisson", type=float, help="Poisson's ratio (required)")
    p.add_argument("--density", type=float,
                   help="kg/m^3 (default: from a mass column of the atoms dump)")
    p.add_argument("--pressure-pa", type=float,
                   help="pressure to record (default: the plate's force / area, else the walls')")
    p.add_argument("--law", default="hertz", choices=["hertz", "none"],
                   help="contact law the forces are checked against (default hertz)")
    p.add_argument("--timestep", type=int, help="snapshot to read (default: the last)")
    p.add_argument("--seed", type=int, default=0, help="seed to record (default 0)")
    p.add_argument("-o", "--output", required=True, help="packing file to write (.h5)")
    p.set_defaults(func=_cmd_import_liggghts)

    p = sub.add_parser("yade-path", help="print the folder holding tdem_yade.py, to put on "
                                         "sys.path in your own YADE script (docs/import.md)")
    p.set_defaults(func=_cmd_yade_path)


def _add_export_plot(sub):
    p = sub.add_parser("export", help="export a packing to VTK (.vtu) for ParaView")
    p.add_argument("packing")
    p.add_argument("-o", "--output", help="output .vtu (default: beside the input)")
    p.add_argument("--thermal", help="a run's thermal.h5: add its temperatures as point data")
    p.set_defaults(func=_cmd_export)

    p = sub.add_parser("plot", help="save a picture (PNG) of a packing: section and 3-D view")
    p.add_argument("packing")
    p.add_argument("-o", "--output", help="output .png (default: beside the input)")
    p.set_defaults(func=_cmd_plot)


def _add_module_commands(sub):
    """validate, window, paper-compare, fft-reference: options that live in their modules."""
    p = sub.add_parser("validate", help="run the cases of docs/validation.md (the papers' own "
                                        "cases) and rebuild it from the results (resumes)")
    from validation.run import add_arguments as validate_arguments   # one home for its options
    validate_arguments(p)
    p.set_defaults(func=_cmd_validate)

    _module_command(sub, "window", "tdem_post.window", func=_cmd_window,
                    help="run campaign cases again on 003's output times (0.2-7 s) and fit "
                         "gamma there, beside the case's own fit (docs/campaign.md)")
    _module_command(sub, "paper-compare", "tdem_post.paper_compare", func=_cmd_paper_compare,
                    help="the figure of gamma_paper(p) and tau(p) against 003's fits "
                         "(docs/campaign.md, Why the paper's gamma falls)")
    _module_command(sub, "fft-reference", "tdem_post.fft_conductivity",
                    func=_cmd_fft_reference,
                    description="One sphere in the periodic cube (the simple-cubic array) on "
                                "a refined sequence of grids, against Rayleigh's formula: the "
                                "convergence table of docs/fft_reference.md (the solver: "
                                "tdem_post/fft_conductivity.py).",
                    help="the FFT reference's convergence against Rayleigh's formula on one "
                         "sphere in the periodic cube (docs/fft_reference.md)")


# the subcommands in the order `tdem --help` lists them, one function per group
_SUBCOMMANDS = (_add_pack, _add_run, _add_calibrate_laws_demo, _add_campaign, _add_post,
                _add_etc, _add_info, _add_import_yade_path, _add_export_plot, _add_module_commands)


def build_parser() -> argparse.ArgumentParser:
    """The command line: every command, its arguments and their help (each group of commands
    declared by one of :data:`_SUBCOMMANDS`, in the order of ``tdem --help``; each command's
    work is its ``_cmd_*``)."""
    from . import __version__
    parser = argparse.ArgumentParser(
        prog="tdem", description="Thermal DEM on real packings of spheres (YADE-made).")
    parser.add_argument("--version", action="version", version=f"tdem {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for add in _SUBCOMMANDS:
        add(sub)
    return parser


# a value that starts with a minus sign: a negative number or a list of numbers
_NEGATIVE_VALUE = re.compile(r"^-(\d|\.\d|inf\b|nan\b)[\w.,+\-]*$", re.IGNORECASE)


def _value_options(parser: argparse.ArgumentParser) -> set[str]:
    """The long options of ``parser`` and its subcommands that take a value."""
    options = set()
    for action in parser._actions:          # (argparse has no public list of them)
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                options |= _value_options(sub)
        elif action.nargs != 0:
            options.update(o for o in action.option_strings if o.startswith("--"))
    return options


def _negative_values(argv: list[str], parser: argparse.ArgumentParser) -> list[str]:
    """``--young -1e8`` as ``--young=-1e8``: argparse takes a word starting with '-' for an
    option unless it is a plain negative number (-5, -.5), so ``-1e8`` or ``-1,2`` came out as
    "expected one argument". Joined to its option (one that takes a value), the value reaches
    the option's own check, which refuses it in one line naming the flag."""
    takes_value = _value_options(parser)
    out: list[str] = []
    for word in argv:
        if out and out[-1] in takes_value and _NEGATIVE_VALUE.match(word):
            out[-1] = f"{out[-1]}={word}"
        else:
            out.append(word)
    return out


# the signals tdem turns into an interrupt (their cleanup is Ctrl-C's: nothing half-written, no
# lock left), with the exit status of a process they end, 128 + the signal's number
_SIGNALS = {signal.SIGINT: "interrupted", signal.SIGTERM: "terminated (SIGTERM)"}
_received: list[int] = []


def _on_signal(signum, frame):
    """SIGINT and SIGTERM raise KeyboardInterrupt where the program is, so every cleanup path
    of Ctrl-C runs for both (SIGTERM used to end a run at once: no message, the output's lock
    file left). The signal is recorded: an interrupt swallowed on its way (by a finaliser,
    "Exception ignored ...") still ends the command with the signal's status."""
    _received.append(signum)
    raise KeyboardInterrupt


def _late_signal(signum, frame):
    """After the command returned (its files written or refused): one line, the signal's
    status, at once (a KeyboardInterrupt raised during the interpreter's shutdown was printed
    as "Exception ignored ... KeyboardInterrupt" and the process exited 0)."""
    try:
        sys.stderr.write(f"tdem: {_SIGNALS.get(signum, 'interrupted')}\n")
        sys.stderr.flush()
    finally:
        os._exit(128 + signum)


def _install_signal_handlers(handler) -> dict:
    """``handler`` for SIGINT and SIGTERM (not where the parent set them to be ignored, as
    nohup does); returns the handlers it replaced."""
    previous = {}
    for signum in _SIGNALS:
        old = signal.getsignal(signum)
        if old is not signal.SIG_IGN:
            previous[signum] = signal.signal(signum, handler)
    return previous


def main(argv=None) -> int:
    """The ``tdem`` program (``argv`` None: the command line; the process ends after it) or a
    call in-process with ``argv`` (tests: the signal handlers are put back on return)."""
    import threading
    from thermal_kernel.network import NetworkError
    from thermal_kernel.output import ThermalFileError
    from thermal_kernel.packing import PackingError
    from thermal_kernel.scene import SceneError
    from .yade import YadeError
    program = argv is None
    parser = build_parser()
    args = parser.parse_args(_negative_values(list(sys.argv[1:] if argv is None else argv),
                                              parser))
    # before any parallel kernel is compiled; a NUMBA_THREADING_LAYER* setting of the user wins
    prefer_openmp()
    if threading.current_thread() is not threading.main_thread():   # no signals there
        return _main(args, (UserError, PackingError, YadeError, SceneError, NetworkError,
                            ThermalFileError))
    _received.clear()
    previous = _install_signal_handlers(_on_signal)
    try:
        try:
            code = _main(args, (UserError, PackingError, YadeError, SceneError, NetworkError,
                                ThermalFileError))
        except KeyboardInterrupt:   # a second signal while the first one's line was printed
            code = 0
        if _received and code in (0, 1):    # an interrupt swallowed on its way (a finaliser)
            print(f"tdem: {_SIGNALS[_received[-1]]}", file=sys.stderr, flush=True)
        return 128 + _received[-1] if _received else code
    finally:
        if program:     # until the process has ended: one line and the signal's status (a
            # late handler the command set itself, e.g. tdem post's, is kept)
            for signum in _SIGNALS:
                if signal.getsignal(signum) is _on_signal:
                    signal.signal(signum, _late_signal)
        else:
            for signum, handler in previous.items():
                signal.signal(signum, handler)


def _main(args, user_errors) -> int:
    try:
        code = args.func(args)      # None, or an exit code (validate: 1 if a case failed)
        sys.stdout.flush()          # a closed pipe shows here, not at exit
    except user_errors as e:
        print(f"tdem: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as e:
        signum = _received[-1] if _received else signal.SIGINT
        print(f"tdem: {_SIGNALS[signum]}" + (f": {e}" if str(e) else ""), file=sys.stderr)
        return 128 + signum
    except BrokenPipeError:         # `tdem info ... | head`: the reader has gone, exit quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141                  # 128 + SIGPIPE, as a C tool killed by it
    except OSError as e:            # the filesystem: a full disk, a read-only or missing folder
        print(f"tdem: error: {_os_error(e)}", file=sys.stderr)
        return 2
    return code if isinstance(code, int) else 0


def _os_error(e: OSError) -> str:
    """One line: the file (the destination of a rename) and what went wrong."""
    name = e.filename2 if getattr(e, "filename2", None) else e.filename
    what = e.strerror or str(e)
    if name is not None:
        name = str(name)
        if name.endswith(".tmp") or ".tmp." in name:      # say the file the user asked for
            name = name.replace(".tmp", "", 1) if ".tmp." in name else name[:-4]
        what = f"{name}: {what}"
    return " ".join(what.split())


if __name__ == "__main__":
    sys.exit(main())
