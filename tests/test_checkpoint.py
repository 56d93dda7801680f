"""`tdem run --checkpoint-every K` and `--resume` (thermal_kernel/checkpoint.py).

Asserted: a run that writes checkpoints gives the same bits as one that does not (explicit and
Crank-Nicolson), and removes its checkpoint when it ends; a run killed (SIGKILL) after its first
checkpoint, then resumed, writes exactly the temperatures, heat flows and ledger of the
uninterrupted run; resuming with another scene, another packing of the same size (content
hash), without a checkpoint, or a steady solve with checkpoints are one-line errors.
"""
import os
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest

from thermal_kernel.lattice import simple_cubic_packing
from thermal_kernel.packing import write_packing

# `make coverage` counts this module (marker kernel: its subject is thermal_kernel, and it is
# fast enough with NUMBA_DISABLE_JIT=1)
pytestmark = pytest.mark.kernel

SCENE = '''packing = "lattice.h5"
law = "terreros"
[material]
conductivity = 50.0
density = 7800.0
heat_capacity = 460.0
[initial]
temperature = 300.0
[[boundary]]
kind = "temperature"
on = "xmin"
value = 400.0
[[boundary]]
kind = "temperature"
on = "xmax"
value = 300.0
[solver]
'''
FIELDS = ("time", "temperature", "boundary_heat_flow", "boundary_energy", "source_energy",
          "stored_energy_change")


def tdem(*args, **kw):
    return subprocess.run([sys.executable, "-m", "tdem.cli", *map(str, args)],
                          capture_output=True, text=True, **kw)


def read(path):
    with h5py.File(path) as f:
        return {k: f[k][()] for k in FIELDS}


def assert_same_bits(a, b):
    for k in FIELDS:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)


@pytest.fixture
def lattice(tmp_path):
    write_packing(tmp_path / "lattice.h5", simple_cubic_packing((16, 16, 16), spacing_m=1e-3))
    return tmp_path


# slow: `tdem run` twice in subprocesses, per case;
# over ~1.3 s on the shared 2-core machine, warm numba cache (--durations, 2026-12-01)
@pytest.mark.slow
@pytest.mark.parametrize("solver", [
    'method = "explicit"\nend_time = 2.0\noutput_times = [0.2, 0.5, 0.9, 1.4, 2.0]\n',
    'method = "implicit"\ntheta = 0.5\ndt = 0.05\nend_time = 2.0\n'
    'output_times = [0.2, 0.5, 0.9, 1.4, 2.0]\n'])
def test_checkpoints_do_not_change_the_bits(lattice, solver):
    (lattice / "s.toml").write_text(SCENE + solver)
    assert tdem("run", lattice / "s.toml", "--out", lattice / "plain", "--quiet").returncode == 0
    proc = tdem("run", lattice / "s.toml", "--out", lattice / "ck", "--quiet",
                "--checkpoint-every", 2)
    assert proc.returncode == 0, proc.stderr
    assert_same_bits(read(lattice / "plain" / "thermal.h5"), read(lattice / "ck" / "thermal.h5"))
    assert not (lattice / "ck" / "thermal.checkpoint.h5").exists()


# slow: a `tdem run` killed mid-way (~1 s per output interval), then resumed;
# over ~1.3 s on the shared 2-core machine, warm numba cache (--durations, 2026-12-01)
@pytest.mark.slow
def test_killed_run_resumes_to_the_same_bits(lattice):
    # long enough (~1 s per output interval) to be killed after the first checkpoint
    (lattice / "s.toml").write_text(SCENE + 'method = "explicit"\nend_time = 100.0\n'
                                    'output_times = [20.0, 40.0, 60.0, 80.0, 100.0]\n')
    out = lattice / "ck"
    ckpt = out / "thermal.checkpoint.h5"
    proc = subprocess.Popen([sys.executable, "-m", "tdem.cli", "run", str(lattice / "s.toml"),
                             "--out", str(out), "--quiet", "--checkpoint-every", "1",
                             "--threads", "1"])
    while not ckpt.exists() and proc.poll() is None:
        time.sleep(0.005)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert proc.returncode == -signal.SIGKILL, "the run ended before it could be interrupted"
    assert not (out / "thermal.h5").exists()
    with h5py.File(ckpt) as f:
        assert 1 <= len(f["outputs/times"]) < 5
    resumed = tdem("run", lattice / "s.toml", "--out", out, "--resume", "--threads", "1")
    assert resumed.returncode == 0, resumed.stderr
    assert "resuming from" in resumed.stdout
    assert not ckpt.exists()
    full = tdem("run", lattice / "s.toml", "--out", lattice / "plain", "--quiet", "--threads", "1")
    assert full.returncode == 0
    assert_same_bits(read(lattice / "plain" / "thermal.h5"), read(out / "thermal.h5"))


