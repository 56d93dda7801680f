"""Each MPI rank reads and builds its own rows of the network (issue 25; docs/scaling.md).

The PETSc backend's build (:mod:`thermal_kernel.mpi_run`): no rank reads the whole packing,
evaluates the law on every contact or every particle, or runs the boundary kinds on every
particle. Collective over an mpi4py communicator:

1. rank r reads the r-th block of the file's particles (it is their *directory*), checked as
   the whole reader checks them, with the same first fault
   (:func:`~.packing_ranks.read_packing_on_ranks`; the walls and wall contacts, a surface's
   worth, on every rank); the ranks sort the Morton order together
   (:func:`~.solvers.partition.morton_blocks_on_ranks`, the whole sort's order bit for bit)
   and rank r owns the r-th block of it; values go between the owners and the directories by
   :class:`~.solvers.partition.Routes`: no rank holds the order;
2. rank r reads the r-th slice of the file's contact rows (``read_contact_rows``), fetches
   their spheres from the directories and checks the rows against them
   (``check_contact_rows``, the reader's checks); a scene's ``[neighbours]`` criterion is
   chosen over every rank's rows with collectives
   (:func:`~.neighbours.choose_neighbours_on_ranks`: the bulk flags found by the
   directories, the mean radius summed over the ranks; the gap giving the target bulk Z
   found by a bisection over the ratios' bits, the ranks' summed weights gathered a step: the
   whole build's gap, bit for bit) and each row marked kept or not; the neighbour counts (of
   the kept rows) are summed at the directories and fetched back; each contact goes, with its
   two spheres' values, to the rank(s) owning its particles (one Alltoallv a field): a rank
   then holds the contacts touching its particles, in the file's order (duplicates found
   there: both copies reach the owner of i);
3. each rank fetches its own particles from their directories and evaluates the law's
   capacities on them (:func:`_owner_block`; a refusal counted over every rank, naming the
   lowest particle, as the whole build's), then the law on its contacts
   (:func:`~.problem.evaluate_law`, the one law registry, on a packing of the contacts'
   spheres; H = 0 on the rows not kept) and builds its rows of A = L + diag(g) with the
   in-process arithmetic (the same sums in the same order: the rows equal the whole build's
   bit for bit, ``tests/mpi_rank_build_check.py``);
4. each rank runs the boundary kinds (:func:`~.problem.boundary_problem`, the one registry) on
   its own particles, sorted by packing index, seeing the whole packing through
   :class:`RanksWhole` (a count, a flag, a sum in packing order, the phases present, reduced
   over the ranks): its rows of the problem, the whole problem's restricted to it, bit for
   bit; a source is built over its block and evaluated there every step. What rank 0's
   summary needs of the per-particle arrays is reduced over the ranks
   (:func:`_summary_on_ranks`: the constant powers, the steady reference, the maximum
   principle's inputs, the mean capacity);
5. the clusters (:func:`_clusters_on_ranks`): each rank labels the components of its own rows'
   contacts, rank 0 joins them through the cut contacts (the same numbering as in-process)
   and sends back each component's label and tied flag; the untied particles' rows come to
   rank 0 (:func:`_untied_rows`), the explicit bound is each rank's over its rows, the least
   on rank 0 (:func:`_explicit_bound`), and rank 0 makes its
   :class:`~.network.NetworkSummary` (:func:`_root_summary`: network.summary_of's of the whole
   network, bit for bit but the sums the ranks add from partial sums, to 1e-14).

What rank 0 holds beyond its block: arrays of the components (one per cluster and rattler:
the joining) and of the untied particles; during the run, the start and the temperatures it
gathers at an output time (they go, one time at a time, into the run's history, paged to disk
when large: :func:`~.atomic.history_rows`). ``mpi_run --whole-build`` builds the network whole
on rank 0 instead (for comparison).
"""
from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .boundaries.base import Whole
from .neighbours import choose_neighbours_on_ranks, dump_gap_tolerance_of, face_distance
from .network import (ClusterCounts, NetworkSummary, ProblemSummary, UntiedParticles,
                      constant_flows, explicit_ratios, network_flags, particle_terms,
                      principle_of, untied_components, validate)
from .packing import (CONTACT_BLOCK_ROWS, Packing, PackingError, _check_pairs,
                      check_contact_rows, read_contact_rows)
from .packing_ranks import read_packing_on_ranks
from .problem import bad_capacity, boundary_problem, capacity_refusal, evaluate_law
from .scene import SceneError
from .solvers.partition import (RankError, Routes, agree, alltoallv, block_starts,
                                 exchange_counts, fetch, morton_blocks_on_ranks)

