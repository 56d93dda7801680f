"""The dense generator's pure part (``dense_packing.py`` runs it under YADE): radii, the
domain, the initial cloud, the stiffness stages, the tiling of a relaxed periodic cell, the
phases (inclusions and a random dispersion), the contacts of the relaxed state from arrays, and
the solid fractions. numpy, scipy and the standard library only: tested by plain pytest, and
``dense_params.check`` runs the domain check here in ``tdem pack`` before YADE starts.
"""
import math

import numpy as np

from .neighbours import neighbour_pairs
from .placement import equal_spheres_for_volume, random_sequential_addition
from .tiling import carve, repetitions, tile

CLOUD_BATCH = 4096             # candidates drawn at a time by the cloud (one stream for all)
CLOUD_MAX_TRIES = 100000       # candidates of one sphere before the cloud gives up
DISPERSION_MAX_TRIES = 100000  # candidates of the whole dispersion


class CloudError(RuntimeError):
    """The initial cloud could not be placed (a run failure, exit status 3)."""


def draw_radii(p):
    """Seeded radii: uniform in mean (1 +- spread), or a normal of sigma/mean truncated at
    +- radius_truncation_sigmas (and above 0.1 mean) by rejection."""
    rng = np.random.default_rng(p["seed"])
    rm, n = p["radius_mean_m"], p["n_particles"]
    if p["radius_distribution"] == "uniform":
        return rm * (1 + p["radius_spread"] * (2 * rng.random(n) - 1))
    s = p["radius_sigma_over_mean"]
    lo = max(0.1, 1 - p["radius_truncation_sigmas"] * s)
    hi = 1 + p["radius_truncation_sigmas"] * s
    out = np.empty(0)
    while out.size < n:
        x = 1 + s * rng.standard_normal(2 * n)
        out = np.concatenate([out, x[(x >= lo) & (x <= hi)]])
    return rm * out[:n]


