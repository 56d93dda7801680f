"""``kind = "source"``: a volumetric heat source in a region moving at constant velocity."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..laws.base import sphere_volume
from .base import BoundaryKind, BuildContext, Rows

SOURCE_SHAPES = ("cylinder", "sphere", "box")


@dataclass(frozen=True, kw_only=True)
class SourceBoundary(BoundaryKind):
    """A power density q = ``value`` (W/m^3) in a convex region (cylinder, sphere or box)
    whose centre moves as c(t) = ``centre_m`` + ``velocity_m_s`` t, on between
    ``start_time`` and ``stop_time`` (s) (000, Table 4: a cylinder of radius 4 mm, depth 2 mm
    moving at 3.3 mm/s across a sheet).

    Definition (the same for every law): q is a power per unit of **bulk** volume -- the
    continuum the packing stands for, as in 000's sheet, where q heats the sheet's volume. Each
    particle stands for the bulk volume V_p / phi (phi the packing's ``solid_fraction``) and
    receives S_p = q V_p / phi (W) while its centre is in the region. The total power is thus
    q x (the bulk volume of the particles whose centres are in the region), on average
    q x V(region within the bed); where the local solid fraction differs from the bed's mean
    phi (a region deep in a bed whose mean phi includes the looser wall layer) it differs by
    phi_local / phi. The law's capacity rule (V_p, V_p / f_vl for Terreros, V_p / phi for
    Haddad) decides how much the heat raises the temperatures, never how much heat enters.

    In time the power is integrated exactly over each step: a particle receives
    S_p tau_p / dt over a step of length dt, tau_p the time its centre spends in the region
    during the step (:class:`MovingSource`), so the energy delivered does not depend on the
    time step, also when the source crosses particles within one step. A periodic packing
    wraps the region across its periodic faces. At most one source per scene; a value of 0,
    and a source that never holds a particle centre while it is on within the run, are
    refused.

    Keys: ``value`` (W/m^3), ``shape`` (cylinder | sphere | box, default cylinder),
    ``centre_m`` (m, at t = 0), ``radius_m`` (m, cylinder and sphere), ``depth_m`` (m,
    cylinder length along ``axis``, default infinite), ``axis`` (default z),
    ``half_size_m`` (m, box), ``velocity_m_s`` (m/s), ``start_time`` / ``stop_time`` (s),
    ``name`` (default ``source:<shape>``).
    """
    kind: ClassVar[str] = "source"
    unit: ClassVar[str] = "W/m^3"
    example: ClassVar[str] = 'value = 1.0\nshape = "sphere"\nradius_m = 0.5'
    example_name: ClassVar[str] = "source:sphere"
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
        if b.value == 0:
            t.fail("value", "expected a power density != 0 W/m^3 (a source of 0 heats nothing: "
                            "leave the [[boundary]] out)")
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
        src = self.moving(ctx, index)
        self.check_reaches(ctx, index, src)
        return src

    def moving(self, ctx: BuildContext, index: int) -> MovingSource:
        """The :class:`MovingSource` on the packing: each particle stands for V_p / phi of
        bulk (phi the packing's solid fraction), whatever the law."""
        packing = ctx.packing
        phi = float(ctx.particles.solid_fraction)
        if not 0.0 < phi <= 1.0:
            raise ctx.error(f"boundary[{index}].value", f"the source's power is q x the bulk "
                            f"volume V_p / phi each particle stands for, and {packing.path}'s "
                            f"solid_fraction is {phi!r}; expected a packing with 0 < "
                            "solid_fraction <= 1")
        length = np.asarray(packing.domain_hi, float) - np.asarray(packing.domain_lo, float)
        src = MovingSource(self, packing.position, sphere_volume(packing.radius) / phi,
                           periodic=packing.periodic, length=length)
        for k in np.flatnonzero(src.wrap):
            if 2 * src.half[k] > length[k]:
                key = 'half_size_m' if self.shape == 'box' else 'radius_m'
                raise ctx.error(f"boundary[{index}].{key}",
                                f"the {self.shape} source spans {2 * src.half[k]:g} m along "
                                f"{'xyz'[k]}, more than the periodic cell of {packing.path} "
                                f"({length[k]:g} m): it would overlap its own periodic image; "
                                "expected a region narrower than the cell")
        return src

    def window(self, scene) -> tuple[float, float]:
        """The times (t0, t1) over which the source can act in the run: its [start_time,
        stop_time] within [0, end_time] (steady: the whole of [start_time, stop_time], or the
        start when it never stops)."""
        end = scene.solver.end_time
        if not math.isfinite(end):
            end = self.stop_time if math.isfinite(self.stop_time) else self.start_time
        return max(self.start_time, 0.0), min(self.stop_time, end)

    def check_reaches(self, ctx: BuildContext, index: int, src: MovingSource) -> None:
        """A source whose region never holds a particle centre while it is on heats nothing:
        refused (one line) rather than run as a silent no-op. (A moving source on a periodic
        axis is followed over at most 256 half-cells of travel.)"""
        where = f"boundary[{index}]"
        scene, packing = ctx.scene, ctx.packing
        t0, t1 = self.window(scene)
        if t0 > t1:
            raise ctx.error(f"{where}.start_time", f"the source starts at t = {t0:g} s, after "
                            f"the run ends (end_time = {scene.solver.end_time:g} s); expected "
                            "a start within the run")
        if t1 > t0:
            reaches = np.any(src.time_inside(t0, t1, max_pieces=256) > 0)
        else:
            reaches = np.any(src.inside(t0))
        if not ctx.whole.any(reaches):
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
    return _intervals(b, np.asarray(position, dtype=float) - c0, v, t0, t1)


def _intervals(b: SourceBoundary, d0, v, t0, t1):
    """:func:`source_time_intervals` for the offsets ``d0`` of the centres from the region's
    centre at t = 0 and its velocity ``v``."""
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


def _half_extent(b: SourceBoundary) -> np.ndarray:
    """(3,) the region's half-extent along x, y, z (inf where it is unbounded)."""
    if b.shape == "sphere":
        return np.full(3, float(b.radius_m))
    if b.shape == "box":
        return np.asarray(b.half_size_m, dtype=float)
    a = np.abs(np.asarray(b.axis, dtype=float))
    a = a / np.linalg.norm(a)
    out = np.empty(3)
    for k in range(3):
        along = a[k] * b.depth_m / 2 if a[k] > 0 else 0.0
        out[k] = along + b.radius_m * math.sqrt(max(0.0, 1.0 - a[k] ** 2))
    return out


def _invariant_axes(b: SourceBoundary) -> np.ndarray:
    """(3,) bool: the region is unchanged by a shift along the axis (an endless cylinder along
    x, y or z): no periodic image is needed there."""
    if b.shape != "cylinder" or math.isfinite(b.depth_m):
        return np.zeros(3, bool)
    a = np.abs(np.asarray(b.axis, dtype=float))
    a = a / np.linalg.norm(a)
    return a == 1.0


class MovingSource:
    """The power of a :class:`SourceBoundary` as the solvers' ``source(t0, t1) -> (N,) W``: the
    mean power over the step [t0, t1] (``t0 == t1``: the power at that instant).

    Particle p receives q V_p / phi while its centre is in the region (phi the packing's solid
    fraction: V_p / phi is the bulk volume the particle stands for, the same for every law).
    Over a step it receives q V_p / phi x tau_p / (t1 - t0), tau_p the exact time its centre
    spends in the region within the step and within [start_time, stop_time]: the region is
    convex and moves at constant velocity, so tau_p is one interval (slabs give linear bounds,
    discs and balls a quadratic; :func:`source_time_intervals`). The energy delivered is
    therefore the same for any time step (a source crossing a particle within one step still
    heats it), and the temperatures see the power spread over the step.

    Periodic axes (``periodic``, cell lengths ``length``): a centre is in the region when one of
    its periodic images is (minimum image, and the images one cell away over the step; a step
    that moves the source more than half a cell is cut into pieces that do not). A region wider
    than the cell along a periodic axis would overlap its own image: refused by
    :meth:`SourceBoundary.term`."""

    def __init__(self, boundary, position, represented_volume_m3, periodic=(False,) * 3,
                 length=(math.inf,) * 3):
        self.b = boundary
        self.position = np.asarray(position, dtype=float)
        self.volume = np.asarray(represented_volume_m3, dtype=float)
        axis = np.asarray(boundary.axis, dtype=float)
        self.axis = axis / np.linalg.norm(axis)
        self.velocity = np.asarray(boundary.velocity_m_s, dtype=float)
        self.half = _half_extent(boundary)
        invariant = _invariant_axes(boundary)
        self.periodic = np.asarray(periodic, bool).copy()
        self.length = np.asarray(length, dtype=float)
        self.wrap = self.periodic & ~invariant       # axes along which images are needed
        self._still_mask = None

    # ------------------------------------------------------------------ geometry
    def centre(self, t):
        return np.asarray(self.b.centre_m, dtype=float) + self.velocity * t

    def offsets(self, t, idx=None):
        """Centre - source centre at time t, the minimum image along the periodic axes."""
        x = self.position if idx is None else self.position[idx]
        d = x - self.centre(t)
        if self.periodic.any():
            L = self.length[self.periodic]
            d[:, self.periodic] -= L * np.round(d[:, self.periodic] / L)
        return d

    def inside(self, t):
        """(N,) bool: the centre (or a periodic image of it) is in the region at time t."""
        b = self.b
        d = self.offsets(t)
        if b.shape == "sphere":
            return np.einsum("ij,ij->i", d, d) <= b.radius_m ** 2
        if b.shape == "box":
            return np.all(np.abs(d) <= np.asarray(b.half_size_m), axis=1)
        along = d @ self.axis
        radial2 = np.einsum("ij,ij->i", d, d) - along ** 2
        return (radial2 <= b.radius_m ** 2) & (np.abs(along) <= b.depth_m / 2)

    def time_inside(self, t0, t1, max_pieces=None):
        """(N,) s: the time each centre spends in the region within [t0, t1] and within the
        source's [start_time, stop_time]. ``max_pieces``: at most that many pieces of half a
        cell's travel on a periodic axis (the rest of the interval is left out; for the
        reach check only)."""
        n = self.position.shape[0]
        a, z = max(float(t0), self.b.start_time), min(float(t1), self.b.stop_time)
        if not z > a:
            return np.zeros(n)
        if not self.velocity.any():                  # a still source: one mask, cached
            if self._still_mask is None:
                self._still_mask = self.inside(0.0)
            return np.where(self._still_mask, z - a, 0.0)
        pieces = 1
        if self.wrap.any():
            travel = np.abs(self.velocity[self.wrap]) * (z - a)
            pieces = max(1, int(np.max(np.ceil(travel / (0.5 * self.length[self.wrap])))))
            if max_pieces is not None and pieces > max_pieces:
                z = a + (z - a) * max_pieces / pieces
                pieces = max_pieces
        out = np.zeros(n)
        if pieces == 1:
            self._add_piece(out, a, z)
            return out
        edges = np.linspace(a, z, pieces + 1)
        for s0, s1 in zip(edges[:-1], edges[1:]):
            self._add_piece(out, s0, s1)
        return out

    def _add_piece(self, out, s0, s1):
        """Add to ``out`` the time in [s0, s1] (the source moving less than half a cell)."""
        h = s1 - s0
        # candidates: the (periodic) distance to the middle of the region's path over the
        # piece within its half-extent plus half the travel, axis by axis on the shrinking set
        # (one pass over every centre, then over the few left: the source is small)
        reach = self.half + 0.5 * np.abs(self.velocity) * h
        mid = self.centre(s0 + 0.5 * h)
        idx = None
        for k in np.argsort(reach):
            if not np.isfinite(reach[k]):
                continue
            x = (self.position[:, k] if idx is None else self.position[idx, k]) - mid[k]
            if self.periodic[k]:
                x = x - self.length[k] * np.round(x / self.length[k])
            keep = np.abs(x) <= reach[k]
            idx = np.flatnonzero(keep) if idx is None else idx[keep]
            if idx.size == 0:
                return
        if idx is None:
            idx = np.arange(self.position.shape[0])
        d = self.offsets(s0, idx)
        base = d
        if not self.wrap.any():
            first, last = _intervals(self.b, base, self.velocity, 0.0, h)
            out[idx] += np.clip(last - first, 0.0, None)
            return
        shifts = [np.zeros(3)]
        for k in np.flatnonzero(self.wrap):
            shifts = [s + e * self.length[k] * np.eye(3)[k] for s in shifts for e in (-1, 0, 1)]
        for s in shifts:
            first, last = _intervals(self.b, base + s, self.velocity, 0.0, h)
            out[idx] += np.clip(last - first, 0.0, None)

    def restricted(self, particles) -> MovingSource:
        """The same source over the particles ``particles`` only (their powers in that order,
        equal to the whole source's bit for bit: every particle's power is its own): what a
        rank of the PETSc backend evaluates for its block."""
        idx = np.asarray(particles, dtype=np.int64)
        return MovingSource(self.b, self.position[idx], self.volume[idx],
                            periodic=self.periodic, length=self.length)

    # ------------------------------------------------------------------ the solvers' term
    def __call__(self, t0, t1):
        t0, t1 = float(t0), float(t1)
        if t1 > t0:
            return self.b.value * self.volume * (self.time_inside(t0, t1) / (t1 - t0))
        if t0 < self.b.start_time or t0 > self.b.stop_time:
            return np.zeros(self.position.shape[0])
        return np.where(self.inside(t0), self.b.value * self.volume, 0.0)

    def max_rise_rate(self, capacity_j_k, free):
        """(up K/s, down K/s, start s, stop s): the fastest the source alone can raise / lower a
        free particle's temperature, max_p q V_p / (phi C_p), and when it is on; by time t it
        adds at most rate x (the time it is on by then) (the bound
        :func:`~thermal_kernel.solvers.check_physics` widens the maximum principle by). The
        rate over some particles only (a rank's block) is their part of the maximum."""
        c = np.asarray(capacity_j_k, dtype=float)[free]
        rate = float(np.max(abs(self.b.value) * self.volume[free] / c)) if c.size else 0.0
        up, down = (rate, 0.0) if self.b.value > 0 else (0.0, rate)
        return up, down, float(self.b.start_time), float(self.b.stop_time)
