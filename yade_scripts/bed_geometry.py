"""The compressed bed's pure part (``compressed_bed.py`` runs it under YADE): the equal-area
prism of the cylinder, the initial random cloud, the wall modulus that makes YADE's wall contacts
Hertz with R* = r, the contact damping ratio, and the contact arrays of a dump computed from the
interactions YADE reports. numpy and the standard library only: tested by plain pytest.
"""
import math

import numpy as np

from .placement import random_sequential_addition

CLOUD_BATCH = 64          # candidates drawn at a time for one sphere of the cloud
CLOUD_JAM_TRIES = 20000   # rejected candidates of one sphere after which the cloud grows 5 %


def prism(radius, segments):
    """Equal-area regular prism: (vertex radius, apothem, half side length)."""
    phi = math.pi / segments
    vertex = radius * math.sqrt(2.0 * math.pi / (segments * math.sin(2.0 * phi)))
    return vertex, vertex * math.cos(phi), vertex * math.sin(phi)


def wall_sim_modulus(young, poisson, wall_young, wall_poisson):
    """Young's modulus of the simulated wall material that makes YADE's wall contact (radius r/2)
    equal to Hertz with R* = r and the real particle/wall E*; None if no finite modulus does."""
    inv_real = (1.0 - poisson ** 2) / young + (1.0 - wall_poisson ** 2) / wall_young
    rest = inv_real / math.sqrt(2.0) - (1.0 - poisson ** 2) / young
    if rest <= 0.0:
        return None
    return (1.0 - wall_poisson ** 2) / rest


def damping_ratio(restitution):
    """Contact damping ratio (YADE's betan) that gives the normal restitution coefficient:
    Tsuji's coefficient, which YADE uses for ``en``, written per critical damping
    2 sqrt(m k_n) of the tangent Hertz stiffness: beta = sqrt(5/6) (-ln e) / sqrt(ln^2 e + pi^2).
    Unlike ``en`` (a coefficient fixed when the contact is made), it follows the modulus when
    the bed is re-stiffened."""
    if restitution >= 1.0:
        return 0.0
    log_e = math.log(restitution)
    return math.sqrt(5.0 / 6.0) * -log_e / math.sqrt(log_e ** 2 + math.pi ** 2)


def pressure_name(p):
    return f"packing_{p:.4g}Pa.h5"


def random_cloud(n, r_mean, spread, inner_radius, solid_fraction, seed):
    """Random sequential addition of n non-overlapping spheres (largest first, kept 1e-3 r_mean
    apart) in a cylinder of radius inner_radius, from z = 0 upward, its height set by the solid
    fraction. Returns positions (sorted by height), radii and the height; deterministic for a
    seed.

    Each sphere draws its candidates CLOUD_BATCH at a time (uniform in the cylinder's
    cross-section and height); after CLOUD_JAM_TRIES rejections of one sphere the height grows
    by 5 % (jammed: a little more room). The search grid's cells are 2 r_max wide."""
    rng = np.random.default_rng(seed)
    radii = np.sort(r_mean * (1.0 + spread * rng.uniform(-1.0, 1.0, n)))[::-1]
    volume = 4.0 / 3.0 * math.pi * float(np.sum(radii ** 3))
    room = {"height": volume / (solid_fraction * math.pi * inner_radius ** 2)}
    gap = 1e-3 * r_mean

    def candidates(k, rk):
        tries = 0
        while True:
            u = rng.uniform(0.0, 1.0, (CLOUD_BATCH, 3))
            for ur, ut, uz in u:
                tries += 1
                rho = (inner_radius - rk - gap) * math.sqrt(ur)
                th = 2.0 * math.pi * ut
                yield (rho * math.cos(th), rho * math.sin(th),
                       rk + gap + (room["height"] - 2 * rk) * uz)
            if tries > CLOUD_JAM_TRIES:
                room["height"] *= 1.05
                tries = 0

    # Cells of 2 r_max, not 2 r_max + gap: the bed's clouds have always been made so, and this
    # keeps every seed's cloud bit for bit. A pair closer than r_i + r_j + gap in cells two
    # apart (both radii within gap of r_max) is not tested; the clouds of 2,000 and 7,500
    # spheres (seeds 1, 2) come out the same with the exact width.
    pos = random_sequential_addition(radii, candidates, gap=gap,
                                     cell_width=2.0 * float(radii[0]))
    order = np.lexsort((pos[:, 1], pos[:, 0], pos[:, 2]))
    return pos[order], radii[order], room["height"]


