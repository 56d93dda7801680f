"""Neighbour pairs of a packing by the gap criterion (numpy only; used under YADE).

A pair (i, j), i < j, is kept when its centre distance is below (1 + gap_tolerance)(r_i + r_j).
In a periodic cell the minimum image is used (the cell must be more than twice the cut-off).
Chunked all-pairs search: exact, O(N^2 / chunk) memory-light, a few seconds for 20,000 spheres.
"""
import numpy as np


def neighbour_pairs(position, radius, gap_tolerance, cell=None, chunk=512):
    """Return (pair (M,2) int64 sorted, branch (M,3) from i to j, minimum image applied)."""
    position = np.asarray(position, dtype=float)
    radius = np.asarray(radius, dtype=float)
    n = len(radius)
    factor = 1.0 + gap_tolerance
    pairs, branches = [], []
    for start in range(0, n, chunk):
        stop = min(n, start + chunk)
        d = position[None, :, :] - position[start:stop, None, :]          # (c, n, 3): i -> j
        if cell is not None:
            d -= np.round(d / cell) * cell
        dist2 = np.einsum("cnk,cnk->cn", d, d)
        cut = factor * (radius[start:stop, None] + radius[None, :])
        ii, jj = np.nonzero(dist2 < cut ** 2)
        ii += start
        upper = jj > ii
        ii, jj = ii[upper], jj[upper]
        pairs.append(np.stack([ii, jj], axis=1))
        branches.append(d[ii - start, jj])
    pair = np.concatenate(pairs).astype(np.int64) if pairs else np.zeros((0, 2), np.int64)
    branch = np.concatenate(branches) if branches else np.zeros((0, 3))
    order = np.lexsort((pair[:, 1], pair[:, 0]))
    return pair[order], branch[order]
