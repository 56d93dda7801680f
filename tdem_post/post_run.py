"""Post-processing of one thermal run of a bed between two held walls (003, sec. 4.3-4.4).

    analyse(thermal_h5, n_bins=10) -> PostResult      (compute: typed results, no file)
    write_post(result) -> dict                         (figures, CSVs, summary.json)
    post_run(thermal_h5, n_bins=10) -> dict            (both: the summary)

Each quantity has its compute function and typed result: slab_of -> Slab, profiles_of ->
Profiles, fit_profiles -> GammaResult, steady_etc -> EffectiveConductivity
(thermal_kernel.effective, length convention "held_centres"), tau_of -> Tau, flux_field ->
FluxField, fabric_of -> Fabric, mean_field -> {law: gamma_mf}; PostResult.summary() is the one
mapping to post/summary.json's keys.

From ``thermal.h5`` alone (:func:`thermal_kernel.output.read_thermal`: the scene as it ran,
stored in the file, and the packing it names, checked against the content hash it stored):
- binned profiles along the axis joining the two temperature boundaries (partial volumes),
  between the mean centre planes of the two held sets of spheres (the slab length L);
- gamma = k_eff / k_p fitted to all profiles against the slab solution (003 App. A), with its
  95 % interval and the rms residual; the bed's volumetric heat capacity is phi rho c_p (the heat
  capacity of the bed per unit volume: the particles' capacity over the bed volume);
- gamma from the steady solve: k_eff = Q L / (A dT) with Q the heat through the hot wall
  (heat in = heat out checked: refused above thermal_kernel.effective.BALANCE_TOLERANCE), A
  the bed's cross-section;
- tau of the middle section (003 eq. 41), exactly from the network (one sparse solve) and from
  the time series (with the steady temperature from the steady solve, not the last snapshot);
- mean-field predictions gamma_mf = phi Z H_mean / (2 pi R_mean k_p) for the laws of
  MEAN_FIELD_LAWS on the same contacts (forces from the dump, modulus from the scene);
- figure ``post/profiles.png`` (+ ``profiles.csv``) and ``post/summary.json``.
Rattlers (no conducting contact) keep their initial temperature: they are left out of the
profiles (their number is reported).
"""
from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from thermal_kernel.calibrate import cross_section
from thermal_kernel.network import assemble
from thermal_kernel.effective import EffectiveConductivity, effective_conductivity
from thermal_kernel.output import ThermalRun, read_run_packing, read_thermal
from thermal_kernel.atomic import savefig_atomic, write_text_atomic
from thermal_kernel.packing import packing_statistics
from thermal_kernel.problem import FACES, boundary_particles, build_problem
from thermal_kernel.scene import SceneError

from .analytic import (slab_mean_temperature, slab_midplane_characteristic_time,
                       slab_temperature)
from .fabric import affine_conductivity, contact_angle_pdf, love_weber_stress, mean_nz2
from .flux import HALO_RADII, coefficient_of_variation, halo_radii, particle_flux
from .fits import (GammaFit, characteristic_time_network, characteristic_time_series,
                   fit_gamma)
from .profiles import binned_profile, partial_volumes

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
    """gamma = k_eff / k_p fitted to every profile against the slab solution (003 App. A)."""
    fit: GammaFit
    per_time: list               # [t, gamma, ci95 low, ci95 high] of each output time alone
    gamma_paper: float           # gamma / phi: 003's convention (alpha from rho_p c_p)
    gamma_paper_ci95: list
    tau_slab_s: float            # the slab's own mid-plane time L^2 / (8 alpha)


