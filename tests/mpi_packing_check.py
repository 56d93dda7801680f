"""Run under mpirun (tests/test_packing_ranks.py): thermal_kernel/packing_ranks.py's
read_packing_on_ranks against the whole reader, read_packing(path, contacts=False), on every
rank, for each packing file named on the command line. A file the whole reader refuses must be
refused with the same one-line message on every rank; a file it reads must give each rank its
block of the particles bit for bit, the same walls, wall contacts, domain, attributes, contact
count, scales and content hash.

Prints "packing_ranks OK <ranks> <files>" on rank 0 when every check passed, and a line
"<file>: <message or ok>" per file (rank 0) to show what was compared.
"""
import sys

import numpy as np
from mpi4py import MPI

from thermal_kernel.checkpoint import packing_sha256
from thermal_kernel.packing import PackingError, contact_check_scales, read_packing
from thermal_kernel.packing_ranks import read_packing_on_ranks
from thermal_kernel.solvers.partition import block_starts

HEAD_ARRAYS = ("pair", "overlap", "normal_force", "branch", "wall_point", "wall_normal",
               "wall_radius", "wall_particle", "wall_index", "wall_overlap",
               "wall_normal_force", "domain_lo", "domain_hi", "periodic", "contact_radius",
               "wall_contact_radius")


def same_array(a, b) -> bool:
    """Equal bit for bit: dtype, shape and bytes (None only to None)."""
    if a is None or b is None:
        return a is None and b is None
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def same_attrs(a, b) -> bool:
    """Equal attributes, NaN equal to NaN (pressure_pa may be NaN: none)."""
    return a.keys() == b.keys() and all(
        a[k] == b[k] or (isinstance(a[k], float) and isinstance(b[k], float)
                         and np.isnan(a[k]) and np.isnan(b[k])) for k in a)


def compare(comm, path) -> str:
    rank = comm.Get_rank()
    try:
        whole = read_packing(path, contacts=False)
        want = None
    except PackingError as e:
        whole, want = None, str(e)
    try:
        got = read_packing_on_ranks(path, comm)
        got_error = None
    except PackingError as e:
        got, got_error = None, str(e)
    assert got_error == want, (rank, path, want, got_error)
    if want is not None:
        return want
    lo, hi = got.starts[rank], got.starts[rank + 1]
    assert got.n_particles == whole.n_particles, (path, got.n_particles)
    # the blocks are the directories' (partition.block_starts), on every rank alike
    assert np.array_equal(got.starts, block_starts(whole.n_particles, comm.Get_size())), path
    for key in ("position", "radius", "phase"):
        assert same_array(got.block[key], getattr(whole, key)[lo:hi]), (path, rank, key)
    head = got.head
    for key in HEAD_ARRAYS:
        assert same_array(getattr(head, key), getattr(whole, key)), (path, key)
    assert head.wall_name == whole.wall_name and head.wall_kind == whole.wall_kind, path
    assert same_attrs(head.attrs, whole.attrs) and head.path == whole.path, path
    assert head.file_contacts == whole.file_contacts, path
    assert head.position.shape == (0, 3) and head.yade_id is None, path
    assert got.scales == contact_check_scales(whole.position, whole.domain_lo,
                                              whole.domain_hi), (path, got.scales)
    assert got.sha256 == packing_sha256(whole), path
    return "ok"


def main(paths):
    comm = MPI.COMM_WORLD
    for path in paths:
        verdict = compare(comm, path)
        if comm.Get_rank() == 0:
            print(f"{path}: {verdict}", flush=True)
    comm.Barrier()
    if comm.Get_rank() == 0:
        print(f"packing_ranks OK {comm.Get_size()} {len(paths)}", flush=True)


if __name__ == "__main__":
    from mpi_abort import run
    sys.exit(run(main, sys.argv[1:]))