@dataclasses.dataclass
class RankBuild:
    """One rank's result: ``share`` and ``meta`` for
    :class:`~.solvers.petsc_backend.DistributedNetwork` (``built=``), this rank's block of the
    Morton order (``mine``, packing indices) and the routes between the blocks and the file's
    order; on rank 0 the packing's path and size, the network's
    :class:`~.network.NetworkSummary` and the problem's info; None on the others."""
    share: dict
    meta: dict
    mine: np.ndarray
    routes: Routes
    particles: object = None
    net: object = None
    info: dict | None = None
    packing_sha256: str = ""
    local_source: object = None     # the source over this rank's block (its places), or None


def _max():
    from mpi4py import MPI
    return MPI.MAX


def _sum_at_directories(comm, ids, values, fblock):
    """``values`` of the particles ``ids`` (sorted, unique) added up at their directories: the
    sums over every rank, this rank's file block (int64)."""
    rank, size = comm.Get_rank(), comm.Get_size()
    dest = np.searchsorted(fblock, ids, side="right") - 1
    send_n, recv_n = exchange_counts(comm, dest, size)
    got = alltoallv(comm, np.asarray(ids, dtype=np.int64), send_n, recv_n) - fblock[rank]
    vals = alltoallv(comm, np.asarray(values, dtype=np.int64), send_n, recv_n)
    return np.bincount(got, weights=vals, minlength=int(fblock[rank + 1] - fblock[rank])
                       ).astype(np.int64)


def _exchange_contacts(comm, fields: dict, oi, oj, size):
    """Every contact (the rows of ``fields``' arrays) sent to the ranks owning its two
    particles (``oi``, ``oj``; one Alltoallv a field, each field freed once sent); the contacts
    this rank receives, in the file's order (``fields["contact_row"]``)."""
    rows = np.concatenate([np.arange(oi.size), np.flatnonzero(oj != oi)])
    dest = np.concatenate([oi, oj[oj != oi]])
    rows = rows[np.argsort(dest, kind="stable")]
    send_n, recv_n = exchange_counts(comm, dest, size)
    del dest
    got = {}
    for name in list(fields):
        a = fields.pop(name)
        got[name] = None if a is None else alltoallv(comm, a[rows], send_n, recv_n)
        del a
    order = np.argsort(got["contact_row"], kind="stable")
    for name in got:                    # one field at a time: one extra copy at most
        if got[name] is not None:
            got[name] = got[name][order]
    return got


def build_on_ranks(scene, packing_path, comm, *, conductance_factor=None) -> RankBuild:
    """The build above; collective. Errors (a bad packing, a law's value out of range, a bad
    boundary) are raised on every rank (:func:`agree`). ``conductance_factor``: a .npy file of
    one factor per dumped contact row multiplying the law's conductances (each rank reads its
    contacts' rows; written by ``thermal_kernel.run.run_in_memory``). Each step is a function
    below; what a step leaves behind is dropped here as soon as the next has used it (the
    memory per rank: docs/scaling.md)."""
    rank, size = comm.Get_rank(), comm.Get_size()

    # 1. each rank reads its block of the file's particles (it is their directory), checked
    # as the whole reader checks them; the Morton order sorted on the ranks, its block of it
    pk = read_packing_on_ranks(packing_path, comm)
    head = dict(n=pk.n_particles, m=int(pk.head.file_contacts), path=pk.head.path,
                attrs=pk.head.attrs, lo=pk.head.domain_lo, hi=pk.head.domain_hi,
                periodic=pk.head.periodic, scales=pk.scales)
    n, m = head["n"], head["m"]
    starts = block_starts(n, size)          # the ranks' blocks of the Morton order
    fblock = np.asarray(pk.starts)          # the directories' blocks of the file's particles
    lo, hi = int(starts[rank]), int(starts[rank + 1])
    fb = pk.block
    mine = morton_blocks_on_ranks(comm, fb["position"], starts)
    routes = Routes(comm, mine, starts)     # owners <-> directories
    own_new = routes.places()               # the file block's places in the order
    n_bulk, own_bulk = _bulk_flags(comm, scene.neighbours, pk.head, fb, n)

    # 2. this rank's slice of the contact rows, checked, chosen, sent to their particles' owners
    got, nb_block, choice = _contacts_to_owners(scene, comm, head, starts, fblock, fb, own_new,
                                                n_bulk, own_bulk)
    del own_bulk

    # 3. this rank's particles from their directories, the law's capacities on them (checked
    # over every rank); then the law on each rank's contacts and this rank's rows of A
    blk = _owner_block(scene, comm, pk.head, fb, nb_block, mine, fblock)
    del fb["position"]
    directory = dict(radius=fb["radius"], phase=fb["phase"], nb=nb_block, new=own_new)
    del fb, nb_block, own_new
    ids, new_l, active = _conducting_contacts(scene, comm, head, got, directory, fblock,
                                              conductance_factor)
    del got, directory
    adjacency, columns, degree, totals = _rank_rows(comm, active, ids, new_l, lo, hi, n)
    del active, ids, new_l

    # 4. the boundary kinds (the one registry) on this rank's particles, the whole packing's
    # counts and sums by reductions: its per-particle and boundary rows
    own, problem, info, parts = _owner_problem(scene, comm, blk, choice, n)
    local_source = (None if problem.source is None
                    else problem.source.restricted(_sorted_place(blk.by)))
    del problem, blk

    # 5. clusters: components of this rank's own contacts, joined on rank 0 by the cut ones;
    # the tied flags and the untied particles' labels back at their owners
    label, own["tied"], counts = _clusters_on_ranks(comm, adjacency, columns, lo, hi, mine,
                                                    own["held"] | (own["g"] > 0), starts)
    from .solvers.petsc_backend import share_block
    own.update(share_block(adjacency, degree, own["g"], lo, n, columns))
    del columns
    pieces = _untied_rows(comm, own, mine, adjacency, degree, label)
    del adjacency, label
    bound = _explicit_bound(comm, own, degree, mine)
    meta = dict(n=n, starts=starts, nb=len(scene.boundaries),
                has_source=local_source is not None, cut=totals["cut"],
                active_contacts=totals["n_active"],
                source_boundary=int(parts["problem"].source_boundary))
    if rank != 0:
        return RankBuild(share=own, meta=meta, mine=mine, routes=routes,
                         local_source=local_source)
    parts["clusters"] = counts
    net = _root_summary(parts, pieces, bound, n, m, totals)
    return RankBuild(share=own, meta=meta, mine=mine, routes=routes, particles=SimpleNamespace(
        path=head["path"], n_particles=n), net=net, info=info,
        packing_sha256=pk.sha256, local_source=local_source)


