"""The three solvers on MPI ranks through PETSc (issue 25; docs/scaling.md, docs/solvers.md).

Runs under ``mpirun`` in the PETSc venv (``.venv-mpi``: Debian's petsc4py and mpi4py are built for
Debian's numpy 1.24, the project's ``.venv`` has numpy 2), started by ``tdem run SCENE --ranks N``
through :mod:`thermal_kernel.mpi_run`. Like the in-process solvers it sees an assembled
:class:`~thermal_kernel.network.Network` only -- never a law or a boundary kind -- and returns the
same :class:`~thermal_kernel.solvers.ThermalResult`, so the output file, its flags and the checks
are the in-process ones.

Distribution. The particles are ordered along a Morton curve of their centres
(:mod:`.partition`; sorted on the ranks by the per-rank build) and the order cut into one
contiguous block per rank; values go between the blocks and rank 0 in the file's order through
the particles' directories (:class:`~.partition.Routes`: no rank holds the order). A rank holds
only its
rows of A = L + diag(g) (L the graph Laplacian, g the exchange conductance), renumbered in that
order, with the per-particle and boundary rows of its block (:func:`share_rows`). Each rank
builds its share itself from its part of the packing (``built=``, thermal_kernel/rank_build.py:
the contacts touching its particles, the law evaluated on those), or rank 0 cuts every share
from a whole assembled network and sends it (``net``: a scene with a ``[neighbours]``
criterion, and the bench). Each rank puts its rows into a PETSc MPIAIJ matrix; vectors are
distributed the same way. Held particles keep their rows in the vectors and are masked: their
increment is 0.

* explicit: T' = T + dt/C (b + S - A T) on free rows, one distributed mat-vec a step; dt and its
  bound are the in-process ones (``check_dt``, the exact positivity bound of the network).
* implicit (theta, Rannacher, TR-BDF2): the in-process time loop
  (:func:`~.implicit.drive_implicit`: the plan, the schemes' stages, the ledger's weights, the
  result) over :class:`DistributedOperator`, which supplies the linear algebra below.
  M = C/h + theta A with the held rows and columns
  replaced by the identity (``MatZeroRowsColumns``: symmetric positive definite, the held
  columns eliminated as in-process); increments solved by CG preconditioned by GAMG (default)
  or hypre BoomerAMG, the residual measured unpreconditioned so ``tol`` is the true residual.
* steady: the same CG on the tied free particles (identity elsewhere); floating clusters and
  rattlers as in :mod:`.steady` (rank 0, from the untied particles' rows and powers).

The energy ledger: each rank sums the heat through the held particles and exchange rows it owns,
every step (the fluxes the step used, as in-process); the sums meet at the output times only.
A transient run's start is set on the ranks' rows (:meth:`DistributedNetwork.start_rows`: the
held rows and the energy their hold takes); at each output time the ranks also sum the
boundaries' heat flows and the stored energy over their rows
(:meth:`DistributedNetwork.output_terms`, one reduction with the ledger), and rank 0 gathers
the temperatures and records all of it with the in-process
:class:`~thermal_kernel.solvers.Recorder` (or hands the temperatures to ``on_output``: ``tdem
run`` keeps them in :func:`~thermal_kernel.atomic.history_rows`, on disk when large). A
source's power is each particle's own: each rank evaluates the source restricted to its block
every step (:meth:`DistributedNetwork.source_powers`; one number a step is summed over the
ranks, the heat it put in), nothing is scattered from rank 0.

Still whole on rank 0 (docs/scaling.md): the network's per-particle arrays and boundary rows
while the ranks' shares are made (with the per-rank build; the whole network with ``net``);
the run then reads only the network's :class:`~thermal_kernel.network.NetworkSummary` there
(``thermal_kernel.mpi_run``; a steady solve fills its floating clusters and rattlers from the
summary's untied particles and their gathered powers); and one output time's temperatures
while they are recorded.
"""
from __future__ import annotations

import math
import time

import numpy as np
import scipy.sparse as sp

from ..network import NetworkSummary, untied_of

from .common import (Recorder, SolverState, ThermalResult, check_times, hold_start,
                     start_parts, step_plan)
from .explicit import explicit_schedule
from .implicit import drive_implicit, scheme_args
from .partition import Routes, block_starts, cut_contacts, owner_of_particle, particle_order
from .steady import fill_untied, steady_result, steady_start

PRECONDITIONERS = ("gamg", "hypre")
# hypre BoomerAMG's defaults (Falgout coarsening, classical interpolation) built a hierarchy that
# made each CG iteration ~5x dearer on packing networks (probe for issue 25); these options, the
# ones hypre recommends for 3-D problems, made it as fast as GAMG.
HYPRE_OPTIONS = {"pc_hypre_type": "boomeramg", "pc_hypre_boomeramg_coarsen_type": "HMIS",
                 "pc_hypre_boomeramg_interp_type": "ext+i",
                 "pc_hypre_boomeramg_strong_threshold": "0.5",
                 "pc_hypre_boomeramg_P_max": "4", "pc_hypre_boomeramg_agg_nl": "1"}
