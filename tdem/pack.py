"""``tdem pack SCENE.toml``: build packings with YADE from a scene's ``[pack]`` table."""
from __future__ import annotations

import json
import math
import time
from pathlib import Path

from thermal_kernel.packing import format_statistics, packing_statistics, read_packing
from thermal_kernel.scene import read_toml

from . import yade
from .errors import UserError

# the largest seed: a packing stores its seed as a 64-bit integer (HDF5 attribute); a larger one
# passed every check and failed when YADE wrote the file (round 3, pack:seeds_huge)
SEED_MAX = 2**63 - 1


def parse_seeds(text: str, flag: str = "--seeds") -> list[int]:
    """``--seeds`` "1,2,5": distinct integers from 0 to SEED_MAX, refused in one line naming
    the flag before YADE starts."""
    try:
        seeds = [int(x) for x in str(text).split(",") if x.strip()]
    except ValueError:
        raise UserError(f"{flag}: expected comma-separated integers, got {text!r}") from None
    check_seeds(seeds, flag)
    return seeds


def check_seeds(seeds: list[int], flag: str = "--seeds") -> None:
    if not seeds or len(set(seeds)) != len(seeds) or min(seeds) < 0 or max(seeds) > SEED_MAX:
        raise UserError(f"{flag}: expected distinct integers from 0 to {SEED_MAX} (a seed is "
                        f"stored as a 64-bit integer), got {seeds}")


def read_pack_table(scene_path: Path) -> tuple[str, dict]:
    """Return (generator, resolved params) of a scene's [pack] table; UserError names file+key."""
    scene_path = Path(scene_path)
    scene, _ = read_toml(scene_path, error=UserError)
    table = scene.get("pack")
    if not isinstance(table, dict):
        raise UserError(f"{scene_path}: pack: missing [pack] table (a scene to build a packing "
                        "needs [pack] with generator = \"dense\" or \"bed\")")
    table = dict(table)
    generator = table.pop("generator", None)
    if generator not in yade.SCRIPTS:
        raise UserError(f"{scene_path}: pack.generator: expected one of "
                        f"{', '.join(yade.SCRIPTS)}, got {generator!r}")
    if "output_dir" in table:
        raise UserError(f"{scene_path}: pack.output_dir: not a scene key "
                        "(outputs go to runs/out/<scene name>/, or use tdem pack --out DIR)")
    try:
        params = yade.resolve_params(generator, table)
    except ValueError as e:
        raise UserError(f"{scene_path}: pack.{e}") from None
    if generator == "dense" and params["cell_packing"]:
        _check_cell_packing(scene_path, params)
    return generator, params


def _check_cell_packing(scene_path: Path, params: dict) -> None:
    """The cell_packing file of the tiled path, before YADE starts (the YADE script reads it
    again): a periodic cell made with the same material, pressure and neighbour criterion. The
    path is made absolute (relative to the scene). The other cross-field checks are the
    generator's own (yade_scripts/dense_params.check, run by resolve_params)."""
    cell = Path(params["cell_packing"])
    if not cell.is_absolute():
        cell = (Path(scene_path).resolve().parent / cell).resolve()
        params["cell_packing"] = str(cell)
    try:
        packing = read_packing(cell)
    except Exception as e:      # noqa: BLE001 - the reader's own one-line message
        raise UserError(f"{scene_path}: pack.cell_packing: {e}") from None
    if not all(packing.periodic):
        raise UserError(f"{scene_path}: pack.cell_packing: {cell}: expected a periodic cell "
                        "(a packing made with shape = \"periodic\"), got one with walls")
    for key in ("young_pa", "poisson", "confining_pressure_pa", "gap_tolerance"):
        have = packing.attrs.get(key)
        if have is None or not math.isclose(float(have), float(params[key]), rel_tol=1e-12):
            raise UserError(f"{scene_path}: pack.{key}: {params[key]!r} here, {have!r} in "
                            f"the cell {cell} (cell_packing): they must agree")