@dataclass(frozen=True)
class Tau:
    """tau of the middle section (003 eq. 41)."""
    tau_s: float                 # exactly from the network (one sparse solve)
    tau_series_s: float | None   # from the time series (None for a steady run)


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
    """Everything :func:`analyse` computes from one run; :meth:`summary` is post/summary.json."""
    thermal: Path
    run: ThermalRun
    packing: object
    n_bins: int
    slab: Slab
    profiles: Profiles
    gamma: GammaResult | None    # None for a steady run (no transient)
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

    def summary(self) -> dict:
        fit = self.gamma.fit if self.gamma else None
        flux = {"flux_halo_ratio": self.flux.halo_ratio,
                "flux_halo_radius": self.flux.halo_radius,
                "flux_interior_particles": self.flux.interior_particles}
        if self.flux.cov_raw is not None:
            flux.update(flux_cov_raw=self.flux.cov_raw,
                        flux_cov_raw_volume_weighted=self.flux.cov_raw_volume,
                        flux_cov_halo=self.flux.cov_halo,
                        flux_mean_over_q_per_area=self.flux.mean_over_q_per_area)
        return {
            "thermal": str(self.thermal), "packing": str(self.packing.path),
            "law": self.run.law, "method": self.run.method,
            "n_particles": int(self.packing.n_particles), "pressure_pa": self.pressure_pa,
            "solid_fraction": self.solid_fraction, "mean_coordination": self.mean_coordination,
            "mean_normal_force_n": self.mean_normal_force_n, "rattlers": self.rattlers,
            "gamma": fit.gamma if fit else None, "gamma_ci95": list(fit.ci95) if fit else None,
            # 003 App. A writes alpha = kappa_eff/(rho c_p) with rho the particle density
            # (Table 1): the same fitted diffusivity read in that convention is gamma / phi
            "gamma_paper": self.gamma.gamma_paper if fit else None,
            "gamma_paper_ci95": self.gamma.gamma_paper_ci95 if fit else None,
            "gamma_per_time": self.gamma.per_time if fit else None,
            "gamma_residual_rms_k": fit.residual_rms_k if fit else None,
            "gamma_steady": self.gamma_steady, "steady_balance": self.steady.balance,
            "tau_s": self.tau.tau_s, "tau_series_s": self.tau.tau_series_s,
            # the slab's own mid-plane time with the fitted diffusivity, L^2/(8 alpha)
            "tau_slab_s": self.gamma.tau_slab_s if fit else None,
            "gamma_mean_field": dict(self.mean_field),
            "gamma_affine": self.fabric.gamma_affine,
            "gamma_affine_transverse": self.fabric.gamma_affine_transverse,
            "fabric_nz2": self.fabric.nz2, "fabric_nz2_conductance": self.fabric.nz2_conductance,
            "contact_angle_edges": self.fabric.angle_edges,
            "contact_angle_pdf": self.fabric.angle_pdf,
            # Love-Weber stress of the particle contacts over the bed between the walls, along
            # the axis (compare with the plate's pressure)
            "contact_stress_axial_pa": self.fabric.contact_stress_axial_pa,
            "length_m": self.slab.length_m, "wall_gap_m": self.slab.wall_gap_m,
            "n_bins": self.n_bins, "run_wall_seconds": self.run.wall_seconds,
            **flux,
        }


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


def profiles_of(run: ThermalRun, packing, net, slab: Slab, n_bins: int) -> Profiles:
    """Partial-volume profiles of the conducting spheres in ``n_bins`` bins between the held
    planes, at every output time."""
    conducting = np.asarray(net.conducting)
    z = packing.position[:, slab.axis] - slab.z0_m
    edges = np.linspace(0.0, slab.length_m, n_bins + 1)
    values = binned_profile(z, packing.radius, run.temperature, edges, weights=conducting)
    return Profiles(times_s=run.times, edges_m=edges, values_k=values, height_m=z,
                    conducting=conducting)


