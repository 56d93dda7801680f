"""Terreros, Iordanoff & Charles (2012), equivalent regular polyhedron (000, sec. 4).

Each particle i is given, from its number of particle-particle neighbours n_i, a non-dimensional
transmission surface S_t^nd(n_i) and a local volume fraction f_vl(n_i) (000, Table 1, linear
interpolation between rows, sec. 4.2-4.3). Then (000, sec. 4.4 and eq. 7):

    S_i  = S_t^nd(n_i) R_i^2,   S_ij = sqrt(S_i S_j)
    H_ij = lambda S_ij / d_ij                  (eq. 3 and 7, d_ij the centre distance)
    C_i  = rho_c c_p V_i / f_vl(n_i)           (eq. 6-7: rho_d = rho_c / f_vl)

On a simple-cubic lattice of pitch a (R = a/2) an interior particle has 6 neighbours:
S_t^nd = 4, S = (2R)^2 = a^2, H = lambda a, f_vl = 0.52359 ~ pi/6, C = rho c_p a^3 - the 7-point
finite-difference stencil of 000, sec. 3.

Outside the table (n = 0 for an isolated particle, n > 20) the values are clamped to the first
or last row (n = 1 or 20). The table's values are used as printed (f_vl(6) = 0.52359, not
pi/6 = 0.5235988: relative difference 1.7e-5).

Neighbours: particle-particle rows of the dump, gaps included; wall contacts are not neighbours
(counted by ``thermal_kernel.neighbours.neighbour_counts``). Gaps conduct like any other row
(geometric law, the neighbour criterion put them in the dump); H = 0 only if d <= 0.

Phases: 000 has one conductivity; at a contact between two phases tdem uses the interface rule
of 002, eq. 24 (``interface_mean = "harmonic"`` by default, or ``"arithmetic"``).

Walls: ``WallContactInput`` carries no neighbour count, so a wall contact is a face of the
particle's cube (the 6-neighbour row, S = 4 r^2) and the wall is a mirror particle at centre
distance 2 (r - delta) whose surface (half way) is held at T_w:
H_w = 2 lambda_p 4 r^2 / (2 (r - delta)) - on the lattice 2 lambda a, the finite-difference
half-cell boundary. The wall's conductivity does not enter.
"""
from __future__ import annotations

import numpy as np

from .base import ContactInput, Law, ParticleInput, WallContactInput, sphere_volume
from .haddad import interface_conductivity, positive_distance_ratio

# 000, Table 1: N_neigh, S_t^nd, f_vl (as printed)
TABLE_NEIGHBOURS = np.arange(1, 21, dtype=np.float64)
TABLE_SURFACE = np.array([
    19.98076, 16.78460, 13.58845, 10.39230, 7.19615, 4.0, 3.29903, 2.59807, 2.29545, 1.99282,
    1.69019, 1.38757, 1.30888, 1.23020, 1.15152, 1.07284, 0.99415, 0.91547, 0.83679, 0.75810])
TABLE_VOLUME_FRACTION = np.array([
    0.08502, 0.17004, 0.25506, 0.34008, 0.43184, 0.52359, 0.60188, 0.68017, 0.69525, 0.71032,
    0.72540, 0.74048, 0.75555, 0.77063, 0.78570, 0.80078, 0.81586, 0.83093, 0.84601, 0.86109])

# S_t^nd of the cube face (6 neighbours), used for wall contacts
CUBE_FACE_SURFACE = 4.0


def transmission_surface_nd(neighbours) -> np.ndarray:
    """S_t^nd(n): 000, Table 1, linear between rows, clamped to rows 1 and 20 outside."""
    return np.interp(np.asarray(neighbours, dtype=np.float64), TABLE_NEIGHBOURS, TABLE_SURFACE)


def local_volume_fraction(neighbours) -> np.ndarray:
    """f_vl(n): 000, Table 1, linear between rows, clamped to rows 1 and 20 outside."""
    return np.interp(np.asarray(neighbours, dtype=np.float64), TABLE_NEIGHBOURS,
                     TABLE_VOLUME_FRACTION)


def terreros_conductance(contacts: ContactInput, params: dict) -> np.ndarray:
    """H = lambda sqrt(S_i S_j) / d, S_i = S_t^nd(n_i) R_i^2, W/K; gaps conduct."""
    # 000, sec. 4.4: S_i = S_i^nd R_i^2, S_ij = sqrt(S_i S_j)
    s_i = transmission_surface_nd(contacts.neighbours_i) * contacts.radius_i_m ** 2
    s_j = transmission_surface_nd(contacts.neighbours_j) * contacts.radius_j_m ** 2
    s_ij = np.sqrt(s_i * s_j)
    lam = interface_conductivity(contacts.conductivity_i, contacts.conductivity_j,
                                 params["interface_mean"])
    # 000, eq. 3 and 7: W_ij = S_ij lambda (theta_j - theta_i) / d_ij
    return positive_distance_ratio(lam * s_ij, contacts.distance_m)


def terreros_capacity(particles: ParticleInput, params: dict) -> np.ndarray:
    """C = rho_c c_p V / f_vl(n), J/K (000, eq. 6-7)."""
    # 000, eq. 7: the denominator rho_c c_p V_i / f_vl is the capacity of element i
    return (particles.density * particles.heat_capacity * sphere_volume(particles.radius_m)
            / local_volume_fraction(particles.neighbours))


def terreros_wall_conductance(walls: WallContactInput, params: dict) -> np.ndarray:
    """Cube face on a Dirichlet plane: lambda_p 4 r^2 / (r - delta), W/K."""
    area = CUBE_FACE_SURFACE * walls.radius_m ** 2
    return positive_distance_ratio(walls.conductivity_particle * area,
                                   walls.radius_m - walls.overlap_m)


TERREROS = Law(
    name="terreros",
    kind="geometric",
    conductance=terreros_conductance,
    capacity=terreros_capacity,
    wall_conductance=terreros_wall_conductance,
    formula="H = lambda sqrt(S_i S_j) / d, S_i = S_t^nd(n_i) R_i^2 (Table 1); "
            "C = rho c_p V / f_vl(n)",
    reference="000_1932df0b9b2610fc.txt, sec. 3-4, Table 1, eq. 3-7",
    defaults={"interface_mean": "harmonic"},
)