# slow: refused resumes, each a `tdem` subprocess;
# over ~1.3 s on the shared 2-core machine, warm numba cache (--durations, 2026-12-01)
@pytest.mark.slow
def test_resume_errors_are_one_line(lattice):
    (lattice / "s.toml").write_text(SCENE + 'method = "explicit"\nend_time = 1.0\n'
                                    'output_times = [0.5, 1.0]\n')
    none = tdem("run", lattice / "s.toml", "--out", lattice / "o", "--resume")
    assert none.returncode == 2 and none.stderr.count("\n") == 1
    assert "no checkpoint" in none.stderr
    # a checkpoint of another scene: leave one behind by writing it from a short run's state
    from thermal_kernel.checkpoint import write_checkpoint
    from thermal_kernel.solvers import SolverState
    n = 16 ** 3
    state = SolverState(temperature_k=np.full(n, 300.0), time_s=0.5, step=10,
                        boundary_energy_j=np.zeros(2), source_energy_j=0.0,
                        reference_temperature_k=np.full(n, 300.0), dt_s=0.01, method="explicit")
    outputs = dict(times=[0.5], temperature_k=np.full((1, n), 300.0),
                   boundary_heat_flow_w=np.zeros((1, 2)), boundary_energy_j=np.zeros((1, 2)),
                   source_energy_j=[0.0], stored_energy_j=[0.0])
    write_checkpoint(lattice / "o" / "thermal.checkpoint.h5", state, outputs,
                     dict(steps=10, wall_seconds=0.1, step_seconds=0.1), "another scene", n)
    other = tdem("run", lattice / "s.toml", "--out", lattice / "o", "--resume")
    assert other.returncode == 2 and other.stderr.count("\n") == 1
    assert "scene" in other.stderr and "Traceback" not in other.stderr
    (lattice / "st.toml").write_text(SCENE + 'method = "steady"\n')
    steady = tdem("run", lattice / "st.toml", "--out", lattice / "p", "--checkpoint-every", 1)
    assert steady.returncode == 2 and "steady" in steady.stderr


# slow: `tdem run` and resumes in subprocesses;
# over ~1.3 s on the shared 2-core machine, warm numba cache (--durations, 2026-12-01)
@pytest.mark.slow
def test_resume_on_another_packing_of_the_same_size_is_refused(lattice):
    """The checkpoint stores the packing's content hash: a packing with the same particle count
    but other positions is refused (exit 2, one line naming the packing file); the packing it
    was made on, or a copy of it, resumes."""
    import shutil
    from thermal_kernel.checkpoint import packing_sha256, write_checkpoint
    from thermal_kernel.packing import read_packing
    from thermal_kernel.solvers import SolverState
    text = SCENE + 'method = "explicit"\nend_time = 1.0\noutput_times = [0.5, 1.0]\n'
    (lattice / "s.toml").write_text(text)
    write_packing(lattice / "other.h5", simple_cubic_packing((16, 16, 16), spacing_m=1.1e-3))
    shutil.copy(lattice / "lattice.h5", lattice / "copy.h5")
    same = packing_sha256(read_packing(lattice / "lattice.h5"))
    other = packing_sha256(read_packing(lattice / "other.h5"))
    assert other != same and packing_sha256(read_packing(lattice / "copy.h5")) == same
    n = 16 ** 3
    state = SolverState(temperature_k=np.full(n, 300.0), time_s=0.5, step=10,
                        boundary_energy_j=np.zeros(2), source_energy_j=0.0,
                        reference_temperature_k=np.full(n, 300.0), dt_s=0.005, method="explicit")
    outputs = dict(times=[0.5], temperature_k=np.full((1, n), 300.0),
                   boundary_heat_flow_w=np.zeros((1, 2)), boundary_energy_j=np.zeros((1, 2)),
                   source_energy_j=[0.0], stored_energy_j=[0.0])
    ckpt = lattice / "o" / "thermal.checkpoint.h5"

    def leave_checkpoint(packing_hash):
        write_checkpoint(ckpt, state, outputs, dict(steps=10, wall_seconds=0.1,
                                                    step_seconds=0.1), text, n, packing_hash)

    leave_checkpoint(other)                        # made on other.h5, resumed on lattice.h5
    r = tdem("run", lattice / "s.toml", "--out", lattice / "o", "--resume", "--quiet")
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "lattice.h5" in r.stderr and "--resume" in r.stderr and "Traceback" not in r.stderr
    assert ckpt.exists() and not (lattice / "o" / "thermal.h5").exists()
    # the same packing, and a copy of it given with --packing, resume
    for packing in (None, lattice / "copy.h5"):
        leave_checkpoint(same)
        args = ("--packing", packing) if packing else ()
        r = tdem("run", lattice / "s.toml", "--out", lattice / "o", "--resume", "--quiet",
                 *args)
        assert r.returncode == 0, r.stderr
        assert not ckpt.exists()
        assert list(read(lattice / "o" / "thermal.h5")["time"]) == [0.5, 1.0]
    # and a checkpoint that does not identify its packing is refused, not trusted
    leave_checkpoint("")
    r = tdem("run", lattice / "s.toml", "--out", lattice / "o", "--resume", "--quiet")
    assert r.returncode == 2 and "packing_sha256" in r.stderr and r.stderr.count("\n") == 1