_SHARE_TAG = 25


def _petsc():
    from petsc4py import PETSc      # only under the PETSc venv; imported on first use
    return PETSc


def _share(net, order, new_index, lo, hi) -> dict:
    """Rank's rows ``order[lo:hi]`` of an assembled network: its rows of A = L + diag(g) (CSR,
    columns in the new order, a stored diagonal on every row) and the per-particle and
    boundary rows it owns."""
    mine = order[lo:hi]
    share = share_rows(net.adjacency[mine], net.degree_w_k[mine], mine, lo, new_index, net.n,
                       capacity=net.capacity_j_k, held=net.held,
                       held_t=net.held_temperature_k, g=net.exchange_g_w_k,
                       b=net.constant_rhs_w, tied=net.clusters.tied_particle,
                       fixed_particle=net.fixed_particle, fixed_boundary=net.fixed_boundary,
                       exchange_particle=net.exchange_particle,
                       exchange_row_g=net.exchange_row_g_w_k,
                       exchange_row_t=net.exchange_row_temperature_k,
                       exchange_boundary=net.exchange_boundary, held_boundary=net.held_boundary)
    return dict(share, mine=mine)


def share_rows(adj_rows, degree, mine, lo, new_index, n, *, capacity, held, held_t, g, b, tied,
               fixed_particle, fixed_boundary, exchange_particle, exchange_row_g,
               exchange_row_t, exchange_boundary, held_boundary) -> dict:
    """One rank's share (the keys of :func:`_share_keys`) cut from a whole network's arrays
    (indexed by particle): :func:`share_block` and :func:`share_particles`."""
    out = share_particles(mine, n, capacity=capacity, held=held, held_t=held_t, g=g, b=b,
                          tied=tied, fixed_particle=fixed_particle,
                          fixed_boundary=fixed_boundary, exchange_particle=exchange_particle,
                          exchange_row_g=exchange_row_g, exchange_row_t=exchange_row_t,
                          exchange_boundary=exchange_boundary, held_boundary=held_boundary)
    out.update(share_block(adj_rows, degree, out["g"], lo, n, new_index[adj_rows.indices]))
    return out


def share_block(adj_rows, degree, g_mine, lo, n, columns) -> dict:
    """A rank's rows of A = L + diag(g) as a CSR in the new order (``lo`` its first row) --
    -H off the diagonal, degree + g on it (stored on every row), columns sorted -- from
    ``adj_rows`` (CSR, row k the adjacency row of the rank's k-th particle, columns the
    packing's indices, sorted), their ``degree`` and g, ``columns`` the new place of each
    entry's column: from a whole network (:func:`share_rows`) or built by the rank itself
    (thermal_kernel/rank_build.py)."""
    n_local = adj_rows.shape[0]
    per_row = np.diff(adj_rows.indptr)
    indptr = np.concatenate([[0], np.cumsum(per_row + 1)]).astype(np.int64)
    nnz = int(indptr[-1])
    idx = np.int32 if n < 2 ** 31 - 1 else np.int64
    indices = np.empty(nnz, dtype=idx)
    data = np.empty(nnz)
    off = np.arange(adj_rows.nnz, dtype=np.int64)       # each row one slot further per row
    off += np.repeat(np.arange(n_local, dtype=np.int64), per_row)   # before it (diagonals)
    indices[off] = columns
    data[off] = -adj_rows.data
    del off
    diag = indptr[1:] - 1
    indices[diag] = np.arange(lo, lo + n_local)
    data[diag] = degree + g_mine
    block = sp.csr_matrix((data, indices, indptr.astype(idx)), shape=(n_local, n))
    block.has_sorted_indices = False
    block.sort_indices()
    return dict(lo=lo, indptr=block.indptr, indices=block.indices, data=block.data)


def share_particles(mine, n, *, capacity, held, held_t, g, b, tied, fixed_particle,
                    fixed_boundary, exchange_particle, exchange_row_g, exchange_row_t,
                    exchange_boundary, held_boundary) -> dict:
    """The per-particle and boundary rows of the particles ``mine`` (packing indices), cut
    from arrays indexed by particle, whole (rank 0 of either build)."""
    n_local = mine.size
    local_of = np.full(n, -1, dtype=np.int64)
    local_of[mine] = np.arange(n_local)
    fl = local_of[fixed_particle]
    fk = fl >= 0
    el = local_of[exchange_particle]
    ek = el >= 0
    return dict(
        capacity=np.ascontiguousarray(capacity[mine]),
        held=np.ascontiguousarray(held[mine]), held_t=np.ascontiguousarray(held_t[mine]),
        g=np.ascontiguousarray(g[mine]), b=np.ascontiguousarray(b[mine]),
        tied=np.ascontiguousarray(tied[mine]),
        fixed_local=fl[fk], fixed_boundary=fixed_boundary[fk],
        ex_local=el[ek], ex_g=exchange_row_g[ek], ex_t=exchange_row_t[ek],
        ex_b=exchange_boundary[ek], ex_held_b=held_boundary[exchange_particle[ek]])