def _index_dtype(n):
    """scipy's index type for ``n`` columns (int32 while it holds them: half the bytes)."""
    return np.int32 if n < 2 ** 31 - 1 else np.int64


def _bulk_flags(comm, crit, head, fb, n):
    """Step 1, a [neighbours] criterion ``crit`` only: the bulk particles (their distance to
    every wall and cut face, neighbours.face_distance, against the mean diameter's margin,
    the mean radius summed over the ranks) of this directory's block ``fb``; returns their
    number (every rank) and this block's flags (uint8), or 0, None."""
    if crit is None:
        return 0, None
    margin = 2.0 * (comm.allreduce(float(fb["radius"].sum())) / n) * crit.bulk_margin_diameters
    bulk = face_distance(dataclasses.replace(head, position=fb["position"],
                                             radius=fb["radius"])) >= margin
    return comm.allreduce(int(bulk.sum())), bulk.astype(np.uint8)


def _contacts_to_owners(scene, comm, head, starts, fblock, fb, own_new, n_bulk, own_bulk):
    """Step 2: this rank's slice of the file's contact rows, checked against their spheres
    (fetched from the directories: ``fb`` this directory's particle rows, whose positions are
    dropped once checked; ``own_new`` their places in the order; ``own_bulk`` their bulk
    flags), the rows a [neighbours] criterion keeps, the neighbour counts summed at the
    directories, and every contact sent to the owners of its particles. Returns the contacts
    this rank holds (file order), this directory's neighbour counts and the [neighbours]
    choice (or None); a refusal of the criterion is raised after the pairs' check (the whole
    build's reader refuses a duplicate pair first)."""
    rank, size = comm.Get_rank(), comm.Get_size()
    path, n, m = head["path"], head["n"], head["m"]
    ms = block_starts(m, size)
    part = agree(comm, lambda: read_contact_rows(path, n, m, ms[rank], ms[rank + 1]))
    ends = np.unique(part["pair"])
    loc = np.searchsorted(ends, part["pair"])
    pos_e, rad_e, ph_e, new_e, *bulk_e = fetch(
        comm, ends, fblock, [fb["position"], fb["radius"], fb["phase"], own_new]
        + ([] if own_bulk is None else [own_bulk]))      # the bulk flags: [neighbours] only
    bulk_e = bulk_e[0] if bulk_e else None
    agree(comm, lambda: _check_slice(head, part, loc, pos_e, rad_e, int(ms[rank])))
    pos_e = None
    keep, choice, refused = _choose_rows(scene, comm, head, n_bulk, part, loc, rad_e, bulk_e)
    # the neighbour counts (every dumped row, or the rows kept), summed at the directories,
    # fetched back
    nb_block = _sum_at_directories(comm, ends, np.bincount(
        (loc if keep is None else loc[keep]).reshape(-1), minlength=ends.size), fblock)
    del keep
    owner_e = np.searchsorted(starts, new_e, side="right") - 1
    oi, oj = owner_e[loc[:, 0]], owner_e[loc[:, 1]]
    loc = rad_e = None
    del ends, ph_e, new_e, owner_e, bulk_e
    got = _exchange_contacts(comm, part, oi, oj, size)     # empties part, a field at a time
    part = None
    del oi, oj
    agree(comm, lambda: _check_pairs(path, got["pair"], n, row=got["contact_row"]))
    if refused is not None:
        raise refused
    return got, nb_block, choice


