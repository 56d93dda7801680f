"""method = "shell" (issue 24), the parts that need no YADE: which method "auto" stands for,
which spheres are kept, free and frozen, how the contacts of the pressed domain are merged, the
pressed domain's size, and the near-wall statistics of tdem_post/wall_layers.py on packings whose
profile is known exactly."""
import numpy as np
import pytest

from yade_scripts import params as P
from yade_scripts import shell
from yade_scripts.dense_geometry import Container


@pytest.mark.parametrize("shape, n, expected", [
    ("box", 2000, "direct"), ("box", shell.AUTO_SHELL_ABOVE, "direct"),
    ("box", shell.AUTO_SHELL_ABOVE + 1, "shell"), ("cylinder", 100_000, "shell"),
    ("sphere", 100_000, "shell"), ("periodic", 100_000, "direct")])
def test_auto_method(shape, n, expected):
    assert shell.resolve_method(shape, "auto", n) == expected
    p = P.resolve_and_check("dense", {"shape": shape, "n_particles": n,
                                      "cell_particles": 2000})
    assert p["method"] == expected          # params.json names the method used
    assert shell.resolve_method(shape, "tiled", n) == "tiled"     # a chosen method is kept


def test_split_keeps_whole_spheres_and_layers_them():
    rng = np.random.default_rng(3)
    box = Container("box", 1.0, [1.0, 1.0, 1.0])
    position = rng.random((4000, 3))
    radius = rng.uniform(0.01, 0.03, 4000)
    whole, free, band = shell.split(box, position, radius, 0.1, 0.05)
    distance = np.min(np.concatenate([position, 1.0 - position], axis=1), axis=1)
    np.testing.assert_array_equal(whole, distance >= radius)
    np.testing.assert_array_equal(free, whole & (distance < 0.1))
    np.testing.assert_array_equal(band, whole & (distance >= 0.1) & (distance < 0.15))
    assert not np.any(free & band)
    # the frozen band reaches as far as a free sphere can touch
    assert shell.frozen_band_m(radius, 0.1) >= 2 * radius.max() * 1.1


def test_merge_keeps_unmoved_contacts_and_takes_the_new_ones():
    moved = np.array([True, False, False, True])
    kept = (np.array([[0, 1], [1, 2], [2, 3]]), np.array([10.0, 20.0, 30.0]))
    new = (np.array([[0, 1], [0, 3], [1, 2]]), np.array([11.0, 12.0, 99.0]))
    pair, force = shell.merge_contacts(moved, kept, new)
    # (1, 2) joins two unmoved spheres: the tiled value stays, YADE's copy is dropped
    assert sorted(map(tuple, pair.tolist())) == [(0, 1), (0, 3), (1, 2)]
    assert dict(zip(map(tuple, pair.tolist()), force)) == {(1, 2): 20.0, (0, 1): 11.0,
                                                          (0, 3): 12.0}


@pytest.mark.parametrize("shape", ["box", "cylinder", "sphere"])
def test_pressed_box(shape):
    lo, hi = np.array([0.1, 0.2, 0.3]), np.array([1.1, 1.4, 2.3])
    box = shell.pressed_box(shape, lo, hi, radius_m=0.5)
    if shape == "box":
        np.testing.assert_allclose(box.size, hi - lo)
        assert box.volume == pytest.approx(np.prod(hi - lo))
    elif shape == "cylinder":
        np.testing.assert_allclose(box.size, [1.0, 1.0, 2.0])
        assert box.volume == pytest.approx(np.pi * 0.25 * 2.0)
    else:
        np.testing.assert_allclose(box.size, [1.0, 1.0, 1.0])
        assert box.volume == pytest.approx(4 / 3 * np.pi * 0.125)
    np.testing.assert_allclose(box.centre, box.size / 2)
