# Dense polydisperse packing for continuum conduction (Terreros 2012; Haddad 2021, 002 sec. 2).
#
#   yade -n -j1 -x yade_scripts/dense_packing.py params.json
#
# params.json: see dense_params.py (tdem pack writes it from a scene's [pack] table).
# Steps:
# 1. Seeded radii (uniform mean(1 +- spread), or Gaussian sigma/mean truncated) and a random
#    sequential addition of them, shrunk to solid fraction 0.25, into a fixed domain: periodic
#    cell, box (6 plane walls), cylinder along z (plane caps + a facet mantle) or sphere (facet
#    container). The domain is sized for the final solid fraction expected for its shape.
# 2. Compression by uniform radius growth at fixed domain (like YADE's internal compaction)
#    with frictionless Hertz-Mindlin contacts, until YADE's mean stress equals the confining
#    pressure and the unbalanced-force ratio is small. Speed: the first stage uses a softened
#    modulus; E is then raised tenfold per stage to the real modulus, re-relaxing under the
#    same stress at each (softening changes the network, so the network must be the one of the
#    real modulus - FINDINGS.md). Masses are scaled (no gravity: the static state does not
#    depend on them).
# 3. Dump: contacts are rebuilt from the final radii and positions and their forces computed
#    once with the integrator off, so that overlaps, branches and YADE's forces describe the
#    same geometry exactly. With gap_tolerance > 0 the near neighbours within
#    (1 + gap_tolerance)(r_i + r_j) are dumped too (negative overlap, zero force): the neighbour
#    criterion that sets the coordination number (Haddad uses Z ~ 7.5).
# Imports: yade, numpy, h5py and the standard library only.
import math
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(sys.argv[0])))

import numpy as np  # noqa: E402
from yade import O, geom, utils  # noqa: E402
from yade.wrapper import (FrictMat, ForceResetter, InsertionSortCollider,  # noqa: E402
                          Bo1_Sphere_Aabb, Bo1_Wall_Aabb, Bo1_Facet_Aabb, InteractionLoop,
                          Ig2_Sphere_Sphere_ScGeom, Ig2_Wall_Sphere_ScGeom,
                          Ig2_Facet_Sphere_ScGeom, Ip2_FrictMat_FrictMat_MindlinPhys,
                          Law2_ScGeom_MindlinPhys_Mindlin, NewtonIntegrator, Sphere,
                          GlobalStiffnessTimeStepper)
from yade.minieigenHP import Matrix3  # noqa: E402

import params as P  # noqa: E402
from neighbours import neighbour_pairs  # noqa: E402
from tiling import carve, repetitions, tile  # noqa: E402
from tdem_dump import write_packing  # noqa: E402


def fail(message, code=2):
    print("error: " + message, file=sys.stderr, flush=True)
    sys.exit(code)


def log(message):
    print(message, flush=True)


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
        return lambda x, y, z, r: math.sqrt((x - cx) ** 2 + (y - cy) ** 2 + (z - cz) ** 2) + r <= rad

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


EXPECTED_SOLID_FRACTION = {"periodic": 0.64, "box": 0.60, "cylinder": 0.60, "sphere": 0.60}
CLOUD_SOLID_FRACTION = 0.25
FREE_GROWTH_SOLID_FRACTION = 0.5


