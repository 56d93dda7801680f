"""Calibration of the Haddad transmission coefficient C_t on the packing itself (002, sec. 2.3).

Haddad 2021 (002, eq. 8-9) calibrates C_t so that the packing's effective conductivity equals the
material's: a steady flux test along one axis gives lambda^e = phi L / dT (eq. 8), and
C_t / C_t^arb = lambda / lambda^e (eq. 9). Every Haddad conductance is proportional to C_t
(H = lambda C_t pi R_m^2 / d, eq. 1-7) and the test has only Dirichlet faces, so the steady
heat flow Q - hence lambda^e - is proportional to C_t: ONE sparse steady solve at any C_t^arb
gives the calibrated value exactly, no iteration and no time marching. The scene's law
parameters (``mean_radius``) and ``[neighbours]`` criterion (the gap chosen for a target bulk Z)
are those of the solve.

Test: the two faces normal to ``axis`` held at T_hot and T_cold (their particles: the wall
contacts of a wall of that name, or the spheres reaching the domain face); lambda^e = Q L / (A dT)
(:func:`thermal_kernel.effective.effective_conductivity`, heat in = heat out checked) with L the
domain length along the axis (its length convention "domain") and A the cross-section (the box
face, or pi R^2 for a cylinder wall along the axis); any other cross-section (a sphere container,
a cylinder across the axis) is refused in one line, not replaced by the bounding-box face.
Heterogeneous packings: lambda is the conductivity of phase 0 (the matrix), which is what the
calibration is for.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from .boundaries import TemperatureBoundary, boundary_particles
from .effective import EffectiveConductivity, steady_effective_conductivity
from .output import scene_text_difference, scene_to_json
from .packing import Packing
from .run import ranks_in_effect, run_in_memory
from .scene import Scene, SceneError, SolverConfig, load_scene, read_toml, toml_text
from .section import AXES, cross_section, flux_axes, section_problem


@dataclass(frozen=True)
class Calibration:
    ct: float                     # calibrated C_t, -
    ct_used: float                # C_t of the solve (C_t^arb), -
    conductivity_w_mk: float      # target lambda (phase 0)
    effective_w_mk: float         # lambda^e at ct_used
    heat_flow_w: float            # Q through the hot face at ct_used
    balance: float                # |Q_hot + Q_cold| / Q_hot (steady balance)
    length_m: float
    area_m2: float
    axis: str
    n_hot: int
    n_cold: int
    neighbours: object = None     # thermal_kernel.neighbours.NeighbourChoice (None: every row)


@dataclass(frozen=True)
class FluxTest:
    n_hot: int
    n_cold: int
    law_params: dict
    effective: EffectiveConductivity     # the whole result (length convention "domain")
    neighbours: object = None            # the scene's [neighbours] criterion on this packing
    # (contacts,) W/K: the law's conductance per dumped contact row of the solve (0 for a row
    # the [neighbours] criterion leaves out), with effective.temperature_k the test's field: a
    # reading of the test beyond lambda^e (validation case 5's interior C_t) needs both
    conductance_w_k: np.ndarray | None = field(default=None, repr=False, compare=False)

    @property
    def effective_w_mk(self) -> float:
        """lambda^e = Q L / (A dT), 002 eq. 8."""
        return self.effective.k_eff_w_mk

    @property
    def heat_flow_w(self) -> float:
        """Q through the hot face."""
        return self.effective.q_in_w

    @property
    def balance(self) -> float:
        """|Q_hot + Q_cold| / Q_hot."""
        return self.effective.balance

    @property
    def length_m(self) -> float:
        return self.effective.length_m

    @property
    def area_m2(self) -> float:
        return self.effective.area_m2


def flux_test(scene: Scene, packing: Packing, axis: str = "x", t_hot: float = 1.0,
              t_cold: float = 0.0) -> FluxTest:
    """The steady flux test of 002 sec. 2.2 (any law, any phases): the two faces normal to
    ``axis`` held at ``t_hot`` and ``t_cold``, adiabatic elsewhere, one sparse steady solve."""
    if axis not in AXES:
        raise SceneError(f"{scene.path}: --axis: expected x, y or z, got {axis!r}")
    k = AXES.index(axis)
    if packing.periodic[k]:
        raise SceneError(f"{scene.path}: --axis: {packing.path} is periodic along {axis}: the "
                         "flux test needs two opposite faces (a box, a cylinder along its axis)")
    problem = section_problem(packing, k)
    if problem is not None:
        raise SceneError(f"{scene.path}: --axis: {packing.path} has no cross-section area "
                         f"normal to {axis}: {problem} (expected a box face or a cylinder "
                         f"along {axis}; axes with one: {', '.join(flux_axes(packing)) or 'none'})")
    faces = (f"{axis}min", f"{axis}max")
    test, shift = _flux_scene(scene, faces, t_hot, t_cold)
    t_hot, t_cold = t_hot + shift, t_cold + shift
    run = run_in_memory(test, packing, initial_temperature_k=0.5 * (t_hot + t_cold))
    effective = steady_effective_conductivity(                          # 002, eq. 8
        run.result, run.network, "hot", "cold", t_in=t_hot, t_out=t_cold,
        length_m=float(packing.domain_hi[k] - packing.domain_lo[k]),
        area_m2=cross_section(packing, k), length_convention="domain", where=scene.path)
    if not effective.q_in_w > 0:
        raise SceneError(f"{scene.path}: boundary: no heat flows from {faces[0]} to {faces[1]} "
                         f"in {packing.path} (the two faces are not connected by contacts)")
    return FluxTest(
        n_hot=len(boundary_particles(test, packing, faces[0], "boundary[0]")),
        n_cold=len(boundary_particles(test, packing, faces[1], "boundary[1]")),
        law_params=dict(run.law_params), effective=effective,
        neighbours=run.neighbours, conductance_w_k=run.problem.conductance_w_k)


# a flux test on MPI ranks holds its faces this much above the test's temperatures when the
# colder is not above 0 K (the default 1 / 0: a scene refuses 0 K); the flow and lambda_e are
# the same (linear, the same temperature difference)
RANKS_SHIFT_K = 300.0


def _flux_scene(scene: Scene, faces, t_hot: float, t_cold: float) -> tuple[Scene, float]:
    """The flux test's scene and the shift of its temperatures (K): ``scene`` with the two
    faces held at ``t_hot`` and ``t_cold`` instead of its boundaries, and a steady solve.
    In-process: the scene changed in memory (the shift 0). On MPI ranks (``run_in_memory``
    under ``ranks_of_run_in_memory``: ``tdem calibrate --ranks``), which read a scene's text:
    the scene's own tables with those two changed, as TOML text (``toml_text``), the faces
    shifted by :data:`RANKS_SHIFT_K` when the colder is not above 0 K; a scene its text no
    longer says (changed through the API, a campaign's case) is refused there."""
    if not ranks_in_effect():
        return dataclasses.replace(
            scene, boundaries=(TemperatureBoundary(name="hot", on=faces[0], value=t_hot),
                               TemperatureBoundary(name="cold", on=faces[1], value=t_cold)),
            solver=SolverConfig(method="steady")), 0.0
    if not scene.text or scene_text_difference(scene.text, str(scene.path),
                                               scene_to_json(scene), scene.law,
                                               scene.output.parent) is not None:
        raise SceneError(f"{scene.path}: the flux test on MPI ranks reads the scene's text, "
                         "and the scene was changed after it was read; expected a scene read "
                         "from its file (load_scene)")
    shift = 0.0 if min(t_hot, t_cold) > 0 else RANKS_SHIFT_K
    held = [dict(kind="temperature", name="hot", on=faces[0], value=float(t_hot + shift)),
            dict(kind="temperature", name="cold", on=faces[1], value=float(t_cold + shift))]
    tables, _ = read_toml(scene.path, scene.text)
    tables = {key: value for key, value in tables.items() if key not in ("boundary", "solver")}
    return load_scene(scene.path, text=toml_text(
        dict(tables, boundary=held, solver=dict(method="steady"))),
        out_dir=scene.output.parent), shift


def calibrate_ct(scene: Scene, packing: Packing, axis: str = "x", t_hot: float = 1.0,
                 t_cold: float = 0.0) -> Calibration:
    """Calibrated C_t of ``scene`` (law haddad) on ``packing`` by one steady solve."""
    if scene.law != "haddad":
        raise SceneError(f"{scene.path}: law: tdem calibrate calibrates the haddad law's C_t, "
                         f"the scene uses {scene.law!r}")
    test = flux_test(scene, packing, axis, t_hot, t_cold)
    ct_used = float(test.law_params["ct"])
    conductivity = scene.material(0).conductivity
    return Calibration(
        ct=ct_used * conductivity / test.effective_w_mk,             # 002, eq. 9
        ct_used=ct_used, conductivity_w_mk=conductivity, effective_w_mk=test.effective_w_mk,
        heat_flow_w=test.heat_flow_w, balance=test.balance, length_m=test.length_m,
        area_m2=test.area_m2, axis=axis, n_hot=test.n_hot, n_cold=test.n_cold,
        neighbours=test.neighbours)


def calibrate_axes(scene: Scene, packing: Packing, axes: str = "all", t_hot: float = 1.0,
                   t_cold: float = 0.0):
    """``tdem calibrate``: (calibrations, skipped, ct). ``axes`` "all" takes every axis of
    :func:`flux_axes` and says why the others are skipped ({axis: reason}); one named axis that
    has no flux test is refused (SceneError). ``ct`` is the mean over the calibrated axes: all
    of them have a box-face cross-section, or there is one (a cylinder along its axis), so the
    mean never mixes a bounding-box estimate with a true section."""
    if axes != "all":
        results = [calibrate_ct(scene, packing, a, t_hot, t_cold) for a in axes]
        return results, {}, sum(r.ct for r in results) / len(results)
    usable = flux_axes(packing)
    skipped = {}
    for k, a in enumerate(AXES):
        if packing.periodic[k]:
            skipped[a] = "periodic"
        elif a not in usable:
            skipped[a] = section_problem(packing, k)
    if not usable:
        raise SceneError(f"{scene.path}: --axis: {packing.path} has no axis with a flux test "
                         "(expected a non-periodic axis whose cross-section is a box face or a "
                         "cylinder's disc): " + "; ".join(
                             f"{', '.join(a for a in skipped if skipped[a] == why)}: {why}"
                             for why in dict.fromkeys(skipped.values())))
    results = [calibrate_ct(scene, packing, a, t_hot, t_cold) for a in usable]
    return results, skipped, sum(r.ct for r in results) / len(results)
