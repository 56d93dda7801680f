"""Parameter schema of the compressed-bed generator (``yade_scripts/compressed_bed.py``).

``PARAMS`` is plain data; ``check(p)`` holds the cross-field checks. ``yade_scripts/params.py``
runs both, inside YADE and in ``tdem pack`` (before YADE starts).
Defaults are the pipe-model paper's bed (003, section 4.2 and Table 1): 7,500 spheres of radius
2 mm in a cylinder of radius 30.5 mm, rho 2500 kg/m^3, E 5e10 Pa, nu 0.2, e 0.865, mu 0.3, g 9.81,
compressed by a top plate to 0.28 ... 405 bar.
"""

import math

BAR = 1e5

PARAMS = {
    # --- the bed (003, Table 1) ---------------------------------------------------------------
    "n_particles": dict(kind="int", default=7500, minimum=10,
                        help="number of spheres (-)"),
    "particle_radius_m": dict(kind="float", default=0.002, minimum=1e-9,
                              help="mean sphere radius (m)"),
    "radius_spread": dict(kind="float", default=0.05, minimum=0.0,
                          help="relative half-width of the uniform radius distribution: radii in "
                               "r (1 +- spread) (-, < 0.5)"),
    "cylinder_radius_m": dict(kind="float", default=0.0305, minimum=1e-9,
                              help="inner radius of the cylindrical container (m)"),
    "cylinder_segments": dict(kind="int", default=48, minimum=12,
                              help="the cylinder is simulated as a prism of this many flat, "
                                   "full-height boxes of the same cross-section area (-)"),
    "density": dict(kind="float", default=2500.0, minimum=1e-9,
                    help="real particle density (kg/m^3)"),
    "young_pa": dict(kind="float", default=5e10, minimum=1.0,
                     help="real Young's modulus of the particles (Pa)"),
    "poisson": dict(kind="float", default=0.2, minimum=-0.99,
                    help="Poisson's ratio of the particles (-, < 0.5)"),
    "restitution": dict(kind="float", default=0.865, minimum=1e-6,
                        help="normal coefficient of restitution of every contact (-, <= 1)"),
    "friction": dict(kind="float", default=0.3, minimum=0.0,
                     help="Coulomb friction coefficient, particle-particle (-)"),
    "wall_young_pa": dict(kind="float", default=5e10, minimum=1.0,
                          help="real Young's modulus of the walls (bottom, plate, cylinder) "
                               "(Pa)"),
    "wall_poisson": dict(kind="float", default=0.2, minimum=-0.99,
                         help="Poisson's ratio of the walls (-, < 0.5)"),
    "wall_friction": dict(kind="float", default=0.3, minimum=0.0,
                          help="Coulomb friction coefficient, particle-wall (-)"),
    "gravity_m_s2": dict(kind="float", default=9.81, minimum=0.0,
                         help="gravitational acceleration, along -z (m/s^2)"),
    "pressures_pa": dict(kind="floats", default=[0.28 * BAR, 1 * BAR, 4 * BAR, 16 * BAR,
                                                 64 * BAR, 160 * BAR, 405 * BAR],
                         minimum=1e-9,
                         help="plate pressures to reach, increasing; one packing_<p>Pa.h5 "
                              "each (Pa)"),
    # --- how the quasi-static state is reached ------------------------------------------------
    "settle_young_pa": dict(kind="float", default=5e7, minimum=1.0,
                            help="softened Young's modulus for the gravity settling and the "
                                 "preload; the modulus is then raised to young_pa under "
                                 "constant plate load before any packing_*.h5 is dumped "
                                 "(= young_pa: no softening) (Pa)"),
    "preload_fraction": dict(kind="float", default=0.1, minimum=1e-6,
                             help="the softened bed is loaded only to this fraction of the "
                                  "first pressure, re-stiffened there, and then loaded to the "
                                  "first pressure at the real modulus; a softened network "
                                  "re-stiffened under load keeps lateral stress, which the real "
                                  "loading then dilutes (-, <= 1)"),
    "stiffen_factor": dict(kind="float", default=10.0, minimum=1.01,
                           help="factor by which the modulus is raised per re-stiffening "
                                "step (-)"),
    "density_scaling": dict(kind="float", default=1.0, minimum=1.0,
                            help="mass factor: particle masses are multiplied and gravity is "
                                 "divided by it, so weights stay real and only the time scale "
                                 "changes (-)"),
    "damping": dict(kind="float", default=0.4, minimum=0.0,
                    help="Cundall (local, non-viscous) damping of NewtonIntegrator in the "
                         "quasi-static stages (-, < 1)"),
    "inertial_number": dict(kind="float", default=3e-3, minimum=1e-9,
                            help="the plate speed is limited so that I = (v/H) d sqrt(rho/p) "
                                 "stays below this (-)"),
    "soft_inertial_number": dict(kind="float", default=1e-2, minimum=1e-9,
                                 help="the same limit while the modulus is softened (approach "
                                      "to the preload, re-stiffening); that state is re-relaxed "
                                      "at the real modulus before any dump (-)"),
    "unbalanced_force_target": dict(kind="float", default=1e-3, minimum=1e-9,
                                    help="a state is dumped once YADE's unbalanced-force ratio "
                                         "is below this (-)"),
    "pressure_tolerance": dict(kind="float", default=0.01, minimum=1e-6,
                               help="relative tolerance on the plate pressure at a dump (-)"),
    "settle_damping": dict(kind="float", default=0.7, minimum=0.0,
                           help="Cundall damping while the settled bed relaxes under gravity "
                                "after the fall (-, < 1)"),
    "timestep_safety": dict(kind="float", default=0.8, minimum=1e-3,
                            help="time step = this x the P-wave time step r sqrt(rho/E) (-)"),
    "cloud_solid_fraction": dict(kind="float", default=0.3, minimum=0.01,
                                 help="solid fraction of the initial random cloud; its "
                                      "height follows (-)"),
    "max_steps": dict(kind="int", default=3000000, minimum=1,
                      help="give up (exit 1) if one stage needs more steps (-)"),
    "progress_seconds": dict(kind="float", default=5.0, minimum=0.0,
                             help="wall-clock interval of the progress lines (s)"),
    "seed": dict(kind="int", default=1, minimum=0,
                 help="random seed of the initial cloud (-)"),
    "output_dir": dict(kind="str", default=".",
                       help="folder for packing_<p>Pa.h5, settled.h5, settled.yade.gz"),
    "reuse_settled": dict(kind="bool", default=False,
                          help="if output_dir/settled.yade.gz exists and was made with the "
                               "same bed parameters, start from it instead of settling (-)"),
}


