"""Each MPI rank reads and builds its own rows of the network (issue 25; docs/scaling.md).

The PETSc backend's build (:mod:`thermal_kernel.mpi_run`): no rank reads the whole contact list
or evaluates the law on every contact. Collective over an mpi4py communicator:

1. every rank reads the packing without its contacts (``read_packing(path, contacts=False)``:
   the particles, walls, wall contacts, domain; checked as always) and orders the particles
   along the Morton curve (:mod:`.solvers.partition`): rank r owns a block of that order;
2. rank r reads the r-th slice of the file's contact rows (``read_contact_rows``, the reader's
   row checks on them), adds its rows' neighbour counts to everyone's (one Allreduce: the law's
   n_i, n_j are whole-packing counts) and sends each contact to the rank(s) owning its two
   particles (one all-to-all): a rank then holds the contacts touching its particles, in the
   file's order (duplicates found there: both copies reach the owner of i);
3. each rank evaluates the scene's law on those contacts (:func:`~.problem.evaluate_law`, the
   one law registry) and builds its rows of A = L + diag(g) with the in-process arithmetic
   (the same sums in the same order: the rows equal the whole build's bit for bit,
   ``tests/test_petsc_backend.py``);
4. rank 0 runs the boundary kinds (:func:`~.problem.boundary_problem`, the one registry) on the
   packing without contacts -- what they need is per particle and per wall -- and sends every
   rank the boundary rows (held, exchange and power rows: boundary-sized);
5. the clusters: each rank labels the components of its own rows' contacts, rank 0 joins them
   through the cut contacts (the same numbering as in-process); the degrees, the counts for
   the explicit bounds and the rows of the held and untied particles go to rank 0, which makes
   the in-process :class:`~.network.Network` from them (:func:`~.network.network_of`) without
   the other rows (``adjacency_rows``): what its ledger, steady's floating clusters, the checks
   and the output read.

What stays whole: per particle, on every rank, the centres, radii, phases, the Morton order and
the law's particle inputs (~100 B per particle per rank: docs/scaling.md); on rank 0 the
network's per-particle arrays and the boundary rows. A scene with a ``[neighbours]`` criterion
(a gap chosen over every bulk contact) is still built whole on rank 0 (mpi_run).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .network import cluster_report, network_of, particle_terms, validate
from .packing import PackingError, _check_pairs, read_contact_rows, read_packing
from .problem import boundary_problem, evaluate_law
from .solvers.partition import block_starts, owner_of_particle, particle_order

_CONTACT_FIELDS = ("overlap", "normal_force", "branch", "contact_radius")
# the boundary rows rank 0 sends every rank (validate()'s names)
_ROW_KEYS = ("fixed_particle", "fixed_temperature", "fixed_boundary", "exchange_particle",
             "exchange_g", "exchange_t", "exchange_boundary", "power_particle", "power")


class RankError(RuntimeError):
    """Another rank's part of the build failed: its one-line message (each rank raises)."""


@dataclasses.dataclass
class RankBuild:
    """One rank's result: ``share`` and ``meta`` for
    :class:`~.solvers.petsc_backend.DistributedNetwork` (``built=``); on rank 0 the packing
    without contacts, the Network (without the other ranks' rows), the problem's info and the
    Morton order; None on the others."""
    share: dict
    meta: dict
    order: np.ndarray | None
    particles: object = None
    net: object = None
    info: dict | None = None


def agree(comm, fn):
    """``fn()`` on every rank; if it raised on any, every rank raises: the rank's own error, or
    :class:`RankError` with the message of the lowest rank that failed (no rank waits in a
    collective for one that left)."""
    value, error = None, None
    try:
        value = fn()
    except Exception as e:              # noqa: BLE001 (re-raised below, on every rank)
        error = e
    messages = comm.allgather(None if error is None else (str(error) or type(error).__name__))
    if error is not None:
        raise error
    failed = [m for m in messages if m is not None]
    if failed:
        raise RankError(failed[0])
    return value


