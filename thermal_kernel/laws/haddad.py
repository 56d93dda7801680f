"""Haddad et al. (2021), lattice model of a continuous, heterogeneous medium (002).

    H_pq = lambda S^t_pq / d_pq,  S^t_pq = C_t pi R_m^2                        (002, eq. 3, 7)
    C_p  = c rho_c V_p / phi                                                    (002, eq. 1, 5)

R_m: 002 (sec. 2.1, before eq. 7) calls it "the mean radius of the contact particles" and does
not say which mean. ``mean_radius`` (law parameter) chooses:

    "arithmetic" (default)  R_m = (R_p + R_q) / 2
    "geometric"             R_m = sqrt(R_p R_q)
    "harmonic"              R_m = 2 R_p R_q / (R_p + R_q)

All three give R for R_p = R_q = R and agree with eq. 10-15's single-radius estimates; for a
polydisperse packing arithmetic >= geometric >= harmonic, so the calibrated C_t (eq. 9) grows
from the first to the last (on the tiled 1e5 box, Gaussian radii sigma/mean 0.3, bulk Z 7.5:
docs/validation.md case 6). The default stays the arithmetic mean, the plain reading of "mean
radius".

d_pq is the centre distance, phi the packing's solid fraction, rho_c the continuum density.
At a contact between two phases lambda is the harmonic mean 2 l_p l_q / (l_p + l_q) (002,
eq. 24), or the arithmetic mean (l_p + l_q) / 2 with ``interface_mean = "arithmetic"`` (002 says
it overestimates the effective conductivity).

Capacity: 002 writes eq. 5 as C rho_d V_p / phi with rho_d = rho_c / phi (eq. 1), but eq. 6
divides by C rho_d V_p. Only C_p = c rho_c V_p / phi (= c rho_d V_p) conserves the continuum's
heat capacity (sum of V_p / phi = the domain's volume), so that is the reading used.

Gaps: the law is geometric, not force-based. Every row of the dump conducts, including gaps kept
by the neighbour criterion (overlap <= 0, F_n = 0), with their real centre distance: the dump's
neighbour criterion decides which pairs are neighbours. H = 0 only if d <= 0.

Walls: a mirror particle (radius r) at centre distance 2 (r - delta), the wall's surface (half
way) held at the wall temperature: H_w = 2 lambda_p C_t pi r^2 / (2 (r - delta)). The wall's
conductivity does not enter (the surface, not the wall's body, is at T_w).
"""
from __future__ import annotations

import math

import numpy as np

from .base import ContactInput, Law, ParticleInput, WallContactInput, sphere_volume

INTERFACE_MEANS = ("harmonic", "arithmetic")
MEAN_RADII = ("arithmetic", "geometric", "harmonic")


def mean_radius(r_p, r_q, rule: str = "arithmetic") -> np.ndarray:
    """R_m of a pair, m (002, eq. 7: "the mean radius of the contact particles"; which mean is
    not said): ``arithmetic`` (R_p + R_q)/2, ``geometric`` sqrt(R_p R_q), ``harmonic``
    2 R_p R_q / (R_p + R_q)."""
    r_p = np.asarray(r_p, dtype=np.float64)
    r_q = np.asarray(r_q, dtype=np.float64)
    if rule == "arithmetic":
        return 0.5 * (r_p + r_q)
    if rule == "geometric":
        return np.sqrt(r_p * r_q)
    if rule == "harmonic":
        return 2.0 * r_p * r_q / (r_p + r_q)
    raise ValueError(f"mean_radius: expected one of {', '.join(MEAN_RADII)}, got {rule!r}")


def interface_conductivity(k_i, k_j, rule: str = "harmonic") -> np.ndarray:
    """Conductivity of a contact between two phases, W/m/K (002, eq. 24).

    ``harmonic``: 2 k_i k_j / (k_i + k_j) (0 if both are 0); ``arithmetic``: (k_i + k_j) / 2.
    Both give k for k_i = k_j = k."""
    k_i = np.asarray(k_i, dtype=np.float64)
    k_j = np.asarray(k_j, dtype=np.float64)
    if rule == "harmonic":
        total = k_i + k_j
        # 002, eq. 24: lambda^Gamma = 2 lambda^i lambda^m / (lambda^i + lambda^m)
        return np.divide(2.0 * k_i * k_j, total, out=np.zeros(total.shape), where=total > 0)
    if rule == "arithmetic":
        return 0.5 * (k_i + k_j)
    raise ValueError(f"interface_mean: expected one of {', '.join(INTERFACE_MEANS)}, "
                     f"got {rule!r}")


def positive_distance_ratio(numerator, distance) -> np.ndarray:
    """numerator / distance where distance > 0, else 0 (never inf or negative)."""
    numerator = np.asarray(numerator, dtype=np.float64)
    distance = np.asarray(distance, dtype=np.float64)
    shape = np.broadcast(numerator, distance).shape
    return np.divide(numerator, distance, out=np.zeros(shape), where=distance > 0)


def _ct(params: dict) -> float:
    ct = float(params["ct"])
    if not (math.isfinite(ct) and ct > 0):
        raise ValueError(f"ct: expected a value > 0, got {ct!r}")
    return ct


def haddad_conductance(contacts: ContactInput, params: dict) -> np.ndarray:
    """H = lambda C_t pi R_m^2 / d, R_m the pair's mean radius (``mean_radius``), W/K; gaps
    conduct (geometric law)."""
    # 002, eq. 7: S^t = C_t S_pq, S_pq = pi R_m^2, R_m the mean radius of the two particles
    r_m = mean_radius(contacts.radius_i_m, contacts.radius_j_m,
                      params.get("mean_radius", "arithmetic"))
    area = _ct(params) * math.pi * r_m ** 2
    lam = interface_conductivity(contacts.conductivity_i, contacts.conductivity_j,
                                 params["interface_mean"])
    # 002, eq. 3: H = lambda S^t / d
    return positive_distance_ratio(lam * area, contacts.distance_m)


def haddad_capacity(particles: ParticleInput, params: dict) -> np.ndarray:
    """C = c rho_c V / phi, J/K (002, eq. 1, 5; phi the packing's solid fraction)."""
    phi = float(particles.solid_fraction)
    if not (0.0 < phi <= 1.0):
        raise ValueError(f"solid_fraction: expected a value in (0, 1], got {phi!r}")
    # 002, eq. 5 with eq. 1: C_p = C rho_d V_p = C rho_c V_p / phi
    return particles.heat_capacity * particles.density * sphere_volume(particles.radius_m) / phi


def haddad_wall_conductance(walls: WallContactInput, params: dict) -> np.ndarray:
    """Mirror particle at 2 (r - delta), surface at T_w: lambda_p C_t pi r^2 / (r - delta)."""
    area = _ct(params) * math.pi * walls.radius_m ** 2
    half = walls.radius_m - walls.overlap_m
    return positive_distance_ratio(walls.conductivity_particle * area, half)


HADDAD = Law(
    name="haddad",
    kind="geometric",
    conductance=haddad_conductance,
    capacity=haddad_capacity,
    wall_conductance=haddad_wall_conductance,
    formula="H = lambda C_t pi R_m^2 / d, R_m = (R_i + R_j)/2 (mean_radius: or sqrt(R_i R_j), "
            "2 R_i R_j/(R_i + R_j)), lambda harmonic at interfaces; C = c rho V / phi",
    reference="002_f662a1d4f5957726.txt, eq. 1-7, 24",
    defaults={"ct": 0.806, "interface_mean": "harmonic", "mean_radius": "arithmetic"},
)
