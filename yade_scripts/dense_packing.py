# Dense polydisperse packing for continuum conduction (Terreros 2012; Haddad 2021, 002 sec. 2).
#
#   yade -n -j1 -x yade_scripts/dense_packing.py params.json
#
# params.json: see dense_params.py (tdem pack writes it from a scene's [pack] table).
# Steps: a random cloud of spheres (radii uniform or truncated Gaussian) in a periodic cell is
# compressed isotropically with Hertz-Mindlin contacts at the REAL modulus (frictionless by
# default, which gives the densest random packing, phi ~0.64) until the confining stress is
# reached and the unbalanced-force ratio is below the target. Masses are scaled up meanwhile
# (no gravity, so the static end state does not depend on them). Box, cylinder and sphere
# domains are cut from the periodic packing (spheres wholly inside the region are kept) and get
# walls. Contacts: every touching pair (YADE's own normal force) plus, with gap_tolerance > 0,
# the near neighbours within (1 + gap_tolerance)(r_i + r_j) (negative overlap, zero force), so
# that the neighbour criterion sets the coordination number (Haddad uses Z ~ 7.5).
# Imports: yade, numpy, h5py and the standard library only.
import math
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(sys.argv[0])))

import numpy as np  # noqa: E402
from yade import O, pack, utils  # noqa: E402
from yade.wrapper import (FrictMat, ForceResetter, InsertionSortCollider, Bo1_Sphere_Aabb,  # noqa: E402
                          InteractionLoop, Ig2_Sphere_Sphere_ScGeom,
                          Ip2_FrictMat_FrictMat_MindlinPhys, Law2_ScGeom_MindlinPhys_Mindlin,
                          PeriTriaxController, NewtonIntegrator)
from yade.minieigenHP import Matrix3, Vector3  # noqa: E402

import params as P  # noqa: E402
from neighbours import neighbour_pairs  # noqa: E402
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


def make_cloud(p):
    """Random sequential addition of the radii (largest first) into a periodic cell of the
    requested aspect at solid fraction 0.25: a loose, overlap-free, seeded start."""
    radii = np.sort(draw_radii(p))[::-1]
    n = radii.size
    a = np.asarray(p["aspect"], dtype=float)
    if a.shape != (3,):
        fail("aspect: expected 3 numbers")
    volume = np.sum(4.0 / 3.0 * np.pi * radii ** 3) / 0.25
    side = (volume / a.prod()) ** (1.0 / 3.0) * a
    if 2.2 * radii[0] > side.min() / 2:
        fail("n_particles: too few particles for this aspect (the cell must be wider than "
             "four diameters)")
    rng = np.random.default_rng(p["seed"] + 1)
    centres = np.empty((n, 3))
    for k in range(n):
        for _ in range(100000):
            c = rng.random(3) * side
            d = centres[:k] - c
            d -= np.round(d / side) * side
            if k == 0 or np.min(np.einsum("ij,ij->i", d, d) - (radii[:k] + radii[k]) ** 2) > 0:
                centres[k] = c
                break
        else:
            fail("n_particles: could not place the initial cloud", code=3)
    sp = pack.SpherePack([((float(c[0]), float(c[1]), float(c[2])), float(r))
                          for c, r in zip(centres, radii)])
    return sp, side


