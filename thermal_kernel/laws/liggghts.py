"""The conductance of LIGGGHTS' ``fix heat/gran/conduction`` (3.8.0, default ``contact_area
overlap``), so that a LIGGGHTS user can ask tdem for exactly what LIGGGHTS computes.

    A_ij = -pi/4 (d - r_i - r_j)(d + r_i - r_j)(d - r_i + r_j)(d + r_i + r_j) / d^2   (m^2)
    H_ij = 4 k_i k_j / (k_i + k_j) sqrt(A_ij)                                        (W/K)
    C_i  = m_i c_p = rho 4/3 pi r_i^3 c_p                                             (J/K)

A is the area of the lens where the two spheres' surfaces cross (pi times the squared radius of
the circle they cut), d the centre distance. For equal conductivities H = 2 k sqrt(A) = 2 sqrt(pi)
k a, a the lens radius: sqrt(pi) x the Batchelor-O'Brien 2 k a of that radius. Read in
LIGGGHTS-PUBLIC ``src/fix_heat_gran_conduction.cpp``, ``FixHeatGranCond::post_force_eval``
(``contactArea`` and ``hc``); the temperature update is ``FixScalarTransportEquation::
final_integrate``: T += heatFlux dt / (rmass c_p), explicit Euler, for the atoms of the fix's
group only (the others keep their temperature: that is how LIGGGHTS holds a layer, tdem's
``phase_temperature`` boundary).

Which pairs conduct: LIGGGHTS takes every pair of its neighbour list whose centres are closer
than r_i + r_j at the current positions. tdem computes A from the row's centre distance d (as
LIGGGHTS does, from the positions) and gives H = 0 where d >= r_i + r_j (a gap kept by a
neighbour criterion), where d <= |r_i - r_j| (one sphere inside the other: no lens) and where
a conductivity is 0 (LIGGGHTS: below 1e-10). No force enters.

``area_correction yes`` (LIGGGHTS' option for softened beds): the overlap r_i + r_j - d is
multiplied by (Y*/Y*_orig)^(2/3) before A is computed, Y* the effective modulus of the pair at
``youngsModulus`` (the softened one the forces use) and Y*_orig at ``youngsModulusOriginal``
(the real one); 2/3 = 1 / the Hertz stress-strain exponent 3/2 (``FixHeatGranCond::init``).
With one material (one Poisson ratio) Y*/Y*_orig = Y/Y_orig. tdem: law parameters
``young_softened_pa`` (0 = no correction, the default) and ``young_real_pa`` (0 = the scene's
real modulus, ``[material] young_pa`` or the packing's). Per-type moduli are not reproduced:
one pair of moduli for the whole packing.

Walls (``fix wall/gran`` with heat transfer, ``FixWallGran::addHeatFlux``): the cap a plane
cuts from the sphere, A = pi (r^2 - (r - delta)^2), delta the overlap (corrected as above),
and H = 4 k_p k_w / (k_p + k_w) sqrt(A); H = 0 for delta <= 0.
"""
from __future__ import annotations

import math

import numpy as np

from .base import ContactInput, Law, WallContactInput, mass_capacity

# fix_heat_gran_conduction.cpp: "if (tcoi < SMALL || tcoj < SMALL) hc = 0."
SMALL_CONDUCTIVITY = 1e-10
# FixHeatGranCond::init: expo = 1 / pair_gran->stressStrainExponent(), 3/2 for Hertz
HERTZ_OVERLAP_EXPONENT = 2.0 / 3.0


