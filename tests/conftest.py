"""Test-suite set-up shared by every test module.

Threading layer: the suite is an entry point like ``tdem``: it makes the same numba
threading-layer choice (OpenMP first, a NUMBA_THREADING_LAYER* setting of yours wins) before any
test compiles a parallel kernel, so the kernels called directly here run on the layer ``tdem``
uses.

Markers (registered in pyproject.toml): ``yade`` / ``liggghts`` / ``petsc`` (they run Debian's
YADE, LIGGGHTS or the PETSc backend for real) and ``slow`` (over ~1.3 s each: whole runs
through ``tdem`` subprocesses, campaigns, the quick validation cases) are set where the tests
are, ``@pytest.mark.slow`` on the function with a comment saying why (``pytestmark`` for a
module that is wholly slow). The day-to-day subset is ``make test-fast``, i.e.
``pytest -m "not yade and not liggghts and not slow"``; ``make test`` runs everything.

``jit_only`` (also set here, from JIT_ONLY): tests of what only numba's compiled kernels do, skipped
when NUMBA_DISABLE_JIT=1 (the coverage run of docs/solvers.md, where the kernels run as Python).
"""
import warnings

import pytest

from thermal_kernel.threading_layer import prefer_openmp

# Skipped under NUMBA_DISABLE_JIT=1, each for a stated reason. Entries: a function, or one case
# of it as pytest names it ("function[id]").
JIT_ONLY = {
    # the explicit run it kills mid-way takes minutes as Python (208 s, against 5 s compiled)
    "test_checkpoint.py": ["test_killed_run_resumes_to_the_same_bits"],
    # a diverging run must print no RuntimeWarning: true of the compiled kernel; as Python, numpy
    # scalars warn on overflow
    "test_hard_cases.py": ["test_explicit_dt_at_multiples_of_the_bound[2.5]",
                           "test_explicit_dt_above_the_bound_from_the_command_line[True]"],
    # threading layers exist only for compiled parallel kernels
    "test_threading_layer.py": [
        "test_tdem_uses_openmp_the_users_layer_wins_and_the_bits_do_not_change"],
}


def pytest_configure(config):
    prefer_openmp()


def _mark(items, table, marker):
    """Add ``marker`` to the items ``table`` names; return the names that matched nothing in a
    collected module."""
    found = set()
    for item in items:
        module = item.path.name
        names = table.get(module, ())
        for name in (item.name, getattr(item, "originalname", item.name)):
            if names == "*" or name in names:
                item.add_marker(marker)
                found.add((module, name))
                break
    collected = {item.path.name for item in items}
    return [f"{m}::{n}" for m, names in table.items() if m in collected and names != "*"
            for n in names if (m, n) not in found]


def pytest_collection_modifyitems(config, items):
    import numba
    skip = pytest.mark.skip(reason="NUMBA_DISABLE_JIT=1: tests what only the compiled kernels "
                                   "do (tests/conftest.py JIT_ONLY)")
    missing = _mark(items, JIT_ONLY, pytest.mark.jit_only)
    if numba.config.DISABLE_JIT:
        for item in items:
            if item.get_closest_marker("jit_only"):
                item.add_marker(skip)
    whole_modules = all("::" not in arg for arg in config.args)
    if missing and whole_modules and not config.getoption("keyword"):
        warnings.warn("tests/conftest.py names tests that were not collected: "
                      + ", ".join(missing), pytest.PytestWarning, stacklevel=1)
