"""The periodic-cell tiling of the dense generator (yade_scripts/tiling.py) and its neighbour
search (yade_scripts/neighbours.py), without YADE.

Exact identities:
- the contacts of a tiled block, copied from the cell's periodic contacts, are exactly the pairs
  an independent all-pairs search finds on the tiled positions (same set, same branch vectors to
  round-off): the seams are invisible;
- carving renumbers consistently: every kept pair joins two kept particles, at the same branch;
- the k-d tree neighbour search equals the all-pairs search, periodic or not.
"""
import importlib.util
from pathlib import Path

import numpy as np
import pytest

SCRIPTS = Path(__file__).resolve().parent.parent / "yade_scripts"


def _load(name):
    spec = importlib.util.spec_from_file_location(f"tdem_test_{name}", SCRIPTS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


tiling = _load("tiling")
neighbours = _load("neighbours")


def brute_pairs(position, radius, gap, cell=None):
    """All pairs, O(N^2), the independent reference."""
    d = position[None, :, :] - position[:, None, :]
    if cell is not None:
        d -= np.round(d / cell) * cell
    dist = np.linalg.norm(d, axis=2)
    cut = (1 + gap) * (radius[:, None] + radius[None, :])
    i, j = np.nonzero((dist < cut) & np.triu(np.ones_like(dist, bool), 1))
    return {(a, b): d[a, b] for a, b in zip(i.tolist(), j.tolist())}


@pytest.fixture(scope="module")
def cell_packing():
    """A jittered simple-cubic periodic cell (6 x 5 x 4 sites), polydisperse radii chosen so
    that neighbours touch or nearly touch: many pairs cross the periodic boundary."""
    rng = np.random.default_rng(5)
    shape = np.array([6, 5, 4])
    a = 1e-3
    sites = np.indices(shape).reshape(3, -1).T * a + 0.5 * a
    position = sites + rng.uniform(-0.08, 0.08, sites.shape) * a
    radius = 0.5 * a * rng.uniform(0.9, 1.1, len(sites))
    return position, radius, shape * a


@pytest.mark.parametrize("gap", [0.0, 0.1])
def test_kdtree_search_equals_all_pairs(cell_packing, gap):
    position, radius, cell = cell_packing
    for c in (None, cell):
        pair, branch = neighbours.neighbour_pairs(position, radius, gap, c)
        ref = brute_pairs(position, radius, gap, c)
        assert {tuple(p) for p in pair.tolist()} == set(ref)
        assert len(pair) == len(ref) > 0
        np.testing.assert_allclose(branch, [ref[tuple(p)] for p in pair.tolist()], atol=1e-15)
        assert np.all(np.diff(pair[:, 0]) >= 0)          # sorted by (i, j)


@pytest.mark.parametrize("reps", [(2, 1, 1), (2, 3, 2)])
def test_tiled_contacts_are_the_contacts_of_the_tiled_positions(cell_packing, reps):
    position, radius, cell = cell_packing
    pair, branch = neighbours.neighbour_pairs(position, radius, 0.1, cell)
    position_t, source, pair_t, pair_source = tiling.tile(position, cell, pair, branch, reps)
    radius_t = radius[source]
    assert len(position_t) == len(position) * np.prod(reps)
    ref = brute_pairs(position_t, radius_t, 0.1)            # the block is not periodic
    got = {}
    for (i, j), k in zip(pair_t.tolist(), pair_source.tolist()):
        key, sign = ((i, j), 1.0) if i < j else ((j, i), -1.0)
        got[key] = sign * branch[k]
    assert set(got) == set(ref)
    for key, b in got.items():
        np.testing.assert_allclose(b, ref[key], atol=1e-15)
    # seams: pairs joining two different copies exist and are counted once
    assert np.any(pair_t[:, 0] // len(position) != pair_t[:, 1] // len(position))
    assert len({tuple(sorted(p)) for p in pair_t.tolist()}) == len(pair_t)


def test_carve_keeps_pairs_of_kept_particles(cell_packing):
    position, radius, cell = cell_packing
    pair, branch = neighbours.neighbour_pairs(position, radius, 0.1, cell)
    position_t, source, pair_t, pair_source = tiling.tile(position, cell, pair, branch,
                                                          (3, 3, 3))
    centre = 1.5 * cell
    keep = np.linalg.norm(position_t - centre, axis=1) <= 0.4 * cell.min() * 3
    new_index, rows, pair_c = tiling.carve(keep, pair_t)
    kept = position_t[keep]
    assert len(kept) == keep.sum() and np.all(new_index[keep] == np.arange(keep.sum()))
    assert pair_c.min() >= 0 and pair_c.max() < keep.sum()
    np.testing.assert_allclose(kept[pair_c[:, 1]] - kept[pair_c[:, 0]],
                               branch[pair_source[rows]], atol=1e-15)
    ref = brute_pairs(kept, radius[source[keep]], 0.1)
    assert {tuple(sorted(p)) for p in pair_c.tolist()} == set(ref)


def test_repetitions_cover_the_domain():
    cell = np.array([1.0, 2.0, 0.5])
    reps = tiling.repetitions(cell, [2.0, 2.1, 0.2])
    assert reps.tolist() == [2, 2, 1]
    assert np.all(reps * cell >= [2.0, 2.1, 0.2])


def test_seeds_refused_for_the_bed_generator(tmp_path):
    """--seeds goes through yade-batch only for generators that read a batch table: one line,
    exit 2, before YADE starts."""
    import subprocess
    import sys
    scene = tmp_path / "bed.toml"
    scene.write_text('law = "pipe"\n[pack]\ngenerator = "bed"\n')
    proc = subprocess.run([sys.executable, "-m", "tdem.cli", "pack", str(scene), "--seeds", "1,2"],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "--seeds" in proc.stderr


def test_cell_packing_checked_before_yade(tmp_path):
    """A tiled scene whose cell_packing has walls, or another modulus, is refused by tdem pack in
    one line (exit 2) before YADE starts."""
    import subprocess
    import sys
    data = Path(__file__).resolve().parent / "data"
    base = ('law = "haddad"\n[pack]\ngenerator = "dense"\nshape = "box"\nmethod = "tiled"\n'
            'n_particles = 5000\ngap_tolerance = 0.1\ncell_packing = "{cell}"\n{extra}')
    cases = [(data / "dense_box.h5", "", "expected a periodic cell"),
             (data / "dense_periodic.h5", "young_pa = 5e9\n", "pack.young_pa"),
             (tmp_path / "missing.h5", "", "pack.cell_packing")]
    for cell, extra, expected in cases:
        scene = tmp_path / "tiled.toml"
        scene.write_text(base.format(cell=cell, extra=extra))
        proc = subprocess.run([sys.executable, "-m", "tdem.cli", "pack", str(scene),
                               "--out", str(tmp_path / "out")], capture_output=True, text=True)
        assert proc.returncode == 2, proc.stderr
        assert proc.stderr.strip().count("\n") == 0 and expected in proc.stderr, proc.stderr
        assert not (tmp_path / "out").exists()
