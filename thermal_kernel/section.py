"""The cross-section of a packing normal to an axis, which a flux needs (A in q = Q / A): the
box face, or pi R^2 for a cylinder wall along the axis; any other section (a sphere container, a
cylinder across the axis, a tilted plane) has no constant area and is refused in one line rather
than replaced by the bounding-box face. Used by the flux boundary, the flux test of
``calibrate.py`` and post (one home below all three)."""
from __future__ import annotations

import math

import numpy as np

from .packing import Packing, PackingError

AXES = "xyz"


def _axis_of(vector) -> str | None:
    """'x', 'y' or 'z' if ``vector`` is parallel to that axis (to 1e-9), else None."""
    v = np.abs(np.asarray(vector, dtype=float))
    k = int(np.argmax(v))
    return AXES[k] if abs(v[k] - 1.0) < 1e-9 else None


def section_problem(packing: Packing, axis: int) -> str | None:
    """Why the cross-section of ``packing`` normal to ``axis`` is neither a box face nor a
    cylinder's disc (a cylinder wall along the axis); None if it is one of those.

    Only those two have a constant, known area A, which lambda^e = Q L / (A dT) needs: a sphere
    container, a cylinder lying across the axis or a tilted plane make A vary along the axis
    (and the held "faces" are lines or points of the bounding box)."""
    name = AXES[axis]
    for wall, kind, normal in zip(packing.wall_name, packing.wall_kind, packing.wall_normal):
        if kind == "sphere":
            return (f"wall {wall!r} is a sphere: its sections are discs of varying radius, "
                    "not the bounding-box face")
        along = _axis_of(normal)
        if kind == "cylinder" and along != name:
            return (f"wall {wall!r} is a cylinder along {along or 'a tilted axis'}: its section "
                    f"normal to {name} is not the bounding-box face")
        if kind == "plane" and along is None:
            return f"plane wall {wall!r} is not normal to x, y or z"
    return None


def flux_axes(packing: Packing) -> tuple[str, ...]:
    """The axes along which the flux test is defined: not periodic, and the cross-section a box
    face or a cylinder's disc."""
    return tuple(a for k, a in enumerate(AXES)
                 if not packing.periodic[k] and section_problem(packing, k) is None)


def cross_section(packing: Packing, axis: int) -> float:
    """Area normal to ``axis``: pi R^2 for a cylinder wall along the axis, else the box face.
    Any other section (a sphere container, a cylinder across the axis) is refused
    (:class:`PackingError`, one line) rather than replaced by the bounding-box face."""
    problem = section_problem(packing, axis)
    if problem is not None:
        usable = ", ".join(flux_axes(packing)) or "none"
        raise PackingError(f"{packing.path}: walls: no cross-section area normal to "
                           f"{AXES[axis]}: {problem} (expected a box face or a cylinder along "
                           f"{AXES[axis]}; axes with one: {usable})")
    for kind, normal, radius in zip(packing.wall_kind, packing.wall_normal, packing.wall_radius):
        if kind == "cylinder" and abs(abs(normal[axis]) - 1.0) < 1e-9:
            return math.pi * float(radius) ** 2
    extent = np.delete(packing.domain_hi - packing.domain_lo, axis)
    return float(extent[0] * extent[1])
