"""Random sequential addition of non-overlapping spheres: the one placement routine of tdem.

Used by the initial clouds of both YADE generators (``yade_scripts/dense_geometry.make_cloud``,
``yade_scripts/bed_geometry.random_cloud``), by the random dispersion of inclusions of the dense
generator (``dense_geometry.dispersion_centres``) and by the ETC sweep
(``tdem_post/etc_sweep.py``). numpy and the standard library only: YADE's Python imports it as
``thermal_kernel.placement`` (through ``yade_scripts/placement.py``), and so does the project's;
``tests/test_layers.py`` keeps it importing nothing else.

Each caller keeps its own stream of candidate centres (its seeded draws, in its order), so a
seed gives the same spheres it gave before the four copies became one. A candidate is accepted
when it lies in the domain and its distance d to every sphere already placed satisfies
d^2 - (r_i + r_j + gap)^2 > 0 (touching counts as overlapping). Overlaps are looked for in a grid
of cells at least one largest separation wide, so each test is local: with the default cell
width the decisions are those of a test against every placed sphere.
"""
import math

import numpy as np


def random_sequential_addition(radii, candidates, inside=None, gap=0.0, cell=None,
                               cell_width=None):
    """Place spheres of the given radii one after the other, in that order; each takes the first
    of its candidate centres that is inside the domain and overlaps no sphere placed before.

    radii: the n radii, in placement order (m).
    candidates(k, r): an iterator of candidate centres (x, y, z) for sphere k of radius r; when
        it ends before one is accepted, the placement stops (the caller decides whether that is
        an error: ``len(result) < n``).
    inside(x, y, z, r) -> bool: whether a candidate lies in the domain (None: every candidate).
    gap: clearance kept between two spheres (m): accepted when d > r_i + r_j + gap.
    cell: (3,) size of a periodic cell [0, cell); distances by the minimum image (None: open
        space).
    cell_width: width of the search grid's cells (default 2 max(r) + gap, the largest
        separation: the test is then exact against all pairs; a smaller width misses pairs
        whose centres are more than one cell apart per axis).

    Returns the centres placed, an (m, 3) float array, m <= n.
    """
    radii = [float(r) for r in radii]
    if not radii:
        return np.zeros((0, 3))
    width = 2.0 * max(radii) + gap if cell_width is None else float(cell_width)
    periodic = cell is not None
    if periodic:
        size = [float(c) for c in cell]
        ncell = [max(1, int(s // width)) for s in size]
        widths = [s / m for s, m in zip(size, ncell)]
    else:
        widths = [width] * 3
    offsets = [(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)]
    grid = {}
    xs, ys, zs, rs = [], [], [], []
    for k, r in enumerate(radii):
        for x, y, z in candidates(k, r):
            if inside is not None and not inside(x, y, z, r):
                continue
            home = (int(math.floor(x / widths[0])), int(math.floor(y / widths[1])),
                    int(math.floor(z / widths[2])))
            if periodic:
                home = (home[0] % ncell[0], home[1] % ncell[1], home[2] % ncell[2])
                keys = {((home[0] + a) % ncell[0], (home[1] + b) % ncell[1],
                         (home[2] + c) % ncell[2]) for a, b, c in offsets}
            else:
                keys = [(home[0] + a, home[1] + b, home[2] + c) for a, b, c in offsets]
            if _free(x, y, z, r, gap, keys, grid, xs, ys, zs, rs, size if periodic else None):
                grid.setdefault(home, []).append(len(xs))
                xs.append(x), ys.append(y), zs.append(z), rs.append(r)
                break
        else:
            break
    return np.array([xs, ys, zs], dtype=float).T.reshape(-1, 3)


def _free(x, y, z, r, gap, keys, grid, xs, ys, zs, rs, size):
    """No sphere of the grid cells ``keys`` within r + r_q + gap of (x, y, z)."""
    for key in keys:
        for q in grid.get(key, ()):
            dx, dy, dz = xs[q] - x, ys[q] - y, zs[q] - z
            if size is not None:
                dx -= round(dx / size[0]) * size[0]
                dy -= round(dy / size[1]) * size[1]
                dz -= round(dz / size[2]) * size[2]
            if dx * dx + dy * dy + dz * dz - (rs[q] + r + gap) ** 2 <= 0:
                return False
    return True


def equal_spheres_for_volume(volume, sphere_volume):
    """How many spheres of ``sphere_volume`` are added, one at a time, until their summed
    volume reaches ``volume`` (the sum accumulated as a running float, as the dispersion always
    did)."""
    placed, count = 0.0, 0
    while placed < volume:
        placed += sphere_volume
        count += 1
    return count
