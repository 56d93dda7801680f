"""From a scene and a packing to the solvers' :class:`ThermalProblem`.

This is where the conductance law is applied (once) and the boundaries are turned into rows of
particles; the solvers receive plain arrays and never know which law built the network.
"""
from __future__ import annotations

import math

import numpy as np

from .laws import get_law
from .laws.base import ContactInput, ParticleInput, WallContactInput
from .network import ThermalProblem
from .packing import Packing
from .scene import Scene, SceneError

FACES = {"xmin": (0, -1), "xmax": (0, +1), "ymin": (1, -1), "ymax": (1, +1),
         "zmin": (2, -1), "zmax": (2, +1)}


def neighbour_counts(packing: Packing) -> np.ndarray:
    """Particle–particle neighbours of each particle as listed in the dump (gaps included; wall
    contacts are not neighbours — Terreros 2012, sec. 4.1)."""
    return np.bincount(packing.pair.reshape(-1), minlength=packing.n_particles)


def mechanical_properties(scene: Scene, packing: Packing) -> tuple[float, float]:
    """Real Young's modulus and Poisson ratio: the scene's [material] if given, else the
    packing's (which records the real values even when it was softened)."""
    young = scene.young_pa if not math.isnan(scene.young_pa) else float(packing.attrs["young_pa"])
    poisson = scene.poisson if not math.isnan(scene.poisson) else float(packing.attrs["poisson"])
    return young, poisson


def particle_materials(scene: Scene, packing: Packing):
    """Per-particle conductivity, density, heat capacity from the phases."""
    phases = np.unique(packing.phase)
    k = np.empty(packing.n_particles)
    rho = np.empty(packing.n_particles)
    cp = np.empty(packing.n_particles)
    for phase in phases:
        m = scene.material(phase)
        sel = packing.phase == phase
        k[sel], rho[sel], cp[sel] = m.conductivity, m.density, m.heat_capacity
    return k, rho, cp


def build_law_inputs(scene: Scene, packing: Packing):
    """The ContactInput and ParticleInput the scene's law receives."""
    k, rho, cp = particle_materials(scene, packing)
    young, poisson = mechanical_properties(scene, packing)
    nb = neighbour_counts(packing)
    i, j = packing.pair[:, 0], packing.pair[:, 1]
    contacts = ContactInput(
        radius_i_m=packing.radius[i], radius_j_m=packing.radius[j],
        distance_m=np.linalg.norm(packing.branch, axis=1), overlap_m=packing.overlap,
        normal_force_n=packing.normal_force, conductivity_i=k[i], conductivity_j=k[j],
        neighbours_i=nb[i], neighbours_j=nb[j], young_pa=young, poisson=poisson)
    particles = ParticleInput(
        radius_m=packing.radius, density=rho, heat_capacity=cp, conductivity=k, neighbours=nb,
        solid_fraction=float(packing.attrs["solid_fraction"]))
    return contacts, particles


def law_params(scene: Scene, law) -> dict:
    unknown = sorted(set(scene.law_params) - set(law.defaults))
    if unknown:
        raise SceneError(f"{scene.path}: law_params.{unknown[0]}: unknown parameter of law "
                         f"{law.name!r} (known: {', '.join(sorted(law.defaults)) or 'none'})")
    return {**law.defaults, **scene.law_params}


def boundary_particles(scene: Scene, packing: Packing, on: str, where: str) -> np.ndarray:
    """Particles of a boundary named ``on``: those in the wall's ``wall_contacts`` for a wall of
    the packing, or, for a domain face without a wall, the spheres that reach the face
    (x - r <= lo, x + r >= hi, within 1e-9 of the domain size)."""
    if on in packing.wall_name:
        w = packing.wall_name.index(on)
        return np.unique(packing.wall_particle[packing.wall_index == w])
    if on in FACES:
        axis, side = FACES[on]
        if packing.periodic[axis]:
            raise SceneError(f"{scene.path}: {where}.on: {packing.path} is periodic along "
                             f"{'xyz'[axis]}: {on!r} is no face (the spheres beside it touch "
                             "those beside the opposite one across the periodic boundary); "
                             f"expected a wall ({', '.join(packing.wall_name) or 'none'}) or "
                             "a face of a non-periodic axis")
        x = packing.position[:, axis]
        r = packing.radius
        tol = 1e-9 * float(packing.domain_hi[axis] - packing.domain_lo[axis])
        if side < 0:
            sel = x - r <= packing.domain_lo[axis] + tol
        else:
            sel = x + r >= packing.domain_hi[axis] - tol
        return np.flatnonzero(sel)
    raise SceneError(f"{scene.path}: {where}.on: {on!r} is neither a wall of "
                     f"{packing.path} ({', '.join(packing.wall_name) or 'no walls'}) nor a "
                     f"domain face ({', '.join(FACES)})")


