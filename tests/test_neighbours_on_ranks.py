"""The [neighbours] choice made on the ranks (issue 25): thermal_kernel.neighbours.
choose_neighbours_on_ranks against the whole build's choose_neighbours / choose_gap, without MPI.

The ranks are threads sharing a stand-in communicator (``allgather`` only, the one collective
the function uses); each is given a slice of the rows (uneven, one empty). What could fail: the
bisection stopping one float off the whole build's k-th ratio, a tie split between two ranks
(the whole build keeps ties together), the next ratio taken from the wrong side, a bulk Z
averaged in another order, a refusal said on some ranks only or in other words.

tests/mpi_rank_build_check.py runs the same function under mpirun inside the per-rank build.
"""
import math
import threading
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from thermal_kernel.neighbours import (bulk_particles, choose_gap, choose_neighbours,
                                       choose_neighbours_on_ranks, distance_ratio,
                                       dump_gap_tolerance)
from thermal_kernel.packing import read_packing
from thermal_kernel.scene import NeighbourCriterion, SceneError

DATA = Path(__file__).resolve().parent / "data"


class _Shared:
    def __init__(self, size):
        # a guard against a hang if a rank left early (the assertions below are on values)
        self.barrier = threading.Barrier(size, timeout=120)
        self.slots = [None] * size


class _Comm:
    """One rank's view of :class:`_Shared`: mpi4py's ``allgather`` of a Python object."""

    def __init__(self, shared, rank):
        self.shared, self.rank = shared, rank

    def allgather(self, value):
        self.shared.slots[self.rank] = value
        self.shared.barrier.wait()
        out = list(self.shared.slots)
        self.shared.barrier.wait()
        return out


def _on_ranks(cuts, fn):
    """``fn(comm, lo, hi)`` on one thread a slice ``cuts[r]:cuts[r + 1]``; each rank's value or
    exception."""
    size = len(cuts) - 1
    shared = _Shared(size)
    out = [None] * size

    def run(r):
        try:
            out[r] = fn(_Comm(shared, r), cuts[r], cuts[r + 1])
        except Exception as e:         # noqa: BLE001 (compared below)
            out[r] = e

    threads = [threading.Thread(target=run, args=(r,)) for r in range(size)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return out


def _cuts(m, size):
    """Uneven slices of m rows; the second one empty from 3 ranks on."""
    if size == 1:
        return [0, m]
    inner = sorted(np.random.default_rng(size).integers(1, m, size - 1).tolist())
    if size >= 3:
        inner[1] = inner[0]
    return [0] + inner + [m]


SCENARIOS = [("dense_box", dict(target_z_with_gaps=7.0, bulk_margin_diameters=1.0)),
             ("dense_box", dict(target_z_with_gaps=6.5, bulk_margin_diameters=0.5)),
             ("dense_periodic", dict(target_z_with_gaps=7.4, bulk_margin_diameters=2.0)),
             ("dense_cylinder", dict(target_z_with_gaps=5.9, bulk_margin_diameters=0.5)),
             ("dense_sphere", dict(target_z_with_gaps=7.0, bulk_margin_diameters=1.0)),
             ("dense_box", dict(gap=0.041, bulk_margin_diameters=1.0)),
             # refused: above every dumped row, below the touching contacts, beyond the dump's
             # gap_tolerance, no bulk particle
             ("dense_box", dict(target_z_with_gaps=9.5, bulk_margin_diameters=1.0)),
             ("dense_box", dict(target_z_with_gaps=1.0, bulk_margin_diameters=1.0)),
             ("dense_box", dict(gap=0.2, bulk_margin_diameters=1.0)),
             ("dense_box", dict(target_z_with_gaps=7.0, bulk_margin_diameters=50.0))]


@pytest.mark.parametrize("size", [2, 5])
@pytest.mark.parametrize("dump,crit", SCENARIOS)
def test_the_ranks_choose_what_the_whole_build_chooses(dump, crit, size):
    packing = read_packing(DATA / f"{dump}.h5")
    scene = SimpleNamespace(path="scene.toml", neighbours=NeighbourCriterion(**crit))
    try:
        whole = choose_neighbours(scene, packing)
    except SceneError as e:
        whole = e
    ratio = distance_ratio(packing)
    bulk = bulk_particles(packing, scene.neighbours.bulk_margin_diameters)
    weight = bulk[packing.pair[:, 0]].astype(np.int64) + bulk[packing.pair[:, 1]]
    cuts = _cuts(packing.n_contacts, size)

    def fn(comm, lo, hi):
        return choose_neighbours_on_ranks(
            scene, comm, packing.path, dump_gap_tolerance(packing), packing.n_particles,
            packing.n_contacts, int(bulk.sum()), ratio[lo:hi], weight[lo:hi])

    got = _on_ranks(cuts, fn)
    if isinstance(whole, SceneError):
        assert all(isinstance(g, SceneError) and str(g) == str(whole) for g in got), (
            str(whole), [str(g) for g in got])
        return
    assert not any(isinstance(g, Exception) for g in got), got
    for g in got:       # every number of it, to the bit, on every rank
        assert g.summary() == whole.summary()
    np.testing.assert_array_equal(np.concatenate([g.keep for g in got]), whole.keep)
    assert 0 < whole.n_kept < whole.n_dumped


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("size", [2, 3])
def test_ties_and_the_last_row_as_the_whole_build_has_them(seed, size):
    """Ratios with many ties (rounded to 1/100), weights 0-2: the gap is choose_gap's for
    every target, including one only the last rows reach (the gap just above the largest
    ratio) and ties straddling the ranks' slices."""
    rng = np.random.default_rng(seed)
    m = 400
    ratio = 1.0 + rng.integers(0, 20, m) / 100.0
    weight = rng.integers(0, 3, m).astype(np.int64)
    n_bulk, n = 100, 200
    top = int(weight.sum()) / n_bulk
    for target in (0.3, 1.0, 2.5, top * 0.999, top):
        scene = SimpleNamespace(path="s.toml", neighbours=NeighbourCriterion(
            target_z_with_gaps=target, bulk_margin_diameters=1.0))
        found = choose_gap(ratio, weight, target * n_bulk * (1 - 1e-12))
        cuts = [0] + sorted(int(x) for x in rng.integers(0, m, size - 1)) + [m]
        got = _on_ranks(cuts, lambda comm, lo, hi, scene=scene: choose_neighbours_on_ranks(
            scene, comm, "p.h5", math.nan, n, m, n_bulk, ratio[lo:hi], weight[lo:hi]))
        for g in got:
            assert not isinstance(g, Exception), g
            assert g.gap == found[0] and g.n_kept == found[1], (target, g.gap, found)
        keep = np.concatenate([g.keep for g in got])
        np.testing.assert_array_equal(keep, ratio < 1.0 + found[0])
