"""The default solid-solid law of YADE's ThermalEngine (pkg/pfv/Thermal.cpp), so that tdem and
YADE give the same temperatures on the same packing.

    G_ij = 2 (k_i + k_j) r_i r_j / d_ij,   d_ij = r_i + r_j - penetrationDepth   (W/K)
    C_i  = m_i c_p = rho 4/3 pi r_i^3 c_p                                         (J/K)

Read in ``ThermalEngine::computeSolidSolidFluxes`` (the ``else`` branch taken when
``useKernMethod`` and ``useHertzMethod`` are both false) and
``ThermalEngine::computeNewParticleTemperatures`` (T += stepFlux dt / (Cp rho 4/3 pi r^3), rho
the material's density unless ``particleDensity > 0``). In words: the arithmetic-mean
conductivity (k_i + k_j)/2 times a surface 4 r_i r_j (the face (2r)^2 of the simple-cubic cell
for equal spheres) over the centre distance. Checked against YADE 2023.02a on two spheres of
unequal radii and conductivities, overlapping and with a gap: one step matched to 1e-12.

Gaps: YADE conducts over every *real* interaction, whatever the sign of penetrationDepth; a gap
row that the dump kept conducts with its real centre distance (larger d, smaller G). No force
enters. G = 0 only if d <= 0 (YADE skips d == 0).

Walls: YADE's ThermalEngine has no sphere-wall conduction (its boundaries fix the temperature of
particles). tdem's rule: a mirror particle (radius r, same conductivity) at centre distance
2 (r - delta), the wall's surface half way held at T_w: G_w = 2 * 2 (k_p + k_p) r^2 / (2 (r -
delta)) = 4 k_p r^2 / (r - delta). The wall's conductivity does not enter.
"""
from __future__ import annotations

import numpy as np

from .base import ContactInput, Law, WallContactInput, mass_capacity
from .haddad import positive_distance_ratio


def yade_conductance(contacts: ContactInput, params: dict) -> np.ndarray:
    """G = 2 (k_i + k_j) r_i r_j / d, W/K (Thermal.cpp, default branch); gaps conduct."""
    # Thermal.cpp, computeSolidSolidFluxes: thermalResist = 2 (k1 + k2) r1 r2 / (r1 + r2 - pd)
    numerator = (2.0 * (contacts.conductivity_i + contacts.conductivity_j)
                 * contacts.radius_i_m * contacts.radius_j_m)
    return positive_distance_ratio(numerator, contacts.distance_m)


def yade_wall_conductance(walls: WallContactInput, params: dict) -> np.ndarray:
    """Mirror particle at 2 (r - delta), surface at T_w: 4 k_p r^2 / (r - delta), W/K."""
    return positive_distance_ratio(4.0 * walls.conductivity_particle * walls.radius_m ** 2,
                                   walls.radius_m - walls.overlap_m)


YADE = Law(
    name="yade",
    kind="geometric",
    conductance=yade_conductance,
    capacity=mass_capacity,
    wall_conductance=yade_wall_conductance,
    formula="H = 2 (k_i + k_j) r_i r_j / d (YADE ThermalEngine default); C = rho c_p 4/3 pi R^3",
    reference="YADE pkg/pfv/Thermal.cpp, ThermalEngine::computeSolidSolidFluxes and "
              "computeNewParticleTemperatures (useKernMethod = useHertzMethod = False)",
    defaults={},
)