def fit_profiles(profiles: Profiles, slab: Slab, *, conductivity_w_mk, capacity_j_m3k,
                 t_initial, solid_fraction) -> GammaResult | None:
    """gamma fitted to all profiles, and to each output time's alone (the window dependence,
    issue 15); None for a steady run (its one output at t = inf has no transient)."""
    times = profiles.times_s
    if not bool(np.all(np.isfinite(times))):
        return None
    args = dict(conductivity_w_mk=conductivity_w_mk, volumetric_capacity_j_m3k=capacity_j_m3k,
                t_bottom=slab.bottom.value, t_top=slab.top.value, t_initial=t_initial)
    fit = fit_gamma(times, profiles.edges_m, profiles.values_k, **args)
    per_time = []
    for k, t in enumerate(times):
        try:
            one = fit_gamma([t], profiles.edges_m, profiles.values_k[k:k + 1], **args,
                            gamma0=fit.gamma)
            per_time.append([float(t), one.gamma, *one.ci95])
        except (ValueError, RuntimeError):
            per_time.append([float(t), float("nan"), float("nan"), float("nan")])
    return GammaResult(
        fit=fit, per_time=per_time, gamma_paper=fit.gamma / solid_fraction,
        gamma_paper_ci95=[c / solid_fraction for c in fit.ci95],
        tau_slab_s=float(slab_midplane_characteristic_time(slab.length_m,
                                                           fit.diffusivity_m2_s)))


def steady_etc(net, slab: Slab, area_m2: float, initial_k, where) -> EffectiveConductivity:
    """k_eff from the steady heat flow between the two held walls, on the slab length (the
    held sets' centre planes, as the profile fit)."""
    return effective_conductivity(net, slab.bottom.name, slab.top.name, t_in=slab.bottom.value,
                                  t_out=slab.top.value, length_m=slab.length_m, area_m2=area_m2,
                                  length_convention="held_centres", initial_k=initial_k,
                                  where=where)


def tau_of(net, run: ThermalRun, packing, profiles: Profiles, slab: Slab, t_steady) -> Tau:
    """tau of the middle section (the bins around mid-height): from the network, and from the
    time series with the steady temperature of the steady solve (not the last snapshot)."""
    initial = run.initial_temperature
    mid = np.array([0.45 * slab.length_m, 0.55 * slab.length_m])
    w_mid = partial_volumes(profiles.height_m, packing.radius, mid)[:, 0] * profiles.conducting
    tau_net = characteristic_time_network(net, t_steady, initial, w_mid)
    tau_series = None
    if bool(np.all(np.isfinite(run.times))):
        section = (run.temperature @ w_mid) / w_mid.sum()
        tau_series = float(characteristic_time_series(
            run.times, section, float(t_steady @ w_mid / w_mid.sum()),
            float(initial @ w_mid / w_mid.sum())))
    return Tau(tau_s=tau_net, tau_series_s=tau_series)


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
            halo_radius: str = "common") -> PostResult:
    """Every quantity of the module docstring, from the run's output alone; no file written.
    The flux field's Halo radius is ``halo_ratio`` x the packing's mean radius ("common", 002's
    "pre-defined number of DE") or x each particle's own radius ("own")."""
    thermal_h5 = Path(thermal_h5)
    _check_options(thermal_h5, n_bins, halo_ratio, halo_radius)
    run = read_thermal(thermal_h5)          # the scene as it ran, from the run's output
    packing = read_run_packing(run)         # refused if it changed since the run
    scene = run.scene
    slab = slab_of(scene, packing, thermal_h5)
    kp = scene.material(0).conductivity
    mat = scene.material(0)
    stats = packing_statistics(packing)
    phi = float(packing.attrs["solid_fraction"])
    rho_c_bed = phi * mat.density * mat.heat_capacity

    problem, _ = build_problem(dataclasses.replace(scene), packing)
    net = assemble(problem)
    profiles = profiles_of(run, packing, net, slab, n_bins)
    gamma = fit_profiles(profiles, slab, conductivity_w_mk=kp, capacity_j_m3k=rho_c_bed,
                         t_initial=scene.initial_temperature, solid_fraction=phi)
    area = cross_section(packing, slab.axis)
    steady = steady_etc(net, slab, area, np.asarray(run.initial_temperature), thermal_h5)
    t_steady = steady.temperature_k
    touching = packing.overlap > 0
    return PostResult(
        thermal=thermal_h5, run=run, packing=packing, n_bins=n_bins, slab=slab,
        profiles=profiles, gamma=gamma, steady=steady, gamma_steady=steady.k_eff_w_mk / kp,
        tau=tau_of(net, run, packing, profiles, slab, t_steady),
        flux=flux_field(packing, problem.conductance_w_k, t_steady, phi, slab, profiles, steady,
                        halo_ratio, halo_radius),
        fabric=fabric_of(packing, problem.conductance_w_k, slab, area, kp),
        mean_field=mean_field(scene, packing, phi, kp), solid_fraction=phi,
        mean_coordination=float(2.0 * touching.sum() / packing.n_particles),
        mean_normal_force_n=float(stats["mean_normal_force_n"]),
        rattlers=int(np.count_nonzero(~profiles.conducting)),
        pressure_pa=float(packing.attrs.get("pressure_pa", float("nan"))))