def build_problem(scene: Scene, packing: Packing):
    """Return (ThermalProblem, info dict) for a scene on a packing."""
    law = get_law(scene.law)
    params = law_params(scene, law)
    contacts, particles = build_law_inputs(scene, packing)
    conductance = np.asarray(law.conductance(contacts, params), dtype=np.float64)
    capacity = np.asarray(law.capacity(particles, params), dtype=np.float64)

    names = []
    fixed_p, fixed_t, fixed_b = [], [], []
    exch_p, exch_g, exch_t, exch_b = [], [], [], []
    pow_p, pow_w, pow_b = [], [], []
    sources = []
    for b_index, b in enumerate(scene.boundaries):
        where = f"boundary[{b_index}]"
        names.append(b.name)
        if b.kind == "source":
            sources.append((b_index, b))
            continue
        members = boundary_particles(scene, packing, b.on, where)
        if members.size == 0:
            raise SceneError(f"{scene.path}: {where}.on: no particle belongs to {b.on!r} in "
                             f"{packing.path}")
        if b.kind == "temperature":
            fixed_p.append(members)
            fixed_t.append(np.full(members.size, b.value))
            fixed_b.append(np.full(members.size, b_index))
        elif b.kind == "flux":
            # Total power q A over the face, shared in proportion to each sphere's cross-section.
            area = _face_area(scene, packing, b.on, where)
            share = packing.radius[members] ** 2
            pow_p.append(members)
            pow_w.append(b.value * area * share / share.sum())
            pow_b.append(np.full(members.size, b_index))
        elif b.kind == "wall_temperature":
            if b.on not in packing.wall_name:
                raise SceneError(f"{scene.path}: {where}.on: {b.on!r} is not a wall of "
                                 f"{packing.path} (walls: {', '.join(packing.wall_name) or 'none'})")
            if law.wall_conductance is None:
                raise SceneError(f"{scene.path}: {where}.kind: law {law.name!r} has no "
                                 "particle–wall conductance; use kind = \"temperature\"")
            w = packing.wall_name.index(b.on)
            rows = np.flatnonzero(packing.wall_index == w)
            p = packing.wall_particle[rows]
            young, poisson = mechanical_properties(scene, packing)
            kp = particles.conductivity[p]
            kw = kp if math.isnan(b.wall_conductivity) else np.full(p.size, b.wall_conductivity)
            g = law.wall_conductance(WallContactInput(
                radius_m=packing.radius[p], overlap_m=packing.wall_overlap[rows],
                normal_force_n=packing.wall_normal_force[rows], conductivity_particle=kp,
                conductivity_wall=kw, young_pa=young, poisson=poisson), params)
            exch_p.append(p)
            exch_g.append(np.asarray(g, dtype=np.float64))
            exch_t.append(np.full(p.size, b.value))
            exch_b.append(np.full(p.size, b_index))

    fixed_particle = _cat(fixed_p, np.int64)
    fixed_temperature = _cat(fixed_t, np.float64)
    fixed_boundary = _cat(fixed_b, np.int32)
    if fixed_particle.size != np.unique(fixed_particle).size:
        # A particle on two temperature boundaries (an edge of the box): the first one listed
        # in the scene holds it; say so in the info rather than averaging silently.
        _, first = np.unique(fixed_particle, return_index=True)
        first = np.sort(first)
        n_shared = fixed_particle.size - first.size
        fixed_particle, fixed_temperature, fixed_boundary = (
            fixed_particle[first], fixed_temperature[first], fixed_boundary[first])
    else:
        n_shared = 0

    source = None
    source_boundary = -1
    if sources:
        if len(sources) > 1:
            raise SceneError(f"{scene.path}: boundary: at most one source per scene")
        source_boundary, sb = sources[0]
        _check_source_reaches(scene, packing, source_boundary, sb)
        source = MovingSource(sb, packing.position, capacity / (particles.density
                                                                 * particles.heat_capacity))
    problem = ThermalProblem(
        capacity_j_k=capacity, pair=packing.pair, conductance_w_k=conductance,
        fixed_particle=fixed_particle, fixed_temperature_k=fixed_temperature,
        fixed_boundary=fixed_boundary,
        exchange_particle=_cat(exch_p, np.int64), exchange_w_k=_cat(exch_g, np.float64),
        exchange_temperature_k=_cat(exch_t, np.float64),
        exchange_boundary=_cat(exch_b, np.int32),
        power_particle=_cat(pow_p, np.int64), power_w=_cat(pow_w, np.float64),
        power_boundary=_cat(pow_b, np.int32),
        source=source, source_boundary=int(source_boundary), boundary_names=tuple(names))
    info = {"law_params": params, "particles_on_two_temperature_boundaries": n_shared}
    return problem, info


