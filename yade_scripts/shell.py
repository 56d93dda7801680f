"""method = "shell" (issue 24): a walled domain from a tiled periodic cell, relaxed only near
its walls. numpy only (runs under YADE and in the tests); the YADE part is
``dense_packing.press_shell``.

The tiled path (tiling.py) fills the domain with copies of a relaxed periodic cell and carves it:
its faces are cut surfaces, a different material at the boundary from a packing pressed into a
container (looser, layered, with real wall forces). Here the carved domain keeps the spheres whose
centre lies at least ``shell_cut_depth`` of their radii inside it (0, the default: every centre
inside, so the kept material fills the box as the bulk does; 1: only whole spheres, which leaves
a layer ~0.4 mean diameters short of packing along each face), and plane walls start at the kept
spheres' extent (walls_start). The spheres within ``shell_diameters`` mean diameters of the
surface (the shell) are free, the next band (frozen_band_m) is held where the cell put them as the
shell's inner boundary, and the interior does not enter YADE at all. YADE then presses the walls
onto the shell to the confining pressure (servo-controlled walls, the direct path's
softened-modulus stages; every radius in YADE, free or frozen, scaled to the stage's Hertz
overlap, as the direct path's radius controller scales them all), so the cost grows with the
surface, not the volume. Contacts between two spheres that did not move keep the cell's values;
every contact of a shell sphere and every wall contact is YADE's.
"""
import numpy as np

from .dense_geometry import Container

# The frozen band must hold every sphere a shell sphere can touch: two of the largest diameters
# (a Gaussian σ/μ 0.3 truncated at 2σ has r_max = 1.6 r_mean, so 3.2 mean diameters) with the
# neighbour criterion's margin; it is sized from the actual radii (frozen_band_m).
FROZEN_MARGIN = 1.2

# Above this many spheres a walled domain (box, cylinder, sphere) with method = "auto" is made by
# the shell path; at or below it by the direct relaxation (~4 min at 1e4 on one YADE thread).
AUTO_SHELL_ABOVE = 20000


# The shapes the shell path can make: press_shell moves plane walls only (a cylinder's mantle and
# a spherical container are facets; moving them is not written, nor compared with the direct
# reference).
SHELL_SHAPES = ("box",)

# The shapes for which method = "auto" picks the shell path above AUTO_SHELL_ABOVE spheres: none
# yet. Measured on the 1e4 box against three direct seeds (docs/packings.md, 2026-12-02): bulk
# phi, the non-rattlers' Z and Haddad's C_t match, but the walls carry 6.6 % fewer contacts per
# area and the pipe law's gamma is 2.1 % low (tolerances 3 % and 1 %), and at 1e5 the shell costs
# about what the direct box does (~22,000 steps of 73 % of the spheres); "auto" stays direct and
# "shell" must be asked for.
AUTO_SHELL_SHAPES = ()


def resolve_method(shape, method, n_particles):
    """The method "auto" stands for: shell for a shape of AUTO_SHELL_SHAPES with more than
    AUTO_SHELL_ABOVE spheres, direct otherwise; any other method is kept."""
    if method != "auto":
        return method
    if shape in AUTO_SHELL_SHAPES and n_particles > AUTO_SHELL_ABOVE:
        return "shell"
    return "direct"


def boundary_distance(box, position):
    """Distance of each centre to the nearest wall of the domain (positive inside)."""
    return np.min([box.distance_to_wall(w, position) for w in box.walls()], axis=0)


def frozen_band_m(radius, gap_tolerance):
    """Thickness of the frozen band: a shell sphere's reach (its diameter plus a neighbour's,
    with the neighbour criterion's margin) for the largest spheres."""
    return 2.0 * float(np.max(radius)) * (1.0 + gap_tolerance) * FROZEN_MARGIN


def split(box, position, radius, shell_m, band_m, cut_depth=1.0):
    """(kept, shell, band): spheres whose centre lies at least cut_depth of their radii inside
    the domain (1: wholly inside, so a wall can sit on its surface; less: they protrude and the
    walls start at their extent, walls_start), and among them those of the free shell (centre
    within shell_m of the surface) and of the frozen band behind it (the next band_m)."""
    distance = boundary_distance(box, position)
    whole = distance >= cut_depth * radius
    shell = whole & (distance < shell_m)
    band = whole & ~shell & (distance < shell_m + band_m)
    return whole, shell, band


def merge_contacts(moved, kept, new):
    """The contacts of the pressed domain: ``kept`` = (pair, *columns) of the tiled domain,
    whose rows between two spheres that did not move stay as they are; ``new`` = (pair,
    *columns) from YADE's state of the free and frozen spheres, in global indices, whose rows
    touching a moved sphere replace the rest. Returns (pair, *columns)."""
    pair_k, pair_n = kept[0], new[0]
    stay = ~(moved[pair_k[:, 0]] | moved[pair_k[:, 1]])
    fresh = moved[pair_n[:, 0]] | moved[pair_n[:, 1]]
    return tuple(np.concatenate([a[stay], b[fresh]]) for a, b in zip(kept, new))


def pressed_box(lo, hi):
    """The Container of the pressed box between wall positions lo and hi: the domain is what the
    walls enclose after pressing, not the size the cell was carved to."""
    size = np.asarray(hi, dtype=float) - np.asarray(lo, dtype=float)
    box = Container("box", float(np.prod(size)), size / size.max())
    box.size = size.copy()
    box.centre = box.size / 2
    return box


