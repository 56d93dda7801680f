"""A packing's statistics as its importers derive them and ``tdem info`` re-derives them: the
domain between axis-normal walls, the solid fraction, the pressure on the walls, the force-law
check (numpy and the standard library only).

One module for the three users, so that a number means the same wherever it is printed:
``yade_scripts/tdem_yade.py::dump`` (under Debian's YADE, which imports it as the package
``thermal_kernel.packing_stats`` with the repository on its path), ``tdem import liggghts``
(``tdem/liggghts.py``) and ``tdem info``, which recomputes the solid fraction and the wall
pressure from what the file holds and says whether they are the stored ones.

Walls here are axis-normal planes given as ``(name, axis, side, coordinate)`` with ``side``
"min" (the wall bounds the domain from below along ``axis``: its normal points to +axis) or
"max".
"""
from __future__ import annotations

import math

import numpy as np

from . import contact_check

PLATE = "plate"          # the wall whose force gives the pressure when there is one


def domain_box(position, radius, walls, periodic=(False, False, False), box_lo=None,
               box_hi=None):
    """(lo, hi, inferred): the domain bounded along each axis by the periodic box, by the
    innermost axis-normal wall of each side, else by the spheres' bounding box; ``inferred`` is
    the sentence naming the axes (and sides) taken from the bounding box, or None."""
    position, radius = np.asarray(position, float), np.asarray(radius, float)
    lo = (position - radius[:, None]).min(axis=0)
    hi = (position + radius[:, None]).max(axis=0)
    free = []
    for ax in range(3):
        if periodic[ax]:
            lo[ax], hi[ax] = box_lo[ax], box_hi[ax]
            continue
        mins = [c for _, axis, side, c in walls if axis == ax and side == "min"]
        maxs = [c for _, axis, side, c in walls if axis == ax and side == "max"]
        if mins:
            lo[ax] = max(mins)
        if maxs:
            hi[ax] = min(maxs)
        if not (mins and maxs):
            free.append("xyz"[ax] + ("" if not (mins or maxs) else
                                     f" ({'max' if mins else 'min'} side)"))
    inferred = ("domain: " + ", ".join(free) + " from the spheres' bounding box (no wall there)"
                if free else None)
    return lo, hi, inferred


def solid_fraction(radius, lo, hi, cap_radius=(), cap_overlap=()) -> float:
    """Sphere volume inside the box [lo, hi] over its volume: every sphere, less the caps
    beyond the walls (``cap_radius``, ``cap_overlap``: the spheres and overlaps of the contacts
    with the walls that bound the box; a negative overlap is no cap)."""
    radius = np.asarray(radius, float)
    volume = float(np.prod(np.asarray(hi, float) - np.asarray(lo, float)))
    v_solid = float(np.sum(4.0 / 3.0 * np.pi * radius ** 3))
    h = np.clip(np.asarray(cap_overlap, float), 0.0, None)
    if h.size:
        v_solid -= float(np.sum(np.pi * h ** 2 * (3 * np.asarray(cap_radius, float) - h) / 3.0))
    return v_solid / volume


def wall_pressure(walls, wall_index, wall_force, lo, hi) -> tuple[float, str | None]:
    """(pressure in Pa, how): the normal force on the wall named ``plate`` over the domain's face
    normal to it, else the mean of that over the axis-normal ``walls`` ((name, axis) pairs, in
    the file's wall order: ``wall_index`` numbers them); NaN and None without any."""
    wall_index, wall_force = np.asarray(wall_index), np.asarray(wall_force, float)
    size = np.asarray(hi, float) - np.asarray(lo, float)
    per_wall = {}
    for k, (name, axis) in enumerate(walls):
        if axis is None:
            continue
        per_wall[name] = float(wall_force[wall_index == k].sum()) / float(
            np.prod(np.delete(size, axis)))
    if PLATE in per_wall:
        return per_wall[PLATE], "the plate's normal force over the domain's face area"
    if per_wall:
        return (float(np.mean(list(per_wall.values()))),
                f"mean over {len(per_wall)} axis-normal walls of their normal force over the "
                "domain's face area")
    return math.nan, None


def hertz_check(force, r_i, r_j, overlap, young_pa, poisson, label) -> dict:
    """The force-law attributes (``contact_check.check``) of particle-particle contacts against
    Hertz, 4/3 E* sqrt(R*) delta^1.5 with E* of ``young_pa`` and ``poisson``."""
    r_i, r_j = np.asarray(r_i, float), np.asarray(r_j, float)
    e_star = contact_check.effective_modulus(young_pa, poisson)
    return contact_check.check(force, contact_check.hertz_force(r_i * r_j / (r_i + r_j), overlap,
                                                                e_star), label)


def recheck(packing) -> dict | None:
    """What ``tdem info`` re-derives from a packing's arrays with the functions above, beside
    the stored attributes: the solid fraction (``solid_fraction``) and the wall pressure
    (``pressure_pa``, ``pressure_from``: None when no axis-normal wall carries a force). None
    for a domain that is not a box (a cylinder or sphere wall: its volume and face are not the
    bounding box's)."""
    if any(kind != "plane" for kind in packing.wall_kind):
        return None
    walls = [(name, axis_of(normal)) for name, normal in zip(packing.wall_name,
                                                             packing.wall_normal)]
    bounding = np.array([walls[w][1] is not None for w in packing.wall_index], bool)
    phi = solid_fraction(packing.radius, packing.domain_lo, packing.domain_hi,
                         packing.radius[packing.wall_particle[bounding]],
                         packing.wall_overlap[bounding])
    pressure, how = wall_pressure(walls, packing.wall_index, packing.wall_normal_force,
                                  packing.domain_lo, packing.domain_hi)
    return dict(solid_fraction=phi,
                solid_fraction_stored=float(packing.attrs.get("solid_fraction", math.nan)),
                pressure_pa=pressure, pressure_from=how,
                pressure_pa_stored=float(packing.attrs.get("pressure_pa", math.nan)))


def describe_recheck(again: dict) -> str:
    """One line of :func:`recheck`'s numbers for ``tdem info``."""
    text = (f"solid fraction {again['solid_fraction']:.4f} (stored "
            f"{again['solid_fraction_stored']:.4f}); wall pressure ")
    if again["pressure_from"] is None:
        return text + "none (no axis-normal wall)"
    return text + (f"{again['pressure_pa']:.4g} Pa (stored {again['pressure_pa_stored']:.4g} "
                   f"Pa): {again['pressure_from']}")


def axis_of(normal, tol=1e-9):
    """The axis a plane's ``normal`` lies along (|n . e_a| > 1 - tol), else None."""
    normal = np.asarray(normal, float)
    for axis in range(3):
        if abs(normal[axis]) > 1.0 - tol:
            return axis
    return None