# ----------------------------------------------------------------------------- write
def write_post(result: PostResult, plots: bool = True) -> dict:
    """``post/`` beside the run: the figures and CSVs (with ``plots``), then summary.json
    (last: a complete summary.json means the whole post-processing is there, for the campaign's
    resume). Returns the summary, ``files`` naming what was written."""
    out_dir = result.thermal.parent / "post"
    out_dir.mkdir(parents=True, exist_ok=True)
    summary = result.summary()
    summary["files"] = ["summary.json"]
    slab, fit = result.slab, result.gamma.fit if result.gamma else None
    if plots and fit is not None:
        summary["files"] += ["profiles.png", "profiles.csv"]
        p = result.profiles
        _plot_profiles(out_dir, p.times_s, p.edges_m, p.values_k, fit, slab.length_m,
                       slab.bottom.value, slab.top.value, result.run.scene.initial_temperature,
                       summary)
    if plots:
        summary["files"] += ["flux_section.png", "flux_section.csv"]
        _plot_flux_section(out_dir, result.packing, slab.axis, result.flux.q_raw,
                           result.flux.q_halo, summary)
    write_text_atomic(out_dir / "summary.json", json.dumps(summary, indent=1))
    return summary


def post_run(thermal_h5, n_bins: int = 10, plots: bool = True, halo_ratio: float = 3.0,
             halo_radius: str = "common") -> dict:
    """:func:`analyse` then :func:`write_post`: the summary (post/summary.json) as a dict."""
    return write_post(analyse(thermal_h5, n_bins=n_bins, halo_ratio=halo_ratio,
                              halo_radius=halo_radius), plots=plots)


def _pressure_label(summary):
    p = summary["pressure_pa"]
    return f", p = {p / 1e5:.3g} bar" if math.isfinite(p) else ""


def _plot_profiles(out_dir, times, edges, profiles, fit, length, t_b, t_t, t_i, summary):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    centres = 0.5 * (edges[:-1] + edges[1:])
    fine = np.linspace(0, length, 200)
    rows = ["time_s,z_m,tdem_k,analytic_k"]
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for k, t in enumerate(times):
        model = slab_mean_temperature(edges[:-1], edges[1:], t, length, fit.diffusivity_m2_s,
                                      t_b, t_t, t_i)
        line = slab_temperature(fine, t, length, fit.diffusivity_m2_s, t_b, t_t, t_i)
        ax.plot(centres * 1e3, profiles[k], "o", ms=4, color=f"C{k}", label=f"t = {t:g} s")
        ax.plot(fine * 1e3, line, "--", color=f"C{k}")
        rows += [f"{t},{c},{p},{m}" for c, p, m in zip(centres, profiles[k], model)]
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