class DistributedNetwork:
    """One rank's share of a network: its rows of A = L + diag(g) as a PETSc MPIAIJ matrix, in
    the Morton order, and the per-particle arrays of its rows. Collective: every rank passes
    ``built`` (its :class:`~thermal_kernel.rank_build.RankBuild`), or rank 0 the assembled
    ``net`` (and the centres, for the order) and the others None."""

    def __init__(self, net, position_m=None, comm=None, built=None):
        PETSc = _petsc()
        self.PETSc = PETSc
        self.comm = comm or PETSc.COMM_WORLD
        self.mpi = self.comm.tompi4py()
        self.rank, self.size = self.comm.getRank(), self.comm.getSize()
        t0 = time.perf_counter()
        if built is not None:        # each rank built its share (thermal_kernel/rank_build.py)
            self.net = built.net if self.rank == 0 else None
            meta, own, self.mine, self.routes = built.meta, built.share, built.mine, \
                built.routes
        else:
            self.net = net if self.rank == 0 else None
            meta, own = self._send_shares(net, position_m)
            self.mine = own.pop("mine")
            self.routes = Routes(self.mpi, self.mine, meta["starts"])
        self.n, self.starts, self.nb = meta["n"], meta["starts"], meta["nb"]
        self.has_source, self.cut = meta["has_source"], meta["cut"]
        self.n_active_contacts = meta["active_contacts"]
        self.lo = int(own["lo"])
        self.n_local = int(self.starts[self.rank + 1] - self.starts[self.rank])
        self.block = sp.csr_matrix((own["data"], own["indices"], own["indptr"]),
                                   shape=(self.n_local, self.n))
        rows = np.repeat(np.arange(self.n_local), np.diff(self.block.indptr))
        self._diag_pos = np.flatnonzero(self.block.indices == rows + self.lo)
        del rows
        self.capacity, self.held, self.held_t = own["capacity"], own["held"], own["held_t"]
        self.free = ~self.held
        self.g, self.b, self.tied = own["g"], own["b"], own["tied"]
        self.fixed_local, self.fixed_boundary = own["fixed_local"], own["fixed_boundary"]
        self.ex_local, self.ex_g, self.ex_t = own["ex_local"], own["ex_g"], own["ex_t"]
        self.ex_b, self.ex_held_b = own["ex_b"], own["ex_held_b"]
        self.A = self._mat(self.block)
        self.x = self.A.createVecRight()
        self.y = self.A.createVecLeft()
        self._share_source(built)
        self.setup_seconds = time.perf_counter() - t0

    def _share_source(self, built=None):
        """A source's power is a function of each particle alone: each rank evaluates the
        source over its block every step -- the one it built (``built``, the per-rank build:
        the kinds ran on its particles), or the whole source restricted to its block, which
        rank 0 sends (``source.restricted(particles)``); the column it is booked under goes to
        every rank. A source without ``restricted`` stays on rank 0, which evaluates it whole
        and scatters its powers."""
        self.local_source, self.source_boundary = None, -1
        if not self.has_source:
            return
        if built is not None and built.local_source is not None:
            self.local_source = built.local_source
            self.source_boundary = int(built.meta["source_boundary"])
            return
        restricted = None
        if self.rank == 0:
            restricted = getattr(self.net.problem.source, "restricted", None)
            self.source_boundary = int(self.net.problem.source_boundary)
        local, self.source_boundary = self.mpi.bcast(
            (restricted is not None, self.source_boundary), root=0)
        if not local:
            return
        if self.rank == 0:
            for r in range(1, self.size):       # one block at a time: rank 0 has no order
                block = self.mpi.recv(source=r, tag=_SHARE_TAG)
                self.mpi.send(restricted(block), dest=r, tag=_SHARE_TAG)
                del block
            self.local_source = restricted(self.mine)
        else:
            self.mpi.send(self.mine, dest=0, tag=_SHARE_TAG)
            self.local_source = self.mpi.recv(source=0, tag=_SHARE_TAG)

    def source_powers(self, t0, t1):
        """This rank's rows of the source's mean power over [t0, t1] (W), or None without a
        source."""
        if not self.has_source:
            return None
        if self.local_source is not None:
            return np.asarray(self.local_source(t0, t1), dtype=np.float64)
        whole = np.asarray(self.net.problem.source(t0, t1), dtype=np.float64) \
            if self.rank == 0 else None
        return self.scatter(whole)

    def source_total(self, sw_local) -> float:
        """The source's power summed over every rank's rows (W; on every rank)."""
        return float(self.mpi.allreduce(float(sw_local.sum())))

    def source_ledger(self, energy, sw_local, h):
        """The source's heat over ``h`` in this rank's part of the ledger, as the in-process
        solvers book it: under its column, less what lands on the held particles (this rank's
        held rows)."""
        if self.source_boundary >= 0:
            energy[self.source_boundary] += h * float(sw_local.sum())
        if self.fixed_local.size:
            energy -= h * np.bincount(self.fixed_boundary, weights=sw_local[self.fixed_local],
                                      minlength=energy.size)

    def _send_shares(self, net, position_m):
        """Rank 0 (holding the whole ``net``) sends each rank its share; (meta, own share)."""
        meta = None
        order = None
        if self.rank == 0:
            n = net.n
            order = particle_order(position_m, "morton") if position_m is not None \
                else np.arange(n, dtype=np.int64)
            starts = block_starts(n, self.size)
            owner = owner_of_particle(order, starts)
            meta = dict(n=n, starts=starts, nb=net.problem.n_boundaries,
                        has_source=net.problem.source is not None,
                        cut=cut_contacts(net.problem.pair, net.problem.conductance_w_k, owner),
                        active_contacts=int(net.n_active_contacts))
            del owner
        meta = self.mpi.bcast(meta, root=0)
        if self.rank == 0:
            new_index = np.empty(meta["n"], dtype=np.int64)  # packing index -> place in order
            new_index[order] = np.arange(meta["n"], dtype=np.int64)
            starts = meta["starts"]
            for r in range(1, self.size):             # one share at a time: rank 0's peak is
                share = _share(net, order, new_index,  # its own network + one share
                               int(starts[r]), int(starts[r + 1]))
                # the receivers expect _share_keys(), in sorted order, one array a message
                assert sorted(share) == sorted(_share_keys()), sorted(share)
                for key in sorted(share):             # (< 2 GiB each)
                    self.mpi.send(share[key], dest=r, tag=_SHARE_TAG)
                del share
            own = _share(net, order, new_index, 0, int(starts[1]))
            del new_index, order
        else:
            keys = sorted(_share_keys())
            own = {key: self.mpi.recv(source=0, tag=_SHARE_TAG) for key in keys}
        return meta, own

    # ------------------------------------------------------------------ building blocks
    def _mat(self, block: sp.csr_matrix):
        PETSc = self.PETSc
        m = PETSc.Mat().createAIJ(
            size=((self.n_local, self.n), (self.n_local, self.n)), comm=self.comm,
            csr=(block.indptr.astype(PETSc.IntType), block.indices.astype(PETSc.IntType),
                 block.data))
        m.setOption(PETSc.Mat.Option.SYMMETRIC, True)
        m.setOption(PETSc.Mat.Option.SPD, True)
        m.assemble()
        return m

    def matrix(self, diag_add: np.ndarray, scale: float, unknown: np.ndarray):
        """diag(diag_add) + scale A with the rows and columns outside ``unknown`` (this rank's
        rows) replaced by the identity: SPD, those columns eliminated (MatZeroRowsColumns
        finds them on the other ranks too)."""
        data = scale * self.block.data
        data[self._diag_pos] += diag_add
        m = self._mat(sp.csr_matrix((data, self.block.indices, self.block.indptr),
                                    shape=self.block.shape))
        m.zeroRowsColumns(np.flatnonzero(~unknown).astype(self.PETSc.IntType) + self.lo,
                          diag=1.0)
        return m

    def matvec(self, t_local: np.ndarray) -> np.ndarray:
        """(A T) on this rank's rows, T given on them (the neighbours' values come over MPI)."""
        self.x.getArray()[:] = t_local
        self.A.mult(self.x, self.y)
        return self.y.getArray().copy()

    def partial_flows(self, t_local, at_local) -> np.ndarray:
        """(B,) this rank's part of the heat entering through each boundary (held rows and
        exchange rows it owns; without the constant power and the source, which rank 0 adds):
        the terms of Network.boundary_heat_flow."""
        out = np.zeros(self.nb)
        if self.fixed_local.size:
            fl = self.fixed_local
            lt = at_local[fl] - self.g[fl] * t_local[fl]          # (L T)_p = (A T)_p - g_p T_p
            out += np.bincount(self.fixed_boundary, weights=lt, minlength=self.nb)
        if self.ex_local.size:
            q = self.ex_g * (self.ex_t - t_local[self.ex_local])
            out += np.bincount(self.ex_b, weights=q, minlength=self.nb)
            on_held = self.ex_held_b >= 0
            if on_held.any():
                out -= np.bincount(self.ex_held_b[on_held], weights=q[on_held],
                                   minlength=self.nb)
        return out

    def total(self, partial: np.ndarray) -> np.ndarray:
        return self.mpi.allreduce(partial)

    def start_rows(self, T_whole, ref_whole):
        """This rank's rows of a transient run's start, collective: ``T_whole`` (rank 0, from
        :func:`~.common.start_parts`) scattered; from a state its ledger's reference
        ``ref_whole`` too (None: an array's start, whose held rows this rank sets, booking the
        energy that takes, :func:`~.common.hold_start`, and whose reference is T before it).
        Returns (T, T_ref, this rank's part of the ledger (B,)): rank 0 holds no copy of
        either."""
        tl = self.scatter(T_whole)
        if self.mpi.bcast(ref_whole is not None if self.rank == 0 else None, root=0):
            return tl, self.scatter(ref_whole), np.zeros(self.nb)
        ref_local = tl.copy()
        fl = self.fixed_local
        energy = hold_start(tl, fl, self.fixed_boundary, self.capacity[fl], self.held_t[fl],
                            self.nb)
        return tl, ref_local, energy

    def output_terms(self, t_local, ref_local, sw_local) -> np.ndarray:
        """(B + 1,) this rank's part of what a run records besides the temperatures: the
        boundaries' heat flows at ``t_local`` (the terms of Network.boundary_heat_flow on its
        rows, the source's powers ``sw_local`` on them included, if any; rank 0 adds the
        constant power) and the stored energy sum C (T - T_ref) over its rows (NaN without
        ``ref_local``). Collective (the mat-vec)."""
        flow = self.partial_flows(t_local, self.matvec(t_local))
        if sw_local is not None:
            self.source_ledger(flow, sw_local, 1.0)
        stored = (math.nan if ref_local is None
                  else float(np.dot(self.capacity, t_local - ref_local)))
        return np.append(flow, stored)

    def gather(self, t_local: np.ndarray):
        """The whole (N,) array in the packing's order on rank 0 (None elsewhere), through the
        particles' directories (no rank holds the order)."""
        return self.routes.gather(t_local)

    def scatter(self, whole) -> np.ndarray:
        """This rank's rows of an (N,) array given on rank 0 in the packing's order."""
        return self.routes.scatter(whole)

    def on_root(self, fn):
        return on_root(self.mpi, fn)

    def preconditioner(self, pc: str) -> str:
        """``pc``, or the user's ``-pc_type`` of PETSC_OPTIONS (which then gets the hypre
        options below too, and names the run's linear solver)."""
        return self.PETSc.Options().getString("pc_type", pc)

    def ksp(self, matrix, tol: float, pc: str, maxiter: int = 5000):
        PETSc = self.PETSc
        if pc not in PRECONDITIONERS:
            raise ValueError(f"preconditioner = {pc!r}: use one of {', '.join(PRECONDITIONERS)}")
        ksp = PETSc.KSP().create(self.comm)
        ksp.setOperators(matrix)
        ksp.setType("cg")
        ksp.getPC().setType(pc)
        if pc == "hypre":
            opts = PETSc.Options()
            for key, value in HYPRE_OPTIONS.items():
                if not opts.hasName(key):           # PETSC_OPTIONS of the user win
                    opts.setValue(key, value)
        ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
        ksp.setTolerances(rtol=tol, atol=0.0, max_it=maxiter)
        ksp.setFromOptions()                        # PETSC_OPTIONS="-pc_type ..." etc.
        ksp.setUp()
        return ksp

    def solve(self, ksp, rhs_local: np.ndarray, iterations: list) -> np.ndarray:
        b = ksp.getOperators()[0].createVecLeft()
        b.getArray()[:] = rhs_local
        x = b.duplicate()
        x.set(0.0)
        if self.mpi.allreduce(float(np.dot(rhs_local, rhs_local))) == 0.0:
            iterations.append(0)
            return np.zeros_like(rhs_local)
        ksp.solve(b, x)
        iterations.append(int(ksp.getIterationNumber()))
        if ksp.getConvergedReason() < 0:
            raise RuntimeError(f"PETSc CG ({ksp.getPC().getType()}) did not converge: reason "
                               f"{ksp.getConvergedReason()} after {ksp.getIterationNumber()} "
                               f"iterations (tolerance {ksp.getTolerances()[0]:g})")
        return x.getArray().copy()

    def info(self) -> dict:
        return dict(backend="petsc", ranks=self.size, order="morton",
                    cut_contacts=int(self.cut), partition_seconds=self.setup_seconds)


