"""Test-suite set-up shared by every test module.

Threading layer: the suite is an entry point like ``tdem``: it makes the same numba
threading-layer choice (OpenMP first, a NUMBA_THREADING_LAYER* setting of yours wins) before any
test compiles a parallel kernel, so the kernels called directly here run on the layer ``tdem``
uses.

Markers: ``yade`` / ``liggghts`` (they run Debian's YADE or LIGGGHTS for real) are set where the
tests are; ``slow`` is set here, from SLOW below, so that the list of slow tests lives in one
place. The day-to-day subset is ``make test-fast``, i.e.
``pytest -m "not yade and not liggghts and not slow"``; ``make test`` runs everything.

``jit_only`` (also set here, from JIT_ONLY): tests of what only numba's compiled kernels do, skipped
when NUMBA_DISABLE_JIT=1 (the coverage run of docs/solvers.md, where the kernels run as Python).
"""
import warnings

import pytest

from thermal_kernel.threading_layer import prefer_openmp

# Tests that take more than ~1.3 s each on the shared 2-core machine with a warm numba cache
# (measured with --durations, 2026-12-01): whole thermal runs and resumes through `tdem`
# subprocesses, campaigns, the quick validation cases; and test_bad_inputs.py, a module of ~80
# one-second `tdem` subprocesses. Listed by module and function (every parametrised case of a
# function; "*": the whole module); a name that no longer exists is reported as a warning.
SLOW = {
    # every case runs `tdem` in a subprocess (~1 s each even when refused at once; ~90 s in all)
    "test_bad_inputs.py": "*",
    "test_calibrate.py": ["test_wrong_law_and_cli"],
    "test_campaign.py": ["test_seeds_campaign_runs_each_series_and_resumes",
                         "test_report_shows_each_runs_flags", "test_report_of_a_clean_campaign"],
    "test_checkpoint.py": ["test_resume_on_another_packing_of_the_same_size_is_refused",
                           "test_killed_run_resumes_to_the_same_bits",
                           "test_checkpoints_do_not_change_the_bits",
                           "test_resume_errors_are_one_line"],
    "test_etc_sweep.py": ["test_etc_command"],
    "test_export.py": ["test_export_with_the_temperatures_of_a_run"],
    "test_hard_cases.py": ["test_extreme_radii"],
    "test_import_campaign.py": ["test_not_with_pack_or_seeds"],
    # issue 28: whole campaigns run twice (11-18 s each on the shared machine)
    "test_round3_campaign.py": ["test_rerun_after_a_scene_edit_equals_a_fresh_campaign",
                                "test_rerun_after_a_packing_edit_recomputes_that_case_only",
                                "test_a_kept_run_is_posted_again_when_post_changed_or_its_file_is_bad"],
    # issue 25: each case runs mpirun (1-3 ranks of .venv-mpi, ~1.5 s to start); ~100 s in all
    # (22 tests, 2026-12-02, load ~5; 27 since the validation cases on ranks, ~55 s at load ~3)
    "test_petsc_backend.py": "*",
    "test_run_scenes.py": ["test_dt_above_the_bound_is_refused_with_the_bound"],
    "test_solvers.py": ["test_hard_case_default_dt_stays_positive_and_bound_is_tight"],
    "test_threading_layer.py": [
        "test_tdem_uses_openmp_the_users_layer_wins_and_the_bits_do_not_change"],
    "test_validation_inclusions.py": ["test_case8_quick_within_documented_error",
                                      "test_case9_quick_reference_and_error",
                                      "test_case10_quick_realisation_and_error"],
    "test_window.py": ["test_window_fit_of_a_campaign_case"],
}

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
    missing = _mark(items, SLOW, pytest.mark.slow)
    import numba
    skip = pytest.mark.skip(reason="NUMBA_DISABLE_JIT=1: tests what only the compiled kernels "
                                   "do (tests/conftest.py JIT_ONLY)")
    missing += _mark(items, JIT_ONLY, pytest.mark.jit_only)
    if numba.config.DISABLE_JIT:
        for item in items:
            if item.get_closest_marker("jit_only"):
                item.add_marker(skip)
    whole_modules = all("::" not in arg for arg in config.args)
    if missing and whole_modules and not config.getoption("keyword"):
        warnings.warn("tests/conftest.py names tests that were not collected: "
                      + ", ".join(missing), pytest.PytestWarning, stacklevel=1)