def default_out_dir(scene_path: Path) -> Path:
    scene_path = Path(scene_path)
    return scene_path.resolve().parent / "out" / scene_path.stem


def built_packings(scene_path: Path, out_dir: Path | None = None) -> list[Path] | None:
    """The packings an earlier `tdem pack` of this scene wrote in ``out_dir``, if its
    params.json equals the scene's [pack] table now (else None: they must be built again)."""
    generator, params = read_pack_table(scene_path)
    out_dir = Path(out_dir) if out_dir else default_out_dir(scene_path)
    done = out_dir / "params.json"
    made = sorted(out_dir.glob("packing*.h5"))
    if not done.exists() or not made:
        return None
    try:
        old = json.loads(done.read_text())
    except json.JSONDecodeError:
        return None
    old.pop("output_dir", None)
    if old != {k: v for k, v in params.items() if k != "output_dir"}:
        return None
    return made


def build_seeds(scene_path: Path, seeds: list[int], out_dir: Path | None = None, *,
                jobs: int = 2, quiet: bool = False) -> list[Path]:
    """One packing per seed, as one yade-batch table (``jobs`` YADE processes at a time, one
    thread each): ``<out>/seed_<s>/packing.h5``. Print each one's statistics."""
    generator, params = read_pack_table(scene_path)
    out_dir = Path(out_dir).resolve() if out_dir else default_out_dir(scene_path)
    check_seeds(seeds)
    if jobs < 1:
        raise UserError(f"--jobs: expected a number of parallel YADE jobs >= 1, got {jobs}")
    dirs = [out_dir / f"seed_{s}" for s in seeds]
    method = f"method {params['method']}, " if "method" in params else ""
    print(f"tdem pack: {scene_path} -> {out_dir}/seed_<s>/ (generator {generator}, {method}seeds "
          f"{', '.join(map(str, seeds))}, yade-batch with {jobs} job(s) at a time, 1 YADE "
          f"thread each)", flush=True)
    try:
        wall = yade.run_batch(generator, [dict(params, seed=s) for s in seeds], dirs,
                              jobs=jobs, quiet=quiet)
    except yade.YadeError as e:
        raise UserError(str(e)) from None
    made = [d / "packing.h5" for d in dirs]
    for path in made:
        print(f"{path}:", flush=True)
        print(format_statistics(packing_statistics(read_packing(path))), flush=True)
    print(f"tdem pack: {len(made)} packing(s) in {wall:.1f} s", flush=True)
    return made


def build(scene_path: Path, out_dir: Path | None = None, *, threads: int = 1,
          quiet: bool = False) -> list[Path]:
    """Build the packing(s) of a scene and print their statistics; return the files made."""
    generator, params = read_pack_table(scene_path)
    out_dir = Path(out_dir).resolve() if out_dir else default_out_dir(scene_path)
    method = f"method {params['method']}, " if "method" in params else ""
    print(f"tdem pack: {scene_path} -> {out_dir}/ (generator {generator}, {method}"
          f"YADE script yade_scripts/{yade.SCRIPTS[generator]}, {threads} thread(s))", flush=True)
    start = time.time()
    try:
        wall = yade.run_generator(generator, params, out_dir, threads=threads, quiet=quiet)
    except yade.YadeError as e:
        raise UserError(str(e)) from None
    made = sorted(p for p in out_dir.glob("packing*.h5") if p.stat().st_mtime >= start - 1)
    if not made:
        raise UserError(f"{scene_path}: YADE finished but wrote no packing*.h5 in {out_dir}")
    for path in made:
        packing = read_packing(path)
        print(f"{path}:", flush=True)
        print(format_statistics(packing_statistics(packing)), flush=True)
    print(f"tdem pack: {len(made)} packing(s) in {wall:.1f} s", flush=True)
    return made
