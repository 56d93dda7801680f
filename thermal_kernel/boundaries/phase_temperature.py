"""``kind = "phase_temperature"``: every particle of one phase held at a temperature."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .base import BoundaryKind, BuildContext, Rows, read_temperature

# the packing attribute `tdem import liggghts` writes: the LIGGGHTS atom types in phase order
LIGGGHTS_TYPES_ATTR = "liggghts_atom_types"


def _integer(t, key: str, minimum: int) -> int:
    value = t.number(key)
    if value != int(value) or value < minimum:
        t.fail(key, f"expected an integer >= {minimum}, got {value!r}")
    return int(value)


@dataclass(frozen=True, kw_only=True)
class PhaseTemperatureBoundary(BoundaryKind):
    """Holds every particle of one phase at a fixed temperature (Dirichlet): T_p = ``value``
    (K) for each p with ``phase`` p = the given phase.

    This is how LIGGGHTS holds a layer: ``fix heat/gran/conduction`` updates only the atoms of
    its group, so atoms of a type left out of the group keep their temperature. Name the phase
    either as tdem's ``phase`` (the packing's ``particles/phase``, from 0) or as the LIGGGHTS
    atom type ``liggghts_type`` (from 1), mapped to the phase through the packing attribute
    ``liggghts_atom_types`` that ``tdem import liggghts`` writes (the types present, in phase
    order: types 1, 3 present give phases 0, 1). The heat it gives the network is
    sum_q H_pq (T_p - T_q) over its particles (W). A particle already held by an earlier
    boundary of the scene stays with that one.

    Keys: exactly one of ``phase`` (integer >= 0) and ``liggghts_type`` (integer >= 1);
    ``value`` (K, > 0); ``name`` (default ``phase_temperature:phase<k>`` or
    ``phase_temperature:type<k>``).
    """
    kind: ClassVar[str] = "phase_temperature"
    unit: ClassVar[str] = "K"
    example: ClassVar[str] = 'liggghts_type = 2\nvalue = 400.0'  # tests/test_liggghts_law.py
    example_name: ClassVar[str] = "phase_temperature:type2"
    value: float                     # K
    phase: int | None = None
    liggghts_type: int | None = None

    @classmethod
    def parse(cls, t) -> PhaseTemperatureBoundary:
        if t.has("phase") == t.has("liggghts_type"):
            t.fail("", "expected exactly one of phase = <tdem phase, from 0> and "
                       "liggghts_type = <LIGGGHTS atom type, from 1>")
        if t.has("phase"):
            phase, ltype, label = _integer(t, "phase", 0), None, "phase"
        else:
            phase, ltype, label = None, _integer(t, "liggghts_type", 1), "type"
        value = read_temperature(t)
        number = phase if phase is not None else ltype
        return cls(name=t.string("name", default=f"{cls.kind}:{label}{number}"), value=value,
                   phase=phase, liggghts_type=ltype)

    def resolved_phase(self, ctx: BuildContext, where: str) -> int:
        """The packing's phase this boundary names (a LIGGGHTS type mapped through the
        packing's ``liggghts_atom_types``)."""
        if self.phase is not None:
            return self.phase
        text = ctx.packing.attrs.get(LIGGGHTS_TYPES_ATTR)
        if text is None:
            raise ctx.error(f"{where}.liggghts_type",
                            f"{ctx.packing.path} has no attribute {LIGGGHTS_TYPES_ATTR} (not "
                            "made by `tdem import liggghts`); expected phase = <phase> instead")
        types = [int(x) for x in str(text).split()]
        if self.liggghts_type not in types:
            raise ctx.error(f"{where}.liggghts_type",
                            f"type {self.liggghts_type} is not in {ctx.packing.path} (its "
                            f"LIGGGHTS atom types: {' '.join(map(str, types))})")
        return types.index(self.liggghts_type)

    def contribute(self, ctx: BuildContext, index: int, rows: Rows) -> None:
        where = f"boundary[{index}]"
        phase = self.resolved_phase(ctx, where)
        particles = np.flatnonzero(np.asarray(ctx.packing.phase) == phase)
        if ctx.whole.count(particles.size) == 0:
            present = " ".join(map(str, ctx.whole.union(ctx.packing.phase)))
            raise ctx.error(f"{where}.phase" if self.phase is not None
                            else f"{where}.liggghts_type",
                            f"no particle of phase {phase} in {ctx.packing.path} (its phases: "
                            f"{present})")
        rows.hold(index, particles, self.value)