def _slice(total: int, rank: int, size: int) -> tuple[int, int]:
    starts = block_starts(total, size)
    return int(starts[rank]), int(starts[rank + 1])


def _exchange_contacts(comm, part, owner, rank, size):
    """Every contact of ``part`` (a packing holding some of the file's rows) sent to the ranks
    owning its particles (one Alltoallv a field, numpy buffers: no pickled copies; ``part``'s
    contact fields are freed as they go); the contacts this rank receives, in the file's
    order."""
    pair = part.pair
    oi, oj = owner[pair[:, 0]], owner[pair[:, 1]]
    rows = np.concatenate([np.arange(pair.shape[0]), np.flatnonzero(oj != oi)])
    dest = np.concatenate([oi, oj[oj != oi]])
    del oi, oj
    by = np.argsort(dest, kind="stable")
    rows = rows[by]
    send_n = np.bincount(dest, minlength=size).astype(np.int64)
    del dest, by
    recv_n = np.empty(size, dtype=np.int64)
    comm.Alltoall(send_n, recv_n)
    total = int(recv_n.sum())
    fields = {"contact_row": part.contact_row, "pair": pair,
              **{f: getattr(part, f) for f in _CONTACT_FIELDS}}
    got = {}
    del pair
    for name in list(fields):
        a = fields.pop(name)
        setattr(part, name, None)           # the slice's field is freed once it is sent
        if a is None:
            got[name] = None
            continue
        width = int(np.prod(a.shape[1:], dtype=np.int64))
        send = np.ascontiguousarray(a[rows])
        del a
        recv = np.empty((total,) + send.shape[1:], dtype=send.dtype)
        comm.Alltoallv([send, (send_n * width, _displs(send_n) * width)],
                       [recv, (recv_n * width, _displs(recv_n) * width)])
        got[name] = recv
        del send
    order = np.argsort(got["contact_row"], kind="stable")
    for name in got:                    # one field at a time: one extra copy at most
        if got[name] is not None:
            got[name] = got[name][order]
    return got


def _displs(counts):
    return np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)


