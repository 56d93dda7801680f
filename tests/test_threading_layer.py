"""numba's threading layer is chosen by the entry points (thermal_kernel/threading_layer.py),
not on import; a NUMBA_THREADING_LAYER* setting of the user wins; the explicit kernel's bits do
not depend on the layer (each particle sums its own row in column order: no reduction across
threads)."""
import os
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from thermal_kernel.threading_layer import PRIORITY, prefer_openmp

# `make coverage` counts this module (marker kernel: its subject is thermal_kernel, and it is
# fast enough with NUMBA_DISABLE_JIT=1)
pytestmark = pytest.mark.kernel

ROOT = Path(__file__).resolve().parent.parent

# `tdem run` in-process in a fresh interpreter, then the layer numba launched
RUN = """
import sys
from tdem import cli
code = cli.main(["run", "runs/bed_small.toml", "--packing", "tests/data/bed_small_4.05e+07Pa.h5",
                 "--out", sys.argv[1], "--quiet", "--threads", "2"])
import numba
print(code, numba.threading_layer())
"""


def _env(**extra):
    """This environment without any NUMBA_THREADING_LAYER* (the suite's conftest sets one)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_THREADING_LAYER")}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return dict(env, **extra)


def test_prefer_openmp_sets_the_priority_unless_the_user_chose():
    env = {"PATH": "/bin"}
    prefer_openmp(env)
    assert env["NUMBA_THREADING_LAYER_PRIORITY"] == " ".join(PRIORITY) == "omp tbb workqueue"
    for key, value in [("NUMBA_THREADING_LAYER", "tbb"),
                       ("NUMBA_THREADING_LAYER_PRIORITY", "workqueue omp tbb")]:
        env = {key: value}
        prefer_openmp(env)
        assert env == {key: value}


def test_importing_the_kernels_chooses_nothing():
    code = ("import numba, thermal_kernel.solvers.explicit, tdem.cli\n"
            "print(' '.join(numba.config.THREADING_LAYER_PRIORITY))")
    out = subprocess.run([sys.executable, "-c", code], env=_env(), capture_output=True,
                         text=True, cwd=ROOT, check=True).stdout.split()
    assert out == ["tbb", "omp", "workqueue"]      # numba's own default order


def _available(layer):
    probe = ("import numba, numpy as np\n"
             "@numba.njit(parallel=True)\n"
             "def f(a):\n"
             "    for i in numba.prange(a.size): a[i] = i\n"
             "f(np.zeros(4)); print(numba.threading_layer())")
    p = subprocess.run([sys.executable, "-c", probe], env=_env(NUMBA_THREADING_LAYER=layer),
                       capture_output=True, text=True)
    return p.returncode == 0 and p.stdout.strip() == layer


# slow: `tdem run` on the 300-sphere bed under each threading layer;
# over ~1.3 s on the shared 2-core machine, warm numba cache (--durations, 2026-12-01)
@pytest.mark.slow
def test_tdem_uses_openmp_the_users_layer_wins_and_the_bits_do_not_change(tmp_path):
    """`tdem run` (explicit, 2 threads) on the 300-sphere bed: OpenMP by default; with
    NUMBA_THREADING_LAYER set, that layer; the same temperatures and ledger to the bit."""
    import numba
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has fewer than 2 threads on this machine")
    cases = [("default", {}, "omp")] + [
        (layer, {"NUMBA_THREADING_LAYER": layer}, layer)
        for layer in ("tbb", "workqueue") if _available(layer)]
    results = {}
    for name, extra, expected in cases:
        out = tmp_path / name
        p = subprocess.run([sys.executable, "-c", RUN, str(out)], env=_env(**extra),
                           capture_output=True, text=True, cwd=ROOT)
        assert p.returncode == 0, p.stderr
        assert p.stdout.split()[-2:] == ["0", expected], p.stdout
        (h5,) = out.rglob("thermal.h5")
        with h5py.File(h5) as f:
            results[name] = {k: f[k][()] for k in ("temperature", "boundary_energy",
                                                   "stored_energy_change")}
    assert len(results) >= 2
    ref = results["default"]
    for name, got in results.items():
        for key in ref:
            assert np.array_equal(got[key], ref[key]), (name, key)