def source_window(scene: Scene, b) -> tuple[float, float]:
    """The times (t0, t1) over which source ``b`` can act in the run: its [start_time,
    stop_time] within [0, end_time] (steady: the whole of [start_time, stop_time], or the start
    when it never stops)."""
    end = scene.solver.end_time
    if not math.isfinite(end):
        end = b.stop_time if math.isfinite(b.stop_time) else b.start_time
    return max(b.start_time, 0.0), min(b.stop_time, end)


def source_time_intervals(b, position, t0, t1):
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


def _check_source_reaches(scene, packing, index, b):
    """A source whose region never holds a particle centre while it is on heats nothing: refused
    (one line) rather than run as a silent no-op."""
    where = f"boundary[{index}]"
    t0, t1 = source_window(scene, b)
    if t0 > t1:
        raise SceneError(f"{scene.path}: {where}.start_time: the source starts at t = {t0:g} s, "
                         f"after the run ends (end_time = {scene.solver.end_time:g} s); expected "
                         "a start within the run")
    first, last = source_time_intervals(b, packing.position, t0, t1)
    if not np.any(first <= last):
        moving = any(b.velocity_m_s)
        when = f"between t = {t0:g} and {t1:g} s" if moving or t1 > t0 else f"at t = {t0:g} s"
        raise SceneError(f"{scene.path}: {where}.centre_m: the {b.shape} source "
                         f"{'moving from' if moving else 'at'} {list(b.centre_m)} m never "
                         f"contains a particle centre of {packing.path} {when} (domain "
                         f"{packing.domain_lo.tolist()} .. {packing.domain_hi.tolist()} m); "
                         "expected a region that reaches the packing")


def _cat(parts, dtype):
    return np.concatenate(parts).astype(dtype) if parts else np.zeros(0, dtype)


def _face_area(scene, packing, on, where):
    if on not in FACES:
        raise SceneError(f"{scene.path}: {where}.on: a flux boundary needs a domain face "
                         f"({', '.join(FACES)}), got {on!r}")
    axis, _ = FACES[on]
    ext = np.delete(packing.domain_hi - packing.domain_lo, axis)
    return float(ext[0] * ext[1])


class MovingSource:
    """A volumetric heat source of power density q (W/m^3) in a region that moves at constant
    velocity (Terreros 2012, 000, Table 4: a cylinder moving across a sheet).

    A particle whose centre is inside the region receives q times the continuum volume it
    represents, C_i / (rho c_p) — V_i for the granular laws, V_i / f_vl (Terreros) or V_i / phi
    (Haddad) — so the source heats the continuum at q whatever the law. ``power(t0, t1)`` is the
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