def walls_start(box, position, radius):
    """(lo, hi) where the plane walls of a box start: its surface, or the extent of the spheres
    that protrude past it (shell_cut_depth < 1)."""
    lo = np.minimum(0.0, np.min(position - radius[:, None], axis=0))
    hi = np.maximum(np.asarray(box.size, dtype=float), np.max(position + radius[:, None], axis=0))
    return lo, hi


# The outer layer re-inserted as a cloud (shell_cloud_diameters > 0): the walls start where the
# layer holds its spheres at its solid fraction in the direct box, and the spheres are put back
# shrunk by CLOUD_SHRINK (a loose cloud, ~0.26; the direct path's cloud is at 0.25) and grown back
# against the walls in YADE (press_shell), as the direct path grows its cloud against fixed
# walls. Pressing walls onto the layer instead puts the largest spheres on the wall and pushes the
# small ones away from it (17 % fewer centres within 0.25-0.5 mean diameters of the wall, 6.6 %
# fewer wall contacts, docs/packings.md).
# The layer's solid fraction in the direct box: the bulk's, less a deficit at the wall of
# WALL_DEFICIT_D mean diameters of solid per area (the direct 1e4 boxes, 3 seeds: the centres
# within 1.5 d̄ of a wall fill that layer at 0.578, within 3 d̄ at 0.617, bulk 0.654: 0.115 and
# 0.111 d̄), so a layer t mean diameters thick is at phi_bulk - WALL_DEFICIT_D / t.
WALL_DEFICIT_D = 0.112


def layer_solid_fraction(bulk_solid_fraction, layer_diameters):
    """The solid fraction of the outer layer_diameters of a walled box (WALL_DEFICIT_D)."""
    return bulk_solid_fraction - WALL_DEFICIT_D / layer_diameters


CLOUD_SHRINK = 0.75
# candidates in the layer per sphere before the placement gives up
CLOUD_TRIES = 20_000
def cloud_layer(box, position, radius, layer_m, seed, solid_fraction, shrink=1.0):
    """The outer layer of a carved box as a cloud: the spheres whose centre lies within layer_m
    of the surface (every sphere cut by it among them) leave their place; the box grows by a
    margin on each side so that the layer (its thickness now layer_m + margin) holds them at
    ``solid_fraction`` at their own radii, and they are put back at random in it with their
    radii times ``shrink`` (random sequential addition, largest first, candidates from one
    stream seeded by ``seed``; the spheres that stay are obstacles, their radii less 1 %: they
    overlap each other by the Hertz overlaps of the cell).

    Returns (position in the grown box, whether each sphere was re-inserted, grown box size)."""
    from thermal_kernel.placement import random_sequential_addition
    size = np.asarray(box.size, dtype=float)
    moved = boundary_distance(box, position) < layer_m
    inner = np.prod(np.maximum(size - 2.0 * layer_m, 0.0))
    target = float(np.sum(4.0 / 3.0 * np.pi * radius[moved] ** 3)) / solid_fraction + inner
    # the grown box's volume prod(size + 2 margin) = target: bisection on the margin
    lo_m, hi_m = 0.0, float(size.max())
    for _ in range(100):
        margin = 0.5 * (lo_m + hi_m)
        lo_m, hi_m = (margin, hi_m) if np.prod(size + 2.0 * margin) < target else (lo_m, margin)
    grown = size + 2.0 * margin
    stay = np.flatnonzero(~moved)
    # obstacles: the spheres that stay within reach of the layer
    reach = layer_m + 2.0 * float(radius.max())
    near = stay[boundary_distance(box, position[stay]) < reach]
    order = np.flatnonzero(moved)[np.argsort(-radius[moved], kind="stable")]
    rng = np.random.default_rng(seed)
    start = position[near] + margin
    band = layer_m + margin

    # one stream of candidate centres for all the cloud's spheres, drawn in the grown box a
    # batch at a time and kept where they lie in the layer
    stream = {"buffer": [], "used": 0}

    def layer_candidate():
        while stream["used"] == len(stream["buffer"]):
            c = rng.random((4096, 3)) * grown
            depth = np.min(np.minimum(c, grown - c), axis=1)
            stream["buffer"], stream["used"] = c[depth < band].tolist(), 0
        stream["used"] += 1
        return stream["buffer"][stream["used"] - 1]

    def candidates(k, r):
        if k < len(near):
            yield tuple(float(v) for v in start[k])
            return
        for _ in range(CLOUD_TRIES):
            x, y, z = layer_candidate()
            if min(x, y, z) >= r and x + r <= grown[0] and y + r <= grown[1] \
                    and z + r <= grown[2]:
                yield x, y, z

    radii = np.concatenate([radius[near] * 0.99, radius[order] * shrink])
    placed = random_sequential_addition(radii, candidates)
    if len(placed) < len(near):
        raise ValueError("shell_cloud_diameters: the spheres that stay overlap by more than 1 % "
                         "of their radii; cannot place the cloud around them")
    if len(placed) < len(radii):
        raise ValueError(f"shell_cloud_diameters: placed {len(placed) - len(near)} of "
                         f"{len(order)} spheres of the outer layer at solid fraction "
                         f"{solid_fraction * shrink ** 3:.3g}")
    out = position + margin
    out[order] = placed[len(near):]
    return out, moved, grown