def _check_slice(head, part, loc, pos_e, rad_e, row0):
    """The reader's checks of this rank's contact rows ``part`` against their spheres (``loc``
    their places in ``pos_e`` and ``rad_e``), a block of rows at a time as the whole reader
    does (the same messages; ``row0`` the slice's first row in the file)."""
    for b0 in range(0, loc.shape[0], CONTACT_BLOCK_ROWS):
        sl = slice(b0, b0 + CONTACT_BLOCK_ROWS)
        li, lj = loc[sl, 0], loc[sl, 1]
        check_contact_rows(head["path"], part["pair"][sl], rad_e[li], rad_e[lj], pos_e[li],
                           pos_e[lj], part["overlap"][sl], part["normal_force"][sl],
                           part["branch"][sl], head["lo"], head["hi"], head["periodic"],
                           head["scales"], row0=row0 + b0)


def _choose_rows(scene, comm, head, n_bulk, part, loc, rad_e, bulk_e):
    """Step 2, a [neighbours] criterion: the choice made with collectives over every rank's
    rows (neighbours.choose_neighbours_on_ranks: the whole build's, bit for bit), each row of
    ``part`` marked kept or not (``part["keep"]``, which travels with its contact). Returns
    the rows kept (bool), the choice and its refusal (the same on every rank; raised later),
    or None, None, None without a criterion."""
    if scene.neighbours is None:
        return None, None, None
    choice = refused = None
    ratio = (np.linalg.norm(part["branch"], axis=1)
             / (rad_e[loc[:, 0]] + rad_e[loc[:, 1]]))
    weight = bulk_e[loc[:, 0]].astype(np.int64) + bulk_e[loc[:, 1]].astype(np.int64)
    try:
        choice = choose_neighbours_on_ranks(scene, comm, head["path"], dump_gap_tolerance_of(
            head["attrs"]), head["n"], head["m"], n_bulk, ratio, weight)
        keep = choice.keep
    except SceneError as e:
        refused, keep = e, np.zeros(ratio.size, dtype=bool)
    part["keep"] = keep.astype(np.uint8)    # travels with its contact
    return keep, choice, refused


def _conducting_contacts(scene, comm, head, got, directory, fblock, conductance_factor):
    """Step 3: the law on this rank's contacts ``got`` (the one law registry, on a packing of
    the contacts' spheres fetched from the directories; H = 0 on the rows not kept), times
    the conductance factors if any. ``got`` and ``directory`` (this directory's radius,
    phase, nb and new arrays) are emptied as they are used: their arrays freed before the
    rows are built. Returns the particles the contacts touch (packing indices, sorted), their
    places in the order, and the conducting contacts (i, j, H W/K, their places ni, nj)."""
    ids, inv = np.unique(got["pair"], return_inverse=True)
    table = dict(zip(("radius", "phase", "nb", "new"), fetch(
        comm, ids, fblock, [directory.pop(k) for k in ("radius", "phase", "nb", "new")])))
    spheres = Packing(position=np.zeros((ids.size, 3)), radius=table["radius"],
                      phase=table["phase"], pair=inv.reshape(-1, 2),
                      overlap=got["overlap"], normal_force=got["normal_force"],
                      branch=got["branch"], contact_radius=got["contact_radius"],
                      attrs=head["attrs"], path=head["path"], contact_row=got["contact_row"],
                      file_contacts=head["m"])
    kept = None if scene.neighbours is None else got.pop("keep").astype(bool)
    _, _, _, conductance, _ = agree(
        comm, lambda: evaluate_law(scene, spheres, kept, table["nb"]))
    if conductance_factor is not None:      # the in-process product, row by row
        conductance = conductance * np.load(conductance_factor,
                                            mmap_mode="r")[got["contact_row"]]
    kept = None
    pair = got["pair"]
    new_l = table["new"]
    newp = new_l[spheres.pair]          # each contact's two places in the order
    spheres = table = None
    got.clear()
    del inv
    active = conductance > 0
    i, j, h = pair[active, 0], pair[active, 1], conductance[active]
    ni, nj = newp[active, 0], newp[active, 1]
    return ids, new_l, (i, j, h, ni, nj)


