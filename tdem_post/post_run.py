"""Post-processing of one thermal run of a bed between two held walls (003, sec. 4.3-4.4).

    analyse(thermal_h5, n_bins=10) -> PostResult      (compute: typed results, no file)
    write_post(result) -> dict                         (figures, CSVs, summary.json: all or none)
    post_run(thermal_h5, n_bins=10) -> dict            (both: the summary)
    command(run, ...) -> int                           (``tdem post``: both, and the printed table)

Each quantity has its compute function and typed result: slab_of -> Slab, profiles_of ->
Profiles, fit_profiles -> GammaResult, steady_etc -> EffectiveConductivity
(thermal_kernel.effective, length convention "held_centres"), tau_of -> Tau, flux_field ->
FluxField, fabric_of -> Fabric, mean_field -> {law: gamma_mf}; PostResult.record() ->
PostSummary is post/summary.json (its fields are the file's keys, written and read by
tdem_post.records).

From ``thermal.h5`` alone (:func:`thermal_kernel.output.read_thermal`: the scene as it ran,
stored in the file, and the packing it names, checked against the content hash it stored):
- binned profiles along the axis joining the two temperature boundaries (partial volumes),
  between the mean centre planes of the two held sets of spheres (the slab length L);
- gamma = k_eff / k_p fitted to the profiles against the slab solution (003 App. A), with its
  95 % interval and the rms residual. The slab's volumetric heat capacity is the run's own: the
  capacities C_p the run stored (each law's rule: rho c_p V for the granular laws, rho c_p V /
  phi for haddad, rho c_p V / f_vl(n) for terreros) of the spheres between the held planes
  (partial volumes) over the slab's volume A L (:func:`bed_capacity`);
- only the outputs the slab solution can describe enter the fit (:func:`output_window`): after
  the heat has crossed a particle radius, and while the profile is still further from the steady
  state than the slab's own steady misfit on this bed; none, or a run that is flagged (its
  temperatures not a faithful solution), has a source, a flux or a wall exchange, or is steady:
  gamma is *not measurable* and the reason is said (``not_measurable`` in summary.json);
- the model-form spread: the same bed heated from the other wall (hot and cold swapped, solved
  on the run's network), fitted the same way; the two fits' 95 %
  intervals together are ``gamma_model_form_range`` (flag ``gamma_model_form`` when they do not
  overlap: the homogeneous slab does not describe this bed to the fit's precision);
- gamma from the steady solve: k_eff = Q L / (A dT) with Q the heat through the hot wall
  (heat in = heat out checked: refused above thermal_kernel.effective.BALANCE_TOLERANCE), A
  the bed's cross-section;
- tau of the middle section (003 eq. 41), exactly from the network (one sparse solve) and from
  the time series (with the steady temperature of the steady solve, not the last snapshot) when
  the outputs cover the transient (:func:`series_tau_problem`);
- mean-field predictions gamma_mf = phi Z H_mean / (2 pi R_mean k_p) for the laws of
  MEAN_FIELD_LAWS on the same contacts (forces from the dump, modulus from the scene); phi the
  packing's solid_fraction, checked against the spheres between the two walls;
- the run's flags (thermal.h5) as ``flags``, post's own as ``post_flags``;
- figure ``post/profiles.png`` (+ ``profiles.csv``) and ``post/summary.json``, built in a
  temporary folder beside ``post/`` and swapped in whole.
Rattlers (no conducting contact) keep their initial temperature: they are left out of the
profiles (their number is reported).
"""
from __future__ import annotations

import contextlib
import dataclasses
import errno
import math
import os
import shutil
import signal
import sys
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from thermal_kernel.calibrate import cross_section
from thermal_kernel.network import assemble
from thermal_kernel.effective import EffectiveConductivity, effective_conductivity
from thermal_kernel.output import (ThermalFileError, ThermalRun, read_run_packing,
                                   read_thermal)
from thermal_kernel.atomic import savefig_atomic, write_text_atomic
from thermal_kernel.packing import packing_statistics
from thermal_kernel.problem import FACES, boundary_particles, build_problem
from thermal_kernel.scene import SceneError
from thermal_kernel.solvers.implicit import run_implicit
from thermal_kernel.solvers.steady import solve_steady

from .analytic import (slab_mean_temperature, slab_midplane_characteristic_time,
                       slab_temperature)
from .fabric import affine_conductivity, contact_angle_pdf, love_weber_stress, mean_nz2
from .flux import HALO_RADII, coefficient_of_variation, halo_radii, particle_flux
from .fits import (GammaFit, characteristic_time_network, characteristic_time_series,
                   fit_gamma)
from .profiles import binned_profile, partial_volumes
from .records import column, json_text, to_dict

# the laws of the mean-field estimates: post, the CLI and the campaign report all use this list
MEAN_FIELD_LAWS = ("bob", "argento", "pipe")


def _wall_position(packing, on):
    """(axis, coordinate) of a wall of the packing or a domain face."""
    if on in packing.wall_name:
        w = packing.wall_name.index(on)
        if packing.wall_kind[w] != "plane":
            raise ValueError(f"{packing.path}: walls/kind: {on} is not a plane")
        axis = int(np.argmax(np.abs(packing.wall_normal[w])))
        return axis, float(packing.wall_point[w][axis])
    axis, side = FACES[on]
    return axis, float((packing.domain_lo if side < 0 else packing.domain_hi)[axis])


def interior_mask(packing, margin_m):
    """Particles at least ``margin_m`` (scalar or (N,)) inside the domain's non-periodic faces
    and inside every cylinder wall: their halo does not cross a boundary."""
    margin = np.broadcast_to(np.asarray(margin_m, float), (packing.n_particles,))
    x = packing.position
    inside = np.ones(packing.n_particles, bool)
    for axis in range(3):
        if not packing.periodic[axis]:
            inside &= (x[:, axis] - margin >= packing.domain_lo[axis]) & (
                x[:, axis] + margin <= packing.domain_hi[axis])
    for kind, point, normal, radius in zip(packing.wall_kind, packing.wall_point,
                                           packing.wall_normal, packing.wall_radius):
        if kind == "cylinder":
            rel = x - point
            radial = rel - np.outer(rel @ normal, normal) / float(normal @ normal)
            inside &= np.linalg.norm(radial, axis=1) + margin <= radius
    return inside


# ----------------------------------------------------------------------------- typed results
@dataclass(frozen=True, eq=False)
class Slab:
    """The bed between its two temperature boundaries, along ``axis``."""
    axis: int
    bottom: object               # the lower Boundary (thermal_kernel.scene)
    top: object
    held_bottom: np.ndarray      # indices of the spheres each holds
    held_top: np.ndarray
    z0_m: float                  # mean centre plane of the bottom held spheres
    z1_m: float                  # and of the top ones
    length_m: float              # between the two held sets' mean centre planes (slab L)
    wall_gap_m: float            # between the two walls


@dataclass(frozen=True, eq=False)
class Profiles:
    times_s: np.ndarray
    edges_m: np.ndarray          # bin edges from the bottom held plane (0) to L
    values_k: np.ndarray         # (K, n_bins) partial-volume means of the conducting spheres
    height_m: np.ndarray         # (N,) each sphere's height above the bottom held plane
    conducting: np.ndarray       # (N,) a conducting contact, or held


