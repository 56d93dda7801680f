"""Run under mpirun (tests/test_petsc_backend.py): the Morton order sorted on the ranks
(thermal_kernel/solvers/partition.py: morton_blocks_on_ranks) against the whole sort on every
centre (morton_order), and the routes between the ranks' blocks of the order and the file's
order (Routes) against indexing with the whole order, on centres made to break a sort: ties
(centres repeated, so equal keys), a flat axis, a cluster of centres in one corner, and fewer
particles than ranks (an empty block).

Prints "partition OK <ranks>" on rank 0 when every check passed.
"""
import sys

import numpy as np
from mpi4py import MPI

from thermal_kernel.morton import morton_order
from thermal_kernel.solvers.partition import Routes, block_starts, morton_blocks_on_ranks


def centres(kind, n, rng):
    x = rng.random((n, 3))
    if kind == "ties":             # every centre three times: equal keys across the ranks
        x = np.repeat(x[: n // 3 + 1], 3, axis=0)[:n]
        x = x[rng.permutation(n)]
    elif kind == "flat":           # a monolayer: the z bits all 0
        x[:, 2] = 0.5
    elif kind == "corner":         # most centres in one small cell: a long run of near keys
        x[: n - 5] *= 1e-7
    return x


def main():
    comm = MPI.COMM_WORLD
    rank, size = comm.Get_rank(), comm.Get_size()
    rng = np.random.default_rng(25)
    for kind, n in (("random", 10007), ("ties", 3001), ("flat", 2000), ("corner", 500),
                    ("random", size - 1), ("random", 0)):
        x = centres(kind, n, rng)          # the same on every rank (one seed)
        starts = block_starts(n, size)
        lo, hi = starts[rank], starts[rank + 1]
        order = morton_order(x) if n else np.zeros(0, np.int64)
        mine = morton_blocks_on_ranks(comm, x[lo:hi], starts)
        assert np.array_equal(mine, order[lo:hi]), (kind, n, rank)
        routes = Routes(comm, mine, starts)
        place = np.empty(n, np.int64)
        place[order] = np.arange(n)
        assert np.array_equal(routes.places(), place[lo:hi]), (kind, rank)
        values = rng.random(n)             # the same on every rank
        assert np.array_equal(routes.scatter(values if rank == 0 else None), values[mine])
        got = routes.gather(values[mine] * 2.0)
        if rank == 0:
            assert np.array_equal(got, values * 2.0), kind
        flags = (values > 0.5).astype(np.uint8)
        assert np.array_equal(routes.scatter(flags if rank == 0 else None, np.uint8),
                              flags[mine])
        two = np.stack([values, -values], axis=1)
        assert np.array_equal(routes.from_directories(two[lo:hi]), two[mine])
        assert np.array_equal(routes.to_directories(two[mine]), two[lo:hi])
    if rank == 0:
        print(f"partition OK {size}", flush=True)


if __name__ == "__main__":
    from mpi_abort import run
    sys.exit(run(main))
