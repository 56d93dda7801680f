"""Which MPI rank owns which particles (the PETSc backend, docs/scaling.md): a space-filling-curve
order of the particle centres cut into contiguous, equal blocks, so that contacts -- between
neighbours in space -- mostly join two particles of one rank.

numpy only (the functions that take ``comm``, an mpi4py communicator, are collective over
it). ``order[k]`` is the particle (the packing's index) at position k of the new order;
rank r owns positions ``starts[r] .. starts[r + 1] - 1``.

Why a Morton (Z-order) curve: it is computed from the centres alone in O(N log N) (one sort),
needs no graph partitioner, and keeps a block of the order compact in space. Measured on the
100,000-sphere dense box (bench/bench_scaling.py, docs/scaling.md): the packing's own order cut
6.8 % of the contacts on 2 ranks; the Morton order cuts fewer (the table there).
"""
from __future__ import annotations

import numpy as np

from ..morton import morton_keys, morton_order


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


# ---------------------------------------------------------------- on the ranks (collective)
# The file's particles are cut into the same equal blocks (block_starts) as the order: rank r is
# the *directory* of the file's particles starts[r] .. starts[r + 1] - 1 (it reads their rows
# of the packing) and the *owner* of the order's places starts[r] .. starts[r + 1] - 1 (their
# rows of the matrix). No rank holds the whole order: values go between owners and
# directories in one Alltoallv, and to or from rank 0 in the file's order through the
# directories (one Gatherv or Scatterv).

def displacements(counts) -> np.ndarray:
    return np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)


def exchange_counts(comm, dest, size):
    """How many rows this rank sends to each rank (``dest``: each row's rank) and receives from
    each: (send_n, recv_n)."""
    send_n = np.bincount(np.asarray(dest, dtype=np.int64), minlength=size).astype(np.int64)
    recv_n = np.empty(size, dtype=np.int64)
    comm.Alltoall(send_n, recv_n)
    return send_n, recv_n


def alltoallv(comm, send, send_n, recv_n):
    """``send`` (rows grouped by destination rank, ``send_n`` rows each) exchanged: the rows
    this rank receives, ``recv_n`` from each rank, in rank order."""
    send = np.ascontiguousarray(send)
    width = int(np.prod(send.shape[1:], dtype=np.int64))
    recv = np.empty((int(recv_n.sum()),) + send.shape[1:], dtype=send.dtype)
    comm.Alltoallv([send, (send_n * width, displacements(send_n) * width)],
                   [recv, (recv_n * width, displacements(recv_n) * width)])
    return recv


def fetch(comm, ids, starts, columns):
    """The values of the particles ``ids`` (packing indices, sorted, unique) from the ranks
    holding their blocks (rank r holds ``starts[r]:starts[r + 1]``; ``columns`` this rank's
    arrays over its block): arrays aligned with ``ids``. One Alltoallv for the asks, one a
    column for the answers."""
    rank, size = comm.Get_rank(), comm.Get_size()
    dest = np.searchsorted(starts, ids, side="right") - 1      # sorted ids: grouped by rank
    send_n, recv_n = exchange_counts(comm, dest, size)
    asked = alltoallv(comm, np.asarray(ids, dtype=np.int64), send_n, recv_n) - starts[rank]
    return [alltoallv(comm, np.asarray(c)[asked], recv_n, send_n) for c in columns]


class RankError(RuntimeError):
    """Another rank's part of a collective step failed: its one-line message (each rank
    raises)."""


def agree(comm, fn, same=()):
    """``fn()`` on every rank; if it raised on any, every rank raises (no rank waits in a later
    collective for one that left): the rank's own error, or :class:`RankError` with the
    message of the lowest rank that failed. ``same``: exception classes raised alike on every
    rank -- when the lowest failing rank's error is one of them, every rank raises that class
    with its message (a reader's one error, whichever rank met it first)."""
    value, error = None, None
    try:
        value = fn()
    except Exception as e:              # noqa: BLE001 (re-raised below, on every rank)
        error = e
    faults = comm.allgather(None if error is None else (
        next((i for i, cls in enumerate(same) if isinstance(error, cls)), -1),
        str(error) or type(error).__name__))
    failed = [f for f in faults if f is not None]
    if not failed:
        return value
    kind, message = failed[0]
    if kind >= 0:
        raise same[kind](message) from None
    if error is not None:
        raise error
    raise RankError(message)


def gather_blocks(comm, block, starts):
    """Every rank's block ``starts[r]:starts[r + 1]`` gathered on rank 0 as one (N,) array
    (None elsewhere)."""
    block = np.ascontiguousarray(block)
    if comm.Get_rank() != 0:
        comm.Gatherv(block, None, root=0)
        return None
    out = np.empty(int(starts[-1]), dtype=block.dtype)
    comm.Gatherv(block, (out, np.diff(starts)), root=0)
    return out


def scatter_blocks(comm, whole, starts, dtype=np.float64) -> np.ndarray:
    """This rank's block ``starts[r]:starts[r + 1]`` of an (N,) array given on rank 0."""
    rank = comm.Get_rank()
    out = np.empty(int(starts[rank + 1] - starts[rank]), dtype=dtype)
    send = (np.ascontiguousarray(whole, dtype=dtype), np.diff(starts)) if rank == 0 else None
    comm.Scatterv(send, out, root=0)
    return out


def _before(keys, index, key, i) -> int:
    """How many of the pairs (``keys``, ``index``), sorted by key then index, precede
    (``key``, ``i``)."""
    lo = int(np.searchsorted(keys, key, side="left"))
    hi = int(np.searchsorted(keys, key, side="right"))
    return lo + int(np.searchsorted(index[lo:hi], i, side="left"))