@dataclass(frozen=True)
class GammaResult:
    """gamma = k_eff / k_p fitted to the profiles against the slab solution (003 App. A)."""
    fit: GammaFit
    per_time: list               # [t, gamma, ci95 low, ci95 high] of each output time alone
    #                              (None, None, None for an output left out: see left_out)
    gamma_paper: float           # 003's convention: the fitted alpha read as gamma k_p/(rho_p c_p)
    gamma_paper_ci95: list
    tau_slab_s: float            # the slab's own mid-plane time L^2 / (8 alpha)
    used_s: list                 # the output times fitted
    left_out: list               # [[t, why], ...] the outputs the slab solution cannot describe
    other: GammaFit | None = None        # the same bed heated from the other wall
    other_note: str | None = None        # why ``other`` is missing, if it is

    @property
    def model_form_range(self) -> list | None:
        """Both orientations' 95 % intervals together (None without the other orientation)."""
        if self.other is None:
            return None
        return [min(self.fit.ci95[0], self.other.ci95[0]),
                max(self.fit.ci95[1], self.other.ci95[1])]

    @property
    def model_form_spread(self) -> float | None:
        """|gamma - gamma_other| / (gamma + gamma_other): half the difference over the mean."""
        if self.other is None:
            return None
        return abs(self.fit.gamma - self.other.gamma) / (self.fit.gamma + self.other.gamma)

    @property
    def model_form_flag(self) -> bool:
        """The two orientations' 95 % intervals do not overlap."""
        return self.other is not None and (self.other.ci95[0] > self.fit.ci95[1]
                                           or self.other.ci95[1] < self.fit.ci95[0])


@dataclass(frozen=True)
class Tau:
    """tau of the middle section (003 eq. 41)."""
    tau_s: float | None          # exactly from the network (one sparse solve)
    tau_series_s: float | None   # from the time series (None: not measurable, see why)
    tau_note: str | None = None          # why tau_s is None
    series_note: str | None = None       # why tau_series_s is None


@dataclass(frozen=True, eq=False)
class FluxField:
    """Heat flux per particle at steady state (002 eq. 20) and its Halo average (eq. 22-23)."""
    halo_ratio: float
    halo_radius: str             # "common" (ratio x the mean radius) or "own" (ratio x R_p)
    interior_particles: int
    cov_raw: float | None        # coefficient of variation of |q| over the interior
    cov_raw_volume: float | None    # the same weighted by V_p (eq. 20's 1/V_p: the raw CoV per
    #                                 particle is dominated by the small spheres)
    cov_halo: float | None
    mean_over_q_per_area: float | None   # mean axial q of the interior / (Q / A)
    q_raw: np.ndarray = dataclasses.field(repr=False)
    q_halo: np.ndarray = dataclasses.field(repr=False)


@dataclass(frozen=True)
class Fabric:
    """The affine (fabric-tensor) bound of the steady conductivity and the contact fabric."""
    gamma_affine: float          # k_zz / k_p, an upper bound of gamma_steady (Thomson)
    gamma_affine_transverse: float
    nz2: float                   # <n_z^2> of the touching contacts (1/3 isotropic)
    nz2_conductance: float       # conductance-weighted
    angle_edges: list
    angle_pdf: list
    contact_stress_axial_pa: float   # Love-Weber stress of the contacts along the axis


@dataclass(frozen=True, eq=False)
class PostResult:
    """Everything :func:`analyse` computes from one run; :meth:`record` is post/summary.json."""
    thermal: Path
    run: ThermalRun
    packing: object
    n_bins: int
    slab: Slab
    profiles: Profiles
    gamma: GammaResult | None    # None: not measurable (a steady run; why: not_measurable)
    steady: EffectiveConductivity    # length convention "held_centres"
    gamma_steady: float
    tau: Tau
    flux: FluxField
    fabric: Fabric
    mean_field: dict             # {law of MEAN_FIELD_LAWS: gamma_mf}
    solid_fraction: float
    mean_coordination: float
    mean_normal_force_n: float
    rattlers: int                # spheres neither conducting nor held (left out of profiles)
    pressure_pa: float
    bed_capacity_j_m3k: float    # the run's capacity per unit slab volume (bed_capacity)
    solid_fraction_between_walls: float  # the spheres' volume between the two walls / A gap
    not_measurable: dict         # {summary key: why} of what this run cannot give
    post_flags: tuple            # post's own flags (gamma_model_form, solid_fraction, ...)

    def summary(self) -> dict:
        """post/summary.json's content (:meth:`record` as JSON data)."""
        return to_dict(self.record())

    def record(self) -> PostSummary:
        """The run's :class:`PostSummary` (post/summary.json)."""
        g = self.gamma
        fit = g.fit if g else None
        cov = self.flux.cov_raw is not None
        other = g.other if g else None
        return PostSummary(
            thermal=str(self.thermal), packing=str(self.packing.path), law=self.run.law,
            method=self.run.method, flags=self.run.flags, post_flags=",".join(self.post_flags),
            not_measurable=dict(self.not_measurable),
            n_particles=int(self.packing.n_particles), pressure_pa=self.pressure_pa,
            solid_fraction=self.solid_fraction,
            solid_fraction_between_walls=self.solid_fraction_between_walls,
            mean_coordination=self.mean_coordination,
            mean_normal_force_n=self.mean_normal_force_n, rattlers=self.rattlers,
            bed_capacity_j_m3k=self.bed_capacity_j_m3k,
            gamma=fit.gamma if fit else None, gamma_ci95=list(fit.ci95) if fit else None,
            gamma_paper=g.gamma_paper if fit else None,
            gamma_paper_ci95=g.gamma_paper_ci95 if fit else None,
            gamma_per_time=g.per_time if fit else None,
            gamma_outputs_used_s=g.used_s if fit else None,
            gamma_outputs_left_out=g.left_out if fit else None,
            gamma_residual_rms_k=fit.residual_rms_k if fit else None,
            gamma_other_orientation=other.gamma if other else None,
            gamma_other_orientation_ci95=list(other.ci95) if other else None,
            gamma_model_form_range=g.model_form_range if fit else None,
            gamma_model_form_spread=g.model_form_spread if fit else None,
            gamma_steady=self.gamma_steady, steady_balance=self.steady.balance,
            tau_s=self.tau.tau_s, tau_series_s=self.tau.tau_series_s,
            tau_slab_s=g.tau_slab_s if fit else None,
            gamma_mean_field=dict(self.mean_field),
            gamma_affine=self.fabric.gamma_affine,
            gamma_affine_transverse=self.fabric.gamma_affine_transverse,
            fabric_nz2=self.fabric.nz2, fabric_nz2_conductance=self.fabric.nz2_conductance,
            contact_angle_edges=self.fabric.angle_edges,
            contact_angle_pdf=self.fabric.angle_pdf,
            contact_stress_axial_pa=self.fabric.contact_stress_axial_pa,
            length_m=self.slab.length_m, wall_gap_m=self.slab.wall_gap_m,
            n_bins=self.n_bins, run_wall_seconds=self.run.wall_seconds,
            flux_halo_ratio=self.flux.halo_ratio, flux_halo_radius=self.flux.halo_radius,
            flux_interior_particles=self.flux.interior_particles,
            flux_cov_raw=self.flux.cov_raw if cov else None,
            flux_cov_raw_volume_weighted=self.flux.cov_raw_volume if cov else None,
            flux_cov_halo=self.flux.cov_halo if cov else None,
            flux_mean_over_q_per_area=self.flux.mean_over_q_per_area if cov else None)


def _optional():
    return dataclasses.field(default=None, metadata=column(optional=True))


