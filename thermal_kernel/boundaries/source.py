"""``kind = "source"``: a volumetric heat source in a region moving at constant velocity."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .base import BoundaryKind, BuildContext, Rows

SOURCE_SHAPES = ("cylinder", "sphere", "box")


@dataclass(frozen=True, kw_only=True)
class SourceBoundary(BoundaryKind):
    """A power density q = ``value`` (W/m^3) in a convex region (cylinder, sphere or box)
    whose centre moves as c(t) = ``centre_m`` + ``velocity_m_s`` t, on between
    ``start_time`` and ``stop_time`` (s) (000, Table 4: a cylinder of radius 4 mm, depth 2 mm
    moving at 3.3 mm/s across a sheet).

    A particle whose centre is inside the region at the mid-time of a step receives
    S_p = q C_p / (rho_p c_p) (W): q times the continuum volume it represents — V_p for the
    granular laws, V_p / f_vl (Terreros), V_p / phi (Haddad) — so the source heats the
    continuum at q whatever the law (:class:`MovingSource`). At most one source per scene;
    one that never holds a particle centre while it is on within the run is refused.

    Keys: ``value`` (W/m^3), ``shape`` (cylinder | sphere | box, default cylinder),
    ``centre_m`` (m, at t = 0), ``radius_m`` (m, cylinder and sphere), ``depth_m`` (m,
    cylinder length along ``axis``, default infinite), ``axis`` (default z),
    ``half_size_m`` (m, box), ``velocity_m_s`` (m/s), ``start_time`` / ``stop_time`` (s),
    ``name`` (default ``source:<shape>``).
    """
    kind: ClassVar[str] = "source"
    value: float                           # W/m^3
    shape: str = "cylinder"
    centre_m: tuple = (0.0, 0.0, 0.0)      # position at t = 0
    radius_m: float = math.nan
    depth_m: float = math.inf              # cylinder length along its axis (centred on centre_m)
    axis: tuple = (0.0, 0.0, 1.0)
    half_size_m: tuple = (0.0, 0.0, 0.0)   # box
    velocity_m_s: tuple = (0.0, 0.0, 0.0)
    start_time: float = 0.0
    stop_time: float = math.inf

    @classmethod
    def parse(cls, t) -> SourceBoundary:
        shape = t.string("shape", default="cylinder", choices=SOURCE_SHAPES)
        b = cls(
            name=t.string("name", default=f"{cls.kind}:{shape}"),
            value=t.number("value"), shape=shape,
            centre_m=t.vector("centre_m", (0.0, 0.0, 0.0)),
            radius_m=t.number("radius_m", positive=True) if shape != "box" else math.nan,
            depth_m=t.number("depth_m", default=math.inf, positive=True),
            axis=t.vector("axis", (0.0, 0.0, 1.0)),
            half_size_m=t.vector("half_size_m", (0.0, 0.0, 0.0)) if shape == "box"
            else (0.0, 0.0, 0.0),
            velocity_m_s=t.vector("velocity_m_s", (0.0, 0.0, 0.0)),
            start_time=t.number("start_time", default=0.0, minimum=0.0),
            stop_time=t.number("stop_time", default=math.inf))
        if b.stop_time <= b.start_time:
            t.fail("stop_time", f"expected a time after start_time = {b.start_time:g} s, got "
                                f"{b.stop_time:g} s (the source would never be on)")
        if shape == "box" and min(b.half_size_m) <= 0:
            t.fail("half_size_m", "expected three numbers > 0 for a box source")
        if sum(a * a for a in b.axis) == 0:
            t.fail("axis", "expected a non-zero vector")
        return b

    def contribute(self, ctx: BuildContext, index: int, rows: Rows) -> None:
        # made once every boundary has contributed (a bad boundary listed later is reported
        # first, as before the registry)
        rows.source(index, lambda: self.term(ctx, index))

    def term(self, ctx: BuildContext, index: int) -> MovingSource:
        """The source's power S(t0, t1) (W per particle), refused if it heats nothing."""
        self.check_reaches(ctx, index)
        particles = ctx.particles
        return MovingSource(self, ctx.packing.position,
                            ctx.capacity_j_k / (particles.density * particles.heat_capacity))

    def window(self, scene) -> tuple[float, float]:
        """The times (t0, t1) over which the source can act in the run: its [start_time,
        stop_time] within [0, end_time] (steady: the whole of [start_time, stop_time], or the
        start when it never stops)."""
        end = scene.solver.end_time
        if not math.isfinite(end):
            end = self.stop_time if math.isfinite(self.stop_time) else self.start_time
        return max(self.start_time, 0.0), min(self.stop_time, end)

    def check_reaches(self, ctx: BuildContext, index: int) -> None:
        """A source whose region never holds a particle centre while it is on heats nothing:
        refused (one line) rather than run as a silent no-op."""
        where = f"boundary[{index}]"
        scene, packing = ctx.scene, ctx.packing
        t0, t1 = self.window(scene)
        if t0 > t1:
            raise ctx.error(f"{where}.start_time", f"the source starts at t = {t0:g} s, after "
                            f"the run ends (end_time = {scene.solver.end_time:g} s); expected "
                            "a start within the run")
        first, last = source_time_intervals(self, packing.position, t0, t1)
        if not np.any(first <= last):
            moving = any(self.velocity_m_s)
            when = (f"between t = {t0:g} and {t1:g} s" if moving or t1 > t0
                    else f"at t = {t0:g} s")
            raise ctx.error(f"{where}.centre_m", f"the {self.shape} source "
                            f"{'moving from' if moving else 'at'} {list(self.centre_m)} m never "
                            f"contains a particle centre of {packing.path} {when} (domain "
                            f"{packing.domain_lo.tolist()} .. {packing.domain_hi.tolist()} m); "
                            "expected a region that reaches the packing")