def check(p):
    """Cross-field checks of resolved bed parameters: ValueError('key: expected ..., got ...')
    for the first that fails."""
    from .bed_geometry import wall_sim_modulus
    checks = (
        ("radius_spread", p["radius_spread"] < 0.5, "a value < 0.5"),
        ("poisson", p["poisson"] < 0.5, "a value < 0.5"),
        ("wall_poisson", p["wall_poisson"] < 0.5, "a value < 0.5"),
        ("restitution", p["restitution"] <= 1.0, "a value in (0, 1]"),
        ("damping", p["damping"] < 1.0, "a value in [0, 1)"),
        ("settle_damping", p["settle_damping"] < 1.0, "a value in [0, 1)"),
        ("timestep_safety", p["timestep_safety"] <= 1.0, "a value in (0, 1]"),
        ("pressure_tolerance", p["pressure_tolerance"] < 0.5, "a value < 0.5"),
        ("preload_fraction", p["preload_fraction"] <= 1.0, "a value in (0, 1]"),
        ("cloud_solid_fraction", p["cloud_solid_fraction"] <= 0.35,
         "a value <= 0.35 (random sequential addition jams near 0.38)"),
        ("pressures_pa", len(p["pressures_pa"]) > 0, "at least one pressure"),
        ("pressures_pa", all(b > a for a, b in zip(p["pressures_pa"], p["pressures_pa"][1:])),
         "strictly increasing pressures"),
        ("settle_young_pa", p["settle_young_pa"] <= p["young_pa"],
         "a value <= young_pa (it is a softened modulus)"),
        ("cylinder_radius_m",
         p["cylinder_radius_m"] > 3.0 * p["particle_radius_m"] * (1 + p["radius_spread"]),
         "a radius > 3 x the largest particle radius, particle_radius_m (1 + radius_spread)"),
    )
    for key, ok, what in checks:
        if not ok:
            raise ValueError(f"{key}: expected {what}, got {p[key]!r}")
    if wall_sim_modulus(p["young_pa"], p["poisson"], p["wall_young_pa"],
                        p["wall_poisson"]) is None:
        limit = (p["young_pa"] / (1 - p["poisson"] ** 2) / (math.sqrt(2) - 1)
                 * (1 - p["wall_poisson"] ** 2))
        raise ValueError(f"wall_young_pa: expected a value < {limit:.4g} (YADE's wall contact "
                         f"has radius r/2; a stiffer wall cannot be made Hertz with R* = r), "
                         f"got {p['wall_young_pa']!r}")