class Container:
    """The domain the packing fills: a periodic cell, a box, a cylinder along z or a sphere.
    Sized so that the requested spheres fill it at the expected final solid fraction."""

    def __init__(self, shape, volume, aspect):
        self.shape = shape
        a = np.asarray(aspect, dtype=float)
        if shape in ("box", "periodic"):
            self.size = (volume / a.prod()) ** (1.0 / 3.0) * a
            self.radius = float("nan")
        elif shape == "cylinder":
            # aspect z/x is length/diameter: volume = pi R^2 * (2 R * ratio)
            ratio = a[2] / a[0]
            self.radius = (volume / (2.0 * math.pi * ratio)) ** (1.0 / 3.0)
            self.size = np.array([2 * self.radius, 2 * self.radius, 2 * self.radius * ratio])
        else:
            self.radius = (3.0 * volume / (4.0 * math.pi)) ** (1.0 / 3.0)
            self.size = np.full(3, 2 * self.radius)
        self.centre = self.size / 2
        self.volume = volume

    def inside(self, c, r):
        """True where a sphere of radius r centred at c lies wholly inside (walled shapes)."""
        if self.shape == "periodic":
            return np.ones(len(np.atleast_2d(c)), bool)
        c = np.atleast_2d(c)
        r = np.broadcast_to(r, len(c))
        if self.shape == "box":
            return np.all((c - r[:, None] >= 0) & (c + r[:, None] <= self.size), axis=1)
        if self.shape == "cylinder":
            rad = np.hypot(c[:, 0] - self.centre[0], c[:, 1] - self.centre[1])
            return (rad + r <= self.radius) & (c[:, 2] - r >= 0) & (c[:, 2] + r <= self.size[2])
        return np.linalg.norm(c - self.centre, axis=1) + r <= self.radius

    def inside_scalar(self):
        """inside() for one sphere as plain floats: f(x, y, z, r) -> bool (the cloud's hot loop)."""
        sx, sy, sz = (float(v) for v in self.size)
        cx, cy, cz = (float(v) for v in self.centre)
        rad = float(self.radius)
        if self.shape == "periodic":
            return lambda x, y, z, r: True
        if self.shape == "box":
            return lambda x, y, z, r: (x - r >= 0 and y - r >= 0 and z - r >= 0 and
                                       x + r <= sx and y + r <= sy and z + r <= sz)
        if self.shape == "cylinder":
            return lambda x, y, z, r: (math.hypot(x - cx, y - cy) + r <= rad and z - r >= 0
                                       and z + r <= sz)
        return lambda x, y, z, r: (math.sqrt((x - cx) ** 2 + (y - cy) ** 2 + (z - cz) ** 2) + r
                                   <= rad)

    def walls(self):
        walls = []
        if self.shape in ("box", "cylinder"):
            axes = "xyz" if self.shape == "box" else "z"
            for name in axes:
                axis = "xyz".index(name)
                for sign, suffix in ((+1.0, "min"), (-1.0, "max")):
                    point = self.centre.copy() if self.shape == "cylinder" else np.zeros(3)
                    point[axis] = 0.0 if sign > 0 else self.size[axis]
                    normal = np.zeros(3)
                    normal[axis] = sign
                    walls.append(dict(name=name + suffix, kind="plane", point=point,
                                      normal=normal, radius=float("nan")))
        if self.shape == "cylinder":
            walls.append(dict(name="cylinder", kind="cylinder",
                              point=np.array([self.centre[0], self.centre[1], 0.0]),
                              normal=np.array([0.0, 0.0, 1.0]), radius=self.radius))
        if self.shape == "sphere":
            walls.append(dict(name="surface", kind="sphere", point=self.centre.copy(),
                              normal=np.array([0.0, 0.0, 1.0]), radius=self.radius))
        return walls

    def distance_to_wall(self, wall, position):
        """Distance from each centre to a wall, positive inside the domain."""
        if wall["kind"] == "plane":
            return (position - wall["point"]) @ wall["normal"]
        if wall["kind"] == "cylinder":
            return wall["radius"] - np.hypot(position[:, 0] - wall["point"][0],
                                             position[:, 1] - wall["point"][1])
        return wall["radius"] - np.linalg.norm(position - wall["point"], axis=1)