class RankAbort(RuntimeError):
    """Raised on the other ranks when rank 0's part failed (rank 0 raises its own error)."""


def on_root(mpi_comm, fn):
    """``fn()`` on rank 0 of the mpi4py communicator, its (small) result on every rank. An
    exception it raises is raised on rank 0 as it is and on the others as :class:`RankAbort`
    with its message (so none waits for the others in a collective; an exception need not
    pickle)."""
    value, error = None, None
    if mpi_comm.Get_rank() == 0:
        try:
            value = fn()
        except Exception as e:              # noqa: BLE001 (re-raised below, on every rank)
            error = e
    sent, message = mpi_comm.bcast(
        (value, None) if error is None else (None, str(error) or type(error).__name__),
        root=0)
    if error is not None:
        raise error
    if message is not None:
        raise RankAbort(message)
    return sent


def _share_keys():
    return ("mine", "lo", "indptr", "indices", "data", "capacity", "held", "held_t", "g", "b",
            "tied", "fixed_local", "fixed_boundary", "ex_local", "ex_g", "ex_t", "ex_b",
            "ex_held_b")


def _record(dist, rec, k, t_local, ref_local, energy_partial, src_energy, tk, const_b):
    """Output time ``k`` (``tk`` s): the ledger, the flows and the stored energy summed over
    the ranks' rows (one reduction; rank 0 adds the constant power ``const_b``), the
    temperatures gathered; rank 0 records them in ``rec``. Collective."""
    nb = dist.nb
    sums = dist.total(np.concatenate([energy_partial, dist.output_terms(
        t_local, ref_local, dist.source_powers(tk, tk))]))
    T = dist.gather(t_local)
    if dist.rank == 0:
        rec.record(k, T, sums[:nb], src_energy, flow_w=sums[nb:2 * nb] + const_b,
                   stored_j=sums[2 * nb])