def _rank_rows(comm, active, ids, new_l, lo, hi, n):
    """Step 3: the adjacency's rows of this rank's particles (the order's ``lo:hi``; columns
    the packing's indices), built as network.assemble builds the whole one: the same entries,
    sorted, the same row sums (bit for bit). ``active``: the conducting contacts (i, j, H W/K,
    ni, nj). Returns the rows (CSR), their columns' places in the order, the degrees (W/K)
    and the totals over the ranks (each conducting contact counted once, by the owner of its
    first particle): n_active, h_sum (W/K), coord_max, cut."""
    i, j, h, ni, nj = active
    mi, mj = (ni >= lo) & (ni < hi), (nj >= lo) & (nj < hi)
    rows = np.concatenate([ni[mi], nj[mj]]) - lo
    cols = np.concatenate([j[mi], i[mj]])
    vals = np.concatenate([h[mi], h[mj]])
    idx = _index_dtype(n)
    adjacency = sp.coo_matrix((vals, (rows.astype(idx), cols.astype(idx))),
                              shape=(hi - lo, n)).tocsr()
    del rows, cols, vals
    adjacency.sum_duplicates()
    adjacency.sort_indices()
    columns = new_l[np.searchsorted(ids, adjacency.indices)]     # their places in the order
    degree = np.bincount(np.repeat(np.arange(hi - lo), np.diff(adjacency.indptr)),
                         weights=adjacency.data, minlength=hi - lo).astype(np.float64)
    totals = dict(n_active=comm.allreduce(int(np.count_nonzero(mi))),
                  h_sum=comm.allreduce(float(h[mi].sum())),
                  coord_max=comm.allreduce(int(np.diff(adjacency.indptr).max(initial=0)),
                                           op=_max()),
                  cut=comm.allreduce(int(np.count_nonzero(mi & ~mj))))
    return adjacency, columns, degree, totals


def _local_components(comm, adjacency, columns, lo, hi, mine):
    """Step 4: the connected components of this rank's own contacts (both ends in ``lo:hi``),
    numbered after the lower ranks' (exscan). Returns each particle's component, the cut
    contacts as (component, other particle's place in the order), the number of components and
    each component's lowest packing index (``mine``: this rank's particles)."""
    inner = (columns >= lo) & (columns < hi)
    arow = np.repeat(np.arange(hi - lo), np.diff(adjacency.indptr))
    n_comp, lab = connected_components(
        sp.csr_matrix((np.ones(int(inner.sum())), (arow[inner], columns[inner] - lo)),
                      shape=(hi - lo, hi - lo)), directed=False)
    offset = comm.exscan(int(n_comp)) or 0
    gid = lab.astype(np.int64) + offset
    cut_edges = np.stack([gid[arow[~inner]], columns[~inner].astype(np.int64)], axis=1)
    by = np.argsort(lab, kind="stable")     # every label 0 .. n_comp - 1 holds a particle
    starts = np.flatnonzero(np.concatenate([[True], lab[by][1:] != lab[by][:-1]]))
    first = (np.minimum.reduceat(mine[by], starts) if lab.size else np.zeros(0, np.int64))
    return gid, cut_edges, n_comp, first.astype(np.int64)


def _untied_rows(comm, own, mine, adjacency, degree, label):
    """The adjacency rows, degrees, components and capacities of the untied particles
    (floating clusters, rattlers: what a steady solve fills on rank 0): each rank sends those
    of its own. Returns the pieces on rank 0 (rows and columns as packing indices, H W/K; the
    particles, their degrees, labels and capacities), None on the others."""
    want = np.flatnonzero(~own["tied"])
    sub = adjacency[want].tocoo()
    return comm.gather((mine[want][sub.row], sub.col.astype(np.int64), sub.data, mine[want],
                        degree[want], label[want], own["capacity"][want]), root=0)


