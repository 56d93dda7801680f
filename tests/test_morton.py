"""The Z-order curve of thermal_kernel/morton.py (the MPI ranks' blocks; large YADE scenes)."""
import numpy as np

from thermal_kernel.morton import morton_keys, morton_order


def test_the_corners_of_a_cube_come_in_z_order_x_first():
    corners = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], float)
    shuffled = corners[[5, 2, 7, 0, 3, 6, 1, 4]]
    # x is the lowest bit of the key, then y, then z
    assert np.array_equal(shuffled[morton_order(shuffled)], corners)
    assert list(morton_keys(corners)) == sorted(morton_keys(corners))


def test_the_order_is_a_stable_permutation():
    x = np.repeat(np.random.default_rng(1).uniform(size=(100, 3)), 2, axis=0)   # each point twice
    order = morton_order(x)
    assert np.array_equal(np.sort(order), np.arange(200))
    pairs = order.reshape(-1, 2)
    assert np.all(pairs[:, 1] == pairs[:, 0] + 1)         # a tie keeps the index order


def test_neighbours_along_the_curve_are_neighbours_in_space():
    x = np.random.default_rng(2).uniform(size=(4096, 3))
    along = np.linalg.norm(np.diff(x[morton_order(x)], axis=0), axis=1).mean()
    given = np.linalg.norm(np.diff(x, axis=0), axis=1).mean()
    # ~ the spacing of 4096 points (0.06) against a random pair's distance (0.66)
    assert along < 0.15 * given
