"""Each MPI rank reads and builds its own rows of the network (issue 25; docs/scaling.md).

The PETSc backend's build (:mod:`thermal_kernel.mpi_run`): no rank reads the whole contact list
or evaluates the law on every contact, and only rank 0 holds the particles whole. Collective
over an mpi4py communicator:

1. rank 0 reads the packing without its contacts (``read_packing(path, contacts=False)``,
   checked as always: the boundary kinds and the output need the particles whole); rank r
   reads the r-th block of the file's particles (it is their *directory*), the ranks sort
   the Morton order together (:func:`~.solvers.partition.morton_blocks_on_ranks`, the whole
   sort's order bit for bit) and rank r owns the r-th block of it; values go between the
   owners, the directories and rank 0 (in the file's order) by
   :class:`~.solvers.partition.Routes`: no rank holds the order;
2. rank r reads the r-th slice of the file's contact rows (``read_contact_rows``), fetches
   their spheres from the directories and checks the rows against them
   (``check_contact_rows``, the reader's checks); a scene's ``[neighbours]`` criterion is
   chosen over every rank's rows with collectives
   (:func:`~.neighbours.choose_neighbours_on_ranks`: the bulk flags from rank 0, which holds
   the particles; the gap giving the target bulk Z found by a bisection over the ratios'
   bits, the ranks' summed weights gathered a step: the whole build's gap, bit for bit) and each
   row marked kept or not; the neighbour counts (of the kept rows) are summed at the
   directories and fetched back; each contact goes, with its two spheres' values, to the
   rank(s) owning its particles (one Alltoallv a field): a rank then holds the contacts
   touching its particles, in the file's order (duplicates found there: both copies reach
   the owner of i);
3. each rank evaluates the scene's law on those contacts (:func:`~.problem.evaluate_law`, the
   one law registry, on a packing of the contacts' spheres; H = 0 on the rows not kept) and
   builds its rows of A = L + diag(g) with the in-process arithmetic (the same sums in the
   same order: the rows equal the whole build's bit for bit, ``tests/test_petsc_backend.py``);
4. rank 0 evaluates the law's capacities and runs the boundary kinds
   (:func:`~.problem.boundary_problem`, the one registry) on the whole particles, and sends
   each rank the per-particle and boundary rows of its block;
5. the clusters: each rank labels the components of its own rows' contacts, rank 0 joins them
   through the cut contacts (the same numbering as in-process); while rank 0 holds the
   per-particle arrays the kinds made, it keeps what its summary needs of them
   (:func:`_summary_parts`: the constant powers, the steady reference, the maximum
   principle's inputs, the clusters' counts, the untied particles), then drops them; the
   untied particles' rows come to rank 0 (:func:`_untied_rows`), the explicit bound is each
   rank's over its rows, the least on rank 0 (:func:`_explicit_bound`), and rank 0 makes its
   :class:`~.network.NetworkSummary` (:func:`_root_summary`: network.summary_of's of the whole
   network, bit for bit but dt_paper, ``tests/mpi_rank_build_check.py``): what the run, its
   checks and the output read of the network.

What stays whole: on rank 0 the particles (read and checked, for the boundary kinds) and,
while the kinds run and each rank's per-particle rows are sent, the problem's per-particle
arrays; during the run, the start and the temperatures it gathers at an output time (they go,
one time at a time, into the run's history, paged to disk when large:
:func:`~.atomic.history_rows`). ``mpi_run --whole-build`` builds the network whole on rank 0
instead (for comparison).
"""
from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .checkpoint import packing_sha256
from .neighbours import bulk_particles, choose_neighbours_on_ranks, dump_gap_tolerance_of
from .network import (ClusterCounts, NetworkSummary, ProblemSummary, UntiedParticles,
                      cluster_report, constant_flows, explicit_ratios, network_flags,
                      particle_terms,
                      prescribed_mean, principle_of, validate)
from .packing import (CONTACT_BLOCK_ROWS, Packing, PackingError, _check_pairs,
                      check_contact_rows, contact_check_scales, read_contact_rows,
                      read_packing, read_particle_rows)
