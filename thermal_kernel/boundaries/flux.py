"""``kind = "flux"``: a prescribed heat flux through a domain face."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from ..section import cross_section, section_problem
from .base import FACES, BoundaryKind, BuildContext, Rows, members


@dataclass(frozen=True, kw_only=True)
class FluxBoundary(BoundaryKind):
    """A constant heat flux q = ``value`` (W/m^2, > 0 into the packing) through a domain face.

    The total power q A (W), A the bed's section normal to the face (pi R^2 for a cylinder
    wall along that axis, else the face of the domain's box), enters the spheres
    that reach the face, shared in proportion to their cross-sections:
    P_p = q A r_p^2 / sum_f r_f^2. Constant in time; the maximum principle's bounds widen by
    what it can add (thermal_kernel.solvers.max_principle_bounds). A flux on a face whose
    spheres are all held by a temperature boundary is refused (it would heat nothing).

    Keys: ``on`` (a domain face xmin..zmax of a non-periodic axis), ``value`` (W/m^2, any
    sign), ``name`` (default ``flux:<on>``).
    """
    kind: ClassVar[str] = "flux"
    unit: ClassVar[str] = "W/m^2"
    example: ClassVar[str] = 'on = "xmin"\nvalue = -5.0'
    example_name: ClassVar[str] = "flux:xmin"
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
        rows.power(index, p, self.value * area * share / ctx.whole.ordered_sum(share, p))

    def face_area(self, ctx: BuildContext, where: str) -> float:
        """A (m^2): the bed's section normal to the face's axis -- pi R^2 for a cylinder wall
        along that axis, else the face of the domain's box (the section
        :func:`~thermal_kernel.section.cross_section` gives calibrate and post). A packing
        whose section varies along the axis (a sphere container, a cylinder across it) has
        no such area: refused."""
        if self.on not in FACES:
            raise ctx.error(f"{where}.on", f"a flux boundary needs a domain face "
                                           f"({', '.join(FACES)}), got {self.on!r}")
        axis, _ = FACES[self.on]
        problem = section_problem(ctx.packing, axis)
        if problem is not None:
            raise ctx.error(f"{where}.on", f"no face area for a flux on {self.on!r} of "
                                           f"{ctx.packing.path}: {problem}; expected a face "
                                           "whose section is a box face or a cylinder's disc")
        return cross_section(ctx.packing, axis)