# ----------------------------------------------------------------------------- the dump

def hertz_moduli(young_now, young, poisson, wall_young, wall_poisson):
    """E* particle-particle and particle-wall at the modulus in use (the walls are softened by
    the same factor as the particles)."""
    soft = young_now / young
    e_pp = young_now / (2.0 * (1.0 - poisson ** 2))
    e_pw = 1.0 / ((1.0 - poisson ** 2) / young_now
                  + (1.0 - wall_poisson ** 2) / (wall_young * soft))
    return e_pp, e_pw


def dump_contacts(interactions, pos, radii, wall_index, height, e_pp, e_pw):
    """The contact arrays of a dump from YADE's interactions, given as records
    (id1, id2, real, penetration depth (None if not real), kno (None if not real)); bodies
    0 ... n-1 are the spheres, ``wall_index`` maps the other body ids to 0 (bottom), 1 (plate),
    2 (cylinder boxes).

    Overlaps are recomputed from the dumped positions (YADE's penetration depth is one step
    older) so that |branch| = r_i + r_j - overlap holds exactly; the cylinder boxes keep YADE's
    depth. A pair that overlaps but is not yet a real YADE contact (it would become one at the
    next step) gets the Hertz coefficient 4/3 E* sqrt(R*) (R* = r against a wall); a real one
    gets YADE's kno. Returns a dict of arrays (pairs, overlaps, forces = kno overlap^1.5,
    branch, contact_radius and the wall_* arrays), ``undetected`` (pairs not yet real) and
    ``kno_mismatch`` (largest relative difference of YADE's kno to the formula)."""
    n = len(radii)
    pairs, overlaps, kno = [], [], []
    w_particle, w_index, w_overlap, w_kno = [], [], [], []
    yade_kno, hertz_kno = [], []
    undetected = 0
    for a, b, real, penetration, yade_coeff in interactions:
        if a < n and b < n:
            a, b = min(a, b), max(a, b)
            depth = radii[a] + radii[b] - math.dist(pos[a], pos[b])
            if depth <= 0.0:
                continue
            coeff = 4.0 / 3.0 * e_pp * math.sqrt(radii[a] * radii[b] / (radii[a] + radii[b]))
            pairs.append((a, b))
            overlaps.append(depth)
        else:
            particle, wall = (a, b) if a < n else (b, a)
            index = wall_index[wall]
            if index == 0:
                depth = radii[particle] - pos[particle, 2]
            elif index == 1:
                depth = radii[particle] - (height - pos[particle, 2])
            elif real:
                depth = penetration
            else:
                continue
            if depth <= 0.0:
                continue
            coeff = 4.0 / 3.0 * e_pw * math.sqrt(radii[particle])
            w_particle.append(particle)
            w_index.append(index)
            w_overlap.append(depth)
        if real:
            yade_kno.append(yade_coeff)
            hertz_kno.append(coeff)
            coeff = yade_coeff
        else:
            undetected += 1
        if a < n and b < n:
            kno.append(coeff)
        else:
            w_kno.append(coeff)
    mismatch = (float(np.max(np.abs(np.array(yade_kno) / np.array(hertz_kno) - 1.0)))
                if yade_kno else 0.0)
    pairs = np.array(pairs, dtype=np.int64).reshape(-1, 2)
    overlaps = np.array(overlaps)
    forces = np.array(kno) * overlaps ** 1.5
    branch = pos[pairs[:, 1]] - pos[pairs[:, 0]]
    r_i, r_j = radii[pairs[:, 0]], radii[pairs[:, 1]]
    contact_radius = np.sqrt(r_i * r_j / (r_i + r_j) * overlaps)
    w_particle = np.array(w_particle, dtype=np.int64)
    w_index = np.array(w_index, dtype=np.int32)
    w_overlap = np.array(w_overlap)
    w_force = np.array(w_kno) * w_overlap ** 1.5
    w_contact_radius = np.sqrt(radii[w_particle] * w_overlap)
    return dict(pairs=pairs, overlaps=overlaps, forces=forces, branch=branch,
                contact_radius=contact_radius, w_particle=w_particle, w_index=w_index,
                w_overlap=w_overlap, w_force=w_force, w_contact_radius=w_contact_radius,
                undetected=undetected, kno_mismatch=mismatch)