def _land():
    from mpi4py import MPI
    return MPI.LAND


# ----------------------------------------------------------------------------- explicit
def run_explicit(dist: DistributedNetwork, T0, times, *, t_start=None, dt=None, safety=0.9,
                 allow_unstable=False, progress=None, on_output=None) -> ThermalResult | None:
    """Forward Euler on the ranks; the in-process :func:`~.explicit.run_explicit`'s arguments
    and result (on rank 0; None on the others). ``T0`` matters on rank 0 only. Collective.
    ``on_output(k, t, T)`` (rank 0): the temperatures at each output time go there instead of
    into the result (the in-process ``keep_temperatures=False``)."""
    start = {}

    def prelude():
        T, t, step0, energy0, src, ref, state_dt = start_parts(T0, t_start, dist.net.n)
        times_c, dt_, flags = explicit_schedule(dist.net, t, state_dt, times, dt, safety,
                                                allow_unstable)
        start.update(T=T, ref=ref, energy0=energy0)
        return dict(t=t, step0=step0, src=src, dt=dt_, flags=flags, times=times_c)

    p = dist.on_root(prelude)
    times, dt, t = p["times"], p["dt"], p["t"]
    net = dist.net
    tl, ref_l, energy = dist.start_rows(start.pop("T", None), start.pop("ref", None))
    if start.get("energy0") is not None:          # rank 0: a state's ledger
        energy += start["energy0"]
    const_b = _constant_flows(dist)
    rec = Recorder(net, times, None, on_output is None, on_output) if dist.rank == 0 else None
    src = [p["src"]]
    plan = step_plan(times, t, dt)
    n_total = sum(n for n, _ in plan)
    inv_c_free = np.where(dist.free, 1.0 / dist.capacity, 0.0)   # held rows: no change
    step_seconds, done = 0.0, 0
    dist.comm.barrier()
    wall0 = last_report = time.perf_counter()
    t_prev = t
    for k, (tk, (n, h)) in enumerate(zip(times, plan)):
        tk = float(tk)
        w = h * inv_c_free
        c0 = time.perf_counter()
        for s in range(n):
            t0 = t_prev + s * h
            t1 = tk if s == n - 1 else t_prev + (s + 1) * h
            sw_local = dist.source_powers(t0, t1)
            if sw_local is not None:
                src[0] += h * dist.source_total(sw_local)
                dist.source_ledger(energy, sw_local, h)
            at = dist.matvec(tl)
            energy += h * (dist.partial_flows(tl, at) + const_b)
            rhs = dist.b - at if sw_local is None else dist.b + sw_local - at
            tl += w * rhs
            done += 1
            if progress is not None and dist.rank == 0 and (
                    time.perf_counter() - last_report > 0.1 or done == n_total):
                last_report = time.perf_counter()      # ~0.1 s apart, as in-process
                progress(done, n_total, t1)
        step_seconds += time.perf_counter() - c0
        t_prev = tk
        _record(dist, rec, k, tl, ref_l, energy, src[0], tk, const_b)
    wall = time.perf_counter() - wall0
    end = _end_of_run(dist, tl, ref_l, energy, p["flags"])
    if end is None:
        return None
    T_end, ref, energy_total, flags = end
    prob = net.problem
    state = SolverState(temperature_k=T_end, time_s=float(times[-1]), step=p["step0"] + done,
                        boundary_energy_j=energy_total, source_energy_j=src[0],
                        reference_temperature_k=ref, dt_s=dt, method="explicit")
    cups = net.n_active_contacts * done / step_seconds if step_seconds > 0 else float("nan")
    return ThermalResult(
        method="explicit", times=times, temperature_k=rec.T, boundary_heat_flow_w=rec.flow,
        boundary_energy_j=rec.energy, source_energy_j=rec.source, stored_energy_j=rec.stored,
        boundary_names=prob.boundary_names, source_boundary=prob.source_boundary, dt=dt,
        dt_max=net.dt_max_s, dt_paper=net.dt_paper_s, steps=done, wall_seconds=wall,
        contact_updates_per_second=cups, flags=tuple(flags),
        info=dict(step_seconds=step_seconds, clusters=net.clusters.summary(),
                  steps_per_interval=[n for n, _ in plan], dt_per_interval=[h for _, h in plan],
                  dt_max_particle=net.dt_max_particle, **dist.info()),
        state=state)