from .problem import boundary_problem, evaluate_law
from .scene import SceneError
from .solvers.partition import (Routes, alltoallv, block_starts, exchange_counts,
                                 gather_blocks, morton_blocks_on_ranks, scatter_blocks)

class RankError(RuntimeError):
    """Another rank's part of the build failed: its one-line message (each rank raises)."""


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


def _max():
    from mpi4py import MPI
    return MPI.MAX


def _fetch(comm, ids, fblock, columns):
    """The values of the particles ``ids`` (packing indices, sorted, unique) from their
    directories (rank d holds the file's particles ``fblock[d]:fblock[d + 1]``); ``columns``
    this rank's own arrays over its block. Arrays aligned with ``ids``."""
    rank, size = comm.Get_rank(), comm.Get_size()
    dest = np.searchsorted(fblock, ids, side="right") - 1      # sorted ids: grouped by rank
    send_n, recv_n = exchange_counts(comm, dest, size)
    asked = alltoallv(comm, np.asarray(ids, dtype=np.int64), send_n, recv_n) - fblock[rank]
    return [alltoallv(comm, np.asarray(c)[asked], recv_n, send_n) for c in columns]


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

    # 1. rank 0: the particles whole; each rank its block of the file's particles, the Morton
    # order sorted on the ranks, its block of it
    particles, head, packing_hash = _read_particles(comm, packing_path)
    root_in = dict(particles=particles)     # rank 0: dropped once the boundary kinds ran
    del particles
    n, m, path = head["n"], head["m"], head["path"]
    starts = block_starts(n, size)          # the ranks' blocks of the Morton order
    fblock = starts                         # the directories' blocks of the file's particles
    lo, hi = int(starts[rank]), int(starts[rank + 1])
    fb = agree(comm, lambda: read_particle_rows(path, fblock[rank], fblock[rank + 1]))
    mine = morton_blocks_on_ranks(comm, fb["position"], starts)
    routes = Routes(comm, mine, starts)     # owners <-> directories <-> rank 0 (file order)
    own_new = routes.places()               # the file block's places in the order
    n_bulk, own_bulk = _bulk_flags(comm, scene.neighbours, root_in["particles"], fblock)

    # 2. this rank's slice of the contact rows, checked, chosen, sent to their particles' owners
    got, nb_block, choice = _contacts_to_owners(scene, comm, head, starts, fblock, fb, own_new,
                                                n_bulk, own_bulk)
    del own_bulk

    # 3. rank 0: the law's capacities and inputs on the whole particles (its boundary kinds',
    # its output's), then the law on each rank's contacts and this rank's rows of A
    root_in.update(_capacities_on_root(scene, comm, root_in["particles"], nb_block, fblock))
    directory = dict(radius=fb["radius"], phase=fb["phase"], nb=nb_block, new=own_new)
    del fb, nb_block, own_new
    ids, new_l, active = _conducting_contacts(scene, comm, head, got, directory, fblock,
                                              conductance_factor)
    del got, directory
    adjacency, columns, degree, totals = _rank_rows(comm, active, ids, new_l, lo, hi, n)
    del active, ids, new_l

    # 4. clusters: components of this rank's own contacts, joined on rank 0 by the cut ones
    gid, cut_edges, n_comp, comp_first = _local_components(comm, adjacency, columns, lo, hi,
                                                           mine)
    total_comp = comm.allreduce(int(n_comp))
    gid_all = routes.gather(gid, _index_dtype(total_comp))     # int32 while it holds them
    cut_all = comm.gather((cut_edges, comp_first), root=0)     # per component, rank order
    del gid, cut_edges, comp_first

    # 5. rank 0: the boundary kinds, the clusters, what its summary needs of them; each rank
    # its per-particle rows, from which the explicit bound is found
    built = {}
    nb_count, has_source = comm.bcast(agree(comm, (lambda: _root_problem(
        scene, root_in, choice, cut_all, gid_all, total_comp, built)) if rank == 0
        else (lambda: None)), root=0)
    cut_all = gid_all = None
    from .solvers.petsc_backend import share_block
    own = _send_particle_shares(comm, built, routes, starts)
    for key in ("v", "terms", "clusters", "held_boundary", "problem"):
        built.pop(key, None)            # rank 0: no array of every particle from here on
    own.update(share_block(adjacency, degree, own["g"], lo, n, columns))
    del columns
    pieces = _untied_rows(comm, own, mine, adjacency, degree)
    del adjacency
    bound = _explicit_bound(comm, own, degree, mine)
    meta = dict(n=n, starts=starts, nb=nb_count, has_source=has_source, cut=totals["cut"],
                active_contacts=totals["n_active"])
    if rank != 0:
        return RankBuild(share=own, meta=meta, mine=mine, routes=routes)
    net = _root_summary(built, pieces, bound, n, m, totals)
    return RankBuild(share=own, meta=meta, mine=mine, routes=routes, particles=SimpleNamespace(
        path=head["path"], n_particles=n), net=net, info=built["info"],
        packing_sha256=packing_hash)