def build_on_ranks(scene, packing_path, comm) -> RankBuild:
    """The build above; collective. Errors (a bad packing, a law's value out of range, a bad
    boundary) are raised on every rank (:func:`agree`)."""
    rank, size = comm.Get_rank(), comm.Get_size()
    particles = agree(comm, lambda: read_packing(packing_path, contacts=False))
    n, m = particles.n_particles, int(particles.file_contacts)
    order = particle_order(particles.position, "morton")
    starts = block_starts(n, size)
    owner = owner_of_particle(order, starts)
    lo, hi = int(starts[rank]), int(starts[rank + 1])
    mine = order[lo:hi]

    # 2. this rank's slice of the file's contacts; the neighbour counts; the owners' contacts
    part = agree(comm, lambda: read_contact_rows(particles, *_slice(m, rank, size)))
    counts = np.bincount(part.pair.reshape(-1), minlength=n).astype(np.int64)
    comm.Allreduce(_in_place(), counts)
    got = _exchange_contacts(comm, part, owner, rank, size)
    del part
    held_contacts = dataclasses.replace(particles, **got)
    del got
    agree(comm, lambda: _check_pairs(particles.path, held_contacts.pair, n,
                                     row=held_contacts.contact_row))

    # 3. the law on this rank's contacts, its rows of the network
    law, params, pinput, conductance, capacity = agree(
        comm, lambda: evaluate_law(scene, held_contacts, None, counts))
    pair = held_contacts.pair
    held_contacts = None
    active = conductance > 0
    i, j, h = pair[active, 0], pair[active, 1], conductance[active]
    local_of = np.full(n, -1, dtype=np.int64)
    local_of[mine] = np.arange(hi - lo)
    li, lj = local_of[i], local_of[j]
    # the adjacency's rows of this rank's particles (columns the packing's indices), built as
    # network.assemble builds the whole one: the same entries, sorted, the same row sums
    rows = np.concatenate([li[li >= 0], lj[lj >= 0]])
    cols = np.concatenate([j[li >= 0], i[lj >= 0]])
    vals = np.concatenate([h[li >= 0], h[lj >= 0]])
    idx = np.int32 if n < 2 ** 31 - 1 else np.int64
    adjacency = sp.coo_matrix((vals, (rows.astype(idx), cols.astype(idx))),
                              shape=(hi - lo, n)).tocsr()
    del rows, cols, vals
    adjacency.sum_duplicates()
    adjacency.sort_indices()
    degree = np.bincount(np.repeat(np.arange(hi - lo), np.diff(adjacency.indptr)),
                         weights=adjacency.data, minlength=hi - lo).astype(np.float64)
    # each conducting contact counted once, by the owner of its first particle
    first = li >= 0
    n_active = comm.allreduce(int(np.count_nonzero(first)))
    h_sum = comm.allreduce(float(h[first].sum()))
    coord_max = comm.allreduce(int(np.diff(adjacency.indptr).max(initial=0)), op=_max())
    cut = comm.allreduce(int(np.count_nonzero(first & (lj < 0))))
    del pair, conductance, active, i, j, h, li, lj, first

    # 4. the boundary kinds on rank 0; their rows to every rank
    built = {}

    def boundaries():
        problem, info = boundary_problem(scene, particles, law, params, pinput, capacity,
                                         np.zeros(0))
        v = validate(problem)
        built.update(problem=problem, info=info, v=v)
        return {key: v[key] for key in _ROW_KEYS}

    row_data = agree(comm, lambda: boundaries() if rank == 0 else None)
    row_data = comm.bcast(row_data, root=0)
    meta_rows = comm.bcast((len(scene.boundaries), built["problem"].source is not None)
                           if rank == 0 else None, root=0)
    terms = particle_terms({"n": n, **row_data})
    held_boundary = np.full(n, -1, np.int32)
    held_boundary[row_data["fixed_particle"]] = row_data["fixed_boundary"]

    # 5. clusters: components of this rank's own contacts, joined on rank 0 by the cut ones
    own_cols = local_of[adjacency.indices]
    inner = own_cols >= 0
    arow = np.repeat(np.arange(hi - lo), np.diff(adjacency.indptr))
    n_comp, lab = connected_components(
        sp.csr_matrix((np.ones(int(inner.sum())), (arow[inner], own_cols[inner])),
                      shape=(hi - lo, hi - lo)), directed=False)
    offset = comm.exscan(int(n_comp)) or 0
    gid = lab.astype(np.int64) + offset
    cut_edges = np.stack([gid[arow[~inner]], adjacency.indices[~inner].astype(np.int64)], axis=1)
    del own_cols, inner, arow
    gid_all = _gather_whole(comm, gid, order, starts, np.int64)
    degree_all = _gather_whole(comm, degree, order, starts, np.float64)
    cut_all = comm.gather(cut_edges, root=0)
    total_comp = comm.allreduce(int(n_comp))
    clusters = None
    if rank == 0:
        edges = np.concatenate(cut_all)
        graph = sp.coo_matrix((np.ones(edges.shape[0]), (edges[:, 0], gid_all[edges[:, 1]])),
                              shape=(total_comp, total_comp))
        _, joined = connected_components(graph, directed=False)
        label_raw = joined[gid_all]
        # number the components by their first particle, as connected_components does whole
        k = int(label_raw.max()) + 1
        first_p = np.full(k, n, dtype=np.int64)
        np.minimum.at(first_p, label_raw, np.arange(n))
        renumber = np.empty(k, dtype=np.int64)
        renumber[np.argsort(first_p, kind="stable")] = np.arange(k)
        label = renumber[label_raw].astype(np.int32)
        clusters = cluster_report(k, label, terms["held"] | (terms["g_p"] > 0))
        keep_rows = np.flatnonzero(terms["held"] | ~clusters.tied_particle)
        tied = clusters.tied_particle
    else:
        keep_rows, tied = None, None
    del cut_all, gid_all

    # rank 0 keeps the rows of the held and untied particles (its ledger, floating clusters)
    keep_rows = comm.bcast(keep_rows, root=0)
    want = np.flatnonzero(np.isin(mine, keep_rows))
    sub = adjacency[want].tocoo()
    pieces = comm.gather((mine[want][sub.row], sub.col.astype(np.int64), sub.data), root=0)
    del sub
    tied_mine = _scatter_whole(comm, tied, order, starts, lo, hi)

    # the share of this rank, as petsc_backend._share cuts it from a whole network
    from .solvers.petsc_backend import share_rows
    share = share_rows(
        adjacency, degree, mine, lo, np.argsort(order).astype(np.int64), n,
        capacity=capacity, held=terms["held"], held_t=terms["held_t"], g=terms["g_p"],
        b=terms["gt_p"] + terms["pw_p"], tied=_whole_from_mine(tied_mine, mine, n),
        fixed_particle=row_data["fixed_particle"], fixed_boundary=row_data["fixed_boundary"],
        exchange_particle=row_data["exchange_particle"], exchange_row_g=row_data["exchange_g"],
        exchange_row_t=row_data["exchange_t"], exchange_boundary=row_data["exchange_boundary"],
        held_boundary=held_boundary)
    del adjacency
    meta = dict(n=n, starts=starts, nb=meta_rows[0], has_source=meta_rows[1], cut=cut,
                active_contacts=n_active)
    if rank != 0:
        return RankBuild(share=share, meta=meta, order=None)

    rp = np.concatenate([p[0] for p in pieces])
    rc = np.concatenate([p[1] for p in pieces])
    rd = np.concatenate([p[2] for p in pieces])
    idx = np.int32 if n < 2 ** 31 - 1 else np.int64
    root_adj = sp.coo_matrix((rd, (rp.astype(idx), rc.astype(idx))), shape=(n, n)).tocsr()
    root_adj.sum_duplicates()
    root_adj.sort_indices()
    v = dict(built["v"], m=m)       # the file's contacts (the problem holds none of them)
    net = network_of(built["problem"], v, terms, root_adj, degree_all, n_active, clusters,
                     coord_max, h_sum / n_active if n_active else math.nan,
                     adjacency_rows=keep_rows)
    return RankBuild(share=share, meta=meta, order=order, particles=particles, net=net,
                     info=built["info"])