def _constant_flows(dist) -> np.ndarray:
    """(B,) what rank 0 adds to the ranks' summed flows and ledger: the constant power of each
    boundary (Network.constant_boundary_flow_w; zeros on the other ranks)."""
    if dist.rank != 0:
        return np.zeros(dist.nb)
    return np.asarray(dist.net.constant_boundary_flow_w, dtype=np.float64)


def _end_of_run(dist, tl, ref_local, energy, flags):
    """The end of a time-stepping run on the ranks (explicit and implicit), collective: whether
    every rank's temperatures are finite, the boundaries' energies summed, the temperatures and
    the ledger's reference gathered (the run's state). On rank 0 (T_end, T_ref, energy_total,
    flags + non_finite if any was not), else None."""
    finite = dist.mpi.allreduce(bool(np.all(np.isfinite(tl))), op=_land())
    energy_total = dist.total(energy)
    T_end = dist.gather(tl)
    ref = dist.gather(ref_local)
    if dist.rank != 0:
        return None
    return T_end, ref, energy_total, list(flags) + ([] if finite else ["non_finite"])


# ----------------------------------------------------------------------------- implicit
class _Increment:
    """One matrix's CG + preconditioner: ``solve(r)`` the increment, 0 on the held rows."""

    def __init__(self, dist, ksp, iterations):
        self.dist, self.ksp, self.iterations = dist, ksp, iterations

    def solve(self, r):
        return np.where(self.dist.free, self.dist.solve(self.ksp, r, self.iterations), 0.0)


