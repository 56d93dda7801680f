"""The packing file read on MPI ranks, each rank its block of the particles (the PETSc backend).

:func:`read_packing_on_ranks` makes every check of ``read_packing(path, contacts=False)``
(thermal_kernel/packing.py) and reports the same first fault, the same one-line
:class:`PackingError` raised on every rank, but no rank holds an array of every particle: rank r
reads and checks the file's particles ``starts[r]:starts[r + 1]`` (``block_starts``, the
directories of thermal_kernel/solvers/partition.py). What is small is read on every rank: the
root's attributes, the walls, the wall contacts (every row: a surface's worth of spheres, five
numbers a row) and the domain.

How the first fault stays the whole reader's: the checks run in the whole reader's order, a
stage at a time, and after each stage the ranks agree (:func:`_agree`): the fault reported is
the lowest failing rank's first. The blocks are consecutive runs of the file, so the lowest rank
failing holds the lowest index failing. Checks across the whole packing become reductions (the
centres' largest |x|, a max: bit for bit) or exchanges: a wall row's sphere is fetched from its
directory (rank r checks the r-th block of the wall rows), and coincident centres meet on the
rank their bits hash to.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import packing as pk
from .checkpoint import packing_sha256
from .packing import Packing, PackingError
from .solvers.partition import agree, alltoallv, block_starts, exchange_counts, fetch


@dataclass
class PackingOnRanks:
    """One rank's part of a packing file, from :func:`read_packing_on_ranks`.

    ``head``: a :class:`Packing` with everything ``read_packing(path, contacts=False)`` gives
    but the particles' arrays: position (0, 3), radius (0,), phase (0,) int32 and yade_id None
    (so ``head.n_particles`` is 0: use ``n_particles`` here); no contact rows, ``file_contacts``
    their number; the walls, every wall contact, the domain, the attributes and the path.
    ``block``: this rank's particles ``starts[rank]:starts[rank + 1]`` of the file (position
    (k, 3), radius (k,) in the file's float dtype -- float64 as every generator writes, the
    whole reader's arrays' -- and phase (k,) int32). ``scales``:
    :func:`thermal_kernel.packing.contact_check_scales` of every centre. ``sha256``:
    :func:`thermal_kernel.checkpoint.packing_sha256` of the whole read, the same on every rank.
    """
    head: Packing
    n_particles: int
    starts: np.ndarray
    block: dict
    scales: tuple
    sha256: str


def _agree(comm, check):
    """``check()`` on every rank, every rank raising the lowest failing rank's error: a
    PackingError with its message (:func:`~.solvers.partition.agree`)."""
    return agree(comm, check, same=(PackingError,))


def _rows_in_file(f, name) -> int:
    """The length of the dataset ``name``'s first axis (0: none, a group or a scalar: its
    checks refuse it before the length matters)."""
    obj = f.get(name)
    return int(obj.shape[0]) if getattr(obj, "ndim", 0) else 0


def _read_block(comm, f, path, rows, n) -> dict:
    """particles/ as _read_particles checks them, this rank's ``rows`` read: a dataset at a
    time, the ranks agreeing after each (a NaN in a later rank's centres comes before one in
    an earlier rank's radii, as in the whole reader)."""
    def dataset(name, kind, shape):
        obj = f.get(name)
        # a scalar dataset cannot be sliced: read whole (one value), then its shape refused
        read = rows if getattr(obj, "ndim", 1) >= 1 else None
        return _agree(comm, lambda: pk._dataset(f, path, name, kind, shape,
                                                optional=name.endswith("yade_id"), rows=read))
    block = {"position": dataset("particles/position", "f", (None, 3))}
    block["radius"] = dataset("particles/radius", "f", (n,))
    block["phase"] = dataset("particles/phase", "i", (n,))
    dataset("particles/yade_id", "i", (n,))     # checked; hashed from the file, not kept
    return block


def _sum_in_rank_order(comm, value) -> float:
    """``value`` summed over the ranks in rank order: the same float on every rank."""
    total = 0.0
    for part in comm.allgather(float(value)):
        total += part
    return total


def _bucket(position, size) -> np.ndarray:
    """The rank each centre meets its equals on: a hash of its three coordinates' bits, -0.0
    made 0.0 first (equal under ==, as the whole reader compares them; NaN was refused)."""
    bits = np.ascontiguousarray(np.asarray(position, np.float64) + 0.0).view(np.uint64)
    key = np.zeros(position.shape[0], np.uint64)
    with np.errstate(over="ignore"):
        for k in range(3):
            key = (key ^ bits[:, k]) * np.uint64(0x100000001B3)      # FNV-1a-like mixing
            key ^= key >> np.uint64(29)
    return (key % np.uint64(size)).astype(np.int64)


def _first_coincident(comm, position, first):
    """The whole reader's coincident centres among every rank's block (``first``: this
    block's first index): (centre, a, b) -- the lexicographically smallest centre two
    particles share, its two lowest indices a < b and a's coordinates -- or None."""
    size = comm.Get_size()
    index = first + np.arange(position.shape[0], dtype=np.int64)
    if size > 1:
        dest = _bucket(position, size)
        by_rank = np.argsort(dest, kind="stable")
        send_n, recv_n = exchange_counts(comm, dest, size)
        position = alltoallv(comm, position[by_rank], send_n, recv_n)
        index = alltoallv(comm, index[by_rank], send_n, recv_n)
    found = None
    if position.shape[0] > 1:
        # sorted by x, y, z then index: the first equal neighbours are the smallest centre's
        # two lowest indices (the whole reader's lexsort, ties in index order)
        order = np.lexsort((index, position[:, 2], position[:, 1], position[:, 0]))
        equal = np.all(position[order[1:]] == position[order[:-1]], axis=1)
        same = np.flatnonzero(equal)
        if same.size:
            a, b = int(index[order[same[0]]]), int(index[order[same[0] + 1]])
            found = (tuple(float(v) for v in position[order[same[0]]]), a, b,
                     position[order[same[0]]].copy())
    candidates = [c for c in comm.allgather(found) if c is not None]
    # one group per bucket: centres on different ranks differ
    return min(candidates, key=lambda c: c[0]) if candidates else None


def _sha256_on_rank0(comm, head) -> str:
    """packing_sha256 of the whole read: rank 0 streams the particles' and contacts' datasets
    from the file a block of rows at a time, then every rank gets it."""
    digest = _agree(comm, lambda: packing_sha256(head, particles_in_file=True)
                    if comm.Get_rank() == 0 else None)
    return comm.bcast(digest, root=0)


def read_packing_on_ranks(path, comm) -> PackingOnRanks:
    """``read_packing(path, contacts=False)`` on the ranks of ``comm`` (collective): each rank
    reads and checks its block of the particles, every check is made and the first fault is
    the whole reader's, raised as the same PackingError on every rank."""
    from mpi4py import MPI

    rank, size = comm.Get_rank(), comm.Get_size()
    f, path = _agree(comm, lambda: pk._open(path))
    with f:
        attrs = _agree(comm, lambda: pk._read_attrs(f, path))
        n = _rows_in_file(f, "particles/position")
        starts = block_starts(n, size)
        first = int(starts[rank])
        block = _read_block(comm, f, path, slice(first, int(starts[rank + 1])), n)
        if n == 0:      # every rank alike
            raise PackingError(f"{path}: particles/position: expected at least one particle")
        _agree(comm, lambda: pk._check_radius(path, block["radius"], first))

        def small_groups():
            contacts = pk._read_contacts(f, path, n, False)
            walls = pk._read_walls(f, path)
            wall_rows = pk._read_wall_contacts(f, path, n, len(walls[0]))
            return contacts, walls, wall_rows, pk._read_domain(f, path)
        contacts, walls, wall_rows, dom = _agree(comm, small_groups)
    pair, overlap, normal_force, branch, contact_radius, m = contacts
    wall_name, wall_kind, wall_point, wall_normal, wall_radius = walls
    wall_particle, wall_index, wall_overlap, wall_normal_force, wall_contact_radius = wall_rows
    lo, hi = dom["lo"], dom["hi"]
    position, radius = block["position"], block["radius"]
    block["phase"] = block["phase"].astype(np.int32)

    # the whole packing's scales: max |x| over every centre, a max (bit for bit)
    top = comm.allreduce(pk.abs_max(position), op=MPI.MAX)
    scale = top + np.abs(lo).max() + np.abs(hi).max()          # _check_geometry's
    scales = (top + float(np.abs(lo).max()) + float(np.abs(hi).max()), top)
    # this rank's slice of the wall rows, with their spheres fetched from the directories
    wall_starts = block_starts(wall_particle.size, size)
    w0 = int(wall_starts[rank])
    mine = slice(w0, int(wall_starts[rank + 1]))
    wanted, back = np.unique(np.asarray(wall_particle[mine], dtype=np.int64),
                             return_inverse=True)
    r_w, x_w = (a[back] for a in fetch(comm, wanted, starts, [radius, position]))

    # _check_geometry: phases, centres, wall depths (no contact rows)
    _agree(comm, lambda: pk._check_phase(path, block["phase"], first))
    _agree(comm, lambda: pk._check_centres(path, position, lo, hi, scale, first))
    _agree(comm, lambda: pk._check_wall_depth(path, wall_particle[mine], wall_overlap[mine],
                                              r_w, scale, w0))
    # _check_forces_and_walls: each wall's rows in turn (its lowest row first), gap forces
    # (every rank holds the rows), coincident centres
    eps = 8 * np.finfo(float).eps * top
    for w, kind in enumerate(wall_kind):
        at = np.flatnonzero(wall_index[mine] == w)

        def check_wall(w=w, kind=kind, at=at):
            if at.size:
                pk._check_wall_overlap(path, w, kind, wall_point[w], wall_normal[w],
                                       wall_radius[w], w0 + at, wall_particle[mine][at],
                                       r_w[at], x_w[at], wall_overlap[mine][at], eps)
        _agree(comm, check_wall)
    if wall_particle.size:
        pk._check_wall_gap_force(path, wall_particle, wall_overlap, wall_normal_force)
    coincident = _first_coincident(comm, position, first)
    if coincident is not None:
        _, a, b, centre = coincident
        pk._fail_coincident(path, a, b, centre)
    # _check_solid_fraction: the spheres' volume and the caps beyond the walls, summed
    volume = pk.domain_volume(wall_kind, wall_normal, wall_radius, lo, hi)
    whole = _sum_in_rank_order(comm, np.sum(4.0 / 3.0 * math.pi * radius ** 3))
    h = np.clip(wall_overlap[mine], 0.0, None)
    caps = _sum_in_rank_order(comm, np.sum(math.pi * h ** 2 * (3.0 * r_w - h) / 3.0))
    bounds = None if volume is None or not volume > 0 else \
        ((whole - caps) / volume, whole / volume)
    pk._check_solid_fraction_bounds(path, attrs["solid_fraction"], bounds, wall_kind)

    head = Packing(position=np.zeros((0, 3)), radius=np.zeros(0), phase=np.zeros(0, np.int32),
                   pair=pair.astype(np.int64), overlap=overlap, normal_force=normal_force,
                   branch=branch, wall_name=wall_name, wall_kind=wall_kind,
                   wall_point=wall_point, wall_normal=wall_normal, wall_radius=wall_radius,
                   wall_particle=wall_particle.astype(np.int64),
                   wall_index=wall_index.astype(np.int32), wall_overlap=wall_overlap,
                   wall_normal_force=wall_normal_force, domain_lo=lo, domain_hi=hi,
                   periodic=dom["periodic"], attrs=attrs, contact_radius=contact_radius,
                   wall_contact_radius=wall_contact_radius, yade_id=None, path=path,
                   file_contacts=m)
    return PackingOnRanks(head=head, n_particles=n, starts=starts, block=block, scales=scales,
                          sha256=_sha256_on_rank0(comm, head))

