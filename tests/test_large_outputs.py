"""A long run's temperatures at its output times are not held in memory (issue 25: what rank 0,
and the in-process run, held whole): above ``thermal_kernel.atomic.ON_DISK_FROM_BYTES`` the
history is a memory map of an unnamed file beside the output (``atomic.history_rows``) and
thermal.h5 / the checkpoints are written on disk into room reserved first
(``atomic.write_h5_atomic``), instead of built in memory.

Asserted, with the threshold lowered to 0 so the committed 300-sphere bed takes that path:
the same datasets bit for bit as the in-memory path (explicit, implicit, with checkpoints and
resumed from one); the history is a memory map; Python's peak allocation grows by less than a
quarter of a row per output time on that path, by at least a row in memory;
a disk without the room refuses before HDF5 writes anything (ENOSPC), leaving no file.
"""
import errno
import os
import tracemalloc

import h5py
import numpy as np
import pytest

from tdem.committed_beds import BED_THERMAL, BEDS
from thermal_kernel import atomic
from thermal_kernel.atomic import history_rows
from thermal_kernel.run import run_scene
from thermal_kernel.scene import load_scene

pytestmark = pytest.mark.kernel

FIELDS = ("time", "temperature", "boundary_heat_flow", "boundary_energy", "source_energy",
          "stored_energy_change", "capacity", "initial_temperature")
EXPLICIT = '[solver]\nmethod = "explicit"\nend_time = 40.0\noutput_times = [{}]\n'
IMPLICIT = '[solver]\nmethod = "implicit"\ndt = 5.0\nend_time = 200.0\noutput_times = [{}]\n'


def _scene(tmp_path, name, solver, times):
    path = tmp_path / f"{name}.toml"
    path.write_text(f'packing = "{BEDS[1]}"\nlaw = "pipe"\n{BED_THERMAL}\n'
                    + solver.format(", ".join(f"{t:g}" for t in times)))
    return load_scene(path, out_dir=tmp_path / name)


def _read(path):
    with h5py.File(path) as f:
        return {k: f[k][()] for k in FIELDS}


def _run(tmp_path, name, solver, times, **kw):
    summary = run_scene(_scene(tmp_path, name, solver, times), quiet=True, threads=1, **kw)
    return summary, _read(summary.output)


def _on_disk(monkeypatch):
    """Every history and every HDF5 file of a run takes the on-disk path; the files written
    that way are counted."""
    monkeypatch.setattr(atomic, "ON_DISK_FROM_BYTES", 0)
    written = []
    original = atomic._write_h5_reserved

    def spy(path, fill, data_bytes):
        written.append(path.name)
        return original(path, fill, data_bytes)

    monkeypatch.setattr(atomic, "_write_h5_reserved", spy)
    return written


@pytest.mark.parametrize("solver, times", [(EXPLICIT, [5.0, 10.0, 20.0, 40.0]),
                                           (IMPLICIT, [5.0, 10.0, 50.0, 200.0])],
                         ids=["explicit", "implicit"])
def test_on_disk_path_writes_the_same_bits(tmp_path, monkeypatch, solver, times):
    _, in_memory = _run(tmp_path, "memory", solver, times)
    written = _on_disk(monkeypatch)
    summary, on_disk = _run(tmp_path, "disk", solver, times, checkpoint_every=1)
    assert isinstance(summary.run.result.temperature_k, np.memmap)
    # thermal.h5 and a checkpoint after each of the 4 output times, on the reserved path
    assert written.count("thermal.h5") == 1 and written.count("thermal.checkpoint.h5") == 4
    assert not (tmp_path / "disk" / "thermal.checkpoint.h5").exists()
    assert sorted(p.name for p in (tmp_path / "disk").iterdir()) == ["thermal.h5"]
    for key in FIELDS:
        np.testing.assert_array_equal(on_disk[key], in_memory[key], err_msg=key)


def test_a_run_resumed_on_the_disk_path_equals_the_uninterrupted_one(tmp_path, monkeypatch):
    times = [5.0, 10.0, 20.0, 40.0]
    _, whole = _run(tmp_path, "whole", EXPLICIT, times)
    _on_disk(monkeypatch)
    scene = _scene(tmp_path, "part", EXPLICIT, times)
    import thermal_kernel.run as run_module
    check, calls = run_module._check_finite, []

    def interrupted(*args, **kw):      # Ctrl-C as the third chunk ends: two checkpointed
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return check(*args, **kw)

    monkeypatch.setattr(run_module, "_check_finite", interrupted)
    with pytest.raises(KeyboardInterrupt, match="checkpoint .* kept"):
        run_scene(scene, quiet=True, threads=1, checkpoint_every=1)
    assert not scene.output.exists()
    from thermal_kernel.checkpoint import checkpoint_path, packing_sha256, read_checkpoint
    from thermal_kernel.packing import read_packing
    _, done, _ = read_checkpoint(checkpoint_path(scene.output), scene.text, 300,
                                 packing_sha256(read_packing(BEDS[1])))
    assert isinstance(done["temperature_k"], np.memmap)      # read back to disk, not memory
    np.testing.assert_array_equal(done["temperature_k"], whole["temperature"][:2])
    monkeypatch.setattr(run_module, "_check_finite", check)
    resumed = run_scene(scene, quiet=True, threads=1, resume=True)
    assert isinstance(resumed.run.result.temperature_k, np.memmap)
    for key in FIELDS:
        np.testing.assert_array_equal(_read(resumed.output)[key], whole[key], err_msg=key)


