"""method = "shell" (issue 24), the parts that need no YADE: which method "auto" stands for,
which spheres are kept, free and frozen, how the contacts of the pressed domain are merged, the
pressed domain's size, and the near-wall statistics of tdem_post/wall_layers.py on packings whose
profile is known exactly."""
import numpy as np
import pytest

from yade_scripts import params as P
from yade_scripts import dense_params, shell
from yade_scripts.dense_geometry import Container


@pytest.mark.parametrize("shape, n", [("box", 2000), ("box", 100_000), ("cylinder", 100_000),
                                      ("sphere", 100_000), ("periodic", 100_000)])
def test_auto_method(shape, n):
    """auto is direct until the shell path matches the direct reference (AUTO_SHELL_SHAPES is
    empty): params.json names the method used; a method asked for is kept."""
    expected = "shell" if shape in shell.AUTO_SHELL_SHAPES and n > shell.AUTO_SHELL_ABOVE \
        else "direct"
    assert shell.resolve_method(shape, "auto", n) == expected
    p = P.resolve_and_check("dense", {"shape": shape, "n_particles": n,
                                      "cell_particles": 2000})
    assert p["method"] == expected
    assert shell.resolve_method(shape, "tiled", n) == "tiled"
    assert shell.resolve_method("box", "shell", n) == "shell"


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


@pytest.mark.parametrize("cut_depth", [0.0, 0.5, 1.0])
def test_cut_depth_keeps_centres_that_deep_and_the_walls_start_clear_of_them(cut_depth):
    rng = np.random.default_rng(4)
    box = Container("box", 1.0, [1.0, 1.0, 1.0])
    position = rng.random((4000, 3))
    radius = rng.uniform(0.01, 0.03, 4000)
    kept, free, band = shell.split(box, position, radius, 0.1, 0.05, cut_depth)
    distance = np.min(np.concatenate([position, 1.0 - position], axis=1), axis=1)
    np.testing.assert_array_equal(kept, distance >= cut_depth * radius)
    lo, hi = shell.walls_start(box, position[kept], radius[kept])
    # no kept sphere crosses a starting wall, and each wall touches the outermost sphere (or
    # stays on the carved face when none protrudes)
    assert np.all(position[kept] - radius[kept, None] >= lo - 1e-15)
    assert np.all(position[kept] + radius[kept, None] <= hi + 1e-15)
    outer_lo = np.min(position[kept] - radius[kept, None], axis=0)
    outer_hi = np.max(position[kept] + radius[kept, None], axis=0)
    np.testing.assert_allclose(lo, np.minimum(0.0, outer_lo))
    np.testing.assert_allclose(hi, np.maximum(1.0, outer_hi))
    if cut_depth == 1.0:
        np.testing.assert_array_equal(lo, 0.0)
        np.testing.assert_array_equal(hi, 1.0)
    else:
        assert np.all(lo < 0.0) and np.all(hi > 1.0)


def test_cut_depth_is_a_fraction_of_the_radius():
    base = dict(shape="box", n_particles=1000)
    for bad in (-0.1, 1.5):
        with pytest.raises(P.ParamError, match="shell_cut_depth"):
            P.resolve(dense_params.PARAMS, dict(base, shell_cut_depth=bad))


def test_merge_keeps_unmoved_contacts_and_takes_the_new_ones():
    moved = np.array([True, False, False, True])
    kept = (np.array([[0, 1], [1, 2], [2, 3]]), np.array([10.0, 20.0, 30.0]))
    new = (np.array([[0, 1], [0, 3], [1, 2]]), np.array([11.0, 12.0, 99.0]))
    pair, force = shell.merge_contacts(moved, kept, new)
    # (1, 2) joins two unmoved spheres: the tiled value stays, YADE's copy is dropped
    assert sorted(map(tuple, pair.tolist())) == [(0, 1), (0, 3), (1, 2)]
    assert dict(zip(map(tuple, pair.tolist()), force)) == {(1, 2): 20.0, (0, 1): 11.0,
                                                          (0, 3): 12.0}


def test_pressed_box():
    lo, hi = np.array([0.1, 0.2, 0.3]), np.array([1.1, 1.4, 2.3])
    box = shell.pressed_box(lo, hi)
    np.testing.assert_allclose(box.size, hi - lo)
    assert box.volume == pytest.approx(np.prod(hi - lo))
    np.testing.assert_allclose(box.centre, box.size / 2)


def _cubic_lattice(n=12, r=1e-3):
    """A simple cubic lattice of n^3 touching spheres filling the box [0, 2 n r]^3 exactly, with
    its six faces as plane walls touched by the outer layers (overlap 0, force 1 N)."""
    from thermal_kernel.packing import Packing
    from yade_scripts.neighbours import neighbour_pairs
    g = (np.indices((n, n, n)).reshape(3, -1).T * 2 + 1) * r
    radius = np.full(len(g), r)
    pair, branch = neighbour_pairs(g, radius, 0.01)
    names, particle, index = [], [], []
    for axis in range(3):
        for k, side in enumerate(("min", "max")):
            w = len(names)
            names.append("xyz"[axis] + side)
            on = np.flatnonzero(np.isclose(g[:, axis], r if k == 0 else (2 * n - 1) * r))
            particle.append(on)
            index.append(np.full(len(on), w, np.int32))
    particle, index = np.concatenate(particle), np.concatenate(index)
    return Packing(position=g, radius=radius, phase=np.zeros(len(g), np.int32), pair=pair,
                   overlap=2 * r - np.linalg.norm(branch, axis=1), normal_force=np.ones(len(pair)),
                   branch=branch, wall_name=names, wall_kind=["plane"] * 6,
                   wall_particle=particle, wall_index=index, wall_overlap=np.zeros(len(particle)),
                   wall_normal_force=np.ones(len(particle)), domain_lo=np.zeros(3),
                   domain_hi=np.full(3, 2 * n * r))


