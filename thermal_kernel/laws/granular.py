"""Constriction laws of granular packs: the heat crosses the small Hertz contact spot.

Four laws share one shape, ``H = c * a * k_h``, with

* ``a`` the Hertz contact radius from the dumped normal force at the REAL modulus,
  ``a = (3 F_n R* / (4 E*))^(1/3)``, ``R* = r_i r_j / (r_i + r_j)``,
  ``1/E* = (1 - nu^2)/E + (1 - nu^2)/E`` (both bodies of the scene's material). For equal spheres
  this is the paper's ``zeta = (3 F_n (1 - sigma^2) R_P / (4 E))^(1/3)`` (003, eq. 34-35, 40),
  since ``R* = R_P / 2`` and ``E* = E / (2 (1 - sigma^2))``.
* ``k_h = 2 k_i k_j / (k_i + k_j)``: the two halves of the contact in series. Each law is
  written in the papers for one conductivity; its resistance is a sum of one term per sphere
  (1/(4 k a) for a constriction, R_eP for the pipe, 003 eq. 18-20), so unequal conductivities
  give the harmonic mean. With ``k_i = k_j = k`` it is ``k``.
* ``c``: 2 (Batchelor-O'Brien), pi / (2 beta) (Argento-Bouvard, Ott), sqrt(2) / |lambda| with
  lambda = -0.6846 (two-particle pipe, 2.066 for the paper's rounding).

No force, no area: ``F_n = 0`` (gaps kept by the neighbour criterion, or spheres that just
touch) gives ``H = 0``. Capacity: ``rho c_p 4/3 pi R^3`` (003, eq. 21).

Walls (``wall_conductance``): the same formula for a sphere on a plane, ``R* = r``, the wall of
the particle's material (as the bed generator's default, ``wall_young_pa = young_pa``; the
interface carries one modulus), ``k_j`` = the wall's conductivity.
"""
from __future__ import annotations

import math

import numpy as np

from .base import ContactInput, Law, WallContactInput, mass_capacity

# 003, text after eq. 13: sum_m (2m+1)/(2m) P_m(cos psi) P_m(cos phi) -> -0.6846 ("lambda")
PIPE_LEGENDRE_SUM = -0.6846


def effective_modulus(young_pa: float, poisson: float) -> float:
    """E* of two bodies of one material: 1/E* = 2 (1 - nu^2) / E (Hertz)."""
    young_pa, poisson = float(young_pa), float(poisson)
    if not (math.isfinite(young_pa) and young_pa > 0):
        raise ValueError(f"young_pa: expected a finite modulus > 0, got {young_pa!r}")
    if not (-1.0 < poisson < 0.5):
        raise ValueError(f"poisson: expected a value in (-1, 0.5), got {poisson!r}")
    return young_pa / (2.0 * (1.0 - poisson ** 2))


def hertz_contact_radius(normal_force_n, r_star_m, e_star_pa: float) -> np.ndarray:
    """a = (3 F_n R* / (4 E*))^(1/3), m; 0 where F_n <= 0."""
    force = np.clip(np.asarray(normal_force_n, dtype=np.float64), 0.0, None)
    return np.cbrt(3.0 * force * np.asarray(r_star_m, dtype=np.float64) / (4.0 * e_star_pa))


def series_conductivity(k_i, k_j) -> np.ndarray:
    """2 k_i k_j / (k_i + k_j), W/m/K: the two halves of a contact in series (0 if both are 0)."""
    k_i = np.asarray(k_i, dtype=np.float64)
    k_j = np.asarray(k_j, dtype=np.float64)
    total = k_i + k_j
    return np.divide(2.0 * k_i * k_j, total, out=np.zeros(np.broadcast(k_i, k_j).shape),
                     where=total > 0)


def _pair_radius(contacts: ContactInput) -> np.ndarray:
    """Hertz contact radius of each particle pair, m."""
    r_i, r_j = contacts.radius_i_m, contacts.radius_j_m
    r_star = r_i * r_j / (r_i + r_j)
    return hertz_contact_radius(contacts.normal_force_n, r_star,
                                effective_modulus(contacts.young_pa, contacts.poisson))


def _wall_radius(walls: WallContactInput) -> np.ndarray:
    """Hertz contact radius of a sphere on a plane (R* = r), m."""
    return hertz_contact_radius(walls.normal_force_n, walls.radius_m,
                                effective_modulus(walls.young_pa, walls.poisson))


# --- pipe: two-particle pipe model (003, eq. 17-21, 36-40) -------------------------------------