def _index_dtype(n):
    """scipy's index type for ``n`` columns (int32 while it holds them: half the bytes)."""
    return np.int32 if n < 2 ** 31 - 1 else np.int64


def _read_particles(comm, packing_path):
    """Step 1: rank 0 reads the packing without its contacts (checked as always: the boundary
    kinds and the output need the particles whole); every rank gets its
    head (counts, path, attributes, domain and the contact checks' scales). Returns the
    particles and the packing's sha256 (the checkpoints' and the output's; made here, so the
    particles can go once the boundary kinds ran), None and "" but on rank 0, and the head."""
    rank = comm.Get_rank()
    particles = agree(comm, lambda: read_packing(packing_path, contacts=False)
                      if rank == 0 else None)
    head, packing_hash = None, ""
    if rank == 0:
        p = particles
        head = dict(n=p.n_particles, m=int(p.file_contacts), path=p.path, attrs=p.attrs,
                    lo=p.domain_lo, hi=p.domain_hi, periodic=p.periodic,
                    scales=contact_check_scales(p.position, p.domain_lo, p.domain_hi))
        packing_hash = packing_sha256(p)
    return particles, comm.bcast(head, root=0), packing_hash


def _bulk_flags(comm, crit, particles, fblock):
    """Step 1, a [neighbours] criterion ``crit`` only: rank 0 finds the bulk particles (their
    distance to every wall and cut face, the mean radius: the particles whole); returns their
    number (every rank) and this directory's block of the flags (uint8), or 0, None."""
    if crit is None:
        return 0, None
    rank = comm.Get_rank()
    bulk = (bulk_particles(particles, crit.bulk_margin_diameters) if rank == 0 else None)
    n_bulk = comm.bcast(int(bulk.sum()) if rank == 0 else None, root=0)
    return n_bulk, scatter_blocks(comm, bulk, fblock, np.uint8)


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
    pos_e, rad_e, ph_e, new_e, *bulk_e = _fetch(
        comm, ends, fblock, [fb["position"], fb["radius"], fb["phase"], own_new]
        + ([] if own_bulk is None else [own_bulk]))      # the bulk flags: [neighbours] only
    bulk_e = bulk_e[0] if bulk_e else None
    agree(comm, lambda: _check_slice(head, part, loc, pos_e, rad_e, int(ms[rank])))
    pos_e = None
    del fb["position"]
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


def _capacities_on_root(scene, comm, particles, nb_block, fblock):
    """Step 3: rank 0 evaluates the law on the whole particles (its capacities and the inputs
    its boundary kinds and output read), with the neighbour counts gathered from the
    directories. Returns them (a dict on rank 0, empty on the others)."""
    whole = {}
    nb_whole = gather_blocks(comm, nb_block, fblock)

    def capacities():
        law, params, pinput, _, capacity = evaluate_law(scene, particles, None, nb_whole)
        whole.update(law=law, params=params, pinput=pinput, capacity=capacity)

    agree(comm, capacities if comm.Get_rank() == 0 else (lambda: None))
    return whole


