"""``kind = "temperature"``: a Dirichlet boundary."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from .base import BoundaryKind, BuildContext, Rows, members, read_temperature


@dataclass(frozen=True, kw_only=True)
class TemperatureBoundary(BoundaryKind):
    """Holds the particles of a wall or a domain face at a fixed temperature (Dirichlet).

    Imposes T_p = ``value`` (K) for every particle p of ``on``: the particles in the wall's
    ``wall_contacts`` for a wall of the packing, or, for a domain face without a wall, the
    spheres that reach the face (x_p - r_p <= lo, or x_p + r_p >= hi). The heat it gives the
    network is sum_q H_pq (T_p - T_q) over its particles (W). A particle on two temperature
    boundaries is held by the first one listed in the scene.

    Keys: ``on`` (wall name or xmin..zmax), ``value`` (K, > 0), ``name`` (default
    ``temperature:<on>``).
    """
    kind: ClassVar[str] = "temperature"
    unit: ClassVar[str] = "K"
    example: ClassVar[str] = 'on = "xmin"\nvalue = 400.0'
    example_name: ClassVar[str] = "temperature:xmin"
    on: str
    value: float                     # K

    @classmethod
    def parse(cls, t) -> TemperatureBoundary:
        on = t.string("on")
        value = read_temperature(t)
        return cls(name=t.string("name", default=f"{cls.kind}:{on}"), on=on, value=value)

    def contribute(self, ctx: BuildContext, index: int, rows: Rows) -> None:
        rows.hold(index, members(ctx, self.on, f"boundary[{index}]"), self.value)