def _explicit_bound(comm, own, degree, mine):
    """The exact forward-Euler bound min over free p of C_p / (sum_q H_pq + g_p) and its
    particle, as network.network_of finds it on the whole network (the same operations on the
    same values; among equal bounds the lowest packing index, np.argmin's): each rank's over
    its rows, the least on rank 0 (None on the others): (dt_max s, particle or -1)."""
    ratio, any_free = explicit_ratios(own["capacity"], degree, own["g"], own["held"])
    if any_free:
        best = float(ratio.min())
        mine_best = (best, int(mine[ratio == best].min()))
    else:
        mine_best = (math.inf, -1)
    got = comm.gather(mine_best, root=0)
    if got is None:
        return None
    best = min(b for b, _ in got)
    if best == math.inf:
        return math.inf, -1
    return best, min(p for b, p in got if b == best)


def _root_summary(parts, pieces, bound, n, m, totals) -> NetworkSummary:
    """Rank 0: its :class:`~.network.NetworkSummary` from the parts the ranks reduced
    (:func:`_summary_on_ranks`, the clusters' counts), the untied particles' rows ``pieces``,
    the explicit ``bound`` and the ranks' ``totals``: what the run, its checks and the output
    read of the network (as network.summary_of makes it of the whole network)."""
    rp, rc, rd, dp, dv, dl, dc = (np.concatenate([q[k] for q in pieces]) for k in range(7))
    by = np.argsort(dp, kind="stable")
    sel = dp[by]
    adj = sp.coo_matrix((rd, (np.searchsorted(sel, rp), np.searchsorted(sel, rc))),
                        shape=(sel.size, sel.size)).tocsr()
    adj.sum_duplicates()
    lap = (sp.diags(dv[by], format="csr") - adj).tocsr()    # as Network.laplacian's rows
    lap.sort_indices()
    n_active = totals["n_active"]
    h_mean = totals["h_sum"] / n_active if n_active else math.nan
    dt_paper = (float(parts["capacity_mean"] / (totals["coord_max"] * h_mean)) if n_active
                else math.inf)
    clusters = parts["clusters"]
    return NetworkSummary(
        problem=parts["problem"], n=n, n_active_contacts=n_active,
        n_zero_contacts=m - n_active, flags=network_flags(m - n_active, clusters),
        dt_max_s=bound[0], dt_max_particle=bound[1], dt_paper_s=dt_paper,
        clusters=clusters, constant_boundary_flow_w=parts["constant_flows"],
        prescribed_mean_k=parts["prescribed_mean"],
        untied=UntiedParticles(particle=sel, label=dl[by].astype(np.int32),
                               capacity_j_k=dc[by], laplacian=lap,
                               n_components=clusters.n_components),
        principle=parts["principle"])


class RanksWhole(Whole):
    """The whole packing as the boundary kinds see it from one rank's particles (``ids``:
    their packing indices, ascending): counts, flags and the phases present reduced over the
    ranks, a sum in packing order gathered (the few particles of a face), the lowest
    particle's value found over the ranks. Collective: every rank runs the kinds in the same
    order and calls these alike; a kind's refusal follows the reduction it depends on, so every
    rank raises it."""

    def __init__(self, comm, ids):
        self.comm, self.ids = comm, ids

    def count(self, k):
        return int(self.comm.allreduce(int(k)))

    def any(self, flag):
        return bool(self.comm.allreduce(int(bool(flag)), op=_max()))

    def all(self, flag):
        return not self.any(not flag)

    def ordered_sum(self, values, particles):
        got = self.comm.allgather((self.ids[particles], np.asarray(values)))
        at = np.concatenate([g[0] for g in got])
        return np.concatenate([g[1] for g in got])[np.argsort(at, kind="stable")].sum()

    def union(self, values):
        return np.unique(np.concatenate(self.comm.allgather(np.unique(values))))

    def lowest(self, particles, values):
        here = (int(self.ids[particles[0]]), values[0]) if particles.size else None
        got = [g for g in self.comm.allgather(here) if g is not None]
        return min(got, key=lambda g: g[0])[1] if got else None


def _sorted_place(by):
    """``by``: the places (in this rank's block) of its particles sorted by packing index.
    Returns, for each place, the particle's index in that sorted list."""
    inv = np.empty_like(by)
    inv[by] = np.arange(by.size, dtype=by.dtype)
    return inv


