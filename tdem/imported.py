"""Campaigns on existing packing files (imported or made elsewhere): ``[campaign] packings``.

A campaign file may list packing files instead of a ``[pack]`` table::

    [campaign]
    laws = ["pipe"]
    packings = ["../out/liggghts_bed/packing_1.h5", "../out/liggghts_bed/packing_2.h5"]

Paths are relative to the campaign file. Each file is read by the validating reader before any
case runs; its pressure is the file's ``pressure_pa`` (what ``tdem import`` or ``tdem_yade.dump``
measured or was given), which must be a finite number > 0 for the report's fits over pressure.
"""
from __future__ import annotations

import math
from pathlib import Path

from .errors import UserError


def campaign_packings(campaign_path: Path, value, has_pack: bool, seeds=None) -> list[Path]:
    """The packing files of ``[campaign] packings``, checked; UserError in one line."""
    from thermal_kernel.packing import PackingError, read_packing
    where = f"{campaign_path}: campaign.packings"
    if has_pack:
        raise UserError(f"{where}: give either packings or a [pack] table, not both")
    if seeds is not None:
        raise UserError(f"{where}: seeds make packing series from [pack]; a list of packing "
                        "files has none (drop campaign.seeds)")
    if not (isinstance(value, list) and value and all(isinstance(x, str) for x in value)):
        raise UserError(f"{where}: expected a non-empty list of packing file names")
    base = Path(campaign_path).resolve().parent
    paths = [(base / x).resolve() for x in value]
    stems = {}
    for k, path in enumerate(paths):
        if path.stem in stems:
            raise UserError(f"{where}[{k}]: {path.name} has the same name as packings"
                            f"[{stems[path.stem]}]; the case folders are named after the files")
        stems[path.stem] = k
        if not path.is_file():
            raise UserError(f"{where}[{k}]: {path}: file not found")
        try:
            pressure = read_packing(path).attrs["pressure_pa"]
        except PackingError as e:
            raise UserError(f"{where}[{k}]: {e}") from None
        if not (math.isfinite(pressure) and pressure > 0):
            raise UserError(f"{where}[{k}]: {path}: pressure_pa is {pressure!r}; expected a "
                            "pressure > 0 (import with --pressure-pa, or dump with "
                            "pressure_pa=...)")
    return paths
