"""Run under mpirun (tests/test_petsc_backend.py): the steady solve on the ranks
(thermal_kernel.solvers.petsc_backend.solve_steady) against the in-process one
(thermal_kernel.solvers.steady.solve_steady) on a network made to exercise what rank 0 does
from the untied particles alone (rank 0 holding the network's NetworkSummary, as in a run of
thermal_kernel.mpi_run): floating clusters and rattlers scattered over the ranks' blocks, one
cluster with a zero net power (its zero-net part solved for), one with a net power and a
rattler with a power (no steady state: flagged), the others keeping the capacity-weighted mean
of their start.

Prints "steady OK <ranks>" on rank 0 when every check passed.
"""
import sys

import numpy as np
from petsc4py import PETSc

from thermal_kernel.network import assemble, make_problem, summary_of
from thermal_kernel.solvers import petsc_backend as backend
from thermal_kernel.solvers.steady import solve_steady


def network(rng):
    """(problem, centres, start): a tied block of 300 particles (a chain plus random contacts,
    two held ends), floating clusters of 10, 6 and 4 particles and 5 rattlers, the particles'
    numbers shuffled (so that every rank's block holds some of each)."""
    n_tied, sizes, n_ratt = 300, (10, 6, 4), 5
    n = n_tied + sum(sizes) + n_ratt
    pairs = [(i, i + 1) for i in range(n_tied - 1)]
    extra = rng.integers(0, n_tied, size=(400, 2))
    pairs += [tuple(sorted(p)) for p in extra if p[0] != p[1]]
    start = n_tied
    clusters = []
    for s in sizes:
        members = list(range(start, start + s))
        pairs += [(members[k], members[k + 1]) for k in range(s - 1)]
        pairs += [(members[0], members[-1])]
        clusters.append(members)
        start += s
    rattlers = list(range(start, start + n_ratt))
    pairs = np.unique(np.array(pairs, dtype=np.int64), axis=0)
    perm = rng.permutation(n)                  # particle k of the layout is perm[k]
    pairs = np.sort(perm[pairs], axis=1)
    pairs = np.unique(pairs, axis=0)
    h = rng.uniform(0.5, 2.0, pairs.shape[0])
    capacity = rng.uniform(1.0, 3.0, n)
    a, b, c = clusters
    power_p = [a[1], a[5], b[2], rattlers[1]]
    power_w = [1.5, -1.5, 2.0, 0.5]            # a: zero net; b: net; a rattler: net
    problem = make_problem(capacity, pairs, h,
                           fixed=(perm[[0, n_tied - 1]], [400.0, 300.0], [0, 1]),
                           power=(perm[power_p], power_w, [2, 2, 2, 2]),
                           boundary_names=("hot", "cold", "flux"))
    return problem, rng.random((n, 3)), rng.uniform(280.0, 420.0, n)


def main():
    comm = PETSc.COMM_WORLD
    rank, size = comm.getRank(), comm.getSize()
    problem, centres, T0 = network(np.random.default_rng(25))
    net = assemble(problem)
    dist = backend.DistributedNetwork(net if rank == 0 else None,
                                      centres if rank == 0 else None)
    if rank == 0:
        dist.net = summary_of(net)     # what rank 0 holds in mpi_run
    got = backend.solve_steady(dist, T0 if rank == 0 else None)
    if rank != 0:
        return
    want = solve_steady(net, T0)
    span = float(np.ptp(want.temperature_k))
    assert net.clusters.n_floating == 3 and net.clusters.n_rattlers == 5, net.clusters.summary()
    assert got.flags == want.flags, (got.flags, want.flags)
    assert "no_steady_state_in_floating_cluster" in got.flags
    assert got.info["no_steady_state"] == want.info["no_steady_state"], (
        got.info["no_steady_state"], want.info["no_steady_state"])
    err = float(np.abs(got.temperature_k - want.temperature_k).max())
    assert err <= 1e-10 * span, err
    # the untied particles as in-process to round-off (their solve is the same on rank 0)
    untied = ~net.clusters.tied_particle
    err_u = float(np.abs(got.temperature_k[0, untied] - want.temperature_k[0, untied]).max())
    assert err_u <= 1e-12 * span, err_u
    scale = float(np.abs(want.boundary_heat_flow_w).max())
    assert np.abs(got.boundary_heat_flow_w - want.boundary_heat_flow_w).max() <= 1e-9 * scale
    stored = float(np.abs(want.stored_energy_j).max())
    assert abs(float(got.stored_energy_j[0] - want.stored_energy_j[0])) <= 1e-9 * stored
    print(f"steady OK {size}", flush=True)


if __name__ == "__main__":
    from mpi_abort import run
    sys.exit(run(main))
