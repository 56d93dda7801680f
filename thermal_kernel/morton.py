"""Z-order (Morton) keys of sphere centres: one home for the space-filling curve that
``solvers/partition.py`` cuts into the MPI ranks' blocks and that the YADE scripts use to put
large scenes into YADE in memory order (numpy only: YADE's Python imports it).

Spheres close along the curve are close in space, so a loop over contacts that reads the two
spheres' states touches memory that was read shortly before.
"""
from __future__ import annotations

import numpy as np

MORTON_BITS = 21           # per axis: 3 x 21 = 63 bits, one uint64 key


def _spread_bits(v: np.ndarray) -> np.ndarray:
    """Each of the low 21 bits of ``v`` (uint64) moved to every third bit (bit k -> 3k)."""
    v = v & np.uint64(0x1FFFFF)
    v = (v | (v << np.uint64(32))) & np.uint64(0x1F00000000FFFF)
    v = (v | (v << np.uint64(16))) & np.uint64(0x1F0000FF0000FF)
    v = (v | (v << np.uint64(8))) & np.uint64(0x100F00F00F00F00F)
    v = (v | (v << np.uint64(4))) & np.uint64(0x10C30C30C30C30C3)
    v = (v | (v << np.uint64(2))) & np.uint64(0x1249249249249249)
    return v


def morton_keys(position_m: np.ndarray, lo_m=None, hi_m=None) -> np.ndarray:
    """(N,) uint64 Z-order keys of the (N, 3) centres, each axis scaled to 21 bits over the
    bounding box (a flat axis gets key bits 0): the centres' own, or ``lo_m`` .. ``hi_m``
    given (the bounding box of every rank's centres: the MPI ranks' sort,
    :func:`~thermal_kernel.solvers.partition.morton_blocks_on_ranks`)."""
    x = np.asarray(position_m, dtype=np.float64)
    lo = x.min(axis=0) if lo_m is None else np.asarray(lo_m, dtype=np.float64)
    hi = x.max(axis=0) if hi_m is None else np.asarray(hi_m, dtype=np.float64)
    span = np.where(hi > lo, hi - lo, 1.0)
    q = np.floor((x - lo) / span * ((1 << MORTON_BITS) - 1)).astype(np.uint64)
    return (_spread_bits(q[:, 0]) | (_spread_bits(q[:, 1]) << np.uint64(1))
            | (_spread_bits(q[:, 2]) << np.uint64(2)))


def morton_order(position_m: np.ndarray) -> np.ndarray:
    """(N,) int64: the indices of the centres along the Z-order curve (ties in index order)."""
    return np.argsort(morton_keys(position_m), kind="stable").astype(np.int64)
