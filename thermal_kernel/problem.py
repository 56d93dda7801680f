"""From a scene and a packing to the solvers' :class:`ThermalProblem`.

This is where the conductance law is applied (once) and each boundary adds its rows (its kind's
``contribute``, ``thermal_kernel.boundaries``); the solvers receive plain arrays and never know
which law or which boundary kinds built the network.
"""
from __future__ import annotations

import math

import numpy as np

from .boundaries import BuildContext, Rows
from .boundaries.base import Whole
from .boundaries.base import FACES, boundary_particles  # noqa: F401 (imported from here by tdem_post, validation, bench and tests)
from .laws import get_law
from .laws.base import ContactInput, ParticleInput
from .neighbours import choose_neighbours, neighbour_counts
from .network import ThermalProblem
from .packing import Packing
from .scene import Scene, SceneError


def mechanical_properties(scene: Scene, packing: Packing) -> tuple[float, float]:
    """Real Young's modulus and Poisson ratio: the scene's [material] if given, else the
    packing's (which records the real values even when it was softened)."""
    young = scene.young_pa if not math.isnan(scene.young_pa) else float(packing.attrs["young_pa"])
    poisson = scene.poisson if not math.isnan(scene.poisson) else float(packing.attrs["poisson"])
    return young, poisson


def particle_materials(scene: Scene, packing: Packing):
    """Per-particle conductivity, density, heat capacity from the phases, read-only: a packing
    of one phase gets views of its material's three numbers (no arrays of N: 24 bytes per
    particle fewer, the same values)."""
    phases = np.unique(packing.phase)
    if phases.size == 1:
        m = scene.material(phases[0])
        return tuple(np.broadcast_to(np.float64(v), (packing.n_particles,))
                     for v in (m.conductivity, m.density, m.heat_capacity))
    k = np.empty(packing.n_particles)
    rho = np.empty(packing.n_particles)
    cp = np.empty(packing.n_particles)
    for phase in phases:
        m = scene.material(phase)
        sel = packing.phase == phase
        k[sel], rho[sel], cp[sel] = m.conductivity, m.density, m.heat_capacity
    for a in (k, rho, cp):
        a.flags.writeable = False
    return k, rho, cp


def build_law_inputs(scene: Scene, packing: Packing, keep: np.ndarray | None = None,
                     neighbours: np.ndarray | None = None):
    """The ContactInput and ParticleInput the scene's law receives (every dumped row; with
    ``keep``, the neighbour counts are those of the kept rows only). ``neighbours``: the (N,)
    neighbour counts given (a packing holding part of the file's contacts: the ranks'
    counts summed over every part, thermal_kernel/rank_build.py)."""
    k, rho, cp = particle_materials(scene, packing)
    young, poisson = mechanical_properties(scene, packing)
    nb = neighbour_counts(packing, keep) if neighbours is None else neighbours
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


def evaluate_law(scene: Scene, packing: Packing, keep: np.ndarray | None = None,
                 neighbours: np.ndarray | None = None, check_capacity: bool = True):
    """The scene's law on the packing's contacts and particles, checked: (law, params,
    ParticleInput, H per contact of ``packing``, C per particle). The one place a law is
    evaluated: on the whole packing (:func:`build_problem`) or on the contacts a rank holds
    (``packing.contact_row``, ``neighbours`` the whole packing's counts; rank_build.py).
    ``check_capacity`` False: the capacities are the caller's to check (a rank's particles:
    :func:`bad_capacity`, :func:`capacity_refusal` over every rank's)."""
    law = get_law(scene.law)
    params = law_params(scene, law)
    contacts, particles = build_law_inputs(scene, packing, keep, neighbours)
    with np.errstate(all="ignore"):     # a value out of range is said below, in one line
        conductance = np.asarray(law.conductance(contacts, params), dtype=np.float64)
        capacity = np.asarray(law.capacity(particles, params), dtype=np.float64)
    if keep is not None:
        conductance = np.where(keep, conductance, 0.0)
    _check_law_output(scene, law, conductance, capacity if check_capacity else None,
                      packing.contact_row)
    return law, params, particles, conductance, capacity