def _pipe(a_hertz, k_i, k_j):
    # 003, eq. 38: R_P dphi = sqrt(R_P delta_n), the radius of the geometric lens at the Hertz
    # overlap; for any two spheres (or a sphere on a plane) that is sqrt(2 R* delta) = sqrt(2) a.
    a_lens = math.sqrt(2.0) * a_hertz
    lam = abs(PIPE_LEGENDRE_SUM)
    # 003, eq. 18-20: R_eP = -lambda / (2 k_P R_P dphi); H = 1 / (R_eP + R_eL), written without
    # dividing by a_lens so that a_lens = 0 gives H = 0. Equal spheres: 2.066 k zeta (eq. 40).
    total = k_i + k_j
    return np.divide(2.0 * a_lens * k_i * k_j, lam * total, out=np.zeros_like(a_lens),
                     where=total > 0)


def pipe_conductance(contacts: ContactInput, params: dict) -> np.ndarray:
    """Two-particle pipe (003, eq. 17-20, 36-40): H = 1 / (R_eP + R_eL), W/K.

    R_eP = 0.6846 / (2 k_P a_l), a_l = sqrt(2) a the lens radius at the Hertz overlap (eq. 38),
    a = (3 F_n R* / (4 E*))^(1/3). Equal spheres: H = 2.066 k zeta (eq. 40), 1.033 x BOB.
    Unequal conductivities: the two pipe halves in series (eq. 20). F_n = 0 (gaps): H = 0."""
    return _pipe(_pair_radius(contacts), contacts.conductivity_i, contacts.conductivity_j)


def pipe_wall_conductance(walls: WallContactInput, params: dict) -> np.ndarray:
    """Pipe model on a plane: the wall is a mirror sphere of the wall's conductivity, contact
    radius from Hertz with R* = r; F_n = 0 gives 0."""
    return _pipe(_wall_radius(walls), walls.conductivity_particle, walls.conductivity_wall)


# --- bob: Batchelor & O'Brien (003, eq. 34) ----------------------------------------------------

def bob_conductance(contacts: ContactInput, params: dict) -> np.ndarray:
    """Batchelor-O'Brien (003, eq. 34): H = 2 k zeta for equal spheres, W/K.

    Generalised: H = 4 a k_i k_j / (k_i + k_j), one constriction resistance 1/(4 k a) per sphere,
    a = (3 F_n R* / (4 E*))^(1/3). F_n = 0 (gaps): H = 0."""
    # 003, eq. 34: k_BOB = 2 kappa_P zeta; 2 * k_h * a with k_h the series (harmonic) mean
    return 2.0 * _pair_radius(contacts) * series_conductivity(contacts.conductivity_i,
                                                              contacts.conductivity_j)


def bob_wall_conductance(walls: WallContactInput, params: dict) -> np.ndarray:
    """BOB on a plane: 4 a k_p k_w / (k_p + k_w), a from Hertz with R* = r."""
    return 2.0 * _wall_radius(walls) * series_conductivity(walls.conductivity_particle,
                                                           walls.conductivity_wall)


# --- argento, ott: Argento & Bouvard, Ott (003, eq. 35) ----------------------------------------

def _beta(params: dict) -> float:
    beta = float(params["beta"])
    if not (math.isfinite(beta) and beta > 0):
        raise ValueError(f"beta: expected a value > 0, got {beta!r}")
    return beta


def argento_conductance(contacts: ContactInput, params: dict) -> np.ndarray:
    """Argento-Bouvard (003, eq. 35): H = pi / (2 beta) k zeta for equal spheres, W/K.

    Generalised: H = pi / (2 beta) a k_h, k_h = 2 k_i k_j / (k_i + k_j), a the Hertz contact
    radius. beta = 0.899 (Argento-Bouvard) or 0.952 (Ott). F_n = 0 (gaps): H = 0."""
    # 003, eq. 35: k_AB = pi / (2 beta) kappa_P zeta
    return (math.pi / (2.0 * _beta(params)) * _pair_radius(contacts)
            * series_conductivity(contacts.conductivity_i, contacts.conductivity_j))


def argento_wall_conductance(walls: WallContactInput, params: dict) -> np.ndarray:
    """Argento-Bouvard / Ott on a plane: pi / (2 beta) a k_h, a from Hertz with R* = r."""
    return (math.pi / (2.0 * _beta(params)) * _wall_radius(walls)
            * series_conductivity(walls.conductivity_particle, walls.conductivity_wall))


# --- registry entries ---------------------------------------------------------------------------

_HERTZ = "a = (3 F_n R*/(4 E*))^(1/3)"

PIPE = Law(
    name="pipe",
    kind="force",
    conductance=pipe_conductance,
    capacity=mass_capacity,
    wall_conductance=pipe_wall_conductance,
    formula=f"H = 1/(R_eP + R_eL), R_eP = 0.6846/(2 k_P sqrt(2) a), {_HERTZ} "
            "(equal spheres: 2.066 k zeta); C = rho c_p 4/3 pi R^3",
    reference="003_b45c5691e422fa58.txt, eq. 17-21, 36-40",
    defaults={},
)