@dataclass(frozen=True, kw_only=True)
class PostSummary:
    """post/summary.json: one run's post-processed numbers (:meth:`PostResult.record`), its keys
    these fields in this order; None: not measurable (``not_measurable`` says why). Written and
    read by tdem_post.records (a missing or unknown key is refused in one line)."""
    thermal: str                 # the run's thermal.h5
    packing: str
    law: str
    method: str
    flags: str                   # the run's own flags (thermal.h5, comma-separated)
    post_flags: str              # post's own (comma-separated)
    not_measurable: dict[str, str]       # {key: why} of what this run cannot give
    n_particles: int
    pressure_pa: float
    solid_fraction: float
    solid_fraction_between_walls: float
    mean_coordination: float
    mean_normal_force_n: float
    rattlers: int
    bed_capacity_j_m3k: float
    gamma: float | None
    gamma_ci95: list[float] | None
    # 003 App. A writes alpha = kappa_eff/(rho c_p) with rho the particle density (Table 1): the
    # same fitted diffusivity read in that convention
    gamma_paper: float | None
    gamma_paper_ci95: list[float] | None
    gamma_per_time: list | None          # [t_s, gamma, ci95 low, ci95 high] per output
    gamma_outputs_used_s: list[float] | None
    gamma_outputs_left_out: list | None  # [[t_s, why], ...]
    gamma_residual_rms_k: float | None
    # the same bed heated from the other wall: the slab model's form error
    gamma_other_orientation: float | None
    gamma_other_orientation_ci95: list[float] | None
    gamma_model_form_range: list[float] | None
    gamma_model_form_spread: float | None
    gamma_steady: float
    steady_balance: float
    tau_s: float | None
    tau_series_s: float | None
    tau_slab_s: float | None             # L^2/(8 alpha), the slab's with the fitted diffusivity
    gamma_mean_field: dict[str, float]   # {law of MEAN_FIELD_LAWS: gamma_mf}
    gamma_affine: float
    gamma_affine_transverse: float
    fabric_nz2: float
    fabric_nz2_conductance: float
    contact_angle_edges: list[float]     # rad
    contact_angle_pdf: list[float]
    # Love-Weber stress of the particle contacts over the bed between the walls, along the axis
    # (compare with the plate's pressure)
    contact_stress_axial_pa: float
    length_m: float
    wall_gap_m: float
    n_bins: int
    run_wall_seconds: float
    flux_halo_ratio: float
    flux_halo_radius: str
    flux_interior_particles: int
    flux_cov_raw: float | None = _optional()       # (absent: no interior particle)
    flux_cov_raw_volume_weighted: float | None = _optional()
    flux_cov_halo: float | None = _optional()
    flux_mean_over_q_per_area: float | None = _optional()
    files: list[str] | None = _optional()          # what write_post wrote beside it


# ----------------------------------------------------------------------------- compute
def slab_of(scene, packing, where) -> Slab:
    """The two temperature boundaries (opposite walls or faces) and the slab between the mean
    centre planes of the spheres they hold."""
    held = [b for b in scene.boundaries if b.kind == "temperature"]
    if len(held) != 2:
        raise SceneError(f"{where}: scene: the profile fit needs exactly two temperature "
                         f"boundaries (bottom and top), found {len(held)}")
    (ax0, x0), (ax1, x1) = (_wall_position(packing, b.on) for b in held)
    if ax0 != ax1:
        raise SceneError(f"{where}: scene: the two temperature boundaries are not opposite")
    bottom, top = (held[0], held[1]) if x0 < x1 else (held[1], held[0])
    axis = ax0
    # The Dirichlet condition acts on the held spheres, whose centres lie about one radius
    # inside the walls: the slab of the analytical solution spans the mean centre planes of the
    # two held sets (on a simple-cubic lattice this is exactly the finite-difference slab).
    held_bottom, held_top = (boundary_particles(scene, packing, b.on, "boundary")
                             for b in (bottom, top))
    z0, z1 = (float(np.mean(packing.position[h][:, axis])) for h in (held_bottom, held_top))
    return Slab(axis=axis, bottom=bottom, top=top, held_bottom=held_bottom, held_top=held_top,
                z0_m=z0, z1_m=z1, length_m=z1 - z0, wall_gap_m=max(x0, x1) - min(x0, x1))


def profiles_of(run: ThermalRun, packing, net, slab: Slab, n_bins: int,
                temperature=None) -> Profiles:
    """Partial-volume profiles of the conducting spheres in ``n_bins`` bins between the held
    planes, at every output time (of ``temperature`` (K, N) instead of the run's if given)."""
    conducting = np.asarray(net.conducting)
    z = packing.position[:, slab.axis] - slab.z0_m
    edges = np.linspace(0.0, slab.length_m, n_bins + 1)
    values = binned_profile(z, packing.radius,
                            run.temperature if temperature is None else temperature, edges,
                            weights=conducting)
    return Profiles(times_s=run.times, edges_m=edges, values_k=values, height_m=z,
                    conducting=conducting)


# ----------------------------------------------------------------------------- what is measurable
# Flags of a run (thermal.h5 'flags') that leave its temperatures a faithful solution of the
# network: its own bookkeeping (docs/solvers.md: rattlers and floating clusters keep their
# initial temperature, contacts of zero conductance are dropped). Any other flag --
# max_principle, energy_ledger, non_finite, dt_above_bound, below_absolute_zero, ... or one added
# later -- says they are not, and no transient quantity is taken from them.
BENIGN_FLAGS = frozenset({"rattlers", "floating_clusters", "zero_conductance_contacts_dropped"})
# An output enters the gamma fit once the heat has crossed a mean particle radius,
# sqrt(alpha_s t) >= r_mean with alpha_s = gamma_steady k_p / (rho c)_bed (before, the profile is
# the first layer's response to its wall contacts, not a continuum's: on the 405-bar test bed,
# law pipe, one-output fits give gamma/gamma_steady 100, 34, 10.5, 3.9, 1.6, 1.13 at
# sqrt(alpha_s t) = 0.06 ... 0.8 r_mean, then 0.84-0.95 from 1.3 to 8 r_mean), and while its
# profile is further from the steady state (max over the bins) than STEADY_MISFIT_FACTOR x the
# slab's own steady misfit m on this bed, m = max over the bins of |the network's steady profile
# - the slab's linear one|, known before any fit (the same bed: m = 8.8 K, 4.6 % of the span;
# one-output fits 0.91 at 33 K from steady, 0.77 at 6 K, 0.49 at 0.3 K, 0.25 at 5e-4 K, each
# with an interval of +-1-2 %: late profiles fit the bed's steady misfit, not its diffusivity).
STEADY_MISFIT_FACTOR = 2.0
# ... and never closer than this share of the temperature span (a bed the slab describes
# exactly, m ~ 0: the solver's own error)
STEADY_FLOOR = 1e-3
# tau from the time series integrates the middle section's e(t) = T_s - T over the outputs
# (trapezoid) and extrapolates the tail past the last one. Not measurable when e(t_last)/e(0)
# is above this (for an exponential tail that is its share of the integral), or when the
# trapezoid and an exponential interpolation between the outputs differ by more than this share
# of the integral (outputs too far apart for the decay).
TAU_SERIES_TOLERANCE = 0.1
# The packing's solid_fraction against the spheres' volume between the two walls over A x gap
# (post_flags "solid_fraction" above it; on the 405-bar bed 0.5390 against 0.5389)
SOLID_FRACTION_RTOL = 0.01


def transient_problem(run: ThermalRun, scene, slab: Slab) -> str | None:
    """Why the run's temperatures cannot be compared with the slab solution at all (a steady
    run, a flagged run, a source, a flux or a wall exchange); None when they can."""
    if run.method == "steady" or not bool(np.all(np.isfinite(run.times))):
        return "a steady run has no transient (the steady ETC is the answer)"
    bad = [f for f in run.flags.split(",") if f and f not in BENIGN_FLAGS]
    if bad:
        return (f"the run is flagged {', '.join(bad)} (thermal.h5 flags): its temperatures "
                "are not a faithful solution (docs/solvers.md)")
    others = [b for b in scene.boundaries if b is not slab.bottom and b is not slab.top]
    if others:
        b = others[0]
        return (f"the run has a {b.kind} boundary ({getattr(b, 'name', b.kind)}): 003 App. A's "
                "slab solution has only the two held walls")
    return None


