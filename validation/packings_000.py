"""The packings of cases 2 and 3 of docs/validation.md (Terreros 2012, 000 sec. 5.1-5.2).

One periodic cell of 2,000 spheres per seed (`runs/dense_box.toml`'s material: Gaussian radii
sigma/mean 0.3, steel, 1 bar, gap_tolerance 0.1 - the packings of cases 4 and 6), relaxed once by
YADE; every beam and sheet of that seed is copied and carved from it (method = "tiled",
cell_packing), so five seeds cost five small relaxations and the carving costs seconds.

The carved domains are in the cell's units (mean radius ~1 mm): conduction depends on the
Fourier number only, so case 2 compares at the paper's Fo; case 3 rescales the packing to the
paper's 50 x 30 x 2 mm sheet (``scaled``).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from thermal_kernel.packing import Packing

from . import framework as fw

SEEDS = (1, 2, 3, 4, 5)
CELL_PARTICLES = 2000
# beam of 000 Table 2: length 2.18445 mm, radius 0.1155303 mm -> length / diameter
BEAM_LENGTH_M, BEAM_RADIUS_M = 2.18445e-3, 0.1155303e-3
BEAM_N = 19465
BEAM_ASPECT = BEAM_LENGTH_M / (2 * BEAM_RADIUS_M)        # 9.454
# sheet of 000 Table 3: 50 x 30 x 2 mm
SHEET_SIZE_M = (50e-3, 30e-3, 2e-3)
SHEET_NS = (1000, 5000, 20000)


def cell_name(seed: int) -> str:
    return f"cell2000_s{seed}"


def beam_name(seed: int, n: int = BEAM_N) -> str:
    return f"beam_{n}_s{seed}"


def sheet_name(n: int, seed: int) -> str:
    return f"sheet_{n}_s{seed}"


def _cell_path(seed: int) -> str:
    return str(fw.OUT / "packings" / cell_name(seed) / "packing.h5")


def register(seeds=SEEDS) -> None:
    for s in seeds:
        fw.register_packing(cell_name(s), "runs/dense_box.toml",
                            dict(shape="periodic", n_particles=CELL_PARTICLES, seed=s))
        fw.register_packing(beam_name(s), "runs/dense_box.toml",
                            dict(shape="cylinder", aspect=[1.0, 1.0, BEAM_ASPECT],
                                 n_particles=BEAM_N, method="tiled",
                                 cell_particles=CELL_PARTICLES, cell_packing=_cell_path(s),
                                 seed=s))
        for n in SHEET_NS:
            # cell_particles is only checked (<= n_particles) when cell_packing is given: the
            # copied cell keeps its own 2,000 spheres
            fw.register_packing(sheet_name(n, s), "runs/dense_box.toml",
                                dict(shape="box", aspect=[25.0, 15.0, 1.0], n_particles=n,
                                     method="tiled", cell_particles=min(n, CELL_PARTICLES),
                                     cell_packing=_cell_path(s), seed=s))


def build(name: str) -> str:
    """The packing file, building the seed's cell first (the carved domains copy it)."""
    scene, overrides = fw.PACKINGS[name]
    cell = overrides.get("cell_packing")
    if cell:
        fw.packing(cell.split("/")[-2])
    return str(fw.packing(name))


def scaled(packing: Packing, factor: float) -> Packing:
    """The same packing with every length multiplied by ``factor`` (positions, radii, branch
    vectors, overlaps, the domain, the walls' radii). Normal forces are left as they are (the
    geometric laws do not read them)."""
    f = float(factor)

    def mul(a):
        return None if a is None else np.asarray(a) * f
    return dataclasses.replace(
        packing, position=packing.position * f, radius=packing.radius * f,
        branch=packing.branch * f, overlap=packing.overlap * f,
        wall_point=packing.wall_point * f, wall_radius=packing.wall_radius * f,
        wall_overlap=packing.wall_overlap * f, domain_lo=packing.domain_lo * f,
        domain_hi=packing.domain_hi * f, contact_radius=mul(packing.contact_radius),
        wall_contact_radius=mul(packing.wall_contact_radius))