BOB = Law(
    name="bob",
    kind="force",
    conductance=bob_conductance,
    capacity=mass_capacity,
    wall_conductance=bob_wall_conductance,
    formula=f"H = 4 a k_i k_j/(k_i + k_j), {_HERTZ} (equal: 2 k zeta); C = rho c_p 4/3 pi R^3",
    reference="003_b45c5691e422fa58.txt, eq. 34 (Batchelor & O'Brien)",
    defaults={},
)

ARGENTO = Law(
    name="argento",
    kind="force",
    conductance=argento_conductance,
    capacity=mass_capacity,
    wall_conductance=argento_wall_conductance,
    formula=f"H = pi/(2 beta) a 2 k_i k_j/(k_i + k_j), {_HERTZ}; C = rho c_p 4/3 pi R^3",
    reference="003_b45c5691e422fa58.txt, eq. 35 (Argento & Bouvard, beta = 0.899)",
    defaults={"beta": 0.899},
)

OTT = Law(
    name="ott",
    kind="force",
    conductance=argento_conductance,
    capacity=mass_capacity,
    wall_conductance=argento_wall_conductance,
    formula=f"H = pi/(2 beta) a 2 k_i k_j/(k_i + k_j), {_HERTZ}; C = rho c_p 4/3 pi R^3",
    reference="003_b45c5691e422fa58.txt, eq. 35 (Ott, beta = 0.952)",
    defaults={"beta": 0.952},
)


# --- pipe_resistance_as_conductance: a DIAGNOSTIC, not a physical law (issue 15) --------------

def pipe_resistance_as_conductance(contacts: ContactInput, params: dict) -> np.ndarray:
    """DIAGNOSTIC (a hypothesis tool, not a physical law): the pipe model's resistance sum of
    003 eq. 18-20 used as if it were the conductance, "H" = R_eP + R_eL (its number in K/W read
    as W/K).

    R_eP = 0.6846 / (2 k_P a_l), R_eL = 0.6846 / (2 k_L a_l), a_l = sqrt(2) a the lens radius
    at the Hertz overlap (eq. 38), a = (3 F_n R* / (4 E*))^(1/3). Equal spheres:
    "H" = 0.6846 / (sqrt(2) k a) = 1 / H_pipe (numerically), so "H" ∝ 1/ζ ∝ F_n^(-1/3): a code
    that did this would find gamma falling with pressure. It tests the hypothesis that 003's
    falling gamma(p) comes from such a slip; nothing else should use it. F_n = 0 (no contact,
    no pipe) or a zero conductivity (no pipe): 0, not infinity."""
    return _resistance_sum(_pair_radius(contacts), contacts.conductivity_i,
                           contacts.conductivity_j)


def _resistance_sum(a_hertz, k_i, k_j):
    a_lens = math.sqrt(2.0) * np.asarray(a_hertz, dtype=np.float64)
    k_i = np.asarray(k_i, dtype=np.float64)
    k_j = np.asarray(k_j, dtype=np.float64)
    lam = abs(PIPE_LEGENDRE_SUM)
    ok = (a_lens > 0) & (k_i > 0) & (k_j > 0)
    out = np.zeros(np.broadcast(a_lens, k_i, k_j).shape)
    den_i = np.where(ok, 2.0 * k_i * a_lens, 1.0)
    den_j = np.where(ok, 2.0 * k_j * a_lens, 1.0)
    np.copyto(out, lam / den_i + lam / den_j, where=ok)
    return out


def pipe_resistance_as_conductance_wall(walls: WallContactInput, params: dict) -> np.ndarray:
    """The same diagnostic on a plane: R_eP + R_eW of the sphere and its mirror (the wall's
    conductivity), a from Hertz with R* = r; F_n = 0 gives 0."""
    return _resistance_sum(_wall_radius(walls), walls.conductivity_particle,
                           walls.conductivity_wall)


PIPE_RESISTANCE_AS_CONDUCTANCE = Law(
    name="pipe_resistance_as_conductance",
    kind="force",
    conductance=pipe_resistance_as_conductance,
    capacity=mass_capacity,
    wall_conductance=pipe_resistance_as_conductance_wall,
    formula="DIAGNOSTIC, not a physical law: \"H\" = R_eP + R_eL = 0.6846/(2 k_P sqrt(2) a) + "
            f"0.6846/(2 k_L sqrt(2) a) (K/W read as W/K; equal spheres: 1/H_pipe), {_HERTZ}; "
            "C = rho c_p 4/3 pi R^3",
    reference="003_b45c5691e422fa58.txt, eq. 17-20 (resistances), used as a conductance to test "
              "why 003's gamma falls with pressure (issue 15)",
    defaults={},
    diagnostic=True,
)
