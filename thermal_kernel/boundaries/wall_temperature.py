"""``kind = "wall_temperature"``: heat exchange with a wall held at a temperature."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..laws.base import WallContactInput
from .base import BoundaryKind, BuildContext, Rows, members, read_temperature


@dataclass(frozen=True, kw_only=True)
class WallTemperatureBoundary(BoundaryKind):
    """A wall held at Tw = ``value`` (K) that exchanges heat with the particles touching it.

    Each wall contact k (particle p) of the wall ``on`` gives g_k (Tw - T_p) (W), g_k (W/K)
    the law's particle-wall conductance (``Law.wall_conductance``) of that contact: the
    particle's radius, the wall overlap and normal force, the particle's conductivity and the
    wall's (``wall_conductivity``, W/m/K; default: the particle's). A particle is not held:
    its temperature lies between Tw and its neighbours'.

    Keys: ``on`` (a wall of the packing), ``value`` (K, > 0), ``wall_conductivity``
    (optional, W/m/K > 0), ``name`` (default ``wall_temperature:<on>``).
    """
    kind: ClassVar[str] = "wall_temperature"
    unit: ClassVar[str] = "K"
    example: ClassVar[str] = 'on = "xmin"\nvalue = 400.0\nwall_conductivity = 2.0'
    example_name: ClassVar[str] = "wall_temperature:xmin"
    on: str
    value: float                     # K
    wall_conductivity: float = math.nan   # W/m/K; NaN = the particle's

    @classmethod
    def parse(cls, t) -> WallTemperatureBoundary:
        on = t.string("on")
        value = read_temperature(t)
        return cls(name=t.string("name", default=f"{cls.kind}:{on}"), on=on, value=value,
                   wall_conductivity=t.number("wall_conductivity", default=math.nan, positive=True))

    def contribute(self, ctx: BuildContext, index: int, rows: Rows) -> None:
        where = f"boundary[{index}]"
        packing, law = ctx.packing, ctx.law
        members(ctx, self.on, where)
        if self.on not in packing.wall_name:
            raise ctx.error(f"{where}.on", f"{self.on!r} is not a wall of {packing.path} "
                                           f"(walls: {', '.join(packing.wall_name) or 'none'})")
        if law.wall_conductance is None:
            raise ctx.error(f"{where}.kind", f"law {law.name!r} has no particle–wall "
                                             "conductance; use kind = \"temperature\"")
        w = packing.wall_name.index(self.on)
        contact = np.flatnonzero(packing.wall_index == w)
        p = packing.wall_particle[contact]
        kp = ctx.particles.conductivity[p]
        kw = kp if math.isnan(self.wall_conductivity) else np.full(p.size,
                                                                   self.wall_conductivity)
        g = law.wall_conductance(WallContactInput(
            radius_m=packing.radius[p], overlap_m=packing.wall_overlap[contact],
            normal_force_n=packing.wall_normal_force[contact], conductivity_particle=kp,
            conductivity_wall=kw, young_pa=ctx.young_pa, poisson=ctx.poisson), ctx.params)
        rows.exchange(index, p, g, self.value)