def bed_capacity(capacity_j_k, packing, slab: Slab, area_m2: float, weights) -> float:
    """The run's heat capacity per unit volume of the slab (J/m^3/K): sum_p C_p v_p / V_p over
    A L, with C_p the capacities the run used (the law's rule), v_p the part of sphere p between
    the two held planes (partial volumes, as the profiles) and ``weights`` (N,) the spheres that
    take part (conducting or held: a rattler keeps its initial temperature). On a simple-cubic
    lattice this is the finite-difference slab's capacity exactly (the held layers' inner halves
    fill the end half-cells); for the granular laws it is phi rho c_p, for haddad (C_p = rho c_p
    V_p / phi, 002 eq. 5) rho c_p."""
    z = packing.position[:, slab.axis]
    inside = partial_volumes(z, packing.radius, np.array([slab.z0_m, slab.z1_m]))[:, 0]
    share = inside / (4.0 / 3.0 * np.pi * packing.radius ** 3)
    return float(np.sum(np.asarray(capacity_j_k) * share * np.asarray(weights, float))
                 / (area_m2 * slab.length_m))


def solid_fraction_between_walls(packing, slab: Slab, area_m2: float) -> float:
    """The spheres' volume between the two held walls (caps beyond them cut) over A x gap."""
    lo, hi = sorted(_wall_position(packing, b.on)[1] for b in (slab.bottom, slab.top))
    z = packing.position[:, slab.axis]
    inside = partial_volumes(z, packing.radius, np.array([lo, hi]))[:, 0]
    return float(inside.sum() / (area_m2 * (hi - lo)))


def output_window(profiles: Profiles, steady_k, slab: Slab, t_initial, alpha_s: float,
                  r_mean: float) -> list:
    """[why or None] for each output: None when the slab solution can describe it (see
    STEADY_MISFIT_FACTOR). ``steady_k`` (B,): the network's steady profile in the same bins."""
    lo, hi = profiles.edges_m[:-1], profiles.edges_m[1:]
    linear = slab_mean_temperature(lo, hi, math.inf, slab.length_m, 1.0, slab.bottom.value,
                                   slab.top.value, t_initial)
    misfit = float(np.nanmax(np.abs(steady_k - linear)))
    span = max(abs(slab.bottom.value - t_initial), abs(slab.top.value - t_initial),
               abs(slab.bottom.value - slab.top.value))
    floor = max(STEADY_MISFIT_FACTOR * misfit, STEADY_FLOOR * span)
    out = []
    for k, t in enumerate(profiles.times_s):
        depth = math.sqrt(max(alpha_s * t, 0.0))
        if not t >= r_mean ** 2 / alpha_s:      # sqrt(alpha_s t) >= r_mean
            out.append(f"t = {t:g} s: the heat has crossed {depth / r_mean:.2g} of a particle "
                       f"radius (sqrt(alpha t), alpha from gamma_steady): below the continuum "
                       "scale")
            continue
        away = float(np.nanmax(np.abs(profiles.values_k[k] - steady_k)))
        if not away > floor:
            out.append(f"t = {t:g} s: {away:.3g} K from the steady state, within "
                       f"{floor:.3g} K (the slab's steady misfit on this bed is {misfit:.3g} K)")
        else:
            out.append(None)
    return out


def fit_profiles(profiles: Profiles, slab: Slab, *, conductivity_w_mk, capacity_j_m3k,
                 t_initial, particle_capacity_j_m3k, window, gamma0=0.05):
    """gamma fitted to the outputs ``window`` (from :func:`output_window`) admits, and to each
    of them alone (the window dependence, issue 15). Returns (GammaResult, None), or (None,
    why) when no output is admitted or the profiles do not determine gamma."""
    times = profiles.times_s
    use = np.array([w is None for w in window], bool)
    left_out = [[float(t), w] for t, w in zip(times, window) if w is not None]
    if not use.any():
        return None, (f"none of the {len(times)} outputs is one the slab solution can describe ("
                      + "; ".join(w for _, w in left_out[:1] + left_out[-1:][len(left_out) < 2:])
                      + ")")
    args = dict(conductivity_w_mk=conductivity_w_mk, volumetric_capacity_j_m3k=capacity_j_m3k,
                t_bottom=slab.bottom.value, t_top=slab.top.value, t_initial=t_initial)
    fit = fit_gamma(times[use], profiles.edges_m, profiles.values_k[use], **args, gamma0=gamma0)
    if not (np.all(np.isfinite(fit.ci95)) and fit.ci95[0] > 0):
        return None, (f"the profiles do not determine gamma (95 % interval [{fit.ci95[0]:.3g}, "
                      f"{fit.ci95[1]:.3g}])")
    per_time = []
    for k, t in enumerate(times):
        if not use[k]:
            per_time.append([float(t), None, None, None])
            continue
        try:
            one = fit_gamma([t], profiles.edges_m, profiles.values_k[k:k + 1], **args,
                            gamma0=fit.gamma)
            per_time.append([float(t), one.gamma, *one.ci95])
        except (ValueError, RuntimeError):
            per_time.append([float(t), None, None, None])
    # 003 App. A: alpha = gamma_paper k_p / (rho_p c_p), the particle's capacity per volume
    paper = fit.diffusivity_m2_s * particle_capacity_j_m3k / conductivity_w_mk
    return GammaResult(
        fit=fit, per_time=per_time, gamma_paper=float(paper),
        gamma_paper_ci95=[float(c * paper / fit.gamma) for c in fit.ci95],
        tau_slab_s=float(slab_midplane_characteristic_time(slab.length_m,
                                                           fit.diffusivity_m2_s)),
        used_s=[float(t) for t in times[use]], left_out=left_out), None


# The other orientation's transient: Crank-Nicolson with Rannacher start-up (second order,
# stiff start-up modes damped; docs/solvers.md), each output interval in STEPS_PER_OUTPUT equal
# steps -- a cost set by the number of outputs, whatever the run's own step was (an explicit run
# at its stability bound, or a fine implicit step, would cost the run's time again). On the
# 405-bar bed (outputs 5-100 s) the fitted gamma agrees with a run of the swapped scene at
# dt = 0.25 s within 0.1 %.
STEPS_PER_OUTPUT = 40


def transient_on(net, t_initial: float, times):
    """The transient on the network ``net`` from a uniform ``t_initial`` at ``times`` (s,
    increasing): (K, N) K. Raises FloatingPointError for a flagged result."""
    state = np.full(net.capacity_j_k.shape[0], float(t_initial))
    out, t_prev = [], 0.0
    for t in np.asarray(times, float):
        result = run_implicit(net, state, [t], dt=(t - t_prev) / STEPS_PER_OUTPUT, theta=0.5,
                              scheme="rannacher")
        bad = [f for f in result.flags if f not in BENIGN_FLAGS]
        if bad:
            raise FloatingPointError(f"flagged {', '.join(bad)}")
        out.append(result.temperature_k[-1])
        state, t_prev = result.state, float(t)
    return np.array(out)