def test_history_is_a_memory_map_only_above_the_threshold(tmp_path, monkeypatch):
    assert type(history_rows(3, 5, tmp_path)) is np.ndarray        # 120 B: in memory
    assert type(history_rows(3, 5)) is np.ndarray                  # no folder: in memory
    monkeypatch.setattr(atomic, "ON_DISK_FROM_BYTES", 100)
    rows = history_rows(3, 5, tmp_path)
    assert isinstance(rows, np.memmap) and rows.shape == (3, 5)
    rows[:] = 7.0
    assert float(rows.sum()) == 105.0
    assert list(tmp_path.iterdir()) == []                          # unlinked at once


def test_peak_memory_does_not_grow_by_a_row_per_output_time(tmp_path, monkeypatch):
    """Python's peak allocation of a run with 1,000 and with 4,000 output times (300 spheres, a
    row of 2,400 B each): in memory it grows by at least a row per output time (the history,
    and thermal.h5's image beside it); on the disk path by less than a quarter of a row (what
    remains per output time: its flows, energies and step counts, independent of N)."""
    row_bytes = 8 * 300

    def peak(name, k):
        times = np.arange(1, k + 1) * 0.05
        solver = ('[solver]\nmethod = "implicit"\ndt = 0.05\nend_time = '
                  f'{times[-1]:g}\noutput_times = [{{}}]\n')
        scene = _scene(tmp_path, f"{name}_{k}", solver, times)
        tracemalloc.start()
        try:
            run_scene(scene, quiet=True, threads=1)
            return tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()

    per_output_in_memory = (peak("memory", 4000) - peak("memory", 1000)) / 3000
    _on_disk(monkeypatch)
    per_output_on_disk = (peak("disk", 4000) - peak("disk", 1000)) / 3000
    assert per_output_in_memory >= row_bytes, per_output_in_memory
    assert per_output_on_disk < row_bytes / 4, per_output_on_disk
    np.testing.assert_array_equal(
        _read(tmp_path / "disk_4000" / "thermal.h5")["temperature"],
        _read(tmp_path / "memory_4000" / "thermal.h5")["temperature"])


def test_no_room_on_disk_is_refused_before_hdf5_writes(tmp_path):
    free = os.statvfs(tmp_path).f_bavail * os.statvfs(tmp_path).f_frsize
    target = tmp_path / "big.h5"
    with open(tmp_path / "probe", "wb+") as f:
        try:
            if not atomic._reserve(f, 4096):
                pytest.skip("this filesystem reserves no space (fallocate unsupported)")
        except OSError:
            pytest.skip("this filesystem cannot reserve 4 KB")
    os.unlink(tmp_path / "probe")
    with pytest.raises(OSError) as e:
        atomic.write_h5_atomic(target, lambda f: f.create_dataset("x", data=np.zeros(3)),
                               data_bytes=free + 2 ** 40)
    assert e.value.errno in (errno.ENOSPC, errno.EFBIG)
    assert e.value.filename == str(target)
    assert list(tmp_path.iterdir()) == []


def test_a_history_the_disk_cannot_hold_is_refused_before_the_run(tmp_path, monkeypatch):
    """The history's file is reserved before it is mapped: a disk without the room raises
    ENOSPC at once, naming the folder (a write through the map to a full disk would kill the
    process with SIGBUS instead), and nothing is left there."""
    free = os.statvfs(tmp_path).f_bavail * os.statvfs(tmp_path).f_frsize
    with open(tmp_path / "probe", "wb+") as f:
        try:
            if not atomic._reserve(f, 4096, keep_size=False):
                pytest.skip("this filesystem reserves no space (fallocate unsupported)")
        except OSError:
            pytest.skip("this filesystem cannot reserve 4 KB")
    os.unlink(tmp_path / "probe")
    monkeypatch.setattr(atomic, "ON_DISK_FROM_BYTES", 0)
    n_times = (free + 2 ** 40) // 8000 + 1
    with pytest.raises(OSError) as e:
        history_rows(n_times, 1000, tmp_path)
    assert e.value.errno in (errno.ENOSPC, errno.EFBIG)
    assert e.value.filename == str(tmp_path)
    assert list(tmp_path.iterdir()) == []
