"""Boundary kinds, registered by name (explicit dict, no discovery), as the laws are.

Each kind is a frozen dataclass (:class:`~thermal_kernel.boundaries.base.BoundaryKind`) in
its own module: its fields are the keys of its ``[[boundary]]`` table; ``parse`` reads and
checks them from the scene file; ``contribute`` turns it, on a packing, into rows of the
solvers' problem (held particles, exchange rows, constant power, a time-dependent source).
Its docstring says what it imposes, in which units, by which formula; ``docs/scenes.md``
describes each one.

A new kind: a module here with its class (``kind``, fields, ``parse``, ``contribute``,
docstring; ``unit``, ``example`` and ``example_name``, which ``tests/test_boundaries.py``
checks against the docstring and the parser), one line in :data:`BOUNDARIES`, and its
end-to-end test in ``tests/test_boundaries.py``. The solvers never change: they see rows, not kinds.
A kind sees only ``ctx.packing``'s particles, which on the PETSc backend's ranks are one rank's
(thermal_kernel/rank_build.py): a number it needs of every particle (a count for a "no particle"
refusal, a sum, the phases present, "any"/"all") goes through ``ctx.whole``
(:class:`~thermal_kernel.boundaries.base.Whole`), the identity in-process.
"""
from __future__ import annotations

import dataclasses

from .base import FACES, BoundaryKind, BuildContext, Rows, boundary_particles
from .flux import FluxBoundary
from .phase_temperature import PhaseTemperatureBoundary
from .source import SOURCE_SHAPES, MovingSource, SourceBoundary, source_time_intervals
from .temperature import TemperatureBoundary
from .wall_temperature import WallTemperatureBoundary

BOUNDARIES: dict[str, type[BoundaryKind]] = {
    "temperature": TemperatureBoundary,
    "flux": FluxBoundary,
    "wall_temperature": WallTemperatureBoundary,
    "source": SourceBoundary,
    "phase_temperature": PhaseTemperatureBoundary,
}


def keys(cls: type[BoundaryKind]) -> tuple[str, ...]:
    """The keys of a kind's ``[[boundary]]`` table besides ``kind``: its fields."""
    return tuple(f.name for f in dataclasses.fields(cls))


def parse_boundary(t) -> BoundaryKind:
    """One ``[[boundary]]`` table (a ``thermal_kernel.scene._Table``) as its kind's object.
    A key left over is refused: ``only for kind = "..."`` when another kind has it, else
    ``unknown key``."""
    kind = t.string("kind", choices=tuple(BOUNDARIES))
    cls = BOUNDARIES[kind]
    b = cls.parse(t)
    if not b.name.strip():
        t.fail("name", f"expected a non-empty name (it labels the boundary in the outputs), "
                       f"got {b.name!r}")
    if t.table:                       # the first leftover key, as _Table.done() reports it
        key = min(t.table)
        owners = [k for k, c in BOUNDARIES.items() if c is not cls and key in keys(c)]
        if owners:
            t.fail(key, "only for kind = " + " or ".join(f'"{k}"' for k in owners))
    t.done()
    return b


__all__ = ["BOUNDARIES", "FACES", "SOURCE_SHAPES", "BoundaryKind", "BuildContext",
           "FluxBoundary", "MovingSource", "PhaseTemperatureBoundary", "Rows", "SourceBoundary",
           "TemperatureBoundary",
           "WallTemperatureBoundary", "boundary_particles", "keys", "parse_boundary",
           "source_time_intervals"]