def _in_place():
    from mpi4py import MPI
    return MPI.IN_PLACE


def _max():
    from mpi4py import MPI
    return MPI.MAX


def _gather_whole(comm, local, order, starts, dtype):
    """This rank's values (its block of the order) gathered on rank 0 in the packing's order."""
    counts = np.diff(starts)
    local = np.ascontiguousarray(local, dtype=dtype)
    if comm.Get_rank() != 0:
        comm.Gatherv(local, None, root=0)
        return None
    buf = np.empty(int(starts[-1]), dtype=dtype)
    comm.Gatherv(local, (buf, counts), root=0)
    out = np.empty_like(buf)
    out[order] = buf
    return out


def _scatter_whole(comm, whole, order, starts, lo, hi):
    """This rank's block of a (N,) bool array given on rank 0 in the packing's order."""
    out = np.empty(hi - lo, dtype=np.uint8)
    send = None
    if comm.Get_rank() == 0:
        send = (np.ascontiguousarray(np.asarray(whole)[order], dtype=np.uint8), np.diff(starts))
    comm.Scatterv(send, out, root=0)
    return out.astype(bool)


def _whole_from_mine(values, mine, n):
    out = np.zeros(n, dtype=values.dtype)
    out[mine] = values
    return out


__all__ = ["RankBuild", "RankError", "agree", "build_on_ranks", "PackingError"]