def build_problem(scene: Scene, packing: Packing):
    """Return (ThermalProblem, info dict) for a scene on a packing.

    The scene's ``[neighbours]`` criterion (:mod:`thermal_kernel.neighbours`) gives H = 0 to
    the dumped rows outside it (they stay in the problem's arrays, aligned with the packing's
    rows; the network drops them); ``info["neighbours"]`` is its
    :class:`~thermal_kernel.neighbours.NeighbourChoice` (None without a criterion)."""
    choice = choose_neighbours(scene, packing)
    keep = None if choice is None else choice.keep
    law, params, particles, conductance, capacity = evaluate_law(scene, packing, keep)
    return boundary_problem(scene, packing, law, params, particles, capacity, conductance,
                            choice)


def boundary_problem(scene: Scene, packing: Packing, law, params, particles, capacity,
                     conductance, choice=None, whole: Whole | None = None):
    """(ThermalProblem, info) from the law's outputs: each boundary adds its rows (its kind's
    ``contribute``), checked. ``packing.pair`` and ``conductance`` are the problem's contacts
    (none: the PETSc backend's ranks, which hold the contacts apart, rank_build.py).
    ``whole``: how the kinds see the whole packing when ``packing`` holds a rank's particles
    only (:class:`~thermal_kernel.boundaries.base.Whole`; default: it is whole); the rows are
    then that rank's, the checks and ``info`` the whole packing's."""
    whole = whole or Whole()
    young, poisson = mechanical_properties(scene, packing)
    ctx = BuildContext(scene=scene, packing=packing, law=law, params=params,
                       particles=particles, capacity_j_k=capacity, young_pa=young,
                       poisson=poisson, whole=whole)
    rows = Rows()
    for index, b in enumerate(scene.boundaries):
        b.contribute(ctx, index, rows)
    _check_rows(scene, packing, rows, whole)

    fixed_particle = _cat(rows.fixed_p, np.int64)
    fixed_temperature = _cat(rows.fixed_t, np.float64)
    fixed_boundary = _cat(rows.fixed_b, np.int32)
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
    if rows.sources:
        if len(rows.sources) > 1:
            raise SceneError(f"{scene.path}: boundary: at most one source per scene")
        source_boundary, make = rows.sources[0]
        source = make()
    problem = ThermalProblem(
        capacity_j_k=capacity, pair=packing.pair, conductance_w_k=conductance,
        fixed_particle=fixed_particle, fixed_temperature_k=fixed_temperature,
        fixed_boundary=fixed_boundary,
        exchange_particle=_cat(rows.exch_p, np.int64),
        exchange_w_k=_cat(rows.exch_g, np.float64),
        exchange_temperature_k=_cat(rows.exch_t, np.float64),
        exchange_boundary=_cat(rows.exch_b, np.int32),
        power_particle=_cat(rows.pow_p, np.int64), power_w=_cat(rows.pow_w, np.float64),
        power_boundary=_cat(rows.pow_b, np.int32),
        source=source, source_boundary=int(source_boundary),
        boundary_names=tuple(b.name for b in scene.boundaries))
    info = {"law_params": params,
            "particles_on_two_temperature_boundaries": whole.count(n_shared),
            "neighbours": choice}
    return problem, info


def _scene_inputs(scene: Scene, keys) -> str:
    """The scene's own values of ``keys`` ([material] and every phase, then [law_params]) as
    ``material.density = 1e-320, ...``: what a law's non-finite output came from."""
    out = []
    for phase, m in sorted(scene.materials.items()):
        where = "material" if phase == 0 else f"material.{phase}"
        out += [f"{where}.{k} = {getattr(m, k):g}" for k in keys if hasattr(m, k)]
    if "young_pa" in keys and not math.isnan(scene.young_pa):
        out.append(f"material.young_pa = {scene.young_pa:g}")
    if "poisson" in keys and not math.isnan(scene.poisson):
        out.append(f"material.poisson = {scene.poisson:g}")
    out += [f"law_params.{k} = {v!r}" for k, v in sorted(scene.law_params.items())]
    return ", ".join(out)