class DistributedOperator:
    """This rank's rows for the one implicit time loop, :func:`~.implicit.drive_implicit`
    (the in-process :class:`~.implicit.LocalOperator`'s interface): the unknowns are this
    rank's temperatures (held rows kept at their temperature, their increment 0), the matrices
    MPIAIJ, each solved by CG + ``pc``; the ledger's partial sums meet at the output times."""

    def __init__(self, dist: DistributedNetwork, tol, pc, on_output=None):
        self.dist, self.tol, self.pc = dist, tol, pc
        self.on_output = on_output       # rank 0: the temperatures go there, not kept
        self.net = dist.net
        self.is_root = dist.rank == 0
        self.iterations: list = []
        self.capacity = dist.capacity
        self.recorder = None

    def start(self, T0, t_start, times):
        dist, start = self.dist, {}

        def prelude():
            T, t, step0, energy0, src, ref, _ = start_parts(T0, t_start, dist.net.n)
            start.update(T=T, ref=ref, energy0=energy0)
            return dict(t=t, step0=step0, src=src, flags=list(dist.net.flags),
                        times=check_times(times, t))

        p = dist.on_root(prelude)
        self.t_local, self.ref_local, self.energy0 = dist.start_rows(start.pop("T", None),
                                                                     start.pop("ref", None))
        if start.get("energy0") is not None:      # rank 0: a state's ledger
            self.energy0 += start["energy0"]
        self.const_b = _constant_flows(dist)
        if self.is_root:
            self.recorder = Recorder(self.net, p["times"], None, self.on_output is None,
                                     self.on_output)
        return p["times"], p["t"], p["step0"], p["src"], p["flags"]

    def setup(self):
        pass

    def unknowns(self):
        t_local, self.t_local = self.t_local, None
        return t_local, self.energy0

    def factor(self, h, th):
        dist = self.dist
        return _Increment(dist, dist.ksp(dist.matrix(self.capacity / h, th, dist.free),
                                         self.tol, self.pc), self.iterations)

    def free_only(self, v):
        return np.where(self.dist.free, v, 0.0)

    def rhs(self, tl, sw):
        """F(T) = b + S - A T on the free rows, 0 on the held ones (as -K T_f - L_fd T_d + b_f
        + S_f in-process: A T on a free row is K_ff T_f + L_fd T_d)."""
        r = self.dist.b - self.dist.matvec(tl)
        if sw is not None:
            r = r + sw
        return np.where(self.dist.free, r, 0.0)

    def source(self, t0, t1):
        """This rank's rows of the source's powers (W), or None without a source."""
        return self.dist.source_powers(t0, t1)

    def source_power(self, sw):
        return self.dist.source_total(sw)

    def ledger(self, energy, h, tl, sw):
        """This rank's part of the heat through the boundaries over ``h`` (the held rows at
        their temperature); the source's on rank 0."""
        dist = self.dist
        tl = np.where(dist.free, tl, dist.held_t)
        energy += h * (dist.partial_flows(tl, dist.matvec(tl)) + self.const_b)
        if sw is not None:
            self.dist.source_ledger(energy, sw, h)

    def record(self, k, tl, energy, src_energy, tk):
        _record(self.dist, self.recorder, k, tl, self.ref_local, energy, src_energy, tk,
                self.const_b)

    def barrier(self):
        self.dist.comm.barrier()

    def finish(self, tl, energy, flags):
        """(T at the end, the ledger, flags) on rank 0 (None elsewhere); ``ref`` becomes the
        ledger's whole reference there (the run's state)."""
        end = _end_of_run(self.dist, tl, self.ref_local, energy, flags)
        if end is None:
            return None
        T_end, self.ref, energy_total, flags = end
        return T_end, energy_total, flags

    def solver_info(self, solvers):
        return dict(linear_solver=f"petsc-cg-{self.pc}", cg_iterations=self.iterations,
                    **self.dist.info())


