"""Post-processing of one thermal run of a bed between two held walls (003, sec. 4.3-4.4).

    post_run(thermal_h5, n_bins=10) -> dict

From ``thermal.h5`` alone (:func:`thermal_kernel.output.read_thermal`: the scene as it ran,
stored in the file, and the packing it names, checked against the content hash it stored):
- binned profiles along the axis joining the two temperature boundaries (partial volumes),
  between the mean centre planes of the two held sets of spheres (the slab length L);
- gamma = k_eff / k_p fitted to all profiles against the slab solution (003 App. A), with its
  95 % interval and the rms residual; the bed's volumetric heat capacity is phi rho c_p (the heat
  capacity of the bed per unit volume: the particles' capacity over the bed volume);
- gamma from the steady solve: k_eff = Q L / (A dT) with Q the heat through the hot wall
  (heat in = heat out checked), A the bed's cross-section;
- tau of the middle section (003 eq. 41), exactly from the network (one sparse solve) and from
  the time series (with the steady temperature from the steady solve, not the last snapshot);
- mean-field predictions gamma_mf = phi Z H_mean / (2 pi R_mean k_p) for the bob, argento and
  pipe laws on the same contacts (forces from the dump, modulus from the scene);
- figure ``post/profiles.png`` (+ ``profiles.csv``) and ``post/summary.json``.
Rattlers (no conducting contact) keep their initial temperature: they are left out of the
profiles (their number is reported).
"""
from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from thermal_kernel.calibrate import cross_section
from thermal_kernel.network import assemble
from thermal_kernel.output import read_run_packing, read_thermal
from thermal_kernel.packing import packing_statistics
from thermal_kernel.problem import FACES, boundary_particles, build_problem
from thermal_kernel.scene import SceneError
from thermal_kernel.solvers.steady import solve_steady

from .analytic import (slab_mean_temperature, slab_midplane_characteristic_time,
                       slab_temperature)
from .fabric import affine_conductivity, contact_angle_pdf, love_weber_stress, mean_nz2
from .flux import coefficient_of_variation, particle_flux
from .fits import characteristic_time_network, characteristic_time_series, fit_gamma
from .profiles import binned_profile, partial_volumes
from .files import savefig_atomic, write_text_atomic

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


