"""Run under mpirun (tests/test_petsc_backend.py): the per-rank build (thermal_kernel/rank_build.py)
against the whole build on rank 0 (build_problem + assemble, each rank's share cut from it), on
the same ranks:

- each rank's block of the Morton order (sorted on the ranks, rank 0 sorting every centre) and
  its share -- its rows of A = L + diag(g) (CSR: indptr, indices, data), capacities,
  held flags and temperatures, g, b, tied flags, its held and exchange rows -- bit for bit;
- rank 0's NetworkSummary against the whole network's: the explicit bound and its particle,
  the conducting and zero-H contacts, the flags, the clusters' counts, the constant powers,
  the steady reference, the maximum principle's inputs, the untied particles with their
  Laplacian (bit for bit), dt_paper (its mean H summed in another order: 1e-14);
- a scene's ``[neighbours]`` criterion (thermal_kernel/neighbours.py): the choice made on the
  ranks with collectives -- the gap, the rows kept, the bulk Z's -- equal to the whole build's
  bit for bit (then the rows above, built from the kept rows and their neighbour counts);
- the steady temperatures of the backend on both builds (the same matrix: within 1e-12 of the
  change; PETSc's reductions on 3 ranks do not always sum in the same order).

Prints "rank_build OK <ranks> <contacts cut>" on rank 0 when every check passed.
"""
import sys

import numpy as np
import petsc4py
import scipy.sparse as sp

petsc4py.init([sys.argv[0]])
from petsc4py import PETSc  # noqa: E402

from thermal_kernel.network import assemble, summary_of  # noqa: E402
from thermal_kernel.packing import read_packing  # noqa: E402
from thermal_kernel.problem import build_problem  # noqa: E402
from thermal_kernel.rank_build import build_on_ranks  # noqa: E402
from thermal_kernel.scene import load_scene  # noqa: E402
from thermal_kernel.solvers import petsc_backend as backend  # noqa: E402
from thermal_kernel.solvers.partition import particle_order  # noqa: E402


def same(a, b, what):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape, (what, a.shape, b.shape)
    assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), what


