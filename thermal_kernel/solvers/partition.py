"""Which MPI rank owns which particles (the PETSc backend, docs/scaling.md): a space-filling-curve
order of the particle centres cut into contiguous, equal blocks, so that contacts -- between
neighbours in space -- mostly join two particles of one rank.

numpy only. ``order[k]`` is the particle (the packing's index) at position k of the new order;
rank r owns positions ``starts[r] .. starts[r + 1] - 1``.

Why a Morton (Z-order) curve: it is computed from the centres alone in O(N log N) (one sort),
needs no graph partitioner, and keeps a block of the order compact in space. Measured on the
100,000-sphere dense box (bench/bench_scaling.py, docs/scaling.md): the packing's own order cut
6.8 % of the contacts on 2 ranks; the Morton order cuts fewer (the table there).
"""
from __future__ import annotations

import numpy as np

from ..morton import morton_order


def particle_order(position_m: np.ndarray, kind: str = "morton") -> np.ndarray:
    """(N,) int64: the particles in the order the ranks share them out. ``kind`` "morton" (Z
    order of the centres, ties in index order) or "index" (the packing's own order)."""
    n = int(np.shape(position_m)[0])
    if kind == "index":
        return np.arange(n, dtype=np.int64)
    if kind != "morton":
        raise ValueError(f"order = {kind!r}: use 'morton' or 'index'")
    return morton_order(position_m)


def block_starts(n: int, size: int) -> np.ndarray:
    """(size + 1,) the first position of each rank's block: sizes differ by at most one (the
    first n % size ranks one more), as PETSc's own PETSC_DECIDE split."""
    counts = np.full(size, n // size, dtype=np.int64)
    counts[: n % size] += 1
    return np.concatenate([[0], np.cumsum(counts)])


def owner_of_particle(order: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """(N,) int32: the rank that owns each particle."""
    owner = np.empty(order.size, dtype=np.int32)
    for r in range(starts.size - 1):
        owner[order[starts[r]:starts[r + 1]]] = r
    return owner


def cut_contacts(pair: np.ndarray, conductance_w_k: np.ndarray, owner: np.ndarray) -> int:
    """Conducting contacts (H > 0) whose two particles are on different ranks: each is a value
    the matrix-vector product sends between ranks every step."""
    pair = np.asarray(pair).reshape(-1, 2)
    active = np.asarray(conductance_w_k) > 0
    return int(np.count_nonzero(owner[pair[active, 0]] != owner[pair[active, 1]]))