def source_time_intervals(b: SourceBoundary, position, t0, t1):
    """(first, last) time in [t0, t1] at which each centre lies in the moving region of source
    ``b`` (first > last: never). The region is convex and moves at constant velocity, so the
    times a point spends inside form one interval: slabs give linear bounds, discs and balls a
    quadratic."""
    c0 = np.asarray(b.centre_m, dtype=float)
    v = np.asarray(b.velocity_m_s, dtype=float)
    d0 = np.asarray(position, dtype=float) - c0
    n = len(d0)
    first, last = np.full(n, float(t0)), np.full(n, float(t1))

    def slab(offset, speed, half):
        # |offset - speed t| <= half
        nonlocal first, last
        if not math.isfinite(half):
            return
        if speed == 0.0:
            out = np.abs(offset) > half
            first, last = np.where(out, np.inf, first), np.where(out, -np.inf, last)
            return
        a, b_ = (offset - half) / speed, (offset + half) / speed
        first, last = np.maximum(first, np.minimum(a, b_)), np.minimum(last, np.maximum(a, b_))

    def ball(offset, speed, radius):
        # |offset - speed t|^2 <= radius^2, offset (n, k), speed (k,)
        nonlocal first, last
        a = float(speed @ speed)
        c = np.einsum("ij,ij->i", offset, offset) - radius ** 2
        if a == 0.0:
            first, last = np.where(c > 0, np.inf, first), np.where(c > 0, -np.inf, last)
            return
        bb = offset @ speed
        disc = bb * bb - a * c
        root = np.sqrt(np.clip(disc, 0.0, None))
        lo, hi = (bb - root) / a, (bb + root) / a
        lo, hi = np.where(disc < 0, np.inf, lo), np.where(disc < 0, -np.inf, hi)
        first, last = np.maximum(first, lo), np.minimum(last, hi)

    if b.shape == "sphere":
        ball(d0, v, b.radius_m)
    elif b.shape == "box":
        for k in range(3):
            slab(d0[:, k], v[k], b.half_size_m[k])
    else:
        axis = np.asarray(b.axis, dtype=float)
        axis = axis / np.linalg.norm(axis)
        slab(d0 @ axis, float(v @ axis), b.depth_m / 2)
        ball(d0 - np.outer(d0 @ axis, axis), v - (v @ axis) * axis, b.radius_m)
    return first, last


class MovingSource:
    """The power of a :class:`SourceBoundary` (q W/m^3 in a region moving at constant
    velocity) as the solvers' ``source(t0, t1) -> (N,) W``.

    A particle whose centre is inside the region receives q times the continuum volume it
    represents, C_i / (rho c_p) — V_i for the granular laws, V_i / f_vl (Terreros) or V_i / phi
    (Haddad) — so the source heats the continuum at q whatever the law. ``source(t0, t1)`` is the
    power at the mid-time of the step."""

    def __init__(self, boundary, position, represented_volume_m3):
        self.b = boundary
        self.position = position
        self.volume = represented_volume_m3
        axis = np.asarray(boundary.axis, dtype=float)
        self.axis = axis / np.linalg.norm(axis)

    def inside(self, t):
        b = self.b
        centre = np.asarray(b.centre_m) + np.asarray(b.velocity_m_s) * t
        d = self.position - centre
        if b.shape == "sphere":
            return np.einsum("ij,ij->i", d, d) <= b.radius_m ** 2
        if b.shape == "box":
            return np.all(np.abs(d) <= np.asarray(b.half_size_m), axis=1)
        along = d @ self.axis
        radial2 = np.einsum("ij,ij->i", d, d) - along ** 2
        return (radial2 <= b.radius_m ** 2) & (np.abs(along) <= b.depth_m / 2)

    def __call__(self, t0, t1):
        t = 0.5 * (t0 + t1)
        if t < self.b.start_time or t > self.b.stop_time:
            return np.zeros(self.position.shape[0])
        return np.where(self.inside(t), self.b.value * self.volume, 0.0)
