"""Parameters of yade_scripts/dense_packing.py (checked by yade_scripts/params.py).

``PARAMS`` is plain data; ``check(p)`` holds the cross-field checks, run inside YADE and in
``tdem pack`` (before YADE starts).
"""
PARAMS = {
    "shape": dict(kind="str", default="box", choices=["box", "periodic", "cylinder", "sphere"],
                  help="domain: box (6 plane walls), periodic cell, cylinder (beam along z), "
                       "sphere"),
    "n_particles": dict(kind="int", default=2000, minimum=20,
                        help="number of spheres"),
    "radius_mean_m": dict(kind="float", default=1e-3, minimum=1e-12, help="mean radius, m"),
    "radius_distribution": dict(kind="str", default="gaussian", choices=["uniform", "gaussian"],
                                help="uniform in mean*(1 +- spread) or truncated Gaussian"),
    "radius_spread": dict(kind="float", default=0.2, minimum=0.0,
                          help="uniform: relative half-width of the radius range, -"),
    "radius_sigma_over_mean": dict(kind="float", default=0.3, minimum=0.0,
                                   help="gaussian: sigma/mean of the radius, -"),
    "radius_truncation_sigmas": dict(kind="float", default=2.0, minimum=0.5,
                                     help="gaussian: radii kept within mean +- this many sigma "
                                          "(and > 0.1 mean)"),
    "aspect": dict(kind="floats", default=[1.0, 1.0, 1.0], minimum=0.05,
                   help="relative side lengths x:y:z of the box or cell (cylinder: z is the "
                        "axis, length/diameter = z/x; sphere: unused)"),
    "confining_pressure_pa": dict(kind="float", default=1e5, minimum=1.0,
                                  help="mean stress the packing is compressed to (radii grow "
                                       "in the fixed domain until it is reached), Pa"),
    "compaction_friction": dict(kind="float", default=0.0, minimum=0.0,
                                help="friction coefficient while compressing (0 gives the densest "
                                     "random packing, phi ~0.64; more gives a looser one)"),
    "friction": dict(kind="float", default=0.3, minimum=0.0,
                     help="friction coefficient of the material: switched on for the final "
                          "relaxation at the real modulus, recorded in the dump"),
    "young_pa": dict(kind="float", default=2.1e11, minimum=1.0, help="Young's modulus, Pa (real)"),
    "poisson": dict(kind="float", default=0.3, minimum=0.0, help="Poisson ratio"),
    "density": dict(kind="float", default=7800.0, minimum=1e-9, help="density, kg/m^3 (real)"),
    "density_scaling": dict(kind="float", default=1e4, minimum=1.0,
                            help="mass factor used while compressing (no gravity: the static end "
                                 "state does not depend on it; dt grows by its square root)"),
    "softening_factor": dict(kind="float", default=1e3, minimum=1.0,
                             help="compression starts with E = min(young_pa, this x confining "
                                  "pressure) and raises E tenfold per stage to young_pa, "
                                  "re-relaxing at each (speed only: the dump is at young_pa)"),
    "time_step": dict(kind="str", default="density_scaling", choices=["density_scaling", "p_wave"],
                      help="density_scaling: YADE's GlobalStiffnessTimeStepper scales each "
                           "sphere's mass so that all have the same critical step (the static "
                           "state does not depend on masses); p_wave: 0.5 x the P-wave step of "
                           "the smallest sphere (the path before 2026-11)"),
    "stiffen_factor": dict(kind="float", default=10.0, minimum=1.5,
                           help="factor by which E is raised per stage from the softened start "
                                "to young_pa, -"),
    "method": dict(kind="str", default="auto", choices=["auto", "direct", "tiled", "shell"],
                   help="direct: relax all n_particles in the domain with its walls; tiled: "
                        "relax a periodic cell of cell_particles spheres, copy it side by side "
                        "and carve the domain out of the copies (no walls pressed on the "
                        "spheres; periodicity length = the cell); shell: as tiled, then walls "
                        "pressed onto a shell of shell_diameters along them (the interior "
                        "stays as tiled; boxes only; its packings do not yet match the direct "
                        "ones, docs/packings.md); auto: direct (shell once it matches)"),
    "shell_diameters": dict(kind="float", default=6.0, minimum=1.0,
                            help="shell: thickness of the shell relaxed against the walls, in "
                                 "mean diameters"),
    "shell_press_step": dict(kind="float", default=0.01, minimum=1e-4,
                             help="shell: how far a wall moves per 50 DEM steps while it carries "
                                  "less than a quarter of the pressure, in mean radii"),
    "shell_loaded_step": dict(kind="float", default=0.01, minimum=1e-4,
                              help="shell: in the softened stage, how far a wall moves per 50 DEM "
                                   "steps at most once it carries 5 % of the pressure, in mean "
                                   "radii"),
    "shell_soft_gain": dict(kind="float", default=0.5, minimum=0.05,
                            help="shell: gain of the walls' pressure controller in the soft first "
                                 "stage (1 = the Hertz compliance of the shell's column)"),
    "shell_cut_depth": dict(kind="float", default=0.0, minimum=0.0, maximum=1.0,
                            help="shell: a carved sphere is kept when its centre lies at least "
                                 "this many of its radii inside the surface (1: wholly inside; "
                                 "0: centre inside, the walls start at the kept spheres' extent)"),
    "shell_cloud_diameters": dict(kind="float", default=0.0, minimum=0.0,
                                  help="shell: the spheres within this many mean diameters of "
                                       "the carved faces are put back at random, shrunk, in a "
                                       "box grown to hold them at the direct box's solid "
                                       "fraction for that depth, and grown back against the "
                                       "walls before the stages (0: the walls are pressed onto "
                                       "the carved faces; 3: the direct box's wall layer, "
                                       "docs/packings.md)"),
    "cell_particles": dict(kind="int", default=10000, minimum=20,
                           help="tiled, shell: spheres in the periodic cell that is copied"),
    "cell_packing": dict(kind="str", default="",
                         help="tiled, shell: a periodic packing.h5 made earlier (shape "
                              "\"periodic\", same young_pa, poisson, confining_pressure_pa, "
                              "gap_tolerance) to copy instead of relaxing a new cell; its seed "
                              "and radii are kept"),
    "damping": dict(kind="float", default=0.5, minimum=0.0,
                    help="YADE's non-viscous (local) damping of the compression, 0..1"),
    "unbalanced_force_target": dict(kind="float", default=1e-3, minimum=1e-9,
                                    help="compression ends below this unbalanced-force ratio"),
    "pressure_tolerance": dict(kind="float", default=0.02, minimum=1e-6,
                              help="each stage ends when |mean stress / confining pressure - 1| "
                                   "is below this (and the unbalanced force is small)"),
    "wall_segments": dict(kind="int", default=48, minimum=8,
                          help="facets around the cylinder mantle"),
    "sphere_facet_level": dict(kind="int", default=3, minimum=1,
                               help="the spherical container is an icosphere of 20 x 4^level "
                                    "triangles (level 3: 1,280, sag 0.0046 R)"),
    "gap_tolerance": dict(kind="float", default=0.0, minimum=0.0,
                          help="neighbour criterion: pairs with centre distance < "
                               "(1 + gap_tolerance)(r_i + r_j) are dumped as contacts (gaps "
                               "have negative overlap and zero force); 0 = touching only"),
    "wall_gap_tolerance": dict(kind="float", default=0.1, minimum=0.0,
                               help="a particle is a wall contact when its distance to the wall "
                                    "< (1 + this) r"),
    "inclusions": dict(kind="list", default=[],
                       help="spherical inclusions: list of {centre = [fx, fy, fz] (fractions of "
                            "the domain box), radius = f (fraction of the smallest side), "
                            "phase = int}"),
    "inclusion_volume_fraction": dict(kind="float", default=0.0, minimum=0.0,
                                      help="random dispersion: volume fraction of the domain "
                                           "covered by non-overlapping spherical inclusions"),
    "inclusion_radius_over_mean": dict(kind="float", default=3.0, minimum=0.5,
                                       help="random dispersion: inclusion radius / mean particle "
                                            "radius"),
    "inclusion_phase": dict(kind="int", default=1, minimum=1,
                            help="random dispersion: phase id of particles inside inclusions"),
    "seed": dict(kind="int", default=1, minimum=0, help="random seed"),
    "max_seconds": dict(kind="float", default=3600.0, minimum=1.0,
                        help="give up (exit 3) if compression takes longer, s"),
    "output_dir": dict(kind="str", default=".", help="folder for packing.h5 (set by tdem pack)"),
}


