"""Heat flux per particle (Haddad 2021, 002 eq. 20) and its Halo smoothing (eq. 22-23).

eq. 20: the flux of particle p is the volume average of its contact heat flows,
    q_p = phi / (2 V_p) sum_q H_pq (T_p - T_q) l_pq        (W/m^2)
with l_pq the branch vector from p to q (H_pq d_pq (T_p - T_q) is the paper's phi_pq, times the
unit vector e_pq), the sign chosen so that q points from hot to cold (q = -k grad T).
eq. 22-23 (Halo): the same average over every particle r whose centre lies within the halo
radius R_halo of p: q_p = phi sum_r m_r / (2 sum_r V_r), m_r = sum_q H_rq (T_r - T_q) l_rq.
002 sec. 3: the Halo "has a radius R_Halo and contains a pre-defined number of DE", and its size
is read as a "Halo-DE radius ratio". The halo radius is chosen by ``halo_radius``:
  - "common" (the default, 002's reading): R_halo = ratio x r_mean for every particle, r_mean the
    arithmetic (number) mean radius of the packing. Every halo then holds about the same number of
    spheres, phi ratio^3 r_mean^3 / <r^3> (~ 0.5 ratio^3 for radii of sigma/mu 0.3), as the
    paper's "pre-defined number of DE"; the number mean is the "radius of the DE" a packing is
    described by (the r_mean of every tdem report); 002 gives no size distribution
    ("polydisperse"), and for narrow radii any mean gives nearly the same ratio;
  - "own": R_halo = ratio x R_p, p's own radius (tdem before issue 23): the halos of the large
    spheres reach ~2x further than the common one, those of the small ones hold few spheres.
A uniform gradient on a regular lattice gives the exact flux at every interior particle, for any
halo (tested). The coefficient of variation of |q| over the particles whose halo stays inside the
domain measures the scatter the halo removes (002 Fig. 10); eq. 20's 1/V_p makes the raw
statistic, counted per particle, dominated by the small spheres: ``weights`` = V_p gives it per
unit solid volume.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

HALO_RADII = ("common", "own")


def check_halo_radius(halo_radius) -> str:
    """``halo_radius`` if it is one of HALO_RADII, else a one-line ValueError."""
    if not isinstance(halo_radius, str) or halo_radius not in HALO_RADII:
        raise ValueError(f"halo_radius: expected one of {', '.join(map(repr, HALO_RADII))} "
                         f"(the Halo radius is ratio x the packing's mean radius, or ratio x "
                         f"each particle's own radius), got {halo_radius!r}")
    return halo_radius


def reference_radius(radius_m) -> float:
    """r_mean of the "common" halo: the arithmetic mean radius of the packing."""
    return float(np.mean(np.asarray(radius_m, float)))


def halo_radii(radius_m, halo_ratio, halo_radius="common"):
    """(N,) halo radius of every particle: ratio x r_mean ("common") or ratio x R_p ("own")."""
    check_halo_radius(halo_radius)
    radius_m = np.asarray(radius_m, float)
    if halo_radius == "own":
        return halo_ratio * radius_m
    return np.full(len(radius_m), halo_ratio * reference_radius(radius_m))


def contact_moments(n_particles, pair, branch_m, conductance_w_k, temperature_k):
    """(N, 3) m_p = sum_q H_pq (T_p - T_q) l_pq (W m), each contact counted for both ends."""
    i, j = np.asarray(pair).T
    flow = np.asarray(conductance_w_k) * (temperature_k[i] - temperature_k[j])     # i -> j, W
    contrib = flow[:, None] * np.asarray(branch_m)
    m = np.zeros((n_particles, 3))
    np.add.at(m, i, contrib)
    np.add.at(m, j, contrib)          # (T_j - T_i)(l_ji) = (T_i - T_j) l_ij: the same vector
    return m


def particle_flux(position_m, radius_m, pair, branch_m, conductance_w_k, temperature_k,
                  solid_fraction, halo_ratio=0.0, halo_radius="common"):
    """(N, 3) heat flux per particle, W/m^2: eq. 20 (halo_ratio 0) or the Halo average of
    eq. 22-23 over the particles within the halo radius of p (``halo_radius``: "common",
    ratio x the mean radius, or "own", ratio x R_p)."""
    check_halo_radius(halo_radius)
    n = len(radius_m)
    m = contact_moments(n, pair, branch_m, conductance_w_k, np.asarray(temperature_k, float))
    volume = 4.0 / 3.0 * np.pi * np.asarray(radius_m) ** 3
    if halo_ratio <= 0:
        return solid_fraction * m / (2.0 * volume[:, None])
    return halo_flux(position_m, radius_m, m, volume, solid_fraction, halo_ratio,
                     halo_radius=halo_radius)


def halo_members(position_m, radius_m, particles, halo_ratio, halo_radius="common", tree=None):
    """[array of member indices] of the halo of each particle of ``particles``: every particle
    whose centre lies within p's halo radius (halo_radii) of p's centre, p included."""
    position_m = np.asarray(position_m, float)
    particles = np.asarray(particles)
    reach = halo_radii(radius_m, halo_ratio, halo_radius)[particles]
    tree = cKDTree(position_m) if tree is None else tree
    return [np.asarray(x, np.int64) for x in tree.query_ball_point(position_m[particles], reach)]


def halo_flux(position_m, radius_m, moments, volume_m3, solid_fraction, halo_ratio,
              particles=None, chunk=4096, tree=None, halo_radius="common"):
    """(P, 3) Halo flux (002 eq. 22-23) of the particles ``particles`` (default all, P = N)
    from the contact moments m_r of contact_moments: phi sum_r m_r / (2 sum_r V_r) over the
    particles r of p's halo (halo_members; ``halo_radius`` "common": ratio x the packing's mean
    radius, "own": ratio x R_p). Done ``chunk`` particles at a time (one neighbour list per
    chunk, summed with np.add.reduceat), so memory stays bounded at 1e5-1e6 particles and large
    halos (ratio 11 holds ~700 spheres)."""
    position_m = np.asarray(position_m, float)
    radius_m = np.asarray(radius_m, float)
    moments = np.asarray(moments, float)
    volume_m3 = np.asarray(volume_m3, float)
    particles = np.arange(len(radius_m)) if particles is None else np.asarray(particles)
    reach = halo_radii(radius_m, halo_ratio, halo_radius)
    tree = cKDTree(position_m) if tree is None else tree
    out = np.empty((len(particles), 3))
    for start in range(0, len(particles), chunk):
        sel = particles[start:start + chunk]
        lists = tree.query_ball_point(position_m[sel], reach[sel])
        counts = np.fromiter((len(x) for x in lists), np.int64, len(lists))
        members = np.fromiter((k for x in lists for k in x), np.int64, int(counts.sum()))
        offsets = np.concatenate(([0], np.cumsum(counts)[:-1]))
        m_sum = np.add.reduceat(moments[members], offsets, axis=0)
        v_sum = np.add.reduceat(volume_m3[members], offsets)
        out[start:start + len(sel)] = solid_fraction * m_sum / (2.0 * v_sum[:, None])
    return out


def coefficient_of_variation(flux, mask=None, weights=None):
    """std / mean of |q| over the particles in ``mask`` (default all); with ``weights`` (e.g.
    the particle volumes V_p) the weighted mean and the weighted (population) std."""
    magnitude = np.linalg.norm(flux, axis=1)
    w = None if weights is None else np.asarray(weights, float)
    if mask is not None:
        magnitude = magnitude[mask]
        w = None if w is None else w[mask]
    if w is None:
        return float(magnitude.std() / magnitude.mean())
    mean = float(np.sum(w * magnitude) / np.sum(w))
    return float(np.sqrt(np.sum(w * (magnitude - mean) ** 2) / np.sum(w)) / mean)