def icosphere(level):
    """The spherical container's facets: a regular icosahedron inscribed in the unit sphere,
    each triangle split into four ``level`` times, the new vertices pushed out onto the sphere.
    Returns (vertices (V, 3), triangles (20 4^level, 3) of vertex indices). Its triangles are
    nearly equal (unlike a latitude-longitude sphere, whose slivers at the poles pair with many
    near-wall spheres in YADE's collider): for the same sag, fewer and more compact facets."""
    t = (1.0 + math.sqrt(5.0)) / 2.0
    corners = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
               (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    vertices = [np.array(c, dtype=float) / math.sqrt(1.0 + t * t) for c in corners]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
             (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
             (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(level):
        middle = {}

        def mid(a, b, middle=middle):
            key = (min(a, b), max(a, b))
            if key not in middle:
                x = vertices[a] + vertices[b]
                vertices.append(x / np.linalg.norm(x))
                middle[key] = len(vertices) - 1
            return middle[key]
        split = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            split += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = split
    return np.array(vertices), np.array(faces, dtype=np.int64)


def facet_sag(shape, radius, segments=48, level=3):
    """How far (m) the facet container lies inside the analytic cylinder or sphere of
    ``radius`` at most (its vertices are on the analytic surface, its flat facets sag between
    them): YADE's ``geom.facetCylinder`` with ``segments`` sides, R (1 - cos(pi / n)); the
    :func:`icosphere` of ``level``, R minus its smallest distance from the centre to a facet's
    plane (exact; 0.0046 R at level 3). 0 for a box or a periodic cell."""
    if shape == "cylinder":
        return radius * (1.0 - math.cos(math.pi / segments))
    if shape == "sphere":
        v, f = icosphere(level)
        normal = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
        normal /= np.linalg.norm(normal, axis=1)[:, None]
        return radius * (1.0 - float(np.min(np.abs(np.einsum("ij,ij->i", normal, v[f[:, 0]])))))
    return 0.0


def check_facet_sag(p, radii, box):
    """ValueError('wall_segments: ...' / 'sphere_facet_level: ...') when a sphere of the
    initial cloud, placed inside the analytic container, could have its centre beyond a facet:
    the contact would push it out and it would leave the container (measured: a 2,000-sphere
    sphere container of 16 x 8 latitude-longitude facets lost one, which flew off and made
    YADE's collider run every step)."""
    if box.shape not in ("cylinder", "sphere"):
        return
    smallest = float(radii.min()) * cloud_shrink(box.shape)
    if box.shape == "cylinder":
        key, step = "wall_segments", 2

        def sag(n):
            return facet_sag("cylinder", box.radius, segments=n)
    else:
        key, step = "sphere_facet_level", 1

        def sag(level):
            return facet_sag("sphere", box.radius, level=level)
    value = p[key]
    if sag(value) < smallest:
        return
    need = value
    while sag(need) >= smallest:
        need += step
    raise ValueError(f"{key}: the {box.shape}'s facets sag {sag(value):.3g} m inside its radius "
                     f"{box.radius:.4g} m, more than the smallest sphere of the initial cloud "
                     f"({smallest:.3g} m), which could start outside them and leave the "
                     f"container; expected at least {need}, got {value}")


EXPECTED_SOLID_FRACTION = {"periodic": 0.64, "box": 0.60, "cylinder": 0.60, "sphere": 0.60}
CLOUD_SOLID_FRACTION = 0.25
FREE_GROWTH_SOLID_FRACTION = 0.5


def cloud_shrink(shape):
    """The factor the drawn radii are shrunk by in the initial cloud, so that it fills the
    container (sized for the final solid fraction) at CLOUD_SOLID_FRACTION."""
    return (CLOUD_SOLID_FRACTION / EXPECTED_SOLID_FRACTION[shape]) ** (1.0 / 3.0)


def relaxed_params(p):
    """The parameters of what YADE relaxes: the domain itself, or for method = "tiled" a
    periodic cell of cell_particles spheres (also for method = "shell", which copies it)."""
    if p["method"] in ("tiled", "shell"):
        return dict(p, shape="periodic", n_particles=p["cell_particles"])
    return p


def cloud_domain(p, count_key="n_particles"):
    """Seeded radii (largest first) and the container sized for them at the final solid
    fraction expected for its shape. ValueError('key: ...') when the parameters cannot make a
    domain (a parameter check: ``dense_params.check`` runs it before YADE starts, naming
    ``count_key``, the key that sets the number of spheres relaxed)."""
    radii = np.sort(draw_radii(p))[::-1]
    if np.asarray(p["aspect"], dtype=float).shape != (3,):
        raise ValueError("aspect: expected 3 numbers")
    volume = np.sum(4.0 / 3.0 * np.pi * radii ** 3) / EXPECTED_SOLID_FRACTION[p["shape"]]
    box = Container(p["shape"], volume, p["aspect"])
    if 2.2 * radii[0] > box.size.min() / 2:
        raise ValueError(f"{count_key}: too few particles for this shape and aspect (the domain "
                         "must be wider than four diameters)")
    check_facet_sag(p, radii, box)
    return radii, box


def make_cloud(p):
    """Seeded radii and a random sequential addition of them (largest first, shrunk so that
    they fill the container at solid fraction 0.25): a loose, overlap-free start. The
    container is sized for the final solid fraction expected for its shape; the radii grow
    back during compression to whatever size the confining pressure gives.

    Candidates are uniform in the container's box, drawn CLOUD_BATCH at a time from one stream
    (seed + 1) shared by all spheres; a sphere that finds no place in CLOUD_MAX_TRIES
    candidates raises CloudError. Returns (centres, shrunk radii, container, drawn radii)."""
    radii, box = cloud_domain(p)
    n = radii.size
    small = radii * cloud_shrink(p["shape"])
    rng = np.random.default_rng(p["seed"] + 1)
    periodic = p["shape"] == "periodic"
    stream = {"buffer": [], "used": 0}

    def candidates(k, r):
        for _ in range(CLOUD_MAX_TRIES):
            if stream["used"] == len(stream["buffer"]):
                stream["buffer"] = (rng.random((CLOUD_BATCH, 3)) * box.size).tolist()
                stream["used"] = 0
            x, y, z = stream["buffer"][stream["used"]]
            stream["used"] += 1
            yield x, y, z

    centres = random_sequential_addition(small, candidates, inside=box.inside_scalar(),
                                         cell=box.size if periodic else None)
    if len(centres) < n:
        raise CloudError("n_particles: could not place the initial cloud")
    return centres, small, box, radii


def stiffness_stages(p):
    """Young's moduli of the compression stages: a softened start (overlaps ~1 % of the radius
    at the confining stress) raised tenfold per stage to the real modulus. Softening is only
    for speed (steps to jam scale with sqrt(E)); every stage re-relaxes under the same stress,
    so the dumped network is the one of the real modulus (FINDINGS: softening changes the
    network, not only the overlaps)."""
    real = p["young_pa"]
    soft = min(real, p["softening_factor"] * p["confining_pressure_pa"])
    stages = [soft]
    factor = p["stiffen_factor"]
    while stages[-1] * factor < real:
        stages.append(stages[-1] * factor)
    if stages[-1] < real:
        stages.append(real)
    return stages


# YADE's Hertz-Mindlin gives a sphere-wall contact R* = r/2 (Ig2_Wall_Sphere: the wall acts as a
# sphere of the same radius) and a sphere-facet contact R* = 2r/3 (the facet acts as a sphere of
# radius 2r), where a sphere on a rigid-shaped plane has R* = r. The walls get a modulus E_w such
# that YADE's contact modulus E_w E / ((1 - nu^2)(E_w + E)) times sqrt(R*_yade) equals
# E / (2 (1 - nu^2)) sqrt(r): E_w / (E_w + E) = c / 2 with c = sqrt(r / R*_yade), i.e.
# E_w = E c / (2 - c). Every dumped wall contact then follows Hertz with R* = r and the
# particle pair's E* = E / (2 (1 - nu^2)) (a wall of the particles' own material).
WALL_YOUNG_FACTOR = {kind: c / (2.0 - c) for kind, c in
                     (("plane", math.sqrt(2.0)), ("facet", math.sqrt(1.5)))}


def tile_cell(p, cell_box, position, radius, pair, branch, overlap, normal_force,
              contact_radius):
    """method = "tiled": copies of the relaxed periodic cell side by side, carved to the
    requested shape (yade_scripts/tiling.py). The domain is sized for n_particles at the
    cell's solid fraction; returns the carved arrays, its walls (cut surfaces) and the
    attributes that describe the tiling."""
    cell = cell_box.size
    phi_cell = float(np.sum(4.0 / 3.0 * np.pi * radius ** 3) / cell_box.volume)
    mean_volume = float(np.mean(4.0 / 3.0 * np.pi * radius ** 3))
    box = Container(p["shape"], p["n_particles"] * mean_volume / phi_cell, p["aspect"])
    reps = repetitions(cell, box.size)
    position_t, source, pair_t, pair_source = tile(position, cell, pair, branch, reps)
    keep = box.inside(position_t, np.zeros(len(position_t)))
    new_index, rows, pair_c = carve(keep, pair_t)
    rows_cell = pair_source[rows]
    position = position_t[keep]
    radius = radius[source[keep]]
    walls = box.walls()
    wall_particle, wall_index, wall_overlap = [], [], []
    for w, wall in enumerate(walls):
        dist = box.distance_to_wall(wall, position)
        near = np.flatnonzero(dist < (1.0 + p["wall_gap_tolerance"]) * radius)
        wall_particle.append(near)
        wall_index.append(np.full(len(near), w, dtype=np.int32))
        wall_overlap.append(radius[near] - dist[near])
    wall_particle = np.concatenate(wall_particle).astype(np.int64)
    info = {"cell_particles": int(len(source) // int(np.prod(reps))),
            "cell_size_m": np.asarray(cell, dtype=float),
            "periodicity_length_m": np.asarray(cell, dtype=float),
            "tiles": int(np.prod(reps)), "tile_repetitions": np.asarray(reps, dtype=np.int64),
            "cell_solid_fraction": phi_cell}
    return (box, position, radius, pair_c, branch[rows_cell], overlap[rows_cell],
            normal_force[rows_cell], contact_radius[rows_cell], walls, wall_particle,
            np.concatenate(wall_index), np.concatenate(wall_overlap),
            np.zeros(len(wall_particle)), info)


def dispersion_centres(p, mean_radius, box, periodic):
    """Random dispersion: centres of non-overlapping inclusions of radius
    inclusion_radius_over_mean x mean_radius, wholly inside a walled domain (anywhere in a
    periodic one, by the minimum image), added until their volume reaches
    inclusion_volume_fraction of the domain or DISPERSION_MAX_TRIES candidates are spent
    (seed + 7919). Returns (centres (m, 3), inclusion radius)."""
    rng = np.random.default_rng(p["seed"] + 7919)
    r_inc = p["inclusion_radius_over_mean"] * mean_radius
    count = equal_spheres_for_volume(p["inclusion_volume_fraction"] * box.volume,
                                     4.0 / 3.0 * math.pi * r_inc ** 3)
    lo, extent = np.zeros(3), box.size.copy()
    spent = {"tries": 0}

    def candidates(k, r):
        while spent["tries"] < DISPERSION_MAX_TRIES:
            spent["tries"] += 1
            c = lo + rng.random(3) * extent
            yield c[0], c[1], c[2]

    def inside(x, y, z, r):
        return bool(box.inside(np.array([x, y, z]), r)[0])

    centres = random_sequential_addition([r_inc] * count, candidates,
                                         inside=None if periodic else inside,
                                         cell=box.size if periodic else None)
    return centres, r_inc


def assign_phases(p, position, radius, box, periodic):
    """Phase of every particle: 0, or the phase of the inclusion its centre lies in - the
    listed spherical inclusions (fractions of the domain box), then the random dispersion.
    Returns (phase (n,) int32, number of dispersed inclusions)."""
    lo, hi = np.zeros(3), box.size.copy()
    phase = np.zeros(len(position), dtype=np.int32)
    extent = hi - lo
    for inc in p["inclusions"]:
        c = lo + np.asarray(inc["centre"], dtype=float) * extent
        rr = float(inc["radius"]) * extent.min()
        phase[np.linalg.norm(position - c, axis=1) <= rr] = int(inc.get("phase", 1))
    if p["inclusion_volume_fraction"] <= 0:
        return phase, 0
    centres_inc, r_inc = dispersion_centres(p, float(radius.mean()), box, periodic)
    for c in centres_inc:
        d = position - c
        if periodic:
            d -= np.round(d / box.size) * box.size
        phase[np.linalg.norm(d, axis=1) <= r_inc] = p["inclusion_phase"]
    return phase, len(centres_inc)


def solid_fractions(position, radius, box, periodic):
    """(solid fraction, bulk solid fraction): the bulk one leaves out a layer of two mean
    diameters along the walls, spheres counted wholly by centre (the wall layer is looser: its
    fraction is the difference to solid_fraction)."""
    volume = 4.0 / 3.0 * np.pi * radius ** 3
    phi = float(volume.sum() / box.volume)
    phi_bulk = phi
    if not periodic:
        layer = 4.0 * float(radius.mean())
        if box.shape == "box":
            inside = np.all(np.abs(position - box.centre) <= box.size / 2 - layer, axis=1)
            inner_volume = float(np.prod(box.size - 2 * layer))
        elif box.shape == "cylinder":
            rad = np.hypot(position[:, 0] - box.centre[0], position[:, 1] - box.centre[1])
            inside = (rad <= box.radius - layer) & \
                (np.abs(position[:, 2] - box.centre[2]) <= box.size[2] / 2 - layer)
            inner_volume = math.pi * (box.radius - layer) ** 2 * (box.size[2] - 2 * layer)
        else:
            inside = np.linalg.norm(position - box.centre, axis=1) <= box.radius - layer
            inner_volume = 4.0 / 3.0 * math.pi * (box.radius - layer) ** 3
        phi_bulk = float(volume[inside].sum() / inner_volume) if inner_volume > 0 else phi
    return phi, phi_bulk


def relaxed_contacts(position, radius, gap_tolerance, cell, force):
    """The contacts of the relaxed state from its arrays: every pair within
    (1 + gap_tolerance)(r_i + r_j) (minimum image in a periodic ``cell``), its overlap
    r_i + r_j - |branch| and contact radius, and YADE's normal force from ``force``
    {(i, j): |F_n|} (0 for a gap). Returns (pair, branch, overlap, normal_force,
    contact_radius, touching pairs that YADE had not paired yet)."""
    pair, branch = neighbour_pairs(position, radius, gap_tolerance, cell)
    distance = np.linalg.norm(branch, axis=1)
    overlap = radius[pair[:, 0]] + radius[pair[:, 1]] - distance
    r_star = radius[pair[:, 0]] * radius[pair[:, 1]] / (radius[pair[:, 0]] + radius[pair[:, 1]])
    normal_force = np.zeros(len(pair))
    n_untracked = 0
    for k, (a, b) in enumerate(pair):
        if overlap[k] > 0:
            f = force.get((int(a), int(b)))
            if f is None:
                n_untracked += 1      # touching by < round-off, not yet paired by YADE
            else:
                normal_force[k] = f
    contact_radius = np.sqrt(np.clip(overlap, 0, None) * r_star)
    return pair, branch, overlap, normal_force, contact_radius, n_untracked


def relaxed_wall_contacts(box, walls, position, radius, wall_gap_tolerance, wall_touch):
    """Wall contacts: every particle YADE has in contact with a wall, ``wall_touch``
    {(particle, wall): (depth, |F_n|)} (the cylinder mantle and the spherical container are
    facet polygons), plus the near-wall particles within (1 + wall_gap_tolerance) r of the
    analytic wall surface (negative overlap, zero force). Returns (particle, wall, overlap,
    force) arrays."""
    wall_particle, wall_index, wall_overlap, wall_force = [], [], [], []
    for w, wall in enumerate(walls):
        dist = box.distance_to_wall(wall, position)
        near = set(np.flatnonzero(dist < (1.0 + wall_gap_tolerance) * radius).tolist())
        near |= {q for (q, ww) in wall_touch if ww == w}
        for q in sorted(near):
            wall_particle.append(q)
            wall_index.append(w)
            if (q, w) in wall_touch:
                wall_overlap.append(wall_touch[(q, w)][0])
                wall_force.append(wall_touch[(q, w)][1])
            else:
                wall_overlap.append(min(radius[q] - dist[q], 0.0))
                wall_force.append(0.0)
    return (np.array(wall_particle, dtype=np.int64), np.array(wall_index, dtype=np.int32),
            np.array(wall_overlap, dtype=float), np.array(wall_force, dtype=float))