def run_implicit(dist: DistributedNetwork, T0, times, *, dt, theta=1.0, scheme="theta",
                 startup_steps=None, t_start=None, tol=1e-12, pc="gamg",
                 progress=None, on_output=None) -> ThermalResult | None:
    """theta / Rannacher / TR-BDF2 on the ranks: the in-process time loop
    (:func:`~.implicit.drive_implicit`) over this rank's rows, each increment solved by
    PETSc's CG + ``pc`` to the relative residual ``tol``. Result on rank 0 (None elsewhere).
    Collective."""
    theta, startup_steps = scheme_args(scheme, theta, startup_steps)
    op = DistributedOperator(dist, tol, dist.preconditioner(pc), on_output)
    return drive_implicit(op, T0, times, dt=dt, theta=theta, scheme=scheme,
                          startup_steps=startup_steps, t_start=t_start, progress=progress)


# ----------------------------------------------------------------------------- steady
def solve_steady(dist: DistributedNetwork, T0=None, *, tol=1e-12, pc="gamg",
                 source_interval=None, maxiter=5000) -> ThermalResult | None:
    """The in-process :func:`~.steady.solve_steady` on the ranks: (L + G) T = b for the free
    particles of tied clusters by CG + ``pc`` (relative residual ``tol``), the deviation from
    T_ref solved for as in-process; the boundaries' flows and the stored energy summed over the
    ranks' rows; floating clusters and rattlers on rank 0 as in-process, from the network's
    untied particles (``dist.net.untied`` of a NetworkSummary, or the whole network) and their
    powers, gathered. ``T0`` matters on rank 0 only. Result on rank 0 (None elsewhere).
    Collective."""
    pc = dist.preconditioner(pc)
    dist.comm.barrier()
    wall0 = time.perf_counter()
    start = {}

    def prelude():
        t_ref, t0, flags = steady_start(dist.net, T0, source_interval, dist.has_source)
        start.update(T0=t0)
        return dict(t_ref=t_ref, flags=flags, has_T0=t0 is not None)

    p = dist.on_root(prelude)
    t_ref = p["t_ref"]
    sw = (dist.source_powers(*source_interval) if dist.has_source and
          source_interval is not None else None)       # this rank's rows
    b_local = dist.b if sw is None else dist.b + sw
    unknown = ~dist.held & dist.tied                     # this rank's rows
    t_d = np.where(dist.held, dist.held_t - t_ref, 0.0)
    # rhs_u = b_u - (L t_d)_u - T_ref g_u; on a free row (A t_d) = (L t_d) (t_d = 0 there)
    rhs = np.where(unknown, b_local - dist.matvec(t_d) - t_ref * dist.g, 0.0)
    iterations: list = []
    n_unknowns = int(dist.mpi.allreduce(int(np.count_nonzero(unknown))))
    if n_unknowns:
        ksp = dist.ksp(dist.matrix(np.zeros(dist.n_local), 1.0, unknown), tol, pc, maxiter)
        x = dist.solve(ksp, rhs, iterations)
    else:
        x = np.zeros(dist.n_local)
    # the untied rows stay 0 here: no flow passes them (a held particle's neighbours are tied,
    # an untied particle's exchange rows have g = 0); rank 0 sets them below
    t_local = np.where(dist.held, dist.held_t, np.where(unknown, t_ref + x, 0.0))
    tied = dist.tied
    # the stored energy over the tied rows here (the untied ones, 0 in both, add nothing)
    t0_local = (np.where(tied, dist.scatter(start.get("T0")), 0.0) if p["has_T0"]
                else None)
    sums = dist.total(dist.output_terms(t_local, t0_local, sw))
    source_total = dist.source_total(sw) if sw is not None else None
    untied_b = dist.mpi.gather((dist.mine[~tied], b_local[~tied]), root=0)
    T = dist.gather(t_local)
    if dist.rank != 0:
        return None
    net = dist.net
    flags, T0 = list(p["flags"]), start["T0"]
    u = net.untied if isinstance(net, NetworkSummary) else untied_of(net)
    got = np.concatenate([q[0] for q in untied_b])
    b_untied = np.empty(u.particle.size)
    b_untied[np.searchsorted(u.particle, got)] = np.concatenate([q[1] for q in untied_b])
    no_steady = fill_untied(u, T, T0, b_untied, t_ref, flags)
    if T0 is not None:      # the untied particles' part of sum C (T - T0)
        sel = u.particle
        sums[-1] += float(np.dot(u.capacity_j_k, T[sel] - T0[sel]))
    return steady_result(net, T, T0, None, flags, time.perf_counter() - wall0, no_steady,
                         flow_w=sums[:-1] + _constant_flows(dist), stored_j=sums[-1],
                         source_total_w=source_total, linear_solver=f"petsc-cg-{pc}",
                         tol=tol, unknowns=n_unknowns, t_ref=t_ref, cg_iterations=iterations,
                         **dist.info())


__all__ = ["DistributedNetwork", "on_root", "run_explicit", "run_implicit", "solve_steady",
           "PRECONDITIONERS", "HYPRE_OPTIONS"]
