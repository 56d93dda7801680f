"""For the scripts run under mpirun (tests/mpi_*_check.py): a failure on one rank (an assertion
of rank 0's, say) aborts every rank, so that the test sees a non-zero exit instead of the other
ranks waiting in a collective for ever."""
import sys
import traceback


def run(main, *args):
    try:
        return main(*args)
    except BaseException:           # noqa: BLE001 (printed, then every rank stops)
        traceback.print_exc()
        sys.stdout.flush()
        sys.stderr.flush()
        from mpi4py import MPI
        MPI.COMM_WORLD.Abort(3)
