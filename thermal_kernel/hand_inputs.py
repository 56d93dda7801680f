"""Law inputs made by hand, with known answers: one contact of two spheres, the contacts and
particles of the simple-cubic lattice (``lattice.py``), and a registered law evaluated on them
with its defaults plus the given parameters.

One home for what ``tests/test_laws.py`` asserts and the exact validation cases 1 and 11
(``validation/case1_lattice.py``, ``case11_two_spheres.py``) report: the same inputs and the same
calls, so a case's numbers are the test's.
"""
from __future__ import annotations

import numpy as np

from .lattice import simple_cubic_packing
from .laws import get_law
from .laws.base import ContactInput, ParticleInput

# The material of the hand-computed two-sphere values (003 Table 1): E = 50 GPa, nu = 0.2.
YOUNG_PA, POISSON = 5e10, 0.2


def conductance(name, contacts, **params):
    """H (W/K) of law ``name`` on ``contacts``, its defaults overridden by ``params``."""
    law = get_law(name)
    return np.asarray(law.conductance(contacts, {**law.defaults, **params}))


def capacity(name, particles, **params):
    """C (J/K) of law ``name`` for ``particles``, its defaults overridden by ``params``."""
    law = get_law(name)
    return np.asarray(law.capacity(particles, {**law.defaults, **params}))


def wall_conductance(name, walls, **params):
    """H (W/K) of law ``name`` for wall contacts ``walls``, its defaults overridden."""
    law = get_law(name)
    return np.asarray(law.wall_conductance(walls, {**law.defaults, **params}))


def one_contact(r_i, r_j, d, k_i, k_j, force=0.0, n_i=6, n_j=6) -> ContactInput:
    """One contact: radii r_i, r_j (m) at centre distance d (m), conductivities k_i, k_j
    (W/m/K), normal force (N), neighbour counts n_i, n_j; material YOUNG_PA, POISSON."""
    a = lambda x: np.array([x], dtype=float)  # noqa: E731
    return ContactInput(radius_i_m=a(r_i), radius_j_m=a(r_j), distance_m=a(d),
                        overlap_m=a(r_i + r_j - d), normal_force_n=a(force),
                        conductivity_i=a(k_i), conductivity_j=a(k_j), neighbours_i=a(n_i),
                        neighbours_j=a(n_j), young_pa=YOUNG_PA, poisson=POISSON)


def hertz_radius_equal_spheres(force, radius):
    """zeta = (3 F_n (1 - nu^2) R_P / (4 E))^(1/3) (m), two equal spheres (003 eq. 34-35, 40)."""
    return (3 * force * (1 - POISSON ** 2) * radius / (4 * YOUNG_PA)) ** (1 / 3)


def lattice_inputs(shape=(5, 5, 5), a=2e-3, lam=134.0, rho=2790.0, cp=880.0):
    """(packing, neighbour counts, ContactInput, ParticleInput) of a simple-cubic lattice of
    pitch ``a`` (m), one material: conductivity ``lam``, density ``rho``, heat capacity ``cp``."""
    pk = simple_cubic_packing(shape, spacing_m=a)
    nb = np.bincount(pk.pair.reshape(-1), minlength=pk.n_particles)
    i, j = pk.pair[:, 0], pk.pair[:, 1]
    m, n = pk.pair.shape[0], pk.n_particles
    contacts = ContactInput(
        radius_i_m=pk.radius[i], radius_j_m=pk.radius[j],
        distance_m=np.linalg.norm(pk.branch, axis=1), overlap_m=pk.overlap,
        normal_force_n=pk.normal_force, conductivity_i=np.full(m, lam),
        conductivity_j=np.full(m, lam), neighbours_i=nb[i], neighbours_j=nb[j],
        young_pa=pk.attrs["young_pa"], poisson=pk.attrs["poisson"])
    particles = ParticleInput(radius_m=pk.radius, density=np.full(n, rho),
                              heat_capacity=np.full(n, cp), conductivity=np.full(n, lam),
                              neighbours=nb, solid_fraction=pk.attrs["solid_fraction"])
    return pk, nb, contacts, particles