def _conducting_contacts(scene, comm, head, got, directory, fblock, conductance_factor):
    """Step 3: the law on this rank's contacts ``got`` (the one law registry, on a packing of
    the contacts' spheres fetched from the directories; H = 0 on the rows not kept), times
    the conductance factors if any. ``got`` and ``directory`` (this directory's radius,
    phase, nb and new arrays) are emptied as they are used: their arrays freed before the
    rows are built. Returns the particles the contacts touch (packing indices, sorted), their
    places in the order, and the conducting contacts (i, j, H W/K, their places ni, nj)."""
    ids, inv = np.unique(got["pair"], return_inverse=True)
    table = dict(zip(("radius", "phase", "nb", "new"), _fetch(
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
    contacts as (component, other particle's packing index), the number of components and
    each component's lowest packing index (``mine``: this rank's particles)."""
    inner = (columns >= lo) & (columns < hi)
    arow = np.repeat(np.arange(hi - lo), np.diff(adjacency.indptr))
    n_comp, lab = connected_components(
        sp.csr_matrix((np.ones(int(inner.sum())), (arow[inner], columns[inner] - lo)),
                      shape=(hi - lo, hi - lo)), directed=False)
    offset = comm.exscan(int(n_comp)) or 0
    gid = lab.astype(np.int64) + offset
    cut_edges = np.stack([gid[arow[~inner]], adjacency.indices[~inner].astype(np.int64)], axis=1)
    by = np.argsort(lab, kind="stable")     # every label 0 .. n_comp - 1 holds a particle
    starts = np.flatnonzero(np.concatenate([[True], lab[by][1:] != lab[by][:-1]]))
    first = (np.minimum.reduceat(mine[by], starts) if lab.size else np.zeros(0, np.int64))
    return gid, cut_edges, n_comp, first.astype(np.int64)


def _root_problem(scene, root_in, choice, cut_all, gid_all, total_comp, built):
    """Step 5, rank 0: the boundary kinds (the one registry) on the whole particles, the
    per-particle terms, the clusters (the ranks' components joined by the cut contacts), into
    ``built``. ``root_in`` (the particles, the law's outputs on them) is emptied once the
    kinds ran: the particles' arrays go before the terms are made (a source keeps the centres
    it evaluates). Returns the number of boundaries and whether there is a source (every rank
    needs them)."""
    particles = root_in.pop("particles")
    n = particles.n_particles
    problem, info = boundary_problem(scene, particles, root_in["law"], root_in["params"],
                                     root_in["pinput"], root_in["capacity"], np.zeros(0),
                                     choice)
    del particles
    root_in.clear()
    v = validate(problem)
    terms = particle_terms(v)
    k, label = _join_components(cut_all, gid_all, total_comp, n)
    clusters = cluster_report(k, label, terms["held"] | (terms["g_p"] > 0))
    held_boundary = np.full(n, -1, np.int32)
    held_boundary[v["fixed_particle"]] = v["fixed_boundary"]
    built.update(problem=problem, info=info, v=v, terms=terms, clusters=clusters,
                 held_boundary=held_boundary,
                 parts=_summary_parts(problem, v, terms, clusters, held_boundary))
    return len(scene.boundaries), problem.source is not None


def _summary_parts(problem, v, terms, clusters, held_boundary) -> dict:
    """Rank 0, step 5, while it holds the per-particle arrays: what its NetworkSummary needs
    of them, each as the whole network computes it (the same operations on the same values:
    network.constant_flows, prescribed_mean, principle_of, np.mean of the capacities for
    dt_paper, the clusters' counts and the untied particles)."""
    held, pw_p, c = terms["held"], terms["pw_p"], v["capacity"]
    powered = np.unique(v["power_particle"])
    free_powered = powered[~held[powered]]
    rate = getattr(problem.source, "max_rise_rate", None)
    untied = np.flatnonzero(~clusters.tied_particle)
    return dict(
        problem=ProblemSummary.of(problem),
        constant_flows=constant_flows(
            np.bincount(v["power_boundary"], weights=v["power"],
                        minlength=len(problem.boundary_names)),
            v["power_particle"], v["power"], held, held_boundary),
        prescribed_mean=prescribed_mean(v["fixed_temperature"], v["exchange_t"],
                                        v["exchange_g"]),
        principle=principle_of(
            np.concatenate([v["fixed_temperature"], v["exchange_t"]]), pw_p[free_powered],
            c[free_powered], has_power=bool(np.any(pw_p[powered] != 0)),
            has_source=problem.source is not None,
            source_rate=None if rate is None else rate(c, ~held)),
        capacity_mean=float(np.mean(c)),
        clusters=ClusterCounts.of(clusters),
        untied=untied, untied_label=clusters.label[untied], untied_capacity=c[untied])


def _join_components(cut_all, gid_all, total_comp, n):
    """Rank 0: the ranks' components joined through the cut contacts, numbered by their first
    particle as connected_components numbers the whole network's (the in-process clusters).
    ``cut_all``: each rank's cut contacts and its components' lowest packing indices. Works
    per component (one array of N: the labels). Returns their number and each particle's
    label (int32)."""
    edges = np.concatenate([c[0] for c in cut_all])
    first_of = np.concatenate([c[1] for c in cut_all])     # by component id (rank order)
    graph = sp.coo_matrix((np.ones(edges.shape[0]), (edges[:, 0], gid_all[edges[:, 1]])),
                          shape=(total_comp, total_comp))
    k, joined = connected_components(graph, directed=False)
    first_p = np.full(k, n, dtype=np.int64)
    np.minimum.at(first_p, joined, first_of)
    renumber = np.empty(k, dtype=np.int32)
    renumber[np.argsort(first_p, kind="stable")] = np.arange(k, dtype=np.int32)
    return (k, renumber[joined][gid_all]) if n else (0, np.zeros(0, np.int32))


def _untied_rows(comm, own, mine, adjacency, degree):
    """The adjacency rows and degrees of the untied particles (floating clusters, rattlers:
    what a steady solve fills on rank 0): each rank sends those of its own. Returns the pieces
    on rank 0 (rows and columns as packing indices, H W/K; the particles and their degrees),
    None on the others."""
    want = np.flatnonzero(~own["tied"])
    sub = adjacency[want].tocoo()
    return comm.gather((mine[want][sub.row], sub.col.astype(np.int64), sub.data, mine[want],
                        degree[want]), root=0)


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


def _root_summary(built, pieces, bound, n, m, totals) -> NetworkSummary:
    """Rank 0: its :class:`~.network.NetworkSummary` from the parts it made while it held the
    per-particle arrays (:func:`_summary_parts`), the untied particles' rows ``pieces``, the
    explicit ``bound`` and the ranks' ``totals``: what the run, its checks and the output read
    of the network (as network.summary_of makes it of the whole network)."""
    parts = built.pop("parts")
    sel = parts["untied"]
    rp, rc, rd, dp, dv = (np.concatenate([q[k] for q in pieces]) for k in range(5))
    adj = sp.coo_matrix((rd, (np.searchsorted(sel, rp), np.searchsorted(sel, rc))),
                        shape=(sel.size, sel.size)).tocsr()
    adj.sum_duplicates()
    deg = np.empty(sel.size)
    deg[np.searchsorted(sel, dp)] = dv
    lap = (sp.diags(deg, format="csr") - adj).tocsr()       # as Network.laplacian's rows
    lap.sort_indices()
    n_active = totals["n_active"]
    h_mean = totals["h_sum"] / n_active if n_active else math.nan
    dt_paper = (float(parts["capacity_mean"] / (totals["coord_max"] * h_mean)) if n_active
                else math.inf)
    return NetworkSummary(
        problem=parts["problem"], n=n, n_active_contacts=n_active,
        n_zero_contacts=m - n_active, flags=network_flags(m - n_active, parts["clusters"]),
        dt_max_s=bound[0], dt_max_particle=bound[1], dt_paper_s=dt_paper,
        clusters=parts["clusters"], constant_boundary_flow_w=parts["constant_flows"],
        prescribed_mean_k=parts["prescribed_mean"],
        untied=UntiedParticles(particle=sel, label=parts["untied_label"],
                               capacity_j_k=parts["untied_capacity"], laplacian=lap,
                               n_components=parts["clusters"].n_components),
        principle=parts["principle"])


def _send_particle_shares(comm, built, routes, starts):
    """Each rank's per-particle and boundary rows (the keys of ``share_particles``) from rank
    0's whole arrays, in the file's order: the per-particle ones through the directories
    (:class:`~.solvers.partition.Routes`), the boundary rows to the owners of their particles
    (:func:`_rows_to_owners`, in their order on rank 0). This rank's."""
    root = comm.Get_rank() == 0
    v, t = (built["v"], built["terms"]) if root else ({}, {})
    own = {}
    for key, whole, dtype in (
            ("capacity", v.get("capacity"), np.float64), ("held", t.get("held"), np.uint8),
            ("held_t", t.get("held_t"), np.float64), ("g", t.get("g_p"), np.float64),
            ("b", (t["gt_p"] + t["pw_p"]) if root else None, np.float64),
            ("tied", built["clusters"].tied_particle if root else None, np.uint8)):
        own[key] = routes.scatter(whole, dtype)
    own["held"], own["tied"] = own["held"].view(bool), own["tied"].view(bool)
    places = routes.places()
    local, cols = _rows_to_owners(comm, starts, places, v.get("fixed_particle"), dict(
        fixed_boundary=v.get("fixed_boundary")))
    own.update(fixed_local=local, fixed_boundary=cols["fixed_boundary"])
    local, cols = _rows_to_owners(comm, starts, places, v.get("exchange_particle"), dict(
        ex_g=v.get("exchange_g"), ex_t=v.get("exchange_t"), ex_b=v.get("exchange_boundary"),
        ex_held_b=built["held_boundary"][v["exchange_particle"]] if root else None))
    own.update(ex_local=local, **cols)
    return own


def _rows_to_owners(comm, starts, places, particle, columns):
    """Rows given on rank 0 (``particle``: each row's packing index; ``columns``: name ->
    (R,) array, None on the other ranks) sent through their particles' directories
    (``places``: the directory's block's places in the order) to the particles' owners.
    Returns this rank's rows, in their order on rank 0: (their particles' places in this
    rank's block, {name: values})."""
    rank, size = comm.Get_rank(), comm.Get_size()
    spec = comm.bcast([(k, np.asarray(a).dtype.str) for k, a in sorted(columns.items())]
                      if rank == 0 else None, root=0)
    if rank == 0:
        particle = np.asarray(particle, dtype=np.int64)
        dest = np.searchsorted(starts, particle, side="right") - 1
        by = np.argsort(dest, kind="stable")
        send = dict(row=by.astype(np.int64), particle=particle[by],
                    **{k: np.asarray(columns[k])[by] for k, _ in spec})
    else:
        dest = np.zeros(0, dtype=np.int64)
        send = dict(row=np.zeros(0, np.int64), particle=np.zeros(0, np.int64),
                    **{k: np.zeros(0, dtype=dt) for k, dt in spec})
    send_n, recv_n = exchange_counts(comm, dest, size)
    got = {k: alltoallv(comm, a, send_n, recv_n) for k, a in send.items()}
    got["place"] = places[got.pop("particle") - starts[rank]]
    owner = np.searchsorted(starts, got["place"], side="right") - 1
    by = np.argsort(owner, kind="stable")
    send_n, recv_n = exchange_counts(comm, owner, size)
    got = {k: alltoallv(comm, a[by], send_n, recv_n) for k, a in got.items()}
    in_order = np.argsort(got.pop("row"), kind="stable")
    return (got.pop("place")[in_order] - starts[rank],
            {k: a[in_order] for k, a in got.items()})


__all__ = ["RankBuild", "RankError", "agree", "build_on_ranks", "PackingError"]