def main(scene_path):
    comm = PETSc.COMM_WORLD.tompi4py()
    rank = comm.Get_rank()
    scene = load_scene(scene_path)
    whole = info = None
    if rank == 0:
        packing = read_packing(scene.packing)
        problem, info = build_problem(scene, packing)
        whole = assemble(problem)
    ref = backend.DistributedNetwork(whole, packing.position if rank == 0 else None)
    rb = build_on_ranks(scene, scene.packing, comm)
    mine = backend.DistributedNetwork(None, built=rb)
    for key in ("indptr", "indices", "data"):
        same(getattr(ref.block, key), getattr(mine.block, key), f"rank {rank}: A.{key}")
    # and both against A = L + diag(g) made by scipy from the whole network (the small scenes:
    # dense), its columns in the Morton order; a stored diagonal on every row
    dense = None
    if rank == 0:
        order = particle_order(packing.position, "morton")
        dense = (whole.laplacian + sp.diags(whole.exchange_g_w_k)).toarray()[order][:, order]
    dense = comm.bcast(dense, root=0)
    same(mine.block.toarray(), dense[mine.lo:mine.lo + mine.n_local], f"rank {rank}: A")
    assert mine._diag_pos.size == mine.n_local, rank
    same(ref.mine, mine.mine, f"rank {rank}: its block of the Morton order")
    for key in ("capacity", "held", "held_t", "g", "b", "tied", "fixed_local",
                "fixed_boundary", "ex_local", "ex_g", "ex_t", "ex_b", "ex_held_b"):
        same(getattr(ref, key), getattr(mine, key), f"rank {rank}: {key}")
    assert (ref.lo, ref.n_local, ref.cut, ref.n_active_contacts) == \
        (mine.lo, mine.n_local, mine.cut, mine.n_active_contacts), rank
    if rank == 0:
        # the [neighbours] choice: every number of it, to the bit (None: no criterion)
        mine_choice = rb.info["neighbours"]
        assert (info["neighbours"] is None) == (mine_choice is None) == (
            scene.neighbours is None)
        if mine_choice is not None:
            s1, s2 = info["neighbours"].summary(), mine_choice.summary()
            assert s1.keys() == s2.keys()
            for key in s1:
                assert s1[key] == s2[key] or (s1[key] != s1[key] and s2[key] != s2[key]), (
                    key, s1[key], s2[key])
                assert type(s1[key]) is type(s2[key]), (key, s1[key], s2[key])
            # rank 0's rows kept: the first slice of the whole build's
            keep = mine_choice.keep
            same(info["neighbours"].keep[:keep.size], keep, "neighbours.keep (rank 0's rows)")
            assert 0 < s1["n_kept"] < s1["n_dumped"], s1      # the criterion does cut rows
        # rank 0's NetworkSummary against the whole network's (summary_of): every number
        # bit for bit but the sums the ranks add up from their partial sums (dt_paper's mean
        # H and mean C, the steady reference, the constant powers: 1e-14)
        a, b = summary_of(whole), rb.net
        assert (a.n, a.dt_max_s, a.dt_max_particle, a.n_active_contacts, a.n_zero_contacts,
                a.flags, a.principle) == (
            b.n, b.dt_max_s, b.dt_max_particle, b.n_active_contacts, b.n_zero_contacts,
            b.flags, b.principle), (a, b)
        assert abs(a.dt_paper_s - b.dt_paper_s) <= 1e-14 * a.dt_paper_s
        assert abs(a.prescribed_mean_k - b.prescribed_mean_k) <= 1e-14 * a.prescribed_mean_k
        flows = np.abs(a.constant_boundary_flow_w - b.constant_boundary_flow_w)
        assert np.all(flows <= 1e-14 * np.abs(a.constant_boundary_flow_w).max(initial=0.0)), \
            (a.constant_boundary_flow_w, b.constant_boundary_flow_w)
        # the source stays on the ranks, each over its block (checked below)
        assert (a.problem.boundary_names, a.problem.source_boundary) == (
            b.problem.boundary_names, b.problem.source_boundary)
        assert b.problem.source is None
        assert (a.clusters.n_components, a.clusters.n_rattlers) == (
            b.clusters.n_components, b.clusters.n_rattlers)
        same(a.clusters.floating_sizes, b.clusters.floating_sizes, "clusters.floating_sizes")
        for key in ("particle", "label", "capacity_j_k"):
            same(getattr(a.untied, key), getattr(b.untied, key), f"untied.{key}")
        same(a.untied.laplacian.toarray(), b.untied.laplacian.toarray(), "untied.laplacian")
        assert a.untied.n_components == b.untied.n_components
        assert a.untied.particle.size == int((~whole.clusters.tied_particle).sum())
    # a source: each rank's, built by the kinds on its particles, gives the whole source's
    # powers over its block, bit for bit (a still and a moving window, an instant)
    has_source = comm.bcast(whole.problem.source is not None if rank == 0 else None, root=0)
    assert (rb.local_source is not None) == has_source, rank
    if has_source:
        for t0, t1 in ((0.0, 2.0), (0.3, 0.5), (0.5, 0.5), (1.0, 1.7)):
            powers = comm.bcast(whole.problem.source(t0, t1) if rank == 0 else None, root=0)
            same(rb.local_source(t0, t1), powers[rb.mine], f"rank {rank}: source {t0} {t1}")
    r1 = backend.solve_steady(ref, np.full(ref.n, 300.0) if rank == 0 else None)
    r2 = backend.solve_steady(mine, np.full(ref.n, 300.0) if rank == 0 else None)
    if rank == 0:
        # the same matrix and right-hand side; PETSc's reductions on 3 ranks need not sum in
        # the same order from one solve to the next (two solves of the whole build differ
        # alike), so the temperatures agree to round-off, not always to the bit
        t0 = 300.0
        diff = float(np.abs(r1.temperature_k - r2.temperature_k).max())
        change = float(np.abs(r1.temperature_k - t0).max())
        assert diff <= 1e-12 * change, ("steady temperatures", diff, change)
        print(f"rank_build OK {comm.Get_size()} {mine.cut}", flush=True)


if __name__ == "__main__":
    from mpi_abort import run
    run(main, sys.argv[1])
