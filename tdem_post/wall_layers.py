"""Statistics of the layer a wall imposes on a packing (issue 24: is a walled packing made by a
faster path the same as the direct walled relaxation near its walls?).

For each plane wall of a box, only the central part of the face is used (centres at least
``edge_margin`` from the four other walls), so edges and corners do not blur the profile:

* ``solid_fraction_profile``: φ(distance from the wall) in slabs parallel to it, each sphere's
  exact volume inside the slab (a spherical segment) over the slab's volume;
* ``coordination_profile``: the mean number of dumped neighbours (touching + gap neighbours of the
  dump's criterion) and of touching neighbours of the spheres whose centre is in each slab;
* ``wall_contacts_per_area``: the wall contacts that carry a force (or overlap) per wall area,
  in units of 1 / mean diameter².

Distances and slab widths are in mean diameters (d̄ = 2 r̄ of the packing). numpy only.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from thermal_kernel.packing import Packing

AXES = "xyz"


@dataclass(frozen=True)
class WallLayers:
    """Near-wall profiles of one packing, averaged over its plane walls (box faces)."""
    distance_over_d: np.ndarray          # slab centres, distance from the wall / d̄
    solid_fraction: np.ndarray           # φ per slab
    z_with_gaps: np.ndarray              # dumped neighbours per sphere, centres in the slab
    z_touching: np.ndarray               # touching neighbours per sphere, centres in the slab
    wall_contacts_per_d2: float          # wall contacts with a force per wall area × d̄²
    walls_used: int


def plane_walls(packing: Packing) -> list[tuple[int, int, float]]:
    """(wall index, axis, sign) of the plane walls named like box faces (xmin ... zmax): sign +1
    for a *min wall (the domain lies at larger coordinates)."""
    out = []
    for w, (name, kind) in enumerate(zip(packing.wall_name, packing.wall_kind)):
        if kind == "plane" and len(name) == 4 and name[0] in AXES and name[1:] in ("min", "max"):
            out.append((w, AXES.index(name[0]), 1.0 if name.endswith("min") else -1.0))
    return out


def _segment_volume(radius, lo, hi):
    """Volume of the part of a sphere (centre 0, radius r) between the planes lo < hi (all
    arrays): ∫ π (r² - x²) dx over [max(lo, -r), min(hi, r)]."""
    a = np.clip(lo, -radius, radius)
    b = np.clip(hi, -radius, radius)
    f = lambda x: np.pi * (radius ** 2 * x - x ** 3 / 3.0)      # noqa: E731
    return f(b) - f(a)


def _face(packing: Packing, axis: int, sign: float, edge_margin_m: float):
    """Distance of every centre from the wall, and the mask of centres in the face's central
    part (at least edge_margin from the other walls), and that central part's area."""
    lo, hi = packing.domain_lo, packing.domain_hi
    x = packing.position
    distance = (x[:, axis] - lo[axis]) if sign > 0 else (hi[axis] - x[:, axis])
    central = np.ones(len(x), dtype=bool)
    area = 1.0
    for k in range(3):
        if k == axis:
            continue
        central &= (x[:, k] >= lo[k] + edge_margin_m) & (x[:, k] <= hi[k] - edge_margin_m)
        area *= max(float(hi[k] - lo[k]) - 2.0 * edge_margin_m, 0.0)
    return distance, central, area


def wall_layers(packing: Packing, depth_d: float = 5.0, slab_d: float = 0.1,
                edge_margin_d: float = 5.0, layer_d: float = 0.5) -> WallLayers:
    """φ in slabs of ``slab_d`` and Z in layers of ``layer_d`` mean diameters over the first
    ``depth_d`` from every plane wall, averaged over the walls (central parts of the faces)."""
    d_mean = 2.0 * float(packing.radius.mean())
    walls = plane_walls(packing)
    if not walls:
        raise ValueError(f"{packing.path}: no plane wall named xmin ... zmax (a box's faces)")
    edges = np.arange(0.0, depth_d + 1e-9, slab_d) * d_mean
    z_edges = np.arange(0.0, depth_d + 1e-9, layer_d) * d_mean
    n = packing.n_particles
    z_all = np.bincount(packing.pair.reshape(-1), minlength=n)
    touching = packing.overlap > 0
    z_touch = np.bincount(packing.pair[touching].reshape(-1), minlength=n)
    phi = np.zeros(len(edges) - 1)
    z_gap_sum = np.zeros(len(z_edges) - 1)
    z_touch_sum = np.zeros(len(z_edges) - 1)
    z_count = np.zeros(len(z_edges) - 1)
    wall_contacts = 0
    wall_area = 0.0
    for w, axis, sign in walls:
        distance, central, area = _face(packing, axis, sign, edge_margin_d * d_mean)
        r = packing.radius
        near = central & (distance - r < edges[-1])
        for b in range(len(edges) - 1):
            vol = _segment_volume(r[near], edges[b] - distance[near], edges[b + 1] - distance[near])
            phi[b] += vol.sum() / (area * (edges[b + 1] - edges[b]))
        layer = np.digitize(distance, z_edges) - 1
        sel = central & (layer >= 0) & (layer < len(z_edges) - 1)
        z_gap_sum += np.bincount(layer[sel], weights=z_all[sel], minlength=len(z_count))
        z_touch_sum += np.bincount(layer[sel], weights=z_touch[sel], minlength=len(z_count))
        z_count += np.bincount(layer[sel], minlength=len(z_count))
        on_wall = packing.wall_index == w
        carries = (packing.wall_normal_force > 0) | (packing.wall_overlap > 0)
        wall_contacts += int(np.sum(on_wall & carries & central[packing.wall_particle]))
        wall_area += area
    centres = 0.5 * (edges[:-1] + edges[1:]) / d_mean
    with np.errstate(invalid="ignore", divide="ignore"):
        z_gap = z_gap_sum / z_count
        z_t = z_touch_sum / z_count
    return WallLayers(
        distance_over_d=centres, solid_fraction=phi / len(walls),
        z_with_gaps=z_gap,
        z_touching=z_t, wall_contacts_per_d2=wall_contacts * d_mean ** 2 / wall_area,
        walls_used=len(walls))


def layer_centres(depth_d: float = 5.0, layer_d: float = 0.5) -> np.ndarray:
    """Centres of the coordination layers of :func:`wall_layers`, in mean diameters."""
    edges = np.arange(0.0, depth_d + 1e-9, layer_d)
    return 0.5 * (edges[:-1] + edges[1:])