def _owner_block(scene, comm, head, fb, nb_block, mine, fblock):
    """Step 3: this rank's particles (``mine``, its block of the order), sorted by packing
    index (so that the kinds' rows come in the whole problem's order), fetched from their
    directories (``fb`` this directory's particles, ``nb_block`` their neighbour counts): a
    Packing of them with the walls and their own wall contacts (``head``: the file's walls
    and wall contacts, every rank's), and the law's inputs and capacities on them. A phase
    without a material, then a capacity out of range, refused as the whole build refuses it
    (the lowest phase; the count over every rank and the lowest particle)."""
    by = np.argsort(mine, kind="stable")
    ids = mine[by]
    pos, rad, phase, nb = fetch(comm, ids, fblock, [fb["position"], fb["radius"],
                                                     fb["phase"], nb_block])
    wp = np.asarray(head.wall_particle, dtype=np.int64)
    at = np.minimum(np.searchsorted(ids, wp), max(ids.size - 1, 0))
    hit = (ids[at] == wp) if ids.size else np.zeros(wp.size, bool)
    block = dataclasses.replace(
        head, position=pos, radius=rad, phase=phase, pair=np.zeros((0, 2), np.int64),
        overlap=np.zeros(0), normal_force=np.zeros(0), branch=np.zeros((0, 3)),
        contact_radius=None, yade_id=None, wall_particle=at[hit],
        wall_index=np.asarray(head.wall_index)[hit],
        wall_overlap=np.asarray(head.wall_overlap)[hit],
        wall_normal_force=np.asarray(head.wall_normal_force)[hit],
        wall_contact_radius=(None if head.wall_contact_radius is None
                             else np.asarray(head.wall_contact_radius)[hit]))
    whole = RanksWhole(comm, ids)
    agree(comm, lambda: [scene.material(int(p)) for p in whole.union(phase)])
    law, params, pinput, _, capacity = agree(comm, lambda: evaluate_law(
        scene, block, None, nb, check_capacity=False))
    bad = bad_capacity(capacity)
    n_bad = whole.count(bad.sum())
    if n_bad:
        k = np.flatnonzero(bad)
        raise capacity_refusal(scene, law, whole.lowest(k, capacity[k]), n_bad,
                               whole.count(ids.size), whole.lowest(k, ids[k]))
    return SimpleNamespace(ids=ids, by=by, packing=block, whole=whole, law=law,
                           params=params, pinput=pinput, capacity=capacity)


def _owner_problem(scene, comm, blk, choice, n):
    """Step 4: the boundary kinds (:func:`~.problem.boundary_problem`, the one registry) on
    this rank's particles ``blk`` (:func:`_owner_block`), seeing the whole packing through
    :class:`RanksWhole`: this rank's rows of the problem, in the whole problem's order. Returns
    this rank's per-particle and boundary rows (at its places in the order: the keys of the
    PETSc backend's share), the problem (its rows over this rank's particles, sorted by
    packing index), the info (the whole build's) and the summary's parts reduced over the
    ranks (:func:`_summary_on_ranks`)."""
    problem, info = agree(comm, lambda: boundary_problem(
        scene, blk.packing, blk.law, blk.params, blk.pinput, blk.capacity, np.zeros(0),
        choice, whole=blk.whole))
    v = agree(comm, lambda: validate(problem))
    terms = particle_terms(v)
    held_boundary = np.full(v["n"], -1, np.int32)
    held_boundary[v["fixed_particle"]] = v["fixed_boundary"]
    by = blk.by

    def at_places(a):
        out = np.empty_like(a)
        out[by] = a
        return out

    own = dict(capacity=at_places(v["capacity"]), held=at_places(terms["held"]),
               held_t=at_places(terms["held_t"]), g=at_places(terms["g_p"]),
               b=at_places(terms["gt_p"] + terms["pw_p"]),
               fixed_local=by[v["fixed_particle"]], fixed_boundary=v["fixed_boundary"],
               ex_local=by[v["exchange_particle"]], ex_g=v["exchange_g"],
               ex_t=v["exchange_t"], ex_b=v["exchange_boundary"],
               ex_held_b=held_boundary[v["exchange_particle"]])
    parts = _summary_on_ranks(comm, problem, v, terms, held_boundary, n)
    return own, problem, info, parts