def bad_capacity(capacity_j_k) -> np.ndarray:
    """The capacities a law may not give: not finite or <= 0."""
    return ~np.isfinite(capacity_j_k) | (capacity_j_k <= 0)


def capacity_refusal(scene: Scene, law, value, n_bad: int, n: int, first: int) -> SceneError:
    """The one-line refusal of ``n_bad`` of ``n`` capacities (``first``: the lowest particle,
    its C ``value``): the whole packing's, or the PETSc backend's ranks' reduced
    (rank_build.py)."""
    return SceneError(
        f"{scene.path}: {_scene_inputs(scene, ('density', 'heat_capacity'))}: law "
        f"{law.name!r} gives a heat capacity C = {value:g} J/K for {n_bad} "
        f"of {n} particles (first: particle {first}); expected numbers whose "
        "product rho c_p V is finite and > 0")


def _check_law_output(scene: Scene, law, conductance, capacity, contact_row=None) -> None:
    """A law's H and C computed from the scene's numbers, refused in one line naming the scene
    keys they came from (not the solvers' arrays) when a value is out of floating-point range:
    H not finite or < 0, C not finite or <= 0 (``capacity`` None: C is the caller's to check)."""
    bad = None if capacity is None else bad_capacity(capacity)
    if bad is not None and bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise capacity_refusal(scene, law, capacity[k], int(bad.sum()), capacity.size, k)
    bad = ~np.isfinite(conductance) | (conductance < 0)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        row = k if contact_row is None else int(contact_row[k])     # the file's row
        raise SceneError(
            f"{scene.path}: "
            f"{_scene_inputs(scene, ('conductivity', 'young_pa', 'poisson'))}: law "
            f"{law.name!r} gives a conductance H = {conductance[k]:g} W/K for "
            f"{int(bad.sum())} of {conductance.size} contacts (first: contact {row}); expected "
            "numbers for which the law's H is finite and >= 0")


def _check_rows(scene: Scene, packing: Packing, rows, whole: Whole) -> None:
    """What the boundaries' rows cannot mean, refused in one line: a temperature boundary whose
    particles are all held already by one listed before it (it would hold nothing: "the first
    listed wins" applies to shared edges, not to a whole wall), and a flux whose particles are
    all held (its power would go straight into the held temperature, heating nothing)."""
    held = np.zeros(packing.n_particles, bool)
    held_by = np.full(packing.n_particles, -1, dtype=np.int32)
    for p, index in zip(rows.fixed_p, rows.fixed_i):
        if whole.count(p.size) and whole.all(held[p].all()):
            first = int(whole.lowest(p, held_by[p]))
            raise SceneError(
                f"{scene.path}: boundary[{index}].on: every particle of "
                f"{scene.boundaries[index].on!r} is already held by boundary[{first}] "
                f"({scene.boundaries[first].name!r}, listed first), so "
                f"{scene.boundaries[index].name!r} would hold nothing; expected one temperature "
                "boundary per wall or face")
        fresh = p[~held[p]]
        held[fresh] = True
        held_by[fresh] = index
    for p, index in zip(rows.pow_p, rows.pow_i):
        if whole.count(p.size) and whole.all(held[p].all()):
            first = int(whole.lowest(p, held_by[p]))
            bnd = scene.boundaries[index]
            raise SceneError(
                f"{scene.path}: boundary[{index}].on: every sphere of {bnd.on!r} is held at a "
                f"temperature by boundary[{first}] ({scene.boundaries[first].name!r}): a "
                f"{bnd.kind} there would pass straight into that held temperature and heat "
                "nothing; expected a face whose spheres are free (or no temperature boundary "
                "on it)")


def _cat(parts, dtype):
    return np.concatenate(parts).astype(dtype) if parts else np.zeros(0, dtype)