def other_orientation(run: ThermalRun, packing, slab: Slab, n_bins: int, fit_args: dict,
                      r_mean: float, alpha_s: float):
    """The same bed heated from the other wall (the two held temperatures swapped), solved on
    the run's network (:func:`transient_on`) at its output times, profiled and fitted as the run
    (its own window). Returns (GammaFit, None) or (None, why)."""
    scene = run.scene
    swap = {id(slab.bottom): slab.top.value, id(slab.top): slab.bottom.value}
    boundaries = tuple(dataclasses.replace(b, value=swap[id(b)]) if id(b) in swap else b
                       for b in scene.boundaries)
    swapped = dataclasses.replace(scene, boundaries=boundaries)
    problem, _ = build_problem(swapped, packing)
    net = assemble(problem)
    # outputs before the heat crosses a particle radius are left out whichever wall is hot
    # (output_window): only the others are solved for
    admitted = run.times >= r_mean ** 2 / alpha_s
    if not admitted.any():
        return None, "no output after the heat crossed a particle radius"
    temperature = np.full((run.times.size, packing.n_particles), np.nan)
    try:
        temperature[admitted] = transient_on(net, scene.initial_temperature, run.times[admitted])
    except (FloatingPointError, ValueError, RuntimeError) as e:
        return None, f"the other orientation's transient failed ({e})"
    slab2 = dataclasses.replace(slab, bottom=boundaries[scene.boundaries.index(slab.bottom)],
                                top=boundaries[scene.boundaries.index(slab.top)])
    profiles = profiles_of(run, packing, net, slab2, n_bins, temperature=temperature)
    t_steady = solve_steady(net, np.full(packing.n_particles, scene.initial_temperature))
    steady = binned_profile(profiles.height_m, packing.radius, t_steady.temperature_k[-1],
                            profiles.edges_m, weights=profiles.conducting)
    window = output_window(profiles, steady, slab2, scene.initial_temperature, alpha_s, r_mean)
    result, why = fit_profiles(profiles, slab2, conductivity_w_mk=fit_args["kp"],
                               capacity_j_m3k=fit_args["capacity"],
                               t_initial=scene.initial_temperature,
                               particle_capacity_j_m3k=fit_args["rho_c"], window=window,
                               gamma0=fit_args["gamma0"])
    return (result.fit, None) if result else (None, f"the other orientation: {why}")


def steady_etc(net, slab: Slab, area_m2: float, initial_k, where) -> EffectiveConductivity:
    """k_eff from the steady heat flow between the two held walls, on the slab length (the
    held sets' centre planes, as the profile fit)."""
    return effective_conductivity(net, slab.bottom.name, slab.top.name, t_in=slab.bottom.value,
                                  t_out=slab.top.value, length_m=slab.length_m, area_m2=area_m2,
                                  length_convention="held_centres", initial_k=initial_k,
                                  where=where)


def series_tau_problem(times_s, e_rel) -> str | None:
    """Why tau cannot be read from the time series of the middle section's e(t)/e(0) =
    (T_s - T)/(T_s - T_0) at ``times_s`` (see TAU_SERIES_TOLERANCE); None when it can."""
    t = np.concatenate([[0.0], np.asarray(times_s, float)])
    e = np.concatenate([[1.0], np.asarray(e_rel, float)])
    if abs(e[-1]) > TAU_SERIES_TOLERANCE:
        return (f"the outputs end at t = {t[-1]:g} s with the middle section still "
                f"{100 * abs(e[-1]):.3g} % of its rise from the steady state: the rest of the "
                "integral would be extrapolated")
    # trapezoid against an exponential between two outputs over which e decays (an e that
    # reached 0, or round-off of the other sign, counted as 1e-12 of the one before)
    gap = 0.0
    for k in range(1, len(t)):
        a, b, dt = e[k - 1], e[k], t[k] - t[k - 1]
        if abs(b) < abs(a):
            b_exp = math.copysign(max(abs(b), 1e-12 * abs(a)), a) if a * b <= 0 else b
            gap += abs(0.5 * (a + b) * dt - (a - b_exp) * dt / math.log(a / b_exp))
    total = float(np.trapezoid(e, t))
    if not gap <= TAU_SERIES_TOLERANCE * abs(total):
        return (f"the outputs are too far apart for the decay: between them the trapezoid and "
                f"an exponential differ by {100 * gap / abs(total):.3g} % of the integral")
    return None


def tau_of(net, run: ThermalRun, packing, profiles: Profiles, slab: Slab, t_steady,
           transient_why: str | None = None) -> Tau:
    """tau of the middle section (the bins around mid-height): from the network, and from the
    time series with the steady temperature of the steady solve (not the last snapshot) when
    the run's outputs cover the transient (:func:`series_tau_problem`) and nothing prevents a
    transient reading (``transient_why``)."""
    initial = run.initial_temperature
    mid = np.array([0.45 * slab.length_m, 0.55 * slab.length_m])
    w_mid = partial_volumes(profiles.height_m, packing.radius, mid)[:, 0] * profiles.conducting
    s_steady = float(t_steady @ w_mid / w_mid.sum())
    s_init = float(initial @ w_mid / w_mid.sum())
    span = abs(slab.bottom.value - slab.top.value) + abs(slab.bottom.value - s_init)
    if not abs(s_steady - s_init) > 1e-9 * span:
        why = (f"the middle section's steady temperature is its initial one ({s_init:.6g} K): "
               "eq. 41's e(0) is 0")
        return Tau(tau_s=None, tau_series_s=None, tau_note=why, series_note=why)
    tau_net = characteristic_time_network(net, t_steady, initial, w_mid)
    if transient_why is not None:
        return Tau(tau_s=tau_net, tau_series_s=None, series_note=transient_why)
    section = (run.temperature @ w_mid) / w_mid.sum()
    why = series_tau_problem(run.times, (s_steady - section) / (s_steady - s_init))
    if why is not None:
        return Tau(tau_s=tau_net, tau_series_s=None,
                   series_note=f"{why} (the exact tau is {tau_net:.4g} s)")
    return Tau(tau_s=tau_net, tau_series_s=float(characteristic_time_series(
        run.times, section, s_steady, s_init)))


def flux_field(packing, conductance_w_k, t_steady, solid_fraction, slab: Slab,
               profiles: Profiles, steady: EffectiveConductivity, halo_ratio: float,
               halo_radius: str = "common") -> FluxField:
    """Per-particle heat flux (002 eq. 20) and its Halo average (``halo_radius`` "common":
    ratio x the mean radius, "own": ratio x R_p); their scatter over the interior (the spheres
    whose halo crosses no boundary, between the held planes), the raw one also per unit solid
    volume (weights V_p)."""
    args = (packing.position, packing.radius, packing.pair, packing.branch, conductance_w_k,
            t_steady, solid_fraction)
    q_raw = particle_flux(*args)
    q_halo = particle_flux(*args, halo_ratio=halo_ratio, halo_radius=halo_radius)
    z = profiles.height_m
    reach = np.maximum(halo_radii(packing.radius, halo_ratio, halo_radius), packing.radius)
    interior = interior_mask(packing, reach) & profiles.conducting
    interior &= (z > 0) & (z < slab.length_m)
    cov_raw = cov_raw_volume = cov_halo = ratio = None
    if interior.sum() >= 2:
        sign = 1.0 if slab.bottom.value > slab.top.value else -1.0
        cov_raw = coefficient_of_variation(q_raw, interior)
        cov_raw_volume = coefficient_of_variation(q_raw, interior, weights=packing.radius ** 3)
        cov_halo = coefficient_of_variation(q_halo, interior)
        # mean axial flux of the interior over the heat flow per cross-section Q / A
        ratio = float(sign * q_halo[interior, slab.axis].mean()
                      / (abs(steady.q_in_w) / steady.area_m2))
    return FluxField(halo_ratio=halo_ratio, halo_radius=halo_radius,
                     interior_particles=int(interior.sum()), cov_raw=cov_raw,
                     cov_raw_volume=cov_raw_volume, cov_halo=cov_halo,
                     mean_over_q_per_area=ratio,
                     q_raw=q_raw, q_halo=q_halo)