def _summary_on_ranks(comm, problem, v, terms, held_boundary, n) -> dict:
    """What rank 0's NetworkSummary needs of the per-particle arrays, reduced over the ranks'
    rows (each rank's ``v`` and ``terms`` over its particles): the constant powers
    (network.constant_flows, summed), the steady reference (the prescribed temperatures'
    sum and count), the maximum principle's inputs (network.principle_of on each rank's rows;
    extremes and rates are maxima and minima: the whole network's, bit for bit), the mean
    capacity for dt_paper. Sums over the ranks add the ranks' partial sums: the whole
    network's to round-off (1e-14, tests/mpi_rank_build_check.py)."""
    held, pw_p, c = terms["held"], terms["pw_p"], v["capacity"]
    nb = len(problem.boundary_names)
    flows = comm.allreduce(constant_flows(
        np.bincount(v["power_boundary"], weights=v["power"], minlength=nb),
        v["power_particle"], v["power"], held, held_boundary))
    prescribed = np.concatenate([v["fixed_temperature"],
                                 v["exchange_t"][v["exchange_g"] > 0]])
    total = comm.allreduce(float(prescribed.sum()))
    count = comm.allreduce(int(prescribed.size))
    powered = np.unique(v["power_particle"])
    free_powered = powered[~held[powered]]
    rate = getattr(problem.source, "max_rise_rate", None)
    local = principle_of(
        prescribed, pw_p[free_powered], c[free_powered],
        has_power=bool(np.any(pw_p[powered] != 0)), has_source=problem.source is not None,
        source_rate=None if rate is None else rate(c, ~held))
    principles = comm.allgather(local)
    rates = [p.source_rate for p in principles if p.source_rate is not None]
    principle = dataclasses.replace(
        local, prescribed_lo_k=min(p.prescribed_lo_k for p in principles),
        prescribed_hi_k=max(p.prescribed_hi_k for p in principles),
        power_up_k_s=max(p.power_up_k_s for p in principles),
        power_down_k_s=max(p.power_down_k_s for p in principles),
        plain=all(p.plain for p in principles),
        source_rate=(max(r[0] for r in rates), max(r[1] for r in rates), rates[0][2],
                     rates[0][3]) if rates else None)
    return dict(
        problem=dataclasses.replace(ProblemSummary.of(problem), source=None),
        constant_flows=flows, prescribed_mean=total / count if count else 0.0,
        principle=principle, capacity_mean=comm.allreduce(float(c.sum())) / n)


def _clusters_on_ranks(comm, adjacency, columns, lo, hi, mine, reservoir, starts):
    """Step 5: the clusters (network.cluster_report's) across the ranks. Each rank labels the
    components of its own contacts (:func:`_local_components`), finds the component at the
    other end of each cut contact at its owner, and sends rank 0 those pairs with each
    component's lowest packing index, size and whether it holds a reservoir (``reservoir``: a
    held particle or g > 0, by place). Rank 0 joins them, numbers them by their first particle
    (as connected_components numbers the whole network's) and sends each rank its components'
    labels and tied flags. Returns this rank's particles' labels and tied flags, and the
    clusters' counts on rank 0 (None elsewhere). Rank 0 holds arrays of the components (a
    rattler is one), never of every particle."""
    gid, cut_edges, n_comp, comp_first = _local_components(comm, adjacency, columns, lo, hi,
                                                           mine)
    offset = comm.exscan(int(n_comp)) or 0
    there, back = np.unique(cut_edges[:, 1], return_inverse=True)
    (other,) = fetch(comm, there, starts, [gid])
    edges = np.stack([cut_edges[:, 0], other[back.reshape(-1)]], axis=1)
    local = gid - offset
    tied_c = np.zeros(n_comp, dtype=bool)
    tied_c[local[reservoir]] = True
    size_c = np.bincount(local, minlength=n_comp).astype(np.int64)
    got = comm.gather((edges, comp_first, tied_c, size_c), root=0)
    counts, reply = None, None
    if comm.Get_rank() == 0:
        total = sum(g[1].size for g in got)
        edges = np.concatenate([g[0] for g in got])
        graph = sp.coo_matrix((np.ones(edges.shape[0]), (edges[:, 0], edges[:, 1])),
                              shape=(total, total))
        k, joined = connected_components(graph, directed=False)
        first_p = np.full(k, np.iinfo(np.int64).max, dtype=np.int64)
        np.minimum.at(first_p, joined, np.concatenate([g[1] for g in got]))
        renumber = np.empty(k, dtype=np.int64)
        renumber[np.argsort(first_p, kind="stable")] = np.arange(k)
        label_c = renumber[joined]
        tied = np.zeros(k, dtype=bool)
        tied[label_c[np.concatenate([g[2] for g in got])]] = True
        sizes = np.zeros(k, dtype=np.int64)
        np.add.at(sizes, label_c, np.concatenate([g[3] for g in got]))
        floating, rattlers = untied_components(tied, sizes)
        counts = ClusterCounts(n_components=int(k), floating_sizes=sizes[floating],
                               n_rattlers=int(rattlers.size))
        bounds = np.concatenate([[0], np.cumsum([g[1].size for g in got])])
        reply = [(label_c[a:b], tied[label_c[a:b]]) for a, b in zip(bounds[:-1], bounds[1:])]
    label_c, tied_c = comm.scatter(reply, root=0)
    return label_c[local], tied_c[local], counts


__all__ = ["RankBuild", "RankError", "agree", "build_on_ranks", "PackingError"]