def compress(p, sp, side):
    O.reset()
    O.periodic = True
    O.cell.hSize = Matrix3(side[0], 0, 0, 0, side[1], 0, 0, 0, side[2])
    mat = O.materials.append(FrictMat(
        young=p["young_pa"], poisson=p["poisson"],
        density=p["density"] * p["density_scaling"],
        frictionAngle=math.atan(p["compaction_friction"])))
    sp.toSimulation(material=mat)
    state = {"done": False}
    pc = p["confining_pressure_pa"]
    rate = 0.5   # 1/s: maximum strain rate of the cell (mass-scaled time)

    def done():
        state["done"] = True
        O.pause()
    globals()["tdem_compression_done"] = done
    O.engines = [
        ForceResetter(),
        InsertionSortCollider([Bo1_Sphere_Aabb()]),
        InteractionLoop([Ig2_Sphere_Sphere_ScGeom()], [Ip2_FrictMat_FrictMat_MindlinPhys()],
                        [Law2_ScGeom_MindlinPhys_Mindlin()]),
        PeriTriaxController(goal=Vector3(-pc, -pc, -pc), stressMask=7, dynCell=True,
                            maxStrainRate=Vector3(rate, rate, rate),
                            maxUnbalanced=p["unbalanced_force_target"], relStressTol=1e-3,
                            doneHook="tdem_compression_done()", label="compressor"),
        NewtonIntegrator(damping=0.5),
    ]
    O.dt = 0.5 * utils.PWaveTimeStep()
    start = time.time()
    last = 0.0
    while not state["done"]:
        O.run(500, True)
        now = time.time() - start
        if now - last > 3.0 or state["done"]:
            last = now
            cell_volume = O.cell.volume
            solid = sum(4.0 / 3.0 * math.pi * b.shape.radius ** 3 for b in O.bodies)
            log(f"compress: step {O.iter}, phi {solid / cell_volume:.4f}, "
                f"unbalanced {utils.unbalancedForce():.3g}, {now:.0f} s")
        if now > p["max_seconds"]:
            fail(f"max_seconds: compression not finished after {now:.0f} s "
                 f"(unbalanced {utils.unbalancedForce():.3g})", code=3)
    return time.time() - start


