"""Contact fabric of a bed and the affine (fabric-tensor) estimate of its conductivity (issue 15).

Affine estimate. Impose the uniform gradient G along ``axis`` on every particle: the contact c
passes H_c G.l_c, the dissipation is sum_c H_c (G.l_c)^2 = V G.k.G with

    k_ij = (1/V) sum_c H_c l_i l_j            (l the branch vector, V the bed volume)

(Batchelor & O'Brien's fabric tensor of conductances). Thomson's principle: among all
temperature fields that take the held values on the held particles, the steady one dissipates
least, Q dT. So k_zz is an upper bound of the network's steady conductivity
k_steady = Q L/(A dT), provided the affine field is admissible, i.e. exactly the wall's value on
every held sphere. Held spheres do not sit on one plane; here each one enters at the mean centre
plane of its wall (z0 or z1, the planes that define the slab length L of the post-processing):
in l_z of a contact with a held sphere, the held end's coordinate is its wall's plane. Contacts
between two held spheres of the same wall carry no heat (both at the wall's temperature) and are
left out; particle-wall contacts do not exist in the network (the Dirichlet condition is on the
held spheres). V = A L, A the bed's cross-section. Then k_steady <= k_zz exactly, with equality
when the steady field is affine (a simple-cubic lattice between its held layers).

The isotropic mean field phi Z Hbar/(2 pi Rbar k_p) is the same sum with l^2 -> (2 Rbar)^2,
l_z^2/l^2 -> 1/3 and no correlation between H and the direction: it is *not* a bound. A bed
compressed along z has <n_z^2> > 1/3 and its larger forces (hence conductances) on the more
vertical contacts, which is why the mean field falls below the network.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class AffineEstimate:
    k: np.ndarray            # (3, 3) W/m/K, fabric tensor of conductances (axis in its own slot)
    volume_m3: float         # A L
    n_contacts: int          # contacts in the sum (H > 0, not two held spheres of one wall)


def affine_conductivity(pair, branch, conductance_w_k, position, axis, held_low, held_high,
                        plane_low, plane_high, area_m2) -> AffineEstimate:
    """k_ij = (1/V) sum_c H_c l_i l_j with the held spheres at their walls' planes (see the module
    docstring). ``held_low``/``held_high``: indices of the spheres held by the lower / upper
    wall; ``plane_low``/``plane_high``: those walls' mean centre planes (m, along ``axis``);
    ``area_m2``: the bed's cross-section. k_zz >= k_steady = Q L/(A dT) (Thomson)."""
    pair = np.asarray(pair, dtype=np.int64)
    h = np.asarray(conductance_w_k, dtype=float)
    n = np.asarray(position).shape[0]
    side = np.zeros(n, dtype=np.int8)
    side[np.asarray(held_low, dtype=np.int64)] = -1
    side[np.asarray(held_high, dtype=np.int64)] = 1
    coord = np.asarray(position, dtype=float)[:, axis].copy()
    coord[side < 0] = plane_low
    coord[side > 0] = plane_high
    si, sj = side[pair[:, 0]], side[pair[:, 1]]
    use = (h > 0) & ~((si != 0) & (si == sj))
    lvec = np.asarray(branch, dtype=float)[use].copy()
    i, j = pair[use, 0], pair[use, 1]
    # the axial component between the (moved) ends, in the branch's direction i -> j
    lvec[:, axis] = coord[j] - coord[i]
    volume = float(area_m2) * float(plane_high - plane_low)
    k = (lvec * h[use, None]).T @ lvec / volume
    return AffineEstimate(k=k, volume_m3=volume, n_contacts=int(use.sum()))


def axial_cosines_squared(branch, axis) -> np.ndarray:
    """n_axis^2 of each contact normal (branch / |branch|)."""
    b = np.asarray(branch, dtype=float)
    length2 = np.einsum("ij,ij->i", b, b)
    return np.divide(b[:, axis] ** 2, length2, out=np.zeros(b.shape[0]), where=length2 > 0)


def mean_nz2(branch, mask, axis, weights=None) -> float:
    """<n_z^2> over the contacts in ``mask`` (1/3 for an isotropic fabric), optionally weighted
    (e.g. by the conductance: the direction that carries the heat)."""
    c2 = axial_cosines_squared(branch, axis)[np.asarray(mask, bool)]
    if c2.size == 0:
        return float("nan")
    w = None if weights is None else np.asarray(weights, float)[np.asarray(mask, bool)]
    return float(np.average(c2, weights=w))


def contact_angle_pdf(branch, mask, axis, bins=18):
    """PDF of the angle phi_c in [0, pi/2] between a contact normal and ``axis`` (the polar
    angle of 003 Fig. 5, folded: a contact and its reverse are one). Returns (edges, pdf); an
    isotropic fabric has pdf = sin(phi_c)."""
    c2 = axial_cosines_squared(branch, axis)[np.asarray(mask, bool)]
    angle = np.arccos(np.sqrt(np.clip(c2, 0.0, 1.0)))
    edges = np.linspace(0.0, np.pi / 2, bins + 1)
    pdf, _ = np.histogram(angle, bins=edges, density=True)
    return edges, pdf


def love_weber_stress(branch, normal_force_n, volume_m3) -> np.ndarray:
    """The mean stress carried by the contacts (Love-Weber), sigma_ij = (1/V) sum_c F_c n_i l_j,
    Pa (compression positive); n = l/|l|. Over a bed's particle-particle contacts and the bed's
    volume, sigma_zz is the plate's pressure (plus the weight of the bed above, minus the share
    of the wall contacts): the vertical component of the contact fabric cannot vanish while the
    bed carries the plate."""
    b = np.asarray(branch, dtype=float)
    length = np.linalg.norm(b, axis=1)
    f = np.asarray(normal_force_n, dtype=float)
    use = (length > 0) & (f > 0)
    n = b[use] / length[use, None]
    return (n * f[use, None]).T @ b[use] / float(volume_m3)
