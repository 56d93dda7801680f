"""numba's threading layer for the explicit kernel: a choice for entry points to make.

One explicit step is one parallel loop, so its fork/join cost is paid every step; numba's default
order puts TBB first, and TBB's fork/join cost 130-500 us a step here against ~2 us for OpenMP,
which made 2 threads 10-25x slower than 1 below ~1e5 particles (measured: docs/solvers.md). The
entry points (``tdem`` in tdem/cli.py, the test suite's conftest, the scripts' ``__main__``)
call :func:`prefer_openmp` before any parallel kernel is compiled; importing a library module
changes nothing. The kernels' results are bit-identical whatever the layer or thread count.
"""
from __future__ import annotations

import os
import sys

PRIORITY = ("omp", "tbb", "workqueue")


def prefer_openmp(environ=None) -> None:
    """Ask numba for the OpenMP layer first (TBB, then workqueue, where OpenMP is missing),
    unless the user set any ``NUMBA_THREADING_LAYER*`` variable (or numba's config file chose a
    layer): theirs wins.

    Sets ``NUMBA_THREADING_LAYER_PRIORITY`` in ``environ`` (default: this process's environment,
    so that numba reads it when first imported, without importing numba here: ``tdem pack`` and
    ``tdem info`` never need it), and numba's config too if numba is already imported. The layer
    is fixed when the first parallel kernel runs; calling this later has no effect."""
    env = os.environ if environ is None else environ
    if any(k.startswith("NUMBA_THREADING_LAYER") for k in env):
        return
    numba = sys.modules.get("numba") if environ is None else None
    if numba is not None and numba.config.THREADING_LAYER != "default":
        return
    env["NUMBA_THREADING_LAYER_PRIORITY"] = " ".join(PRIORITY)
    if numba is not None:
        numba.config.THREADING_LAYER_PRIORITY = list(PRIORITY)