def finish(p):
    """Resolve method = "auto" to the method it stands for (yade_scripts/shell.py
    resolve_method: direct up to AUTO_SHELL_ABOVE spheres and for periodic domains, shell
    above), so that params.json and the packing name the method used."""
    from .shell import resolve_method
    p["method"] = resolve_method(p["shape"], p["method"], p["n_particles"])


def check(p):
    """Cross-field checks of resolved dense parameters: ValueError('key: ...') for the first
    that fails. The domain check draws the seeded radii and sizes the domain exactly as the
    generator does (dense_geometry.cloud_domain)."""
    for k, inc in enumerate(p["inclusions"]):
        if not isinstance(inc, dict) or set(inc) - {"centre", "radius", "phase"} \
                or "centre" not in inc or "radius" not in inc:
            raise ValueError(f"inclusions[{k}]: expected {{centre = [fx, fy, fz], radius = f, "
                             "phase = id}")
    tiled = p["method"] in ("tiled", "shell")       # both copy a relaxed periodic cell
    if not tiled and p["cell_packing"]:
        raise ValueError("cell_packing: only used with method = \"tiled\" or \"shell\"")
    if tiled and p["shape"] == "periodic":
        raise ValueError(f"method: \"{p['method']}\" carves a box, cylinder or sphere out of "
                         "copies of a periodic cell; for a periodic domain use method = "
                         "\"direct\"")
    from .shell import SHELL_SHAPES
    if p["method"] == "shell" and p["shape"] not in SHELL_SHAPES + ("periodic",):
        raise ValueError(f"method: \"shell\" is measured for {', '.join(SHELL_SHAPES)} only "
                         f"(docs/packings.md); for a {p['shape']} use \"direct\" (walls) or "
                         "\"tiled\" (cut faces)")
    if p["method"] == "shell" and p["shell_cloud_diameters"] > p["shell_diameters"] - 1.0:
        raise ValueError(f"shell_cloud_diameters: expected at most shell_diameters - 1 "
                         f"({p['shell_diameters'] - 1.0:g}: the cloud is pressed against the "
                         f"free shell, not the frozen band), got {p['shell_cloud_diameters']:g}")
    if tiled and not p["cell_packing"] and p["n_particles"] < p["cell_particles"]:
        raise ValueError(f"cell_particles: expected at most n_particles ({p['n_particles']}) for "
                         f"method = \"{p['method']}\", got {p['cell_particles']}")
    if len(p["aspect"]) != 3:
        raise ValueError(f"aspect: expected 3 numbers (x, y, z), got {len(p['aspect'])}: "
                         f"{p['aspect']}")
    check_memory(p)
    if tiled:
        check_carved_domain(p)
    if not (tiled and p["cell_packing"]):       # YADE relaxes a cloud: can it be made?
        from . import dense_geometry
        dense_geometry.cloud_domain(dense_geometry.relaxed_params(p),
                                    "cell_particles" if tiled else "n_particles")