def morton_blocks_on_ranks(comm, position_block_m, starts) -> np.ndarray:
    """:func:`particle_order` ("morton") sorted on the ranks: rank r gives the centres of its
    block of the file's particles (``starts[r]:starts[r + 1]``) and gets its block of the
    order (the packing indices at places ``starts[r]:starts[r + 1]``), the whole sort's bit
    for bit (the same keys: the bounding box of every centre, reduced; ties in index order),
    no rank holding every key. A sample sort: each rank sorts its keys, every rank's regular
    samples choose ``size - 1`` splitters, the pairs (key, index) go to the rank between
    their splitters and are merged there, then moved to the equal blocks by their places."""
    from mpi4py import MPI

    rank, size = comm.Get_rank(), comm.Get_size()
    x = np.asarray(position_block_m, dtype=np.float64).reshape(-1, 3)
    lo_m, hi_m = np.empty(3), np.empty(3)
    comm.Allreduce(x.min(axis=0) if x.shape[0] else np.full(3, np.inf), lo_m, op=MPI.MIN)
    comm.Allreduce(x.max(axis=0) if x.shape[0] else np.full(3, -np.inf), hi_m, op=MPI.MAX)
    keys = morton_keys(x, lo_m, hi_m)
    index = np.arange(starts[rank], starts[rank + 1], dtype=np.int64)
    by_key = np.argsort(keys, kind="stable")        # index ascending: ties in index order
    keys, index = keys[by_key], index[by_key]
    del by_key
    if size == 1:
        return index
    pick = (np.arange(1, size) * keys.size) // size if keys.size else np.zeros(0, np.int64)
    samples = comm.allgather((keys[pick], index[pick]))
    sk = np.concatenate([s[0] for s in samples])
    si = np.concatenate([s[1] for s in samples])
    ranked = np.lexsort((si, sk))
    chosen = ranked[(np.arange(1, size) * ranked.size) // size] if ranked.size else []
    cuts = [_before(keys, index, sk[c], si[c]) for c in chosen] or [0] * (size - 1)
    send_n = np.diff(np.concatenate([[0], cuts, [keys.size]])).astype(np.int64)
    recv_n = np.empty(size, dtype=np.int64)
    comm.Alltoall(send_n, recv_n)
    keys = alltoallv(comm, keys, send_n, recv_n)
    index = alltoallv(comm, index, send_n, recv_n)
    index = index[np.lexsort((index, keys))]        # this rank's run of the order
    del keys
    first = comm.exscan(int(index.size)) or 0
    dest = np.searchsorted(starts, first + np.arange(index.size), side="right") - 1
    send_n, recv_n = exchange_counts(comm, dest, size)
    return alltoallv(comm, index, send_n, recv_n)


class Routes:
    """The ways between this rank's block of the order (``mine``: the packing indices at its
    places, collective to make) and the file's order: to and from the particles'
    directories (one Alltoallv), and so to or from rank 0 whole (N,) in the file's order
    without any rank holding the order (:func:`morton_blocks_on_ranks`, the PETSc backend).
    Arrays of this rank's block are (n_local, ...) in the order; a directory's are its block
    of the file's particles."""

    def __init__(self, comm, mine, starts):
        self.comm, self.starts = comm, np.asarray(starts, dtype=np.int64)
        rank, size = comm.Get_rank(), comm.Get_size()
        self.n_local = int(np.asarray(mine).size)
        self.n_directory = int(self.starts[rank + 1] - self.starts[rank])
        dest = np.searchsorted(self.starts, mine, side="right") - 1
        self._perm = np.argsort(dest, kind="stable")
        self._send_n, self._recv_n = exchange_counts(comm, dest, size)
        # the directory's rows each received value goes to
        self._at = alltoallv(comm, np.asarray(mine, dtype=np.int64)[self._perm], self._send_n,
                             self._recv_n) - self.starts[rank]

    def to_directories(self, local) -> np.ndarray:
        """This rank's values (its block of the order) at their directories: this rank's
        block of the file's particles (as a directory)."""
        got = alltoallv(self.comm, np.asarray(local)[self._perm], self._send_n, self._recv_n)
        out = np.empty((self.n_directory,) + got.shape[1:], dtype=got.dtype)
        out[self._at] = got
        return out

    def from_directories(self, block) -> np.ndarray:
        """The inverse: the directories' values (this rank's block of the file's particles)
        at their owners: this rank's block of the order."""
        got = alltoallv(self.comm, np.asarray(block)[self._at], self._recv_n, self._send_n)
        out = np.empty((self.n_local,) + got.shape[1:], dtype=got.dtype)
        out[self._perm] = got
        return out

    def places(self) -> np.ndarray:
        """Each particle of this rank's file block: its place in the order."""
        rank = self.comm.Get_rank()
        return self.to_directories(self.starts[rank] + np.arange(self.n_local, dtype=np.int64))

    def gather(self, local, dtype=np.float64):
        """The (N,) array of every rank's block gathered on rank 0 in the file's order (None
        elsewhere)."""
        return gather_blocks(self.comm, self.to_directories(np.asarray(local, dtype=dtype)),
                             self.starts)

    def scatter(self, whole, dtype=np.float64) -> np.ndarray:
        """This rank's block (in the order) of an (N,) array given on rank 0 in the file's
        order."""
        return self.from_directories(scatter_blocks(self.comm, whole, self.starts, dtype))
