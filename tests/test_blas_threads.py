"""thermal_kernel.solvers.blas_threads: every BLAS library loaded (numpy's and scipy's OpenBLAS)
runs with the given thread count inside, and gets its own count back after (threadpoolctl)."""
import scipy.sparse.linalg  # noqa: F401  (loads scipy's OpenBLAS next to numpy's)
from threadpoolctl import threadpool_info

from thermal_kernel.solvers import blas_threads


def _blas():
    return [(i["filepath"], i["num_threads"]) for i in threadpool_info() if i["user_api"] == "blas"]


def test_one_thread_inside_and_restored_after():
    before = _blas()
    assert before, "no BLAS library found by threadpoolctl"
    with blas_threads(1):
        assert [n for _, n in _blas()] == [1] * len(before)
    assert _blas() == before
    with blas_threads(None):        # None: left as it is
        assert _blas() == before
    try:
        with blas_threads(1):
            raise RuntimeError("a failing solve")
    except RuntimeError:
        pass
    assert _blas() == before