def fabric_of(packing, conductance_w_k, slab: Slab, area_m2: float, kp: float) -> Fabric:
    axis = slab.axis
    affine = affine_conductivity(packing.pair, packing.branch, conductance_w_k,
                                 packing.position, axis, slab.held_bottom, slab.held_top,
                                 slab.z0_m, slab.z1_m, area_m2)
    transverse = [a for a in range(3) if a != axis]
    touching = packing.overlap > 0
    angle_edges, angle_pdf = contact_angle_pdf(packing.branch, touching, axis)
    return Fabric(
        gamma_affine=float(affine.k[axis, axis] / kp),
        gamma_affine_transverse=float(np.mean([affine.k[a, a] for a in transverse]) / kp),
        nz2=mean_nz2(packing.branch, touching, axis),
        nz2_conductance=mean_nz2(packing.branch, touching, axis, weights=conductance_w_k),
        angle_edges=angle_edges.tolist(), angle_pdf=angle_pdf.tolist(),
        contact_stress_axial_pa=float(love_weber_stress(
            packing.branch, packing.normal_force, area_m2 * slab.wall_gap_m)[axis, axis]))


def mean_field(scene, packing, solid_fraction, kp) -> dict:
    """gamma_mf = phi Z H_mean / (2 pi R_mean k_p) of each law of MEAN_FIELD_LAWS on the same
    touching contacts (each law with its own default parameters)."""
    touching = packing.overlap > 0
    r_mean = float(packing.radius.mean())
    z_mean = 2.0 * touching.sum() / packing.n_particles
    out = {}
    for law in MEAN_FIELD_LAWS:
        prob, _ = build_problem(dataclasses.replace(scene, law=law, law_params={}), packing)
        h_mean = float(np.mean(prob.conductance_w_k[touching])) if touching.any() else 0.0
        out[law] = solid_fraction * z_mean * h_mean / (2 * math.pi * r_mean * kp)
    return out


def _check_options(thermal_h5, n_bins, halo_ratio, halo_radius="common"):
    if isinstance(n_bins, bool) or not isinstance(n_bins, (int, np.integer)) or n_bins < 1:
        raise SceneError(f"{thermal_h5}: --bins: expected an integer >= 1 (profile bins), got "
                         f"{n_bins!r}")
    if isinstance(halo_ratio, bool) or not isinstance(halo_ratio, (int, float)) \
            or not (math.isfinite(halo_ratio) and halo_ratio >= 0):
        raise SceneError(f"{thermal_h5}: --halo: expected a number >= 0 (the Halo radius over "
                         f"the particle radius, mean or own: --halo-radius; 0: no Halo), got "
                         f"{halo_ratio!r}")
    if not isinstance(halo_radius, str) or halo_radius not in HALO_RADII:
        raise SceneError(f"{thermal_h5}: --halo-radius: expected one of "
                         f"{', '.join(HALO_RADII)} (ratio x the packing's mean radius, or ratio x "
                         f"each particle's own radius), got {halo_radius!r}")


def analyse(thermal_h5, n_bins: int = 10, halo_ratio: float = 3.0,
            halo_radius: str = "common", orientations: bool = True) -> PostResult:
    """Every quantity of the module docstring, from the run's output alone; no file written.
    The flux field's Halo radius is ``halo_ratio`` x the packing's mean radius ("common", 002's
    "pre-defined number of DE") or x each particle's own radius ("own"). ``orientations``: also
    fit the bed heated from the other wall (one more transient solve; the model-form spread)."""
    thermal_h5 = Path(thermal_h5)
    _check_options(thermal_h5, n_bins, halo_ratio, halo_radius)
    run = read_thermal(thermal_h5)          # the scene as it ran, from the run's output
    packing = read_run_packing(run)         # refused if it changed since the run
    scene = run.scene
    slab = slab_of(scene, packing, thermal_h5)
    mat = scene.material(0)
    kp = mat.conductivity
    stats = packing_statistics(packing)
    phi = float(packing.attrs["solid_fraction"])
    area = cross_section(packing, slab.axis)
    post_flags = []
    not_measurable = {}

    problem, _ = build_problem(dataclasses.replace(scene), packing)
    net = assemble(problem)
    # the capacities the run used (thermal.h5), not the law's rule applied again here
    capacity = getattr(run, "capacity", None)
    if capacity is None:
        capacity = np.asarray(net.capacity_j_k)
    elif not np.allclose(capacity, net.capacity_j_k, rtol=1e-9, atol=0.0):
        post_flags.append("capacity_not_the_laws")   # the law's rule changed since the run
    profiles = profiles_of(run, packing, net, slab, n_bins)
    steady = steady_etc(net, slab, area, np.asarray(run.initial_temperature), thermal_h5)
    t_steady = steady.temperature_k
    gamma_steady = steady.k_eff_w_mk / kp
    rho_c_bed = bed_capacity(capacity, packing, slab, area, profiles.conducting)
    phi_walls = solid_fraction_between_walls(packing, slab, area)
    if not abs(phi - phi_walls) <= SOLID_FRACTION_RTOL * phi_walls:
        post_flags.append("solid_fraction")

    obstacle, gamma = _gamma_of(run, packing, slab, profiles, t_steady, gamma_steady,
                                rho_c_bed, n_bins, orientations, post_flags, not_measurable)
    tau = tau_of(net, run, packing, profiles, slab, t_steady, transient_why=obstacle)
    if tau.tau_note:
        not_measurable["tau_s"] = tau.tau_note
    if tau.series_note:
        not_measurable["tau_series_s"] = tau.series_note
    touching = packing.overlap > 0
    return PostResult(
        thermal=thermal_h5, run=run, packing=packing, n_bins=n_bins, slab=slab,
        profiles=profiles, gamma=gamma, steady=steady, gamma_steady=gamma_steady, tau=tau,
        flux=flux_field(packing, problem.conductance_w_k, t_steady, phi, slab, profiles, steady,
                        halo_ratio, halo_radius),
        fabric=fabric_of(packing, problem.conductance_w_k, slab, area, kp),
        mean_field=mean_field(scene, packing, phi, kp), solid_fraction=phi,
        mean_coordination=float(2.0 * touching.sum() / packing.n_particles),
        mean_normal_force_n=float(stats["mean_normal_force_n"]),
        rattlers=int(np.count_nonzero(~profiles.conducting)),
        pressure_pa=float(packing.attrs.get("pressure_pa", float("nan"))),
        bed_capacity_j_m3k=rho_c_bed, solid_fraction_between_walls=phi_walls,
        not_measurable=not_measurable, post_flags=tuple(post_flags))


def _gamma_of(run, packing, slab, profiles, t_steady, gamma_steady, rho_c_bed, n_bins,
              orientations, post_flags, not_measurable) -> tuple:
    """:func:`analyse`'s γ: the fit of the transient profiles (:func:`fit_profiles`, in the
    window :func:`output_window` chooses) and, with ``orientations``, the bed heated from the
    other wall. ``(obstacle, gamma)``: why the run has no transient to fit (None when it has;
    tau_of needs it too) and the fit (None when not measurable); its flag goes to
    ``post_flags``, its reasons to ``not_measurable``."""
    scene = run.scene
    mat = scene.material(0)
    kp = mat.conductivity
    obstacle = transient_problem(run, scene, slab)
    if obstacle is None and not gamma_steady > 0:
        obstacle = "no heat crosses the bed at steady state (gamma_steady 0): no diffusivity"
    why, gamma = obstacle, None
    if obstacle is None:
        r_mean = float(packing.radius.mean())
        alpha_s = gamma_steady * kp / rho_c_bed
        steady_profile = binned_profile(profiles.height_m, packing.radius, t_steady,
                                        profiles.edges_m, weights=profiles.conducting)
        window = output_window(profiles, steady_profile, slab, scene.initial_temperature,
                               alpha_s, r_mean)
        args = dict(kp=kp, capacity=rho_c_bed, rho_c=mat.density * mat.heat_capacity,
                    gamma0=gamma_steady)
        gamma, why = fit_profiles(profiles, slab, conductivity_w_mk=kp,
                                  capacity_j_m3k=rho_c_bed, t_initial=scene.initial_temperature,
                                  particle_capacity_j_m3k=args["rho_c"], window=window,
                                  gamma0=gamma_steady)
        if gamma is not None and orientations:
            other, note = other_orientation(run, packing, slab, n_bins, args, r_mean, alpha_s)
            gamma = dataclasses.replace(gamma, other=other, other_note=note)
            if gamma.model_form_flag:
                post_flags.append("gamma_model_form")
            if note:
                not_measurable["gamma_other_orientation"] = note
    if why is not None:
        not_measurable["gamma"] = why
    return obstacle, gamma


