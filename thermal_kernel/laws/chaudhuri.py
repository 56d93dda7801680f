"""Chaudhuri, Muzzio & Tomassone (2006), the EDEM heat-conduction contact model (004).

    h_c = 4 k_1 k_2 / (k_1 + k_2) * (3 F_N r* / (4 E*))^(1/3)      (004, the one equation)

with F_N the normal force, r* the Hertz effective radius and E* the effective modulus. 004 calls
r* "the geometric mean of the particles radii from the Hertz's elastic contact theory"; the
bracket is the Hertz contact radius only with r* = r_1 r_2 / (r_1 + r_2), which is what is used
(with sqrt(r_1 r_2) two equal spheres would get 2^(1/3) times the Hertz radius). E* of two bodies
of the scene's material: E / (2 (1 - nu^2)). For one material this is exactly the
Batchelor-O'Brien law (`bob`) written with the Hertz radius.

No force, no heat: F_N = 0 (gaps, spheres that just touch) gives h_c = 0. Capacity:
rho c_p 4/3 pi R^3. Particle-geometry contacts (004: "particle-geometry conduction") use the same
formula with r* = r (sphere on a plane) and k_2 the wall's conductivity.
"""
from __future__ import annotations

import numpy as np

from .base import ContactInput, Law, WallContactInput, mass_capacity
from .granular import effective_modulus, hertz_contact_radius


def _h_c(k_1, k_2, force, r_star, e_star):
    k_1 = np.asarray(k_1, dtype=np.float64)
    k_2 = np.asarray(k_2, dtype=np.float64)
    total = k_1 + k_2
    # 004: 4 k1 k2 / (k1 + k2) (3 F_N r* / (4 E*))^(1/3)
    k_term = np.divide(4.0 * k_1 * k_2, total, out=np.zeros(total.shape), where=total > 0)
    return k_term * hertz_contact_radius(force, r_star, e_star)


def chaudhuri_conductance(contacts: ContactInput, params: dict) -> np.ndarray:
    """h_c = 4 k_i k_j/(k_i + k_j) (3 F_n r*/(4 E*))^(1/3), W/K; 0 for F_n = 0."""
    r_i, r_j = contacts.radius_i_m, contacts.radius_j_m
    return _h_c(contacts.conductivity_i, contacts.conductivity_j, contacts.normal_force_n,
                r_i * r_j / (r_i + r_j), effective_modulus(contacts.young_pa, contacts.poisson))


def chaudhuri_wall_conductance(walls: WallContactInput, params: dict) -> np.ndarray:
    """Particle-geometry contact: the same h_c with r* = r and k_2 = the wall's conductivity."""
    return _h_c(walls.conductivity_particle, walls.conductivity_wall, walls.normal_force_n,
                walls.radius_m, effective_modulus(walls.young_pa, walls.poisson))


CHAUDHURI = Law(
    name="chaudhuri",
    kind="force",
    conductance=chaudhuri_conductance,
    capacity=mass_capacity,
    wall_conductance=chaudhuri_wall_conductance,
    formula="H = 4 k_i k_j/(k_i + k_j) (3 F_n r*/(4 E*))^(1/3), r* = r_i r_j/(r_i + r_j); "
            "C = rho c_p 4/3 pi R^3",
    reference="004_4dc2c805659d5117.txt (EDEM Heat Conduction Model; Chaudhuri et al. 2006)",
    defaults={},
)
