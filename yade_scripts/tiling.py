"""A periodic cell tiled to fill a larger domain and carved to a box, cylinder or sphere.

numpy only (runs under YADE and in the tests). The idea (YADE's own ``pack.randomDensePack(...,
spheresInCell=N)`` does the same for a shape): a periodic packing relaxed once is a packing of
all space with period ``cell``; copies of it side by side are the same packing, and the contacts
that cross a seam between two copies are exactly the cell's contacts across its periodic
boundary. Nothing is relaxed again, so the statistics of the tiled domain are those of the cell
(its φ, Z, forces, fabric), and its periodicity length is the cell size.

Carving keeps the spheres whose centre lies inside the target shape; spheres cut by its surface
stay whole. The carved surface is not a wall that was pressed against the spheres: its "wall
contacts" are the spheres within (1 + wall_gap_tolerance) r of the surface, with the geometric
overlap r - distance (0 ... r) and no force. A held-temperature boundary on that surface holds
those spheres, as a walled domain holds the spheres touching its wall.
"""
import numpy as np


def tile_index_grid(reps):
    """(T, 3) integer tile coordinates of a reps[0] x reps[1] x reps[2] block, row-major."""
    reps = np.asarray(reps, dtype=np.int64)
    grid = np.indices(tuple(int(r) for r in reps)).reshape(3, -1).T
    return grid.astype(np.int64)


def tile(position, cell, pair, branch, reps):
    """Copies of a periodic cell side by side.

    position: (n, 3) centres inside [0, cell); pair (m, 2) and branch (m, 3) (from i to j,
    minimum image) of the cell's contacts. Returns (position_t (T n, 3), source (T n,) index of
    each copy in the cell, pair_t (m_t, 2), pair_source (m_t,) index of each copied contact in
    the cell's list). Copy k of particle i has index k n + i. A contact whose partner image lies
    outside the block is dropped (the block is not periodic)."""
    position = np.asarray(position, dtype=float).reshape(-1, 3)
    cell = np.asarray(cell, dtype=float).reshape(3)
    pair = np.asarray(pair, dtype=np.int64).reshape(-1, 2)
    branch = np.asarray(branch, dtype=float).reshape(-1, 3)
    reps = np.asarray(reps, dtype=np.int64).reshape(3)
    n = len(position)
    grid = tile_index_grid(reps)
    n_tiles = len(grid)
    position_t = (position[None, :, :] + (grid * cell)[:, None, :]).reshape(-1, 3)
    source = np.tile(np.arange(n, dtype=np.int64), n_tiles)
    # Which copy of the cell holds j's image: the integer shift of (x_i + branch) - x_j.
    shift = np.rint((position[pair[:, 0]] + branch - position[pair[:, 1]]) / cell).astype(np.int64)
    pairs, sources = [], []
    stride = np.array([reps[1] * reps[2], reps[2], 1], dtype=np.int64)
    for k, g in enumerate(grid):
        partner = g + shift
        ok = np.all((partner >= 0) & (partner < reps), axis=1)
        rows = np.flatnonzero(ok)
        tj = partner[rows] @ stride
        pairs.append(np.stack([k * n + pair[rows, 0], tj * n + pair[rows, 1]], axis=1))
        sources.append(rows)
    pair_t = np.concatenate(pairs) if pairs else np.zeros((0, 2), np.int64)
    pair_source = np.concatenate(sources) if sources else np.zeros(0, np.int64)
    return position_t, source, pair_t, pair_source


def carve(keep, pair):
    """Keep the particles where ``keep`` is true: (new index of each kept particle's old index
    (-1 if dropped), rows of ``pair`` whose two particles are kept, those pairs renumbered)."""
    keep = np.asarray(keep, dtype=bool)
    new_index = np.full(len(keep), -1, dtype=np.int64)
    new_index[keep] = np.arange(int(keep.sum()), dtype=np.int64)
    pair = np.asarray(pair, dtype=np.int64).reshape(-1, 2)
    a, b = new_index[pair[:, 0]], new_index[pair[:, 1]]
    rows = np.flatnonzero((a >= 0) & (b >= 0))
    return new_index, rows, np.stack([a[rows], b[rows]], axis=1)


def repetitions(cell, size):
    """Copies of the cell per axis that cover a domain of the given size from the origin."""
    cell = np.asarray(cell, dtype=float)
    return np.maximum(1, np.ceil(np.asarray(size, dtype=float) / cell - 1e-12)).astype(np.int64)


def seam_distance(position, cell):
    """Distance of each centre to the nearest seam (plane of the tiling) - to compare the
    statistics of spheres on and away from the seams."""
    cell = np.asarray(cell, dtype=float)
    frac = position / cell - np.floor(position / cell)
    return np.min(np.minimum(frac, 1.0 - frac) * cell, axis=1)