def main():
    if len(sys.argv) != 2:
        fail("usage: yade -n -x dense_packing.py params.json")
    try:
        p = P.read_params_json(sys.argv[1], "dense")
    except P.ParamError as e:
        fail(str(e))
    except (OSError, ValueError) as e:
        fail(f"{sys.argv[1]}: {e}")
    for k, inc in enumerate(p["inclusions"]):
        if not isinstance(inc, dict) or set(inc) - {"centre", "radius", "phase"} \
                or "centre" not in inc or "radius" not in inc:
            fail(f"inclusions[{k}]: expected {{centre = [fx, fy, fz], radius = f, phase = id}}")
    t0 = time.time()
    sp, side = make_cloud(p)
    log(f"cloud: {len(sp)} spheres in a periodic cell {side[0]:.4g} x {side[1]:.4g} x "
        f"{side[2]:.4g} m (seed {p['seed']})")
    compress_seconds = compress(p, sp, side)
    O.step()   # interactions and forces consistent with the final positions
    unbalanced = utils.unbalancedForce()
    stress = utils.getStress()
    pressure_cell = -(stress[0, 0] + stress[1, 1] + stress[2, 2]) / 3.0
    L = np.array([O.cell.hSize[0, 0], O.cell.hSize[1, 1], O.cell.hSize[2, 2]])
    ids = np.array([b.id for b in O.bodies])
    radius = np.array([b.shape.radius for b in O.bodies])
    raw = np.array([[b.state.pos[0], b.state.pos[1], b.state.pos[2]] for b in O.bodies])
    position = raw - np.floor(raw / L) * L       # wrapped into the cell [0, L)
    force = {}
    for i in O.interactions:
        if i.isReal:
            a, b = sorted((i.id1, i.id2))
            force[(a, b)] = i.phys.normalForce.norm()
    phi_cell = float(np.sum(4.0 / 3.0 * np.pi * radius ** 3) / np.prod(L))
    log(f"compressed in {compress_seconds:.1f} s: phi {phi_cell:.4f}, mean stress "
        f"{pressure_cell:.4g} Pa, unbalanced {unbalanced:.3g}")

    shape = p["shape"]
    centre = L / 2
    walls = []
    if shape == "periodic":
        keep = np.ones(len(radius), bool)
        region_volume = float(np.prod(L))
        lo, hi = np.zeros(3), L.copy()
    elif shape == "box":
        keep = np.all((position - radius[:, None] >= 0) & (position + radius[:, None] <= L), axis=1)
        region_volume = float(np.prod(L))
        lo, hi = np.zeros(3), L.copy()
        for axis, name in enumerate("xyz"):
            for side_sign, suffix in ((+1, "min"), (-1, "max")):
                point = np.zeros(3)
                point[axis] = 0.0 if side_sign > 0 else L[axis]
                normal = np.zeros(3)
                normal[axis] = side_sign
                walls.append(dict(name=name + suffix, kind="plane", point=point, normal=normal,
                                  radius=float("nan")))
    elif shape == "cylinder":
        R = min(L[0], L[1]) / 2
        rad = np.hypot(position[:, 0] - centre[0], position[:, 1] - centre[1])
        keep = (rad + radius <= R) & (position[:, 2] - radius >= 0) & \
               (position[:, 2] + radius <= L[2])
        region_volume = math.pi * R ** 2 * L[2]
        lo = np.array([centre[0] - R, centre[1] - R, 0.0])
        hi = np.array([centre[0] + R, centre[1] + R, L[2]])
        walls = [dict(name="cylinder", kind="cylinder", point=np.array([centre[0], centre[1], 0.0]),
                      normal=np.array([0.0, 0.0, 1.0]), radius=R),
                 dict(name="zmin", kind="plane", point=np.zeros(3),
                      normal=np.array([0.0, 0.0, 1.0]), radius=float("nan")),
                 dict(name="zmax", kind="plane", point=np.array([0.0, 0.0, L[2]]),
                      normal=np.array([0.0, 0.0, -1.0]), radius=float("nan"))]
    else:  # sphere
        R = float(L.min()) / 2
        dist = np.linalg.norm(position - centre, axis=1)
        keep = dist + radius <= R
        region_volume = 4.0 / 3.0 * math.pi * R ** 3
        lo, hi = centre - R, centre + R
        walls = [dict(name="surface", kind="sphere", point=centre.copy(),
                      normal=np.array([0.0, 0.0, 1.0]), radius=R)]

    index = np.flatnonzero(keep)
    position, radius, ids = position[index], radius[index], ids[index]
    n = len(index)
    periodic = shape == "periodic"
    pair, branch = neighbour_pairs(position, radius, p["gap_tolerance"],
                                   L if periodic else None)
    distance = np.linalg.norm(branch, axis=1)
    overlap = radius[pair[:, 0]] + radius[pair[:, 1]] - distance
    r_star = radius[pair[:, 0]] * radius[pair[:, 1]] / (radius[pair[:, 0]] + radius[pair[:, 1]])
    e_star = p["young_pa"] / (2.0 * (1.0 - p["poisson"] ** 2))
    normal_force = np.zeros(len(pair))
    n_formula = 0
    for k, (a, b) in enumerate(pair):
        if overlap[k] > 0:
            key = tuple(sorted((int(ids[a]), int(ids[b]))))
            if key in force:
                normal_force[k] = force[key]
            else:   # touching, but YADE's collider had not paired them: Hertz, as YADE would
                normal_force[k] = 4.0 / 3.0 * e_star * math.sqrt(r_star[k]) * overlap[k] ** 1.5
                n_formula += 1
    contact_radius = np.sqrt(np.clip(overlap, 0, None) * r_star)

    wall_particle, wall_index, wall_overlap = [], [], []
    for w, wall in enumerate(walls):
        if wall["kind"] == "plane":
            dist = (position - wall["point"]) @ wall["normal"]
        elif wall["kind"] == "cylinder":
            dist = wall["radius"] - np.hypot(position[:, 0] - wall["point"][0],
                                             position[:, 1] - wall["point"][1])
        else:
            dist = wall["radius"] - np.linalg.norm(position - wall["point"], axis=1)
        near = np.flatnonzero(dist < (1.0 + p["wall_gap_tolerance"]) * radius)
        wall_particle.append(near)
        wall_index.append(np.full(len(near), w))
        wall_overlap.append(radius[near] - dist[near])
    wall_particle = np.concatenate(wall_particle) if walls else np.zeros(0, int)
    wall_index = np.concatenate(wall_index) if walls else np.zeros(0, int)
    wall_overlap = np.concatenate(wall_overlap) if walls else np.zeros(0)
    # The cut walls are geometric: no sphere presses on them (overlap <= 0, force 0).
    wall_force = np.zeros(len(wall_particle))

    phase = np.zeros(n, dtype=np.int32)
    box = hi - lo
    for inc in p["inclusions"]:
        c = lo + np.asarray(inc["centre"], dtype=float) * box
        rr = float(inc["radius"]) * box.min()
        phase[np.linalg.norm(position - c, axis=1) <= rr] = int(inc.get("phase", 1))
    if p["inclusion_volume_fraction"] > 0:
        rng = np.random.default_rng(p["seed"] + 7919)
        r_inc = p["inclusion_radius_over_mean"] * p["radius_mean_m"]
        target = p["inclusion_volume_fraction"] * region_volume
        centres = []
        placed, tries = 0.0, 0
        while placed < target and tries < 100000:
            tries += 1
            c = lo + rng.random(3) * box
            if any(np.linalg.norm(c - q) < 2 * r_inc for q in centres):
                continue
            centres.append(c)
            placed += 4.0 / 3.0 * math.pi * r_inc ** 3
        for c in centres:
            phase[np.linalg.norm(position - c, axis=1) <= r_inc] = p["inclusion_phase"]

    volume = 4.0 / 3.0 * np.pi * radius ** 3
    touching = overlap > 0
    phi = float(volume.sum() / region_volume)
    # bulk solid fraction: spheres whose centre lies in the inner half (by linear size) of the
    # region, over that region's volume, each sphere counted wholly (no wall layer)
    inner = np.all(np.abs(position - (lo + hi) / 2) <= box / 4, axis=1)
    phi_bulk = float(volume[inner].sum() / np.prod(box / 2)) if not periodic else phi
    attrs = {
        "generator": "yade_scripts/dense_packing.py", "seed": int(p["seed"]),
        "shape": shape, "solid_fraction": phi, "solid_fraction_bulk": phi_bulk,
        "solid_fraction_cell": phi_cell,
        "mean_coordination": float(2.0 * touching.sum() / n),
        "mean_coordination_with_gaps": float(2.0 * len(pair) / n),
        "pressure_pa": float(pressure_cell), "confining_pressure_pa": p["confining_pressure_pa"],
        "young_pa": p["young_pa"], "young_pa_used": p["young_pa"], "poisson": p["poisson"],
        "density": p["density"], "density_scaling": p["density_scaling"],
        "friction": p["friction"], "compaction_friction": p["compaction_friction"],
        "unbalanced_force_ratio": float(unbalanced),
        "neighbour_criterion": "centre distance < (1 + gap_tolerance)(r_i + r_j)",
        "gap_tolerance": p["gap_tolerance"], "wall_gap_tolerance": p["wall_gap_tolerance"],
        "contacts_force_from_formula": n_formula,
        "radius_distribution": p["radius_distribution"],
        "yade_version": yade_version(), "wall_seconds": time.time() - t0,
    }
    out = os.path.join(p["output_dir"], "packing.h5")
    write_packing(out, position, radius, phase, pair, overlap, normal_force, branch, walls,
                  wall_particle, wall_index, wall_overlap, wall_force, lo, hi,
                  [periodic] * 3, attrs, contact_radius=contact_radius,
                  wall_contact_radius=np.zeros(len(wall_particle)), yade_id=ids)
    log(f"wrote {out}: {n} particles, phi {phi:.4f}, Z {attrs['mean_coordination']:.3f} "
        f"(with gaps {attrs['mean_coordination_with_gaps']:.3f}), {time.time() - t0:.1f} s")


def yade_version():
    try:
        from yade import config
        return str(config.version)
    except Exception:   # noqa: BLE001 - version is informative only
        return "unknown"


main()
sys.exit(0)