def post_run(thermal_h5, n_bins: int = 10, plots: bool = True, halo_ratio: float = 3.0) -> dict:
    thermal_h5 = Path(thermal_h5)
    if isinstance(n_bins, bool) or not isinstance(n_bins, (int, np.integer)) or n_bins < 1:
        raise SceneError(f"{thermal_h5}: --bins: expected an integer >= 1 (profile bins), got "
                         f"{n_bins!r}")
    if isinstance(halo_ratio, bool) or not isinstance(halo_ratio, (int, float)) \
            or not (math.isfinite(halo_ratio) and halo_ratio >= 0):
        raise SceneError(f"{thermal_h5}: --halo: expected a number >= 0 (the Halo radius over "
                         f"the particle radius; 0: no Halo), got {halo_ratio!r}")
    run = read_thermal(thermal_h5)          # the scene as it ran, from the run's output
    packing = read_run_packing(run)         # refused if it changed since the run
    scene = run.scene
    times, temperature, initial = run.times, run.temperature, run.initial_temperature
    held = [b for b in scene.boundaries if b.kind == "temperature"]
    if len(held) != 2:
        raise SceneError(f"{thermal_h5}: scene: the profile fit needs exactly two temperature "
                         f"boundaries (bottom and top), found {len(held)}")
    (ax0, x0), (ax1, x1) = (_wall_position(packing, b.on) for b in held)
    if ax0 != ax1:
        raise SceneError(f"{thermal_h5}: scene: the two temperature boundaries are not opposite")
    bottom, top = (held[0], held[1]) if x0 < x1 else (held[1], held[0])
    axis = ax0
    wall_gap = max(x0, x1) - min(x0, x1)
    # The Dirichlet condition acts on the held spheres, whose centres lie about one radius
    # inside the walls: the slab of the analytical solution spans the mean centre planes of the
    # two held sets (on a simple-cubic lattice this is exactly the finite-difference slab).
    held_bottom, held_top = (boundary_particles(scene, packing, b.on, "boundary")
                             for b in (bottom, top))
    z0, z1 = (float(np.mean(packing.position[h][:, axis])) for h in (held_bottom, held_top))
    length = z1 - z0
    t_initial = scene.initial_temperature
    kp = scene.material(0).conductivity
    mat = scene.material(0)
    stats = packing_statistics(packing)
    phi = float(packing.attrs["solid_fraction"])
    rho_c_bed = phi * mat.density * mat.heat_capacity

    problem, _ = build_problem(dataclasses.replace(scene), packing)
    net = assemble(problem)
    conducting = np.asarray(net.degree_w_k > 0) | np.asarray(net.held)
    z = packing.position[:, axis] - z0
    edges = np.linspace(0.0, length, n_bins + 1)
    profiles = binned_profile(z, packing.radius, temperature, edges, weights=conducting)
    # a steady run (its one output at t = inf) has no transient: no profile fit, no series tau
    transient = bool(np.all(np.isfinite(times)))
    fit = None
    if transient:
        fit = fit_gamma(times, edges, profiles, conductivity_w_mk=kp,
                        volumetric_capacity_j_m3k=rho_c_bed, t_bottom=bottom.value,
                        t_top=top.value, t_initial=t_initial)
        # the window dependence (issue 15): gamma fitted to each output time's profile alone
        per_time = []
        for k, t in enumerate(times):
            try:
                one = fit_gamma([t], edges, profiles[k:k + 1], conductivity_w_mk=kp,
                                volumetric_capacity_j_m3k=rho_c_bed, t_bottom=bottom.value,
                                t_top=top.value, t_initial=t_initial, gamma0=fit.gamma)
                per_time.append([float(t), one.gamma, *one.ci95])
            except (ValueError, RuntimeError):
                per_time.append([float(t), float("nan"), float("nan"), float("nan")])

    steady = solve_steady(net, np.asarray(initial))
    t_steady = steady.temperature_k[-1]
    flows = steady.boundary_heat_flow_w[-1]
    names = list(steady.boundary_names)
    q_bottom = float(flows[names.index(bottom.name)])
    q_top = float(flows[names.index(top.name)])
    balance = abs(q_bottom + q_top) / max(abs(q_bottom), 1e-300)
    area = cross_section(packing, axis)
    k_steady = abs(q_bottom) * length / (area * abs(bottom.value - top.value))
    # middle section: the bin(s) around mid-height
    mid = np.array([0.45 * length, 0.55 * length])
    w_mid = partial_volumes(z, packing.radius, mid)[:, 0] * conducting
    tau_net = characteristic_time_network(net, t_steady, initial, w_mid)
    section = (temperature @ w_mid) / w_mid.sum()
    tau_series = None
    if transient:
        tau_series = float(characteristic_time_series(
            times, section, float(t_steady @ w_mid / w_mid.sum()),
            float(initial @ w_mid / w_mid.sum())))

    # heat flux per particle at steady state (002 eq. 20) and its Halo average (eq. 22-23)
    q_raw = particle_flux(packing.position, packing.radius, packing.pair, packing.branch,
                          problem.conductance_w_k, t_steady, phi)
    q_halo = particle_flux(packing.position, packing.radius, packing.pair, packing.branch,
                           problem.conductance_w_k, t_steady, phi, halo_ratio=halo_ratio)
    interior = interior_mask(packing, halo_ratio * packing.radius) & conducting
    interior &= (z > 0) & (z < length)
    flux_stats = {"flux_halo_ratio": halo_ratio, "flux_interior_particles": int(interior.sum())}
    if interior.sum() >= 2:
        sign = 1.0 if bottom.value > top.value else -1.0
        flux_stats.update(
            flux_cov_raw=coefficient_of_variation(q_raw, interior),
            flux_cov_halo=coefficient_of_variation(q_halo, interior),
            # mean axial flux of the interior over the heat flow per cross-section Q / A
            flux_mean_over_q_per_area=float(sign * q_halo[interior, axis].mean()
                                            / (abs(q_bottom) / area)))

    # affine (fabric-tensor) bound of the steady conductivity and the contact fabric (issue 15)
    affine = affine_conductivity(packing.pair, packing.branch, problem.conductance_w_k,
                                 packing.position, axis, held_bottom, held_top, z0, z1, area)
    transverse = [a for a in range(3) if a != axis]
    touching = packing.overlap > 0
    angle_edges, angle_pdf = contact_angle_pdf(packing.branch, touching, axis)

    mean_field = {}
    r_mean = float(packing.radius.mean())
    z_mean = 2.0 * touching.sum() / packing.n_particles
    for law in MEAN_FIELD_LAWS:
        prob, _ = build_problem(dataclasses.replace(scene, law=law, law_params={}), packing)
        h_mean = float(np.mean(prob.conductance_w_k[touching])) if touching.any() else 0.0
        mean_field[law] = phi * z_mean * h_mean / (2 * math.pi * r_mean * kp)

    out_dir = thermal_h5.parent / "post"
    out_dir.mkdir(parents=True, exist_ok=True)
    summary = {
        "thermal": str(thermal_h5), "packing": str(packing.path), "law": run.law,
        "method": run.method, "n_particles": int(packing.n_particles),
        "pressure_pa": float(packing.attrs.get("pressure_pa", float("nan"))),
        "solid_fraction": phi, "mean_coordination": float(z_mean),
        "mean_normal_force_n": float(stats["mean_normal_force_n"]),
        "rattlers": int(np.count_nonzero(~conducting)),
        "gamma": fit.gamma if fit else None, "gamma_ci95": list(fit.ci95) if fit else None,
        # 003 App. A writes alpha = kappa_eff/(rho c_p) with rho the particle density (Table 1):
        # the same fitted diffusivity read in that convention is gamma / phi
        "gamma_paper": fit.gamma / phi if fit else None,
        "gamma_paper_ci95": [c / phi for c in fit.ci95] if fit else None,
        "gamma_per_time": per_time if fit else None,
        "gamma_residual_rms_k": fit.residual_rms_k if fit else None,
        "gamma_steady": k_steady / kp, "steady_balance": balance,
        "tau_s": tau_net, "tau_series_s": tau_series,
        # the slab's own mid-plane time with the fitted diffusivity, L^2/(8 alpha) (analytic.py)
        "tau_slab_s": float(slab_midplane_characteristic_time(length, fit.diffusivity_m2_s))
        if fit else None,
        "gamma_mean_field": mean_field,
        "gamma_affine": float(affine.k[axis, axis] / kp),
        "gamma_affine_transverse": float(np.mean([affine.k[a, a] for a in transverse]) / kp),
        "fabric_nz2": mean_nz2(packing.branch, touching, axis),
        "fabric_nz2_conductance": mean_nz2(packing.branch, touching, axis,
                                           weights=problem.conductance_w_k),
        "contact_angle_edges": angle_edges.tolist(), "contact_angle_pdf": angle_pdf.tolist(),
        # Love-Weber stress of the particle contacts over the bed between the walls, along the
        # axis (compare with the plate's pressure)
        "contact_stress_axial_pa": float(love_weber_stress(
            packing.branch, packing.normal_force, area * wall_gap)[axis, axis]),
        "length_m": length, "wall_gap_m": wall_gap,
        "n_bins": n_bins,
        "run_wall_seconds": run.wall_seconds,
        **flux_stats,
    }
    summary["files"] = ["summary.json"]
    if plots and fit is not None:
        summary["files"] += ["profiles.png", "profiles.csv"]
        _plot_profiles(out_dir, times, edges, profiles, fit, length, bottom.value, top.value,
                       t_initial, summary)
    if plots:
        summary["files"] += ["flux_section.png", "flux_section.csv"]
        _plot_flux_section(out_dir, packing, axis, q_raw, q_halo, summary)
    # last: a complete summary.json means the whole post-processing is there (campaign resume)
    write_text_atomic(out_dir / "summary.json", json.dumps(summary, indent=1))
    return summary


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
                             (axes[1], halo, f"Halo, ratio {summary['flux_halo_ratio']:g} "
                                             "(eq. 22-23)")):
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