def make_cloud(p):
    """Seeded radii and a random sequential addition of them (largest first, shrunk so that
    they fill the container at solid fraction 0.25): a loose, overlap-free start. The
    container is sized for the final solid fraction expected for its shape; the radii grow
    back during compression to whatever size the confining pressure gives."""
    radii = np.sort(draw_radii(p))[::-1]
    n = radii.size
    if np.asarray(p["aspect"], dtype=float).shape != (3,):
        fail("aspect: expected 3 numbers")
    volume = np.sum(4.0 / 3.0 * np.pi * radii ** 3) / EXPECTED_SOLID_FRACTION[p["shape"]]
    box = Container(p["shape"], volume, p["aspect"])
    if 2.2 * radii[0] > box.size.min() / 2:
        fail("n_particles: too few particles for this shape and aspect (the domain must be "
             "wider than four diameters)")
    shrink = (CLOUD_SOLID_FRACTION / EXPECTED_SOLID_FRACTION[p["shape"]]) ** (1.0 / 3.0)
    small = radii * shrink
    rng = np.random.default_rng(p["seed"] + 1)
    periodic = p["shape"] == "periodic"
    # A grid of cells at least one largest diameter wide: a candidate can only overlap spheres
    # in its own and the 26 neighbouring cells, so each test is local. Plain Python floats per
    # candidate (numpy calls on 3-vectors cost more than the arithmetic); the draws are the
    # same stream as one rng.random(3) per try, so the accept/reject decisions, and the cloud,
    # are those of the all-pairs test this replaced.
    size = [float(x) for x in box.size]
    ncell = [max(1, int(x // (2.0 * small[0]))) for x in size]
    width = [x / m for x, m in zip(size, ncell)]
    inside = box.inside_scalar()
    grid = {}
    xs, ys, zs, rs = [], [], [], []
    offsets = [(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)]
    buffer, used = [], 0
    for k in range(n):
        rk = float(small[k])
        for _ in range(100000):
            if used == len(buffer):
                buffer, used = (rng.random((4096, 3)) * box.size).tolist(), 0
            x, y, z = buffer[used]
            used += 1
            if not inside(x, y, z, rk):
                continue
            home = (min(int(x / width[0]), ncell[0] - 1), min(int(y / width[1]), ncell[1] - 1),
                    min(int(z / width[2]), ncell[2] - 1))
            near = set()
            for off in offsets:
                key = (home[0] + off[0], home[1] + off[1], home[2] + off[2])
                if periodic:
                    key = (key[0] % ncell[0], key[1] % ncell[1], key[2] % ncell[2])
                near.update(grid.get(key, ()))
            free = True
            for q in near:
                dx, dy, dz = xs[q] - x, ys[q] - y, zs[q] - z
                if periodic:
                    dx -= round(dx / size[0]) * size[0]
                    dy -= round(dy / size[1]) * size[1]
                    dz -= round(dz / size[2]) * size[2]
                if dx * dx + dy * dy + dz * dz - (rs[q] + rk) ** 2 <= 0:
                    free = False
                    break
            if not free:
                continue
            xs.append(x), ys.append(y), zs.append(z), rs.append(rk)
            grid.setdefault(home, []).append(k)
            break
        else:
            fail("n_particles: could not place the initial cloud", code=3)
    centres = np.array([xs, ys, zs]).T
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


def build_scene(p, centres, radii, box, young):
    """YADE scene: spheres, container walls (infinite planes; facet polygons for the cylinder
    mantle and the spherical container), frictionless Hertz-Mindlin contacts."""
    O.reset()
    mat = O.materials.append(FrictMat(
        young=young, poisson=p["poisson"], density=p["density"] * p["density_scaling"],
        frictionAngle=math.atan(p["compaction_friction"])))
    plane_mat = O.materials.append(FrictMat(
        young=young * WALL_YOUNG_FACTOR["plane"], poisson=p["poisson"], density=p["density"],
        frictionAngle=math.atan(p["compaction_friction"])))
    facet_mat = O.materials.append(FrictMat(
        young=young * WALL_YOUNG_FACTOR["facet"], poisson=p["poisson"], density=p["density"],
        frictionAngle=math.atan(p["compaction_friction"])))
    wall_of_body = {}
    if box.shape == "periodic":
        O.periodic = True
        O.cell.hSize = Matrix3(box.size[0], 0, 0, 0, box.size[1], 0, 0, 0, box.size[2])
    for w, wall in enumerate(box.walls()):
        if wall["kind"] == "plane":
            axis = int(np.argmax(np.abs(wall["normal"])))
            ids = [O.bodies.append(utils.wall(tuple(float(x) for x in wall["point"]), axis=axis,
                                              material=plane_mat))]
        elif wall["kind"] == "cylinder":
            ids = O.bodies.append(geom.facetCylinder(
                center=tuple(float(x) for x in box.centre), radius=wall["radius"],
                height=box.size[2], segmentsNumber=p["wall_segments"], wallMask=4, material=facet_mat))
        else:
            ids = O.bodies.append(geom.facetSphere(
                center=tuple(float(x) for x in box.centre), radius=wall["radius"],
                thetaResolution=p["wall_segments"], phiResolution=p["wall_segments"] // 2,
                material=facet_mat))
        for i in ids:
            wall_of_body[i] = w
    collider = InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Wall_Aabb(), Bo1_Facet_Aabb()])
    sphere_ids = [O.bodies.append(utils.sphere(tuple(float(x) for x in c), float(r), material=mat))
                  for c, r in zip(centres, radii)]
    O.engines = [
        ForceResetter(),
        collider,
        InteractionLoop([Ig2_Sphere_Sphere_ScGeom(), Ig2_Wall_Sphere_ScGeom(),
                         Ig2_Facet_Sphere_ScGeom()],
                        [Ip2_FrictMat_FrictMat_MindlinPhys()],
                        [Law2_ScGeom_MindlinPhys_Mindlin()]),
        NewtonIntegrator(damping=p["damping"]),
    ]
    if p["time_step"] == "density_scaling":
        # Every sphere's mass is scaled so that its own critical step (from its current contact
        # stiffnesses) equals targetDt: small spheres no longer set the step of all. The static
        # state does not depend on masses (no gravity), only the path to it does.
        O.engines = O.engines[:-1] + [GlobalStiffnessTimeStepper(
            densityScaling=True, timestepSafetyCoefficient=0.8, timeStepUpdateInterval=10,
            targetDt=1.0), O.engines[-1]]
        # (a property that needs the time stepper already in O.engines)
        O.engines[-1].densityScaling = True
    return (mat, plane_mat, facet_mat), np.array(sphere_ids), wall_of_body, collider


def mean_stress(box):
    stress = utils.getStress() if box.shape == "periodic" else utils.getStress(box.volume)
    return -(stress[0, 0] + stress[1, 1] + stress[2, 2]) / 3.0


def compress(p, centres, radii, box):
    """Fixed container; the radii grow (or shrink) uniformly until the mean stress equals the
    confining pressure and the unbalanced-force ratio is below the target, at each stiffness
    stage. The controller uses Hertz's law: overlaps scale as stress^(2/3), so the radius
    change that brings the stress to its target is ~ delta/R ((p_t/p)^(2/3) - 1)."""
    stages = stiffness_stages(p)
    mats, sphere_ids, wall_of_body, collider = build_scene(p, centres, radii, box, stages[0])
    # density_scaling: radii grow 5x faster while the solid fraction is below 0.5 (the p_wave
    # path keeps the growth of the generator before 2026-11, to stay the reference)
    fast_growth = p["time_step"] == "density_scaling"
    solid_fraction_now = CLOUD_SOLID_FRACTION
    p_target = p["confining_pressure_pa"]
    start = time.time()
    last = -10.0
    young_now = stages[0]
    every = 50
    friction_stage = p["friction"] != p["compaction_friction"]
    if friction_stage:
        stages = stages + [stages[-1]]     # the last relaxation again, with friction
    for k, young in enumerate(stages):
        if young != young_now:
            if k == 1:
                # the soft stage grew the radii a lot: rebuild every contact so that its
                # Hertz constant uses the current radii, then scale them stage by stage
                O.interactions.clear()
                collider.doSort = True
            factor = young / young_now
            for m, scale in zip(mats, (1.0, WALL_YOUNG_FACTOR["plane"],
                                       WALL_YOUNG_FACTOR["facet"])):
                O.materials[m].young = young * scale
            for i in O.interactions:
                if i.isReal:
                    i.phys.kno *= factor
                    i.phys.kso *= factor
            young_now = young
        final = k == len(stages) - 1
        if final and friction_stage:
            # Frictionless compaction gives the densest random packing, but at the real
            # modulus its last relaxation crawls (the unbalanced-force ratio hovers at a few
            # 1e-3 for minutes: floppy modes). Once the frictionless packing is at the target
            # stress at the real modulus (unbalanced < 1e-2), the material's friction is
            # switched on, at rest: the contacts are kept (switched on earlier, while the radii
            # still shrink, it opened contacts: Z 3.9 and 17 % rattlers) and the tangential
            # springs damp the floppy modes.
            tan_phi = p["friction"]
            for m in mats:
                O.materials[m].frictionAngle = math.atan(tan_phi)
            for i in O.interactions:
                if i.isReal:
                    i.phys.tangensOfFrictionAngle = tan_phi
        label = ", friction on" if final and friction_stage else ""
        unbalanced_target = p["unbalanced_force_target"] if final else \
            max(p["unbalanced_force_target"], 1e-2)
        e_star = young / (2.0 * (1.0 - p["poisson"] ** 2))
        overlap_scale = (p_target / e_star) ** (2.0 / 3.0)   # typical delta/R at the target
        if p["time_step"] == "p_wave":
            # the P-wave bound of the smallest sphere, at the stage's modulus
            O.dt = 0.5 * utils.PWaveTimeStep()
        settled = 0
        while True:
            O.run(every, True)
            pressure = mean_stress(box)
            unbalanced = utils.unbalancedForce()
            ratio = pressure / p_target
            if fast_growth and solid_fraction_now < FREE_GROWTH_SOLID_FRACTION:
                # the cloud is far from touching: no contact can store energy yet
                grow = 1e-2
            elif pressure <= 0:
                grow = 2e-3
            else:
                grow = 0.5 * overlap_scale * (ratio ** (-2.0 / 3.0) - 1.0)
                grow = min(2e-3, max(-2e-3, grow))
            if abs(ratio - 1.0) < p["pressure_tolerance"] and unbalanced < unbalanced_target:
                settled += 1
                if settled >= 2:
                    break
            else:
                settled = 0
                utils.growParticles(1.0 + grow, updateMass=False, dynamicOnly=True)
                solid_fraction_now *= (1.0 + grow) ** 3
            now = time.time() - start
            if now - last > 3.0:
                last = now
                log(f"compress: E {young:.3g} Pa ({k + 1}/{len(stages)}{label}), step {O.iter}, "
                    f"phi {solid_fraction(box):.4f}, stress/target {ratio:.3f}, "
                    f"unbalanced {unbalanced:.3g}, {now:.0f} s")
            if now > p["max_seconds"]:
                fail(f"max_seconds: compression not finished after {now:.0f} s "
                     f"(stress/target {ratio:.3f}, unbalanced {unbalanced:.3g})", code=3)
        log(f"compress: E {young:.3g} Pa ({k + 1}/{len(stages)}{label}) relaxed at step {O.iter}: "
            f"phi {solid_fraction(box):.4f}, stress/target {ratio:.4f}, unbalanced "
            f"{unbalanced:.3g}, {time.time() - start:.0f} s")
    return time.time() - start, sphere_ids, wall_of_body, collider


def solid_fraction(box):
    return sum(4.0 / 3.0 * math.pi * b.shape.radius ** 3 for b in O.bodies
               if isinstance(b.shape, Sphere)) / box.volume


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


STATE_KEYS = ("box", "position", "radius", "pair", "branch", "overlap", "normal_force",
              "contact_radius", "walls", "wall_particle", "wall_index", "wall_overlap",
              "wall_force", "periodic", "n", "sphere_ids", "unbalanced", "pressure",
              "pressure_normal", "compress_seconds", "compress_steps", "radii_drawn",
              "n_untracked")


def read_cell_packing(p):
    """method = "tiled" with cell_packing: the relaxed periodic cell of an earlier run (a
    packing.h5 of shape "periodic", e.g. made by tdem pack), copied instead of relaxing a new
    one. Its geometry, forces and modulus are used as they are; the run's own material keys
    must agree with the file's (one modulus, one pressure)."""
    import h5py
    path = p["cell_packing"]
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        fail(f"cell_packing: cannot read {path} ({e})")
    with f:
        periodic = np.asarray(f["domain"].attrs.get("periodic", [False] * 3), dtype=bool)
        if not periodic.all() or f.attrs.get("shape") != "periodic":
            fail(f"cell_packing: {path}: expected a periodic cell (shape \"periodic\"), got "
                 f"shape {f.attrs.get('shape')!r}")
        for key in ("young_pa", "poisson", "confining_pressure_pa", "gap_tolerance"):
            if not math.isclose(float(f.attrs[key]), float(p[key]), rel_tol=1e-12):
                fail(f"cell_packing: {path}: {key} is {float(f.attrs[key])!r} in the cell, "
                     f"{p[key]!r} in the parameters (they must agree)")
        attrs = dict(f.attrs)
        hi = np.asarray(f["domain"].attrs["hi"], dtype=float)
        lo = np.asarray(f["domain"].attrs["lo"], dtype=float)
        position = f["particles/position"][...] - lo
        radius = f["particles/radius"][...]
        pair = f["contacts/pair"][...]
        branch = f["contacts/branch"][...]
        overlap = f["contacts/overlap"][...]
        normal_force = f["contacts/normal_force"][...]
        contact_radius = f["contacts/contact_radius"][...] if "contact_radius" in f["contacts"] \
            else np.sqrt(np.clip(overlap, 0, None) * radius[pair[:, 0]] * radius[pair[:, 1]]
                         / (radius[pair[:, 0]] + radius[pair[:, 1]]))
    size = hi - lo
    box = Container("periodic", float(np.prod(size)), size / size.max())
    log(f"cell: {len(radius)} spheres from {path} (seed {attrs.get('seed')}), cell "
        f"{size[0]:.4g} x {size[1]:.4g} x {size[2]:.4g} m")
    return dict(box=box, position=position, radius=radius, pair=pair, branch=branch,
                overlap=overlap, normal_force=normal_force, contact_radius=contact_radius,
                walls=[], wall_particle=np.zeros(0, np.int64),
                wall_index=np.zeros(0, np.int32), wall_overlap=np.zeros(0),
                wall_force=np.zeros(0), periodic=True, n=len(radius), sphere_ids=None,
                unbalanced=float(attrs["unbalanced_force_ratio"]),
                pressure=float(attrs["pressure_pa"]),
                pressure_normal=float(attrs["mean_stress_from_dumped_forces_pa"]),
                compress_seconds=0.0, compress_steps=0,
                radii_drawn=radius / float(attrs["radius_growth_factor"]),
                n_untracked=int(attrs.get("contacts_touching_without_yade_force", 0)))


def relax_cell_or_domain(p):
    """Cloud, compression in YADE and the contacts of the relaxed state, rebuilt from the
    final geometry (the domain itself, or the periodic cell of method = "tiled")."""
    # tiled: the YADE relaxation is that of a periodic cell of cell_particles spheres
    p_relax = dict(p, shape="periodic", n_particles=p["cell_particles"]) \
        if p["method"] == "tiled" else p
    centres, radii0, box, radii_drawn = make_cloud(p_relax)
    log(f"cloud: {len(radii0)} spheres in a {box.shape} domain {box.size[0]:.4g} x "
        f"{box.size[1]:.4g} x {box.size[2]:.4g} m (seed {p['seed']})")
    compress_seconds, sphere_ids, wall_of_body, collider = compress(p_relax, centres, radii0, box)
    # The quasi-static quality of the packing: YADE's state at the end of the relaxation, with
    # its tangential (friction) forces. The rebuilt contacts below carry normal forces only.
    compress_steps = O.iter           # DEM steps of the relaxation: work, whatever the load
    unbalanced = utils.unbalancedForce()
    pressure = mean_stress(box)
    # Rebuild every contact from the final radii and positions and step once: the dumped
    # forces are then YADE's Hertz-Mindlin forces of exactly the dumped geometry (the
    # compression's contacts were created at other radii and stiffnesses).
    # The integrator is switched off for that step so that the dumped positions are exactly
    # the ones the forces were computed from.
    O.interactions.clear()
    collider.doSort = True
    O.engines[-1].dead = True
    O.step()
    pressure_normal = mean_stress(box)
    periodic = box.shape == "periodic"
    index_of = {int(b): k for k, b in enumerate(sphere_ids)}
    radius = np.array([O.bodies[int(b)].shape.radius for b in sphere_ids])
    raw = np.array([[O.bodies[int(b)].state.pos[j] for j in range(3)] for b in sphere_ids])
    position = raw - np.floor(raw / box.size) * box.size if periodic else raw
    n = len(radius)
    force = {}
    walls = box.walls()
    wall_touch = {}
    for i in O.interactions:
        if not i.isReal:
            continue
        a, b = i.id1, i.id2
        if a in index_of and b in index_of:
            key = tuple(sorted((index_of[a], index_of[b])))
            force[key] = i.phys.normalForce.norm()
        else:
            particle, body = (index_of[b], a) if b in index_of else (index_of[a], b)
            w = wall_of_body[body]
            # several facets of one curved wall may touch a sphere: keep the deepest
            key = (particle, w)
            depth = i.geom.penetrationDepth
            if key not in wall_touch or depth > wall_touch[key][0]:
                wall_touch[key] = (depth, i.phys.normalForce.norm())
    log(f"compressed in {compress_seconds:.1f} s: phi {solid_fraction(box):.4f}, mean stress "
        f"{pressure:.4g} Pa, unbalanced {unbalanced:.3g}")

    pair, branch = neighbour_pairs(position, radius, p["gap_tolerance"],
                                   box.size if periodic else None)
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

    # Wall contacts: every particle YADE has in contact with a wall (YADE's depth and force;
    # the cylinder mantle and the spherical container are facet polygons with wall_segments
    # sides), plus the near-wall particles within (1 + wall_gap_tolerance) r of the analytic
    # wall surface (negative overlap, zero force).
    wall_particle, wall_index, wall_overlap, wall_force = [], [], [], []
    for w, wall in enumerate(walls):
        dist = box.distance_to_wall(wall, position)
        near = set(np.flatnonzero(dist < (1.0 + p["wall_gap_tolerance"]) * radius).tolist())
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
    wall_particle = np.array(wall_particle, dtype=np.int64)
    wall_index = np.array(wall_index, dtype=np.int32)
    wall_overlap = np.array(wall_overlap, dtype=float)
    wall_force = np.array(wall_force, dtype=float)

    return {k: v for k, v in locals().items() if k in STATE_KEYS}


def main():
    params_path = P.params_path_from_argv_or_batch(sys.argv, "dense_packing.py")
    if params_path is None:
        fail("usage: yade -n -x dense_packing.py params.json (or yade-batch TABLE "
             "dense_packing.py with a params_json column)")
    try:
        p = P.read_params_json(params_path, "dense")
    except P.ParamError as e:
        fail(str(e))
    except (OSError, ValueError) as e:
        fail(f"{params_path}: {e}")
    for k, inc in enumerate(p["inclusions"]):
        if not isinstance(inc, dict) or set(inc) - {"centre", "radius", "phase"} \
                or "centre" not in inc or "radius" not in inc:
            fail(f"inclusions[{k}]: expected {{centre = [fx, fy, fz], radius = f, phase = id}}")
    if p["method"] == "tiled":
        if p["shape"] == "periodic":
            fail("method: \"tiled\" carves a box, cylinder or sphere out of copies of a periodic "
                 "cell; for a periodic domain use method = \"direct\"")
        if p["n_particles"] < p["cell_particles"]:
            fail(f"cell_particles: expected at most n_particles ({p['n_particles']}) for "
                 f"method = \"tiled\", got {p['cell_particles']}")
    t0 = time.time()
    if p["method"] == "tiled" and p["cell_packing"]:
        state = read_cell_packing(p)
    else:
        state = relax_cell_or_domain(p)
    (box, position, radius, pair, branch, overlap, normal_force, contact_radius, walls,
     wall_particle, wall_index, wall_overlap, wall_force, periodic, n, sphere_ids, unbalanced,
     pressure, pressure_normal, compress_seconds, compress_steps, radii_drawn,
     n_untracked) = (state[k] for k in STATE_KEYS)

    cell_info = {}
    if p["method"] == "tiled" and not p["cell_packing"]:
        # the relaxed cell itself, for later runs (cell_packing = ".../cell.h5")
        touching = overlap > 0
        cell_attrs = {
            "generator": "yade_scripts/dense_packing.py", "seed": int(p["seed"]),
            "shape": "periodic", "domain_volume_m3": float(box.volume),
            "solid_fraction": float(np.sum(4.0 / 3.0 * np.pi * radius ** 3) / box.volume),
            "mean_coordination": float(2.0 * touching.sum() / n),
            "mean_coordination_with_gaps": float(2.0 * len(pair) / n),
            "pressure_pa": float(pressure), "confining_pressure_pa": p["confining_pressure_pa"],
            "mean_stress_from_dumped_forces_pa": float(pressure_normal),
            "young_pa": p["young_pa"], "young_pa_used": p["young_pa"], "poisson": p["poisson"],
            "density": p["density"], "friction": p["friction"],
            "unbalanced_force_ratio": float(unbalanced), "gap_tolerance": p["gap_tolerance"],
            "radius_growth_factor": float(radius.mean() / radii_drawn.mean()),
            "contacts_touching_without_yade_force": n_untracked,
            "time_step": p["time_step"], "compression_seconds": compress_seconds,
            "compression_steps": int(compress_steps), "method": "direct",
            "radius_distribution": p["radius_distribution"]}
        out_cell = os.path.join(p["output_dir"], "cell.h5")
        write_packing(out_cell, position, radius, np.zeros(n, dtype=np.int32), pair, overlap,
                      normal_force, branch, [], np.zeros(0, np.int64), np.zeros(0, np.int32),
                      np.zeros(0), np.zeros(0), np.zeros(3), box.size.copy(), [True] * 3,
                      cell_attrs, contact_radius=contact_radius, wall_contact_radius=np.zeros(0))
        log(f"wrote {out_cell}: the relaxed periodic cell ({n} spheres; reuse it with "
            f"cell_packing = \"{out_cell}\")")
    if p["method"] == "tiled":
        (box, position, radius, pair, branch, overlap, normal_force, contact_radius, walls,
         wall_particle, wall_index, wall_overlap, wall_force, cell_info) = tile_cell(
            p, box, position, radius, pair, branch, overlap, normal_force, contact_radius)
        periodic = False
        n = len(radius)
        sphere_ids = None
        log(f"tiled: {cell_info['tiles']} copies of the {cell_info['cell_particles']}-sphere "
            f"cell carved to a {box.shape} {box.size[0]:.4g} x {box.size[1]:.4g} x "
            f"{box.size[2]:.4g} m: {n} spheres, {len(pair)} neighbour pairs")

    lo, hi = np.zeros(3), box.size.copy()
    phase = np.zeros(n, dtype=np.int32)
    extent = hi - lo
    for inc in p["inclusions"]:
        c = lo + np.asarray(inc["centre"], dtype=float) * extent
        rr = float(inc["radius"]) * extent.min()
        phase[np.linalg.norm(position - c, axis=1) <= rr] = int(inc.get("phase", 1))
    n_dispersed = 0
    if p["inclusion_volume_fraction"] > 0:
        rng = np.random.default_rng(p["seed"] + 7919)
        r_inc = p["inclusion_radius_over_mean"] * float(radius.mean())
        target = p["inclusion_volume_fraction"] * box.volume
        centres_inc = []
        placed, tries = 0.0, 0
        while placed < target and tries < 100000:
            tries += 1
            c = lo + rng.random(3) * extent
            if not periodic and not box.inside(c, r_inc)[0]:
                continue
            d = np.asarray(centres_inc).reshape(-1, 3) - c
            if periodic:
                d -= np.round(d / box.size) * box.size
            if len(centres_inc) and np.min(np.linalg.norm(d, axis=1)) < 2 * r_inc:
                continue
            centres_inc.append(c)
            placed += 4.0 / 3.0 * math.pi * r_inc ** 3
        for c in centres_inc:
            d = position - c
            if periodic:
                d -= np.round(d / box.size) * box.size
            phase[np.linalg.norm(d, axis=1) <= r_inc] = p["inclusion_phase"]
        n_dispersed = len(centres_inc)

    volume = 4.0 / 3.0 * np.pi * radius ** 3
    touching = overlap > 0
    phi = float(volume.sum() / box.volume)
    # bulk solid fraction: the domain without a layer of two mean diameters along its walls,
    # spheres counted wholly by centre (the wall layer is looser: its fraction is the
    # difference to solid_fraction)
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
    attrs = {
        "generator": "yade_scripts/dense_packing.py", "seed": int(p["seed"]),
        "shape": box.shape, "solid_fraction": phi, "solid_fraction_bulk": phi_bulk,
        "domain_volume_m3": float(box.volume),
        "mean_coordination": float(2.0 * touching.sum() / n),
        "mean_coordination_with_gaps": float(2.0 * len(pair) / n),
        "pressure_pa": float(pressure), "confining_pressure_pa": p["confining_pressure_pa"],
        "mean_stress_from_dumped_forces_pa": float(pressure_normal),
        "young_pa": p["young_pa"], "young_pa_used": p["young_pa"],
        "young_pa_softened_start": stiffness_stages(p)[0], "poisson": p["poisson"],
        "density": p["density"], "density_scaling": p["density_scaling"],
        "friction": p["friction"], "compaction_friction": p["compaction_friction"],
        "unbalanced_force_ratio": float(unbalanced),
        "neighbour_criterion": "centre distance < (1 + gap_tolerance)(r_i + r_j)",
        "gap_tolerance": p["gap_tolerance"], "wall_gap_tolerance": p["wall_gap_tolerance"],
        "wall_segments": p["wall_segments"],
        "wall_contact_model": "Hertz with R* = r and E* = E / (2 (1 - nu^2)): a flat wall of "
                              "the particles' material (curved walls: facets, locally flat)"
        if p["method"] == "direct" else
        "cut surface of a tiled periodic packing: spheres within (1 + wall_gap_tolerance) r "
        "of it, overlap = r - distance, no force (nothing was pressed against them)",
        "method": p["method"], "time_step": p["time_step"], "cell_packing": p["cell_packing"],
        "stiffen_factor": p["stiffen_factor"], **cell_info,
        "contacts_touching_without_yade_force": n_untracked,
        "radius_distribution": p["radius_distribution"],
        "radius_mean_requested_m": p["radius_mean_m"],
        "radius_growth_factor": float(radius.mean() / radii_drawn.mean()),
        "inclusions_dispersed": n_dispersed,
        "compression_seconds": compress_seconds, "compression_steps": int(compress_steps),
        "yade_version": yade_version(), "wall_seconds": time.time() - t0,
    }
    out = os.path.join(p["output_dir"], "packing.h5")
    write_packing(out, position, radius, phase, pair, overlap, normal_force, branch, walls,
                  wall_particle, wall_index, wall_overlap, wall_force, lo, hi,
                  [periodic] * 3, attrs, contact_radius=contact_radius,
                  wall_contact_radius=np.zeros(len(wall_particle)), yade_id=sphere_ids)
    log(f"wrote {out}: {n} particles, phi {phi:.4f} (bulk {phi_bulk:.4f}), "
        f"Z {attrs['mean_coordination']:.3f} (with gaps "
        f"{attrs['mean_coordination_with_gaps']:.3f}), {time.time() - t0:.1f} s")


def yade_version():
    try:
        from yade import config
        return str(config.version)
    except Exception:   # noqa: BLE001 - version is informative only
        return "unknown"


main()
sys.exit(0)