# Peak resident memory per sphere of the tiled and shell paths (the 8e6 box: 5.7 GB, ~700 bytes a
# sphere, docs/packings.md), with a margin: a request that cannot fit is refused before YADE.
BYTES_PER_SPHERE = 1000


def check_memory(p):
    """n_particles: refused when the packing cannot fit in this machine's memory."""
    import os
    try:
        physical = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return
    need = BYTES_PER_SPHERE * float(p["n_particles"])
    if need > physical:
        raise ValueError(f"n_particles: {p['n_particles']:.4g} spheres need about "
                         f"{need / 1e9:.3g} GB, this machine has {physical / 1e9:.3g} GB; "
                         f"expected at most {physical / BYTES_PER_SPHERE:.3g}")


def _mean_cube_over_cubed_mean(p):
    """E[r^3] / E[r]^3 of the radius distribution (Gaussian: 1 + 3 s^2; uniform: 1 + s^2)."""
    if p["radius_distribution"] == "gaussian":
        return 1.0 + 3.0 * p["radius_sigma_over_mean"] ** 2
    return 1.0 + p["radius_spread"] ** 2


# Fewer spheres than this in a tiled or shell domain: its solid fraction and statistics would be
# set by the spheres its surface cuts (21 spheres carved from a 400-sphere cell: phi 0.78 against
# the cell's 0.66).
MIN_CARVED_PARTICLES = 100


def check_carved_domain(p):
    """tiled, shell: at least MIN_CARVED_PARTICLES spheres, and at least one mean diameter across
    the smallest side (a thin sheet of one diameter, 000's case, is allowed). The size in mean
    diameters depends only on n_particles, the distribution's shape, the cell's solid fraction
    (~0.65) and the aspect, not on the radii's scale."""
    import math
    import numpy as np
    if p["n_particles"] < MIN_CARVED_PARTICLES:
        raise ValueError(f"n_particles: method = \"{p['method']}\" expected at least "
                         f"{MIN_CARVED_PARTICLES} spheres (fewer: the spheres cut by the surface "
                         f"set the solid fraction), got {p['n_particles']}")
    aspect = np.asarray(p["aspect"], dtype=float)
    volume_d3 = p["n_particles"] * math.pi / 6.0 * _mean_cube_over_cubed_mean(p) / 0.65
    if p["shape"] == "box":
        smallest = (volume_d3 / aspect.prod()) ** (1.0 / 3.0) * aspect.min()
    elif p["shape"] == "cylinder":
        ratio = aspect[2] / aspect[0]
        radius = (volume_d3 / (2.0 * math.pi * ratio)) ** (1.0 / 3.0)
        smallest = min(2.0 * radius, 2.0 * radius * ratio)
    else:
        smallest = 2.0 * (3.0 * volume_d3 / (4.0 * math.pi)) ** (1.0 / 3.0)
    if smallest < 1.0:
        raise ValueError(f"n_particles: a {p['shape']} of {p['n_particles']} spheres with aspect "
                         f"{list(aspect)} is {smallest:.2g} mean diameters across; method = "
                         f"\"{p['method']}\" expected at least 1 (more spheres or another "
                         "aspect)")