# ----------------------------------------------------------------------------- write
# Set by command()'s SIGINT handler: a Ctrl-C that Python swallowed on the way (raised inside a
# weakref callback or a finaliser it is only printed as "Exception ignored") still stops post
# before its folder is swapped in.
_INTERRUPTED = []


@contextlib.contextmanager
def _signals_held():
    """SIGINT and SIGTERM held back for the block (the swap of the post folder), delivered
    when it ends. Main thread only (elsewhere Python delivers none)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _stale(folder: Path) -> bool:
    """A temporary post folder (``.post.tmp-<pid>``, ``.post.old-<pid>``) whose process is
    gone (killed with -9 during its swap, or earlier)."""
    try:
        pid = int(folder.name.rsplit("-", 1)[1])
    except (IndexError, ValueError):
        return False
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except OSError:
        return False
    return False


def _swap_in(tmp: Path, out_dir: Path) -> None:
    """``tmp`` renamed to ``out_dir``; an ``out_dir`` already there (an earlier post) is moved
    aside first and removed after. Signals are held for the two renames, so ``out_dir`` is the
    old folder or the new one, whole."""
    aside = out_dir.with_name(f".post.old-{os.getpid()}")
    for attempt in range(5):                # another post may swap its folder in meanwhile
        moved = False
        with _signals_held():
            if _INTERRUPTED:
                raise KeyboardInterrupt
            if out_dir.is_symlink() or (out_dir.exists() and not out_dir.is_dir()):
                raise NotADirectoryError(20, "expected the post folder, found a file",
                                         str(out_dir))
            try:
                if out_dir.exists():
                    os.rename(out_dir, aside)
                    moved = True
                os.rename(tmp, out_dir)
            except OSError as e:
                if moved:
                    os.rename(aside, out_dir)
                if e.errno in (errno.ENOTEMPTY, errno.EEXIST, errno.ENOENT) and attempt < 4:
                    continue
                raise
        if moved:
            shutil.rmtree(aside, ignore_errors=True)
        return


def write_post(result: PostResult, plots: bool = True) -> dict:
    """``post/`` beside the run, all or nothing: the figures and CSVs (with ``plots``) and
    summary.json are written into ``.post.tmp-<pid>`` beside it, which then replaces ``post/``
    whole (a full disk, Ctrl-C or an error leaves the earlier ``post/``, or none, and no
    temporary folder). Returns the summary, ``files`` naming what was written."""
    parent = result.thermal.parent
    out_dir = parent / "post"
    for old in [*parent.glob(".post.tmp-*"), *parent.glob(".post.old-*")]:
        if _stale(old):
            shutil.rmtree(old, ignore_errors=True)
    tmp = parent / f".post.tmp-{os.getpid()}"
    record = result.record()
    summary = to_dict(record)           # (the figures' labels read it)
    files = ["summary.json"]
    slab, fit = result.slab, result.gamma.fit if result.gamma else None
    try:
        tmp.mkdir()
        if plots and fit is not None:
            files += ["profiles.png", "profiles.csv"]
            p = result.profiles
            _plot_profiles(tmp, p.times_s, p.edges_m, p.values_k, fit, slab.length_m,
                           slab.bottom.value, slab.top.value,
                           result.run.scene.initial_temperature, summary)
        if plots:
            files += ["flux_section.png", "flux_section.csv"]
            _plot_flux_section(tmp, result.packing, slab.axis, result.flux.q_raw,
                               result.flux.q_halo, summary)
        record = dataclasses.replace(record, files=files)
        (tmp / "summary.json").write_text(json_text(record))
        _swap_in(tmp, out_dir)
    except BaseException as e:
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(e, OSError):      # name the file the user knows, not the temporary one
            name = str(e.filename or tmp).replace(str(tmp), str(out_dir), 1)
            raise OSError(e.errno, e.strerror or str(e), name) from None
        raise
    return to_dict(record)


def post_run(thermal_h5, n_bins: int = 10, plots: bool = True, halo_ratio: float = 3.0,
             halo_radius: str = "common") -> dict:
    """:func:`analyse` then :func:`write_post`: the summary (post/summary.json) as a dict."""
    return write_post(analyse(thermal_h5, n_bins=n_bins, halo_ratio=halo_ratio,
                              halo_radius=halo_radius), plots=plots)


def report_lines(r: PostResult, thermal: Path, files) -> list:
    """The lines ``tdem post`` prints: each quantity, or why this run cannot give it."""
    nm = r.not_measurable
    pressure = f", p = {r.pressure_pa:.4g} Pa" if math.isfinite(r.pressure_pa) else ""
    out = [f"tdem post: {thermal} ({r.run.law}, {r.packing.n_particles} particles{pressure})"]
    bad = [f for f in r.run.flags.split(",") if f and f not in BENIGN_FLAGS]
    if bad:
        out.append(f"  run flags          {r.run.flags}   (thermal.h5; for {', '.join(bad)} no "
                   "transient quantity is read from its temperatures)")
    if r.gamma is None:
        out.append(f"  gamma = k_eff/k_p  not measurable from this run: {nm['gamma']}")
    else:
        g = r.gamma
        fit = g.fit
        out.append(f"  gamma = k_eff/k_p  {fit.gamma:.5g}   95 % CI [{fit.ci95[0]:.5g}, "
                   f"{fit.ci95[1]:.5g}], profile residual {fit.residual_rms_k:.3g} K "
                   f"({len(g.used_s)} of {len(g.per_time)} outputs, {g.used_s[0]:g}-"
                   f"{g.used_s[-1]:g} s)")
        for _t, why in g.left_out[:3]:
            out.append(f"    left out: {why}")
        if len(g.left_out) > 3:
            out.append(f"    ... and {len(g.left_out) - 3} more outputs (summary.json)")
        if g.other is not None:
            lo, hi = g.model_form_range
            out.append(f"  heated from the other wall {g.other.gamma:.5g}   95 % CI "
                       f"[{g.other.ci95[0]:.5g}, {g.other.ci95[1]:.5g}]: model-form range "
                       f"[{lo:.5g}, {hi:.5g}] (+-{100 * g.model_form_spread:.3g} %)"
                       + ("; the two intervals do not overlap (flag gamma_model_form): the "
                          "homogeneous slab does not describe this bed to the fit's precision"
                          if g.model_form_flag else ""))
        elif g.other_note:
            out.append(f"  other orientation  not measurable: {g.other_note}")
        out.append(f"  gamma_paper        {g.gamma_paper:.5g}   (003's convention: alpha = "
                   "gamma kappa_p/(rho_p c_p))")
    out.append(f"  gamma (steady ETC) {r.gamma_steady:.5g}   heat in/out balance "
               f"{r.steady.balance:.1e}")
    out.append(f"  gamma affine k_zz  {r.fabric.gamma_affine:.5g}   (upper bound of the steady "
               f"ETC; <n_z^2> {r.fabric.nz2:.4f}, conductance-weighted "
               f"{r.fabric.nz2_conductance:.4f})")
    out.append("  gamma mean field   " + ", ".join(f"{k} {v:.4g}"
                                                  for k, v in r.mean_field.items()))
    if r.tau.tau_s is None:
        out.append(f"  tau (middle)       not measurable: {nm['tau_s']}")
    else:
        series = (f" (from the time series: {r.tau.tau_series_s:.5g} s)"
                  if r.tau.tau_series_s is not None else "")
        out.append(f"  tau (middle)       {r.tau.tau_s:.5g} s{series}")
        if r.tau.tau_series_s is None and r.run.method != "steady":
            out.append(f"    from the time series: not measurable: {nm['tau_series_s']}")
    if r.flux.cov_halo is not None:
        size = "r_mean" if r.flux.halo_radius == "common" else "R_p (own radius)"
        out.append(f"  heat flux (steady) CoV of |q| {r.flux.cov_raw:.3f} per particle "
                   f"({r.flux.cov_raw_volume:.3f} volume-weighted), "
                   f"{r.flux.cov_halo:.3f} with a halo of {r.flux.halo_ratio:g} {size} "
                   f"({r.flux.interior_particles} interior particles); mean axial q / (Q/A) "
                   f"{r.flux.mean_over_q_per_area:.3f}")
    if "solid_fraction" in r.post_flags:
        out.append(f"  solid fraction     the packing says {r.solid_fraction:.4g}, its spheres "
                   f"between the walls fill {r.solid_fraction_between_walls:.4g} (flag "
                   "solid_fraction; the fit uses the run's capacities, not either)")
    if r.post_flags:
        out.append(f"  post flags         {', '.join(r.post_flags)}")
    out.append(f"  wrote {thermal.parent / 'post'}/ ({', '.join(files)})")
    return out


def _program() -> bool:
    """This process is the ``tdem`` command (not a test or a script calling :func:`command`)."""
    main = sys.modules.get("__main__")
    spec = getattr(main, "__spec__", None)
    return Path(sys.argv[0]).name == "tdem" or getattr(spec, "name", "") == "tdem.cli"


def command(run, n_bins: int = 10, halo_ratio: float = 3.0, halo_radius: str = "common") -> int:
    """``tdem post RUN``: :func:`analyse`, :func:`write_post`, then the lines of
    :func:`report_lines` on stdout. Ctrl-C before the post folder is swapped in leaves the
    earlier one (or none), even when Python swallowed it on the way (``_INTERRUPTED``); once
    the folder is whole and reported, a Ctrl-C ends the ``tdem`` process quietly (exit 130)
    instead of surfacing as "Exception ignored ... KeyboardInterrupt" with exit 0."""
    path = Path(run)
    thermal = path / "thermal.h5" if path.is_dir() else path
    if not thermal.exists():
        raise ThermalFileError(f"{thermal}: file not found (give a run folder or its "
                               "thermal.h5)")
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.getsignal(signal.SIGINT) if main_thread else None

    def noted(signum, frame):
        _INTERRUPTED.append(signum)
        raise KeyboardInterrupt

    if main_thread:
        signal.signal(signal.SIGINT, noted)
    try:
        r = analyse(thermal, n_bins=n_bins, halo_ratio=halo_ratio, halo_radius=halo_radius)
        if _INTERRUPTED:
            raise KeyboardInterrupt
        files = write_post(r)["files"]
    finally:
        _INTERRUPTED.clear()
        if main_thread:
            signal.signal(signal.SIGINT, previous)
    for line in report_lines(r, thermal, files):
        print(line)
    sys.stdout.flush()
    if main_thread and _program():
        def quiet(signum, frame):
            sys.stderr.write("tdem: interrupted (post/ was already written whole)\n")
            os._exit(130)
        signal.signal(signal.SIGINT, quiet)
    return 0


def _pressure_label(summary):
    p = summary["pressure_pa"]
    return f", p = {p / 1e5:.3g} bar" if math.isfinite(p) else ""


def _plot_profiles(out_dir, times, edges, profiles, fit, length, t_b, t_t, t_i, summary):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    centres = 0.5 * (edges[:-1] + edges[1:])
    fine = np.linspace(0, length, 200)
    # fitted: 1 for the outputs the fit used, 0 for those left out (summary.json says why)
    rows = ["time_s,z_m,tdem_k,analytic_k,fitted"]
    used = set(summary.get("gamma_outputs_used_s") or times)
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for k, t in enumerate(times):
        model = slab_mean_temperature(edges[:-1], edges[1:], t, length, fit.diffusivity_m2_s,
                                      t_b, t_t, t_i)
        line = slab_temperature(fine, t, length, fit.diffusivity_m2_s, t_b, t_t, t_i)
        fitted = float(t) in used
        ax.plot(centres * 1e3, profiles[k], "o", ms=4, color=f"C{k}",
                mfc=None if fitted else "none",
                label=f"t = {t:g} s" + ("" if fitted else " (left out)"))
        ax.plot(fine * 1e3, line, "--", color=f"C{k}")
        rows += [f"{t},{c},{p},{m},{int(fitted)}"
                 for c, p, m in zip(centres, profiles[k], model)]
    ax.set_xlabel("height above the bottom held spheres (mm)")
    ax.set_ylabel("temperature (K)")
    ax.set_title(f"{summary['law']}{_pressure_label(summary)}: "
                 f"gamma = {fit.gamma:.4g} (dots tdem, dashes slab solution)", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    savefig_atomic(fig, out_dir / "profiles.png", dpi=110)
    plt.close(fig)
    write_text_atomic(out_dir / "profiles.csv", "\n".join(rows) + "\n")


def _halo_label(summary):
    size = "r_mean" if summary.get("flux_halo_radius", "common") == "common" else "R_p"
    return f"Halo {summary['flux_halo_ratio']:g} {size}"


def _plot_flux_section(out_dir, packing, axis, q_raw, q_halo, summary):
    """|q| in a slab one mean radius thick through the domain's centre, containing the axis
    (002 Fig. 16 style): eq. 20 beside its Halo average; data in flux_section.csv."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    across, depth = [a for a in range(3) if a != axis]
    centre = 0.5 * (packing.domain_lo + packing.domain_hi)
    sel = np.abs(packing.position[:, depth] - centre[depth]) < packing.radius.mean()
    x = packing.position[sel, across] * 1e3
    y = packing.position[sel, axis] * 1e3
    raw, halo = (np.linalg.norm(q[sel], axis=1) for q in (q_raw, q_halo))
    top = np.percentile(np.r_[raw, halo], 99) if sel.any() else 1.0
    fig, axes = plt.subplots(1, 2, figsize=(9, 5), sharey=True)
    for ax, values, name in ((axes[0], raw, "eq. 20 (per particle)"),
                             (axes[1], halo, _halo_label(summary) + " (eq. 22-23)")):
        sc = ax.scatter(x, y, c=values, s=12, cmap="inferno", vmin=0, vmax=top)
        ax.set_aspect("equal")
        ax.set_xlabel(f"{'xyz'[across]} (mm)")
        cov = summary.get("flux_cov_raw" if ax is axes[0] else "flux_cov_halo")
        ax.set_title(name + (f": CoV {cov:.3f}" if cov is not None else ""), fontsize=9)
    axes[0].set_ylabel(f"{'xyz'[axis]} (mm)")
    fig.colorbar(sc, ax=axes, label="|q| (W/m^2), steady state")
    fig.suptitle(f"{summary['law']}{_pressure_label(summary)}: heat flux in "
                 f"the section {'xyz'[depth]} = {centre[depth] * 1e3:.3g} mm", fontsize=10)
    savefig_atomic(fig, out_dir / "flux_section.png", dpi=110)
    plt.close(fig)
    rows = ["x_m,y_m,z_m,qx_w_m2,qy_w_m2,qz_w_m2,qx_halo_w_m2,qy_halo_w_m2,qz_halo_w_m2"]
    for p in np.flatnonzero(sel):
        rows.append(",".join(f"{v:.9g}" for v in (*packing.position[p], *q_raw[p], *q_halo[p])))
    write_text_atomic(out_dir / "flux_section.csv", "\n".join(rows) + "\n")
