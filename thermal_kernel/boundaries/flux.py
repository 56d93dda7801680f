"""``kind = "flux"``: a prescribed heat flux through a domain face."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .base import FACES, BoundaryKind, BuildContext, Rows, members


@dataclass(frozen=True, kw_only=True)
class FluxBoundary(BoundaryKind):
    """A constant heat flux q = ``value`` (W/m^2, > 0 into the packing) through a domain face.

    The total power q A (W), A the area of the face of the domain's box, enters the spheres
    that reach the face, shared in proportion to their cross-sections:
    P_p = q A r_p^2 / sum_f r_f^2. Constant in time; the maximum principle does not apply to a
    scene with non-zero flux.

    Keys: ``on`` (a domain face xmin..zmax of a non-periodic axis), ``value`` (W/m^2, any
    sign), ``name`` (default ``flux:<on>``).
    """
    kind: ClassVar[str] = "flux"
    on: str
    value: float                     # W/m^2

    @classmethod
    def parse(cls, t) -> FluxBoundary:
        on = t.string("on")
        value = t.number("value")
        return cls(name=t.string("name", default=f"{cls.kind}:{on}"), on=on, value=value)

    def contribute(self, ctx: BuildContext, index: int, rows: Rows) -> None:
        where = f"boundary[{index}]"
        p = members(ctx, self.on, where)
        area = self.face_area(ctx, where)
        share = ctx.packing.radius[p] ** 2
        rows.power(index, p, self.value * area * share / share.sum())

    def face_area(self, ctx: BuildContext, where: str) -> float:
        """A (m^2): the face ``on`` of the domain's box."""
        if self.on not in FACES:
            raise ctx.error(f"{where}.on", f"a flux boundary needs a domain face "
                                           f"({', '.join(FACES)}), got {self.on!r}")
        axis, _ = FACES[self.on]
        ext = np.delete(ctx.packing.domain_hi - ctx.packing.domain_lo, axis)
        return float(ext[0] * ext[1])