def overlap_ratio(params: dict, young_pa: float) -> float:
    """LIGGGHTS' ``deltan_ratio``: (Y_softened / Y_real)^(2/3) with ``young_softened_pa`` > 0,
    else 1 (no area correction). ``young_real_pa`` 0: the scene's real modulus ``young_pa``."""
    softened = float(params.get("young_softened_pa", 0.0))
    if softened == 0.0:
        return 1.0
    real = float(params.get("young_real_pa", 0.0)) or float(young_pa)
    for key, value in (("young_softened_pa", softened), ("young_real_pa", real)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{key}: expected a modulus > 0 in Pa, got {value!r}")
    # one material: the (1 - nu^2) of both effective moduli cancel
    return (softened / real) ** HERTZ_OVERLAP_EXPONENT


def _series4(k_i, k_j):
    """4 k_i k_j / (k_i + k_j), 0 where either is below LIGGGHTS' SMALL."""
    k_i = np.asarray(k_i, dtype=np.float64)
    k_j = np.asarray(k_j, dtype=np.float64)
    ok = (k_i >= SMALL_CONDUCTIVITY) & (k_j >= SMALL_CONDUCTIVITY)
    total = np.where(ok, k_i + k_j, 1.0)
    return np.where(ok, 4.0 * k_i * k_j / total, 0.0)


def lens_area(radius_i_m, radius_j_m, distance_m) -> np.ndarray:
    """A = -pi/4 (d - r_i - r_j)(d + r_i - r_j)(d - r_i + r_j)(d + r_i + r_j) / d^2, m^2, as
    LIGGGHTS writes it; 0 where the spheres do not cross (d >= r_i + r_j, d <= |r_i - r_j|)."""
    r_i = np.asarray(radius_i_m, dtype=np.float64)
    r_j = np.asarray(radius_j_m, dtype=np.float64)
    d = np.asarray(distance_m, dtype=np.float64)
    crossing = (d < r_i + r_j) & (d > np.abs(r_i - r_j))
    dd = np.where(crossing, d, 1.0)
    # LIGGGHTS' four factors, the middle two as d^2 - (r_i - r_j)^2 and the sums as r_i + r_j,
    # so that H_ij = H_ji to the last bit (the same value up to rounding)
    radsum = r_i + r_j
    area = -math.pi / 4 * ((dd - radsum) * (dd + radsum) * (dd * dd - (r_i - r_j) ** 2)) \
        / (dd * dd)
    return np.where(crossing, np.clip(area, 0.0, None), 0.0)


def liggghts_conductance(contacts: ContactInput, params: dict) -> np.ndarray:
    """H = 4 k_i k_j/(k_i + k_j) sqrt(A), A the lens area at the centre distance d (W/K);
    with ``young_softened_pa`` the overlap r_i + r_j - d is scaled by (Y_soft/Y_real)^(2/3)
    first (LIGGGHTS' ``area_correction yes``). d >= r_i + r_j: H = 0."""
    r_i, r_j = contacts.radius_i_m, contacts.radius_j_m
    d = np.asarray(contacts.distance_m, dtype=np.float64)
    ratio = overlap_ratio(params, contacts.young_pa)
    if ratio != 1.0:
        # fix_heat_gran_conduction.cpp: delta_n = radsum - r; delta_n *= ratio; r = radsum - delta_n
        radsum = r_i + r_j
        d = np.where(d < radsum, radsum - (radsum - d) * ratio, d)
    return _series4(contacts.conductivity_i, contacts.conductivity_j) * np.sqrt(
        lens_area(r_i, r_j, d))


def liggghts_wall_conductance(walls: WallContactInput, params: dict) -> np.ndarray:
    """H = 4 k_p k_w/(k_p + k_w) sqrt(pi (r^2 - (r - delta)^2)) (FixWallGran::addHeatFlux), W/K;
    delta scaled as for pairs with ``young_softened_pa``; delta <= 0: H = 0."""
    r = np.asarray(walls.radius_m, dtype=np.float64)
    delta = np.clip(np.asarray(walls.overlap_m, dtype=np.float64), 0.0, None)
    delta = np.minimum(delta * overlap_ratio(params, walls.young_pa), r)
    rest = r - delta
    area = np.clip(math.pi * (r * r - rest * rest), 0.0, None)
    return _series4(walls.conductivity_particle, walls.conductivity_wall) * np.sqrt(area)


LIGGGHTS = Law(
    name="liggghts",
    kind="overlap",
    conductance=liggghts_conductance,
    capacity=mass_capacity,
    wall_conductance=liggghts_wall_conductance,
    formula="H = 4 k_i k_j/(k_i + k_j) sqrt(A), A = -pi/4 (d-r_i-r_j)(d+r_i-r_j)(d-r_i+r_j)"
            "(d+r_i+r_j)/d^2 the lens area (equal k: 2 sqrt(pi) k a); young_softened_pa > 0: "
            "overlap x (Y_soft/Y_real)^(2/3) (area_correction yes); C = rho c_p 4/3 pi R^3",
    reference="LIGGGHTS-PUBLIC 3.8.0 src/fix_heat_gran_conduction.cpp (FixHeatGranCond::init, "
              "post_force_eval, contact_area overlap), fix_wall_gran.cpp (addHeatFlux), "
              "fix_scalar_transport_equation.cpp (final_integrate)",
    defaults={"young_softened_pa": 0.0, "young_real_pa": 0.0},
)
