"""Synthetic packings with known answers (for tests and examples): a simple-cubic lattice.

Terreros 2012 (000, sec. 3) shows that a simple-cubic lattice of touching spheres with the
conductance of a cube face reproduces the 7-point finite-difference stencil; tests use this
packing to check laws, solvers and post-processing against closed forms.
"""
from __future__ import annotations

import numpy as np

from .packing import Packing

_FACES = (("xmin", 0, -1), ("xmax", 0, +1), ("ymin", 1, -1), ("ymax", 1, +1),
          ("zmin", 2, -1), ("zmax", 2, +1))


def simple_cubic_packing(shape=(4, 4, 4), spacing_m=1e-3, radius_m=None, young_pa=7e10,
                         poisson=0.3, density=2700.0, phase=None) -> Packing:
    """A box of nx*ny*nz spheres on a simple-cubic lattice of pitch ``spacing_m``.

    Face neighbours are contacts with overlap 2r - spacing (r defaults to half the pitch, so
    the spheres just touch); contacts carry the Hertz normal force of that overlap. The six
    faces of the lattice's bounding box are plane walls, in contact with the outer layers.
    """
    nx, ny, nz = shape
    radius_m = spacing_m / 2 if radius_m is None else radius_m
    idx = np.arange(nx * ny * nz).reshape(nx, ny, nz)
    grid = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"),
                    axis=-1).reshape(-1, 3)
    position = (grid + 0.5) * spacing_m
    pairs = []
    for axis in range(3):
        a = np.take(idx, np.arange(shape[axis] - 1), axis=axis).reshape(-1)
        b = np.take(idx, np.arange(1, shape[axis]), axis=axis).reshape(-1)
        pairs.append(np.stack([a, b], axis=1))
    pair = np.concatenate(pairs).astype(np.int64)
    pair = pair[np.lexsort((pair[:, 1], pair[:, 0]))]
    branch = position[pair[:, 1]] - position[pair[:, 0]]
    n = position.shape[0]
    radius = np.full(n, radius_m)
    overlap = np.full(pair.shape[0], 2 * radius_m - spacing_m)
    e_star = young_pa / (2.0 * (1.0 - poisson ** 2))
    r_star = radius_m / 2.0
    force = np.where(overlap > 0, 4.0 / 3.0 * e_star * np.sqrt(r_star)
                     * np.clip(overlap, 0, None) ** 1.5, 0.0)
    lo = np.zeros(3)
    hi = np.array(shape, dtype=float) * spacing_m
    wall_point, wall_normal, wall_particle, wall_index = [], [], [], []
    for w, (_name, axis, side) in enumerate(_FACES):
        point = np.zeros(3)
        point[axis] = lo[axis] if side < 0 else hi[axis]
        normal = np.zeros(3)
        normal[axis] = -side  # pointing into the domain
        wall_point.append(point)
        wall_normal.append(normal)
        layer = 0 if side < 0 else shape[axis] - 1
        members = np.take(idx, [layer], axis=axis).reshape(-1)
        wall_particle.append(members)
        wall_index.append(np.full(members.size, w))
    wall_particle = np.concatenate(wall_particle).astype(np.int64)
    k = wall_particle.size
    return Packing(
        position=position, radius=radius,
        phase=np.zeros(n, np.int32) if phase is None else np.asarray(phase, np.int32),
        pair=pair, overlap=overlap, normal_force=force, branch=branch,
        wall_name=[f[0] for f in _FACES], wall_kind=["plane"] * 6,
        wall_point=np.array(wall_point), wall_normal=np.array(wall_normal),
        wall_radius=np.full(6, np.nan), wall_particle=wall_particle,
        wall_index=np.concatenate(wall_index).astype(np.int32),
        wall_overlap=np.zeros(k), wall_normal_force=np.zeros(k),
        domain_lo=lo, domain_hi=hi, periodic=np.zeros(3, bool),
        attrs=dict(generator="thermal_kernel.lattice.simple_cubic_packing", seed=0,
                   solid_fraction=float(n * 4 / 3 * np.pi * radius_m ** 3 / np.prod(hi - lo)),
                   mean_coordination=2.0 * pair.shape[0] / n, pressure_pa=float("nan"),
                   young_pa=young_pa, poisson=poisson, density=density),
        contact_radius=np.sqrt(np.clip(overlap, 0, None) * r_star),
    )