def test_wall_layers_of_a_cubic_lattice():
    """A simple cubic lattice: φ averaged over one period (a diameter) is π/6 exactly, φ at the
    wall is 0 and at a layer's mid-plane π/4; the wall layer's spheres have 5 neighbours (the
    wall is not one), deeper layers 6; one wall contact per d²."""
    from tdem_post.wall_layers import wall_layers
    layers = wall_layers(_cubic_lattice(), depth_d=3.0, slab_d=0.1, edge_margin_d=2.0,
                         layer_d=1.0)
    assert layers.walls_used == 6
    np.testing.assert_allclose(layers.solid_fraction[:10].mean(), np.pi / 6, rtol=1e-12)
    np.testing.assert_allclose(layers.solid_fraction[10:20].mean(), np.pi / 6, rtol=1e-12)
    # slab 0.4-0.5 d and 0.5-0.6 d straddle the mid-plane: the exact segment average
    x = np.array([0.4, 0.5]) * 2 - 1          # in radii, from the centre
    expected = np.pi * ((x[1] - x[1] ** 3 / 3) - (x[0] - x[0] ** 3 / 3)) / (x[1] - x[0]) / 4
    np.testing.assert_allclose(layers.solid_fraction[4], expected, rtol=1e-12)
    np.testing.assert_allclose(layers.z_with_gaps, [5.0, 6.0, 6.0])
    np.testing.assert_allclose(layers.wall_contacts_per_d2, 1.0)


def test_cloud_layer_puts_the_outer_layer_back_loose_without_overlaps():
    """shell_cloud_diameters: the spheres within layer_m of the faces leave their place and are
    put back at random in the grown box's outer layer, at the layer's solid fraction, overlapping
    neither each other nor the spheres that stay (up to the 1 % the obstacles are shrunk by);
    the spheres that stay are moved by the margin only; the same seed gives the same cloud."""
    # a dense stand-in for the carved packing: an fcc lattice of touching distance 0.03 with
    # radii 0.9-1.0 of 0.015 (solid fraction ~0.64)
    rng = np.random.default_rng(5)
    box = Container("box", 0.3 ** 3, [1.0, 1.0, 1.0])
    a = 0.03 * np.sqrt(2.0)
    cube = np.arange(0.015, 0.3 - 0.015, a)
    base = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]]) * a
    grid = np.stack(np.meshgrid(cube, cube, cube, indexing="ij"), -1).reshape(-1, 3)
    centres = (grid[:, None] + base[None]).reshape(-1, 3)
    centres = centres[np.all(centres <= 0.3 - 0.015, axis=1)]
    radius = 0.015 * rng.uniform(0.9, 1.0, len(centres))
    layer_m = 0.07
    position, moved, grown = shell.cloud_layer(box, centres, radius, layer_m, seed=11,
                                               solid_fraction=0.25)
    margin = (grown[0] - 0.3) / 2
    assert margin > 0
    np.testing.assert_allclose(grown, 0.3 + 2 * margin)
    distance = np.min(np.concatenate([centres, 0.3 - centres], axis=1), axis=1)
    np.testing.assert_array_equal(moved, distance < layer_m)
    np.testing.assert_allclose(position[~moved], centres[~moved] + margin, rtol=0, atol=1e-15)
    # the cloud is inside the grown box and in its outer layer (layer_m + margin thick)
    cloud, r = position[moved], radius[moved]
    assert np.all(cloud - r[:, None] >= 0) and np.all(cloud + r[:, None] <= grown)
    depth = np.min(np.concatenate([cloud, grown - cloud], axis=1), axis=1)
    assert np.all(depth < layer_m + margin)
    # the layer's solid fraction is the one asked for
    layer_volume = np.prod(grown) - (0.3 - 2 * layer_m) ** 3
    np.testing.assert_allclose(np.sum(4 / 3 * np.pi * r ** 3) / layer_volume,
                               0.25, rtol=1e-9)
    # no overlap: cloud-cloud, and cloud-stay beyond the obstacles' 1 %
    d = np.linalg.norm(cloud[:, None] - position[None], axis=2)
    reach = r[:, None] + radius[None] * np.where(moved, 1.0, 0.99)[None]
    d[np.arange(len(cloud)), np.flatnonzero(moved)] = np.inf       # itself
    assert np.all(d > reach)
    again, _, _ = shell.cloud_layer(box, centres, radius, layer_m, seed=11, solid_fraction=0.25)
    np.testing.assert_array_equal(again, position)

