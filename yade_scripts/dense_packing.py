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

import numpy as np

if __name__ == "__main__":       # run by YADE (yade -x): the package yade_scripts is importable
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(sys.argv[0]))))

from thermal_kernel.morton import morton_order  # noqa: E402
from yade_scripts import params as P  # noqa: E402
from yade_scripts import shell  # noqa: E402
from yade_scripts.dense_geometry import (  # noqa: E402
    CLOUD_SOLID_FRACTION, FREE_GROWTH_SOLID_FRACTION, WALL_YOUNG_FACTOR, CloudError, Container,
    assign_phases, icosphere, make_cloud, relaxed_contacts, relaxed_params, relaxed_wall_contacts,
    solid_fractions, stiffness_stages, tile_cell)
from yade_scripts.tdem_dump import write_packing  # noqa: E402
from yade_scripts.tiling import carve  # noqa: E402

# scenes of more spheres than this enter YADE in Z order (build_scene)
MORTON_ABOVE = 20_000

# YADE's names, bound by import_yade() when the script runs: importing this file needs no YADE.
O = geom = utils = Matrix3 = None
FrictMat = ForceResetter = InsertionSortCollider = Bo1_Sphere_Aabb = Bo1_Wall_Aabb = None
Bo1_Facet_Aabb = InteractionLoop = Ig2_Sphere_Sphere_ScGeom = Ig2_Wall_Sphere_ScGeom = None
Ig2_Facet_Sphere_ScGeom = Ip2_FrictMat_FrictMat_MindlinPhys = None
Law2_ScGeom_MindlinPhys_Mindlin = NewtonIntegrator = Sphere = GlobalStiffnessTimeStepper = None
Vector3 = None


def import_yade():
    """Import YADE (only possible inside Debian's yade) and bind its names in this module."""
    global O, geom, utils, Matrix3, FrictMat, ForceResetter, InsertionSortCollider, \
        Bo1_Sphere_Aabb, Bo1_Wall_Aabb, Bo1_Facet_Aabb, InteractionLoop, \
        Ig2_Sphere_Sphere_ScGeom, Ig2_Wall_Sphere_ScGeom, Ig2_Facet_Sphere_ScGeom, \
        Ip2_FrictMat_FrictMat_MindlinPhys, Law2_ScGeom_MindlinPhys_Mindlin, NewtonIntegrator, \
        Sphere, GlobalStiffnessTimeStepper, Vector3
    from yade import O, geom, utils
    from yade.wrapper import (FrictMat, ForceResetter, InsertionSortCollider,
                              Bo1_Sphere_Aabb, Bo1_Wall_Aabb, Bo1_Facet_Aabb, InteractionLoop,
                              Ig2_Sphere_Sphere_ScGeom, Ig2_Wall_Sphere_ScGeom,
                              Ig2_Facet_Sphere_ScGeom, Ip2_FrictMat_FrictMat_MindlinPhys,
                              Law2_ScGeom_MindlinPhys_Mindlin, NewtonIntegrator, Sphere,
                              GlobalStiffnessTimeStepper)
    from yade.minieigenHP import Matrix3, Vector3


def fail(message, code=2):
    print("error: " + message, file=sys.stderr, flush=True)
    sys.exit(code)


def log(message):
    print(message, flush=True)


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
                height=box.size[2], segmentsNumber=p["wall_segments"], wallMask=4,
                material=facet_mat))
        else:
            # an icosphere, not geom.facetSphere: its latitude-longitude slivers at the poles
            # paired with many near-wall spheres (1.65x the box's CPU against 1.3x, same sag)
            vertices, triangles = icosphere(p["sphere_facet_level"])
            corner = np.asarray(box.centre, dtype=float) + wall["radius"] * vertices
            ids = O.bodies.append([
                utils.facet([tuple(float(x) for x in corner[k]) for k in triangle],
                            material=facet_mat, fixed=True)
                for triangle in triangles])
        for i in ids:
            wall_of_body[i] = w
    collider = InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Wall_Aabb(), Bo1_Facet_Aabb()])
    # Above MORTON_ABOVE spheres they enter YADE along a Z-order curve of their centres (body
    # ids in memory order; sphere_ids[k] stays the body of centres[k]): YADE's interaction loop
    # reads both spheres of every contact, and in a random order at 1e5 spheres each read is a
    # cache miss. Measured: 80,000 spheres of a relaxed periodic cell at the real modulus, 1.29x
    # less CPU a step than the random order (0.135 against 0.174 s); 1.25x at 10,000, where the
    # order is left as it was so that the packings quoted at and below 2e4 stay bit for bit.
    sphere_ids = np.empty(len(radii), dtype=np.int64)
    for k in (morton_order(centres) if len(radii) > MORTON_ABOVE else range(len(radii))):
        sphere_ids[k] = O.bodies.append(utils.sphere(tuple(float(x) for x in centres[k]),
                                                     float(radii[k]), material=mat))
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
    return (mat, plane_mat, facet_mat), sphere_ids, wall_of_body, collider


def mean_stress(box):
    stress = utils.getStress() if box.shape == "periodic" else utils.getStress(box.volume)
    return -(stress[0, 0] + stress[1, 1] + stress[2, 2]) / 3.0


def set_young(mats, young, young_now):
    """Raise the modulus of the materials (spheres, plane walls, facets) and of every existing
    contact from young_now to young (the stiffening stages)."""
    factor = young / young_now
    for m, scale in zip(mats, (1.0, WALL_YOUNG_FACTOR["plane"], WALL_YOUNG_FACTOR["facet"])):
        O.materials[m].young = young * scale
    for i in O.interactions:
        if i.isReal:
            i.phys.kno *= factor
            i.phys.kso *= factor


def friction_on(mats, tan_phi):
    """Frictionless compaction gives the densest random packing, but at the real modulus its
    last relaxation crawls (the unbalanced-force ratio hovers at a few 1e-3 for minutes: floppy
    modes). Once the frictionless packing is at the target stress at the real modulus
    (unbalanced < 1e-2), the material's friction is switched on, at rest: the contacts are kept
    (switched on earlier, while the radii still shrink, it opened contacts: Z 3.9 and 17 %
    rattlers) and the tangential springs damp the floppy modes."""
    for m in mats:
        O.materials[m].frictionAngle = math.atan(tan_phi)
    for i in O.interactions:
        if i.isReal:
            i.phys.tangensOfFrictionAngle = tan_phi


def enter_stage(p, mats, stages, k, friction_stage):
    """Stage k of a relaxation (direct or shell): friction switched on for the last one when the
    material has friction; returns (final, its log label, the unbalanced-force ratio that ends
    it: the target at the last stage, 1e-2 before, the typical Hertz overlap/radius at the
    stage's modulus)."""
    final = k == len(stages) - 1
    if final and friction_stage:
        friction_on(mats, p["friction"])
    label = ", friction on" if final and friction_stage else ""
    unbalanced_target = p["unbalanced_force_target"] if final else \
        max(p["unbalanced_force_target"], 1e-2)
    return final, label, unbalanced_target, hertz_overlap(p, stages[k])


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
            set_young(mats, young, young_now)
            young_now = young
        final, label, unbalanced_target, overlap_scale = enter_stage(p, mats, stages, k,
                                                                     friction_stage)
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


def yade_forces(index_of, wall_of_body):
    """YADE's normal forces of the real interactions: {(i, j): |F_n|} between spheres (indices
    of ``index_of``, i < j) and {(particle, wall): (penetration depth, |F_n|)} with the walls
    (several facets of one curved wall may touch a sphere: the deepest is kept)."""
    force, wall_touch = {}, {}
    for i in O.interactions:
        if not i.isReal:
            continue
        a, b = i.id1, i.id2
        if a in index_of and b in index_of:
            force[tuple(sorted((index_of[a], index_of[b])))] = i.phys.normalForce.norm()
        else:
            particle, body = (index_of[b], a) if b in index_of else (index_of[a], b)
            key = (particle, wall_of_body[body])
            depth = i.geom.penetrationDepth
            if key not in wall_touch or depth > wall_touch[key][0]:
                wall_touch[key] = (depth, i.phys.normalForce.norm())
    return force, wall_touch


def solid_fraction(box):
    return sum(4.0 / 3.0 * math.pi * b.shape.radius ** 3 for b in O.bodies
               if isinstance(b.shape, Sphere)) / box.volume


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
    p_relax = relaxed_params(p)
    try:
        centres, radii0, box, radii_drawn = make_cloud(p_relax)
    except CloudError as e:
        fail(str(e), code=3)
    except ValueError as e:         # (a parameter check; read_params ran it already)
        fail(str(e))
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
    if not periodic:
        # a sphere pushed through the walls would be written far outside the domain (the
        # packing reader refuses that file): stop here, before anything is written
        outside = np.flatnonzero(~box.inside(position, np.zeros(n)))
        if outside.size:
            k = int(outside[0])
            fail(f"{outside.size} of {n} spheres left the {box.shape} container during the "
                 f"compression (particle {k} at {np.round(position[k], 6).tolist()} m, domain "
                 f"0 ... {np.round(box.size, 6).tolist()} m); nothing written", code=3)
    walls = box.walls()
    force, wall_touch = yade_forces(index_of, wall_of_body)
    log(f"compressed in {compress_seconds:.1f} s: phi {solid_fraction(box):.4f}, mean stress "
        f"{pressure:.4g} Pa, unbalanced {unbalanced:.3g}")

    pair, branch, overlap, normal_force, contact_radius, n_untracked = relaxed_contacts(
        position, radius, p["gap_tolerance"], box.size if periodic else None, force)
    wall_particle, wall_index, wall_overlap, wall_force = relaxed_wall_contacts(
        box, walls, position, radius, p["wall_gap_tolerance"], wall_touch)
    return {k: v for k, v in locals().items() if k in STATE_KEYS}


def read_params():
    """The run's parameters (params.json, or the batch table's params_json), resolved and
    checked (dense_params.check, as in tdem pack); exit 2 with one line otherwise."""
    params_path = P.params_path_from_argv_or_batch(sys.argv, "dense_packing.py")
    if params_path is None:
        fail("usage: yade -n -x dense_packing.py params.json (or yade-batch TABLE "
             "dense_packing.py with a params_json column)")
    try:
        return P.read_params_json(params_path, "dense")
    except P.ParamError as e:
        fail(str(e))
    except (OSError, ValueError) as e:
        fail(f"{params_path}: {e}")


def write_cell(p, state):
    """method = "tiled": the relaxed periodic cell itself, cell.h5, for later runs
    (cell_packing = ".../cell.h5")."""
    box, position, radius, pair, n = (state[k] for k in ("box", "position", "radius", "pair",
                                                        "n"))
    touching = state["overlap"] > 0
    cell_attrs = {
        "generator": "yade_scripts/dense_packing.py", "seed": int(p["seed"]),
        "shape": "periodic", "domain_volume_m3": float(box.volume),
        "solid_fraction": float(np.sum(4.0 / 3.0 * np.pi * radius ** 3) / box.volume),
        "mean_coordination": float(2.0 * touching.sum() / n),
        "mean_coordination_with_gaps": float(2.0 * len(pair) / n),
        "pressure_pa": float(state["pressure"]),
        "confining_pressure_pa": p["confining_pressure_pa"],
        "mean_stress_from_dumped_forces_pa": float(state["pressure_normal"]),
        "young_pa": p["young_pa"], "young_pa_used": p["young_pa"], "poisson": p["poisson"],
        "density": p["density"], "friction": p["friction"],
        "unbalanced_force_ratio": float(state["unbalanced"]),
        "gap_tolerance": p["gap_tolerance"],
        "radius_growth_factor": float(radius.mean() / state["radii_drawn"].mean()),
        "contacts_touching_without_yade_force": state["n_untracked"],
        "time_step": p["time_step"], "compression_seconds": state["compress_seconds"],
        "compression_steps": int(state["compress_steps"]), "method": "direct",
        "radius_distribution": p["radius_distribution"]}
    out_cell = os.path.join(p["output_dir"], "cell.h5")
    write_packing(out_cell, position, radius, np.zeros(n, dtype=np.int32), pair,
                  state["overlap"], state["normal_force"], state["branch"], [],
                  np.zeros(0, np.int64), np.zeros(0, np.int32), np.zeros(0), np.zeros(0),
                  np.zeros(3), box.size.copy(), [True] * 3, cell_attrs,
                  contact_radius=state["contact_radius"], wall_contact_radius=np.zeros(0))
    log(f"wrote {out_cell}: the relaxed periodic cell ({n} spheres; reuse it with "
        f"cell_packing = \"{out_cell}\")")


def tiled_state(p, state):
    """method = "tiled": the relaxed cell copied side by side and carved to the domain
    (dense_geometry.tile_cell); returns the state of the carved domain and the tiling's
    attributes."""
    (box, position, radius, pair, branch, overlap, normal_force, contact_radius, walls,
     wall_particle, wall_index, wall_overlap, wall_force, cell_info) = tile_cell(
        p, state["box"], state["position"], state["radius"], state["pair"], state["branch"],
        state["overlap"], state["normal_force"], state["contact_radius"])
    n = len(radius)
    log(f"tiled: {cell_info['tiles']} copies of the {cell_info['cell_particles']}-sphere "
        f"cell carved to a {box.shape} {box.size[0]:.4g} x {box.size[1]:.4g} x "
        f"{box.size[2]:.4g} m: {n} spheres, {len(pair)} neighbour pairs")
    return dict(state, box=box, position=position, radius=radius, pair=pair, branch=branch,
                overlap=overlap, normal_force=normal_force, contact_radius=contact_radius,
                walls=walls, wall_particle=wall_particle, wall_index=wall_index,
                wall_overlap=wall_overlap, wall_force=wall_force, periodic=False, n=n,
                sphere_ids=None), cell_info


# groupMask bits of method = "shell" (YADE's collider pairs two bodies whose masks share a bit,
# unless both have the same mask sharing a bit with avoidSelfInteractionMask): walls 1, free
# shell 3, frozen band 6 -> wall-shell, shell-shell and shell-band pairs only.
SHELL_MASK, FROZEN_MASK, FROZEN_ONLY = 3, 6, 4


def wall_bodies(walls, wall_of_body):
    """Per plane wall: its YADE body, and the unit vector along which it moves inward (its
    normal; the shell path makes boxes only, shell.SHELL_SHAPES)."""
    body = {w: b for b, w in wall_of_body.items()}
    return body, {body[w]: np.asarray(wall["normal"], dtype=float) for w, wall in enumerate(walls)}


def wall_extent(box, walls, body):
    """(lo, hi) of the box the plane walls enclose now."""
    lo, hi = np.zeros(3), box.size.copy()
    for w, wall in enumerate(walls):
        axis = int(np.argmax(np.abs(wall["normal"])))
        (lo if wall["normal"][axis] > 0 else hi)[axis] = O.bodies[body[w]].state.pos[axis]
    return lo, hi


def wall_stresses(walls, body, inward, lo, hi):
    """Normal stress of each plane wall, Pa: the spheres' force on it along its outward normal
    over its area now."""
    size = hi - lo
    out = np.zeros(len(walls))
    for w, wall in enumerate(walls):
        b = body[w]
        axis = int(np.argmax(np.abs(wall["normal"])))
        push = -np.dot([O.forces.f(b)[j] for j in range(3)], inward[b])
        out[w] = push / float(np.prod(np.delete(size, axis)))
    return out


def move_walls(walls, body, inward, move_m, every):
    """Each plane wall's velocity: move_m[w] (m, positive inward) over the next `every` steps."""
    for w in range(len(walls)):
        v = inward[body[w]] * (move_m[w] / (every * O.dt))
        O.bodies[body[w]].state.vel = Vector3(*(float(x) for x in v))


def hertz_overlap(p, young):
    """Typical overlap / radius of a Hertz contact at the confining pressure and modulus
    ``young``: (p / E*)^(2/3)."""
    e_star = young / (2.0 * (1.0 - p["poisson"] ** 2))
    return (p["confining_pressure_pa"] / e_star) ** (2.0 / 3.0)


def press_shell(p, box, centres, radii, frozen, shell_m, cloud=None):
    """method = "shell": the free shell and its frozen band in YADE, the walls on the carved
    surface pressed onto the shell until each carries the confining pressure (a servo per wall,
    the compliance of a column of shell_diameters contacts in Hertz's law), through the direct
    path's stages (softened modulus, tenfold stiffening, friction on at the real modulus). The
    radii carry each stage's Hertz overlap and end as given. Returns the pressed state of these
    spheres (indices into centres). ``cloud``: the spheres put back as a shrunk cloud
    (shell.cloud_layer), grown back to their radii against the walls first (grow_cloud).
    One function (~150 lines, most of it the stages' servo loop and its comments): the scene
    lives in YADE's globals, and the loop's state (the stage, the radius factor, the walls'
    bodies and directions, the settled count) is what each stage hands the next."""
    stages = stiffness_stages(p)
    mats, sphere_ids, wall_of_body, collider = build_scene(p, centres, radii, box, stages[0])
    for k, b in enumerate(sphere_ids):
        body = O.bodies[int(b)]
        body.groupMask = FROZEN_MASK if frozen[k] else SHELL_MASK
        if frozen[k]:
            body.dynamic = False
    collider.avoidSelfInteractionMask = FROZEN_ONLY
    cloud_ids = [] if cloud is None else [int(b) for k, b in enumerate(sphere_ids) if cloud[k]]
    for b in cloud_ids:
        O.bodies[b].shape.radius *= shell.CLOUD_SHRINK     # placed at these radii
    walls = box.walls()
    body, inward = wall_bodies(walls, wall_of_body)
    p_target = p["confining_pressure_pa"]
    r_mean = float(np.mean(radii))
    layers = float(p["shell_diameters"])
    every = 50
    t0 = time.time()
    last = -10.0
    young_now = stages[0]
    friction_stage = p["friction"] != p["compaction_friction"]
    if friction_stage:
        stages = stages + [stages[-1]]
    frozen_ids = [int(b) for k, b in enumerate(sphere_ids) if frozen[k]]
    # Every sphere in YADE, free or frozen, carries the stage's Hertz overlap at the confining
    # pressure: its radius is scaled by radius_factor(E) (1 at the real modulus, where the cell
    # was relaxed), as the direct path's radius controller scales every radius at once. Without
    # it the softened shell is compressed against a band held at the real modulus's overlaps,
    # and each stiffening stage opens the seam between them (measured: touching Z 3.9-4.4
    # against 4.8-5.7 there, docs/packings.md).
    # (half of Hertz's typical overlap h = (p/E*)^(2/3) per contact; the direct boxes' contacts
    # hold 1.61-1.65 h force-weighted: with that gain each stiffening starts at the pressure
    # instead of 6.6x it, but the stages end on the unbalanced force's creep all the same -
    # 18,800 steps against 18,583 - and the grown layer lost wall contacts: docs/packings.md)
    def radius_factor(young):
        return 1.0 + 0.5 * (hertz_overlap(p, young) - hertz_overlap(p, p["young_pa"]))

    def scale_radii(factor):
        utils.growParticles(factor, updateMass=False, dynamicOnly=True)     # the free shell
        for b in frozen_ids:
            O.bodies[b].shape.radius *= factor
        collider.doSort = True
    # grown to the soft stage's factor 1e-3 per control interval (the direct path's growth rate):
    # grown at once, a sphere was thrown out of the box in the first steps, before the density
    # scaling had seen its new contacts (the 2,000-sphere test box)
    grown = 1.0
    while grown < radius_factor(stages[0]):
        step_factor = min(1.0 + 1e-3, radius_factor(stages[0]) / grown)
        scale_radii(step_factor)
        grown *= step_factor
        O.run(every, True)
    if cloud_ids:
        grow_cloud(p, box, cloud_ids, collider, walls, body, inward,
                   r_mean * layers * hertz_overlap(p, stages[0]), every)
    for k, young in enumerate(stages):
        if young != young_now:
            set_young(mats, young, young_now)
            if young == p["young_pa"]:
                # back to the cell's radii exactly
                for b, r in zip(sphere_ids, radii):
                    O.bodies[int(b)].shape.radius = float(r)
                collider.doSort = True
            else:
                scale_radii(radius_factor(young) / radius_factor(young_now))
            young_now = young
        final, label, unbalanced_target, overlap_scale = enter_stage(p, mats, stages, k,
                                                                     friction_stage)
        # a wall moves at most this far per control interval: a few overlaps of its column of
        # contacts, or shell_press_step mean radii while it carries less than a quarter of the
        # target (the cut layer's deficit closing: little resistance)
        # (the contacts hold ~3.3 h per diameter, radius_factor above: a servo that gain times
        # stiffer backs the walls off faster after a stiffening but leaves the stages unsettled,
        # docs/packings.md)
        max_move = r_mean * min(1e-2, 2.0 * layers * overlap_scale)
        # Hertz: a column of `layers` contacts of overlap ~ overlap_scale r shortens by
        # layers r overlap_scale ((p_t/p)^(2/3) - 1) to bring its stress from p to p_t; in the
        # soft first stage the cut layer also rearranges: its own gain (shell_soft_gain)
        gain = p["shell_soft_gain"] if k == 0 else 1.0
        settled = 0
        while True:
            O.run(every, True)
            lo, hi = wall_extent(box, walls, body)
            ratio = wall_stresses(walls, body, inward, lo, hi) / p_target
            unbalanced = utils.unbalancedForce()
            # the walls' mean stress within the tolerance (the direct path's criterion on the
            # mean stress), and every wall within twice it
            tol = p["pressure_tolerance"]
            if abs(float(np.mean(ratio)) - 1.0) < tol and np.all(np.abs(ratio - 1.0) < 2 * tol) \
                    and unbalanced < unbalanced_target:
                settled += 1
            else:
                settled = 0
            if settled >= 2:
                break
            move = gain * layers * overlap_scale * r_mean * (
                np.maximum(ratio, 1e-12) ** (-2.0 / 3.0) - 1.0)
            if k == 0:
                # the soft stage: shell_press_step while a wall carries almost nothing (its
                # travel onto the protruding spheres), then shell_loaded_step while the wall
                # layer jams under it
                inward_cap = np.where(ratio < 0.05, p["shell_press_step"] * r_mean,
                                      min(max_move, p["shell_loaded_step"] * r_mean))
            else:
                inward_cap = np.where(ratio < 0.25, p["shell_press_step"] * r_mean, max_move)
            move = np.clip(move, -max_move, inward_cap)
            if settled:
                move[:] = 0.0
            move_walls(walls, body, inward, move, every)
            now = time.time() - t0
            if now - last > 3.0:
                last = now
                log(f"shell: E {young:.3g} Pa ({k + 1}/{len(stages)}{label}), step {O.iter}, "
                    f"wall stress/target {ratio.min():.3f} ... {ratio.max():.3f}, "
                    f"unbalanced {unbalanced:.3g}, {now:.0f} s")
            if now > p["max_seconds"]:
                fail(f"max_seconds: the shell was not pressed after {now:.0f} s (wall "
                     f"stress/target {ratio.min():.3f} ... {ratio.max():.3f}, unbalanced "
                     f"{unbalanced:.3g})", code=3)
        for b in wall_of_body:
            O.bodies[b].state.vel = Vector3(0, 0, 0)
        log(f"shell: E {young:.3g} Pa ({k + 1}/{len(stages)}{label}) relaxed at step {O.iter}: "
            f"wall stress/target {ratio.min():.4f} ... {ratio.max():.4f}, unbalanced "
            f"{unbalanced:.3g}, {time.time() - t0:.0f} s")
    steps = O.iter
    unbalanced = utils.unbalancedForce()
    pressure = float(np.mean(ratio)) * p_target
    # the dump's contacts: YADE's forces of exactly the final geometry (as in the direct path)
    O.interactions.clear()
    collider.doSort = True
    O.engines[-1].dead = True
    O.step()
    lo, hi = wall_extent(box, walls, body)
    pressure_normal = float(np.mean(wall_stresses(walls, body, inward, lo, hi)))
    index_of = {int(b): k for k, b in enumerate(sphere_ids)}
    position = np.array([[O.bodies[int(b)].state.pos[j] for j in range(3)] for b in sphere_ids])
    force, wall_touch = yade_forces(index_of, wall_of_body)
    return dict(position=position, lo=lo, hi=hi, force=force,
                wall_touch=wall_touch, steps=int(steps), seconds=time.time() - t0,
                unbalanced=float(unbalanced), pressure=pressure,
                pressure_normal=pressure_normal)


def grow_cloud(p, box, cloud_ids, collider, walls, body, inward, compliance_m, every):
    """The cloud of method = "shell" (shell.cloud_layer) grown back from shell.CLOUD_SHRINK to
    its radii, as the direct path grows its cloud against fixed walls (1 % per control interval
    while the radii are below 0.9 of theirs, then 0.2 %, the direct path's largest step): the
    walls hold, except that one carrying more than the confining pressure moves out (its Hertz
    compliance_m, the shell's column at the soft stage). The soft stage then presses them."""
    p_target = p["confining_pressure_pa"]
    size_now = shell.CLOUD_SHRINK      # (press_shell shrank them when it built the scene)
    t0, last = time.time(), 0.0
    while size_now < 1.0:
        factor = min(1.0 + (1e-2 if size_now < 0.9 else 2e-3), 1.0 / size_now)
        for b in cloud_ids:
            O.bodies[b].shape.radius *= factor
        size_now *= factor
        collider.doSort = True
        O.run(every, True)
        lo, hi = wall_extent(box, walls, body)
        ratio = wall_stresses(walls, body, inward, lo, hi) / p_target
        out = np.minimum(compliance_m * (np.maximum(ratio, 1e-12) ** (-2.0 / 3.0) - 1.0), 0.0)
        move_walls(walls, body, inward, out, every)
        now = time.time() - t0
        if now - last > 3.0:
            last = now
            log(f"shell: the cloud at {size_now:.3f} of its radii, step {O.iter}, wall "
                f"stress/target {ratio.min():.3f} ... {ratio.max():.3f}, {now:.0f} s")
    for b in body.values():
        O.bodies[b].state.vel = Vector3(0, 0, 0)
    log(f"shell: the cloud grown back to its radii at step {O.iter}, wall stress/target "
        f"{ratio.min():.3f} ... {ratio.max():.3f}, {time.time() - t0:.0f} s")


def shell_state(p, state):
    """method = "shell": tile and carve as method = "tiled" (keeping the spheres whose centre
    lies shell_cut_depth of their radii inside), then press walls onto a shell of
    shell_diameters mean diameters (press_shell); returns the state of the pressed domain and
    the tiling's and shell's attributes. (~85 lines: the carve, the split into free, frozen
    and interior spheres, the press and the reassembly are one pass over the same arrays.)"""
    carved, cell_info = tiled_state(p, state)
    kept_first, _, _ = shell.split(carved["box"], carved["position"], carved["radius"], 0.0, 0.0,
                                   p["shell_cut_depth"])
    if not kept_first.all():
        # the spheres cut by the surface are removed: carve a little more, so that about
        # n_particles remain (with the centre-inside carve none is, and the tiling stands)
        carved, cell_info = tiled_state(
            dict(p, n_particles=int(round(p["n_particles"] / kept_first.mean()))), state)
    box, position, radius = carved["box"], carved["position"], carved["radius"]
    shell_m = p["shell_diameters"] * 2.0 * float(radius.mean())
    band_m = shell.frozen_band_m(radius, p["gap_tolerance"])
    whole, free, band = shell.split(box, position, radius, shell_m, band_m,
                                    p["shell_cut_depth"])
    _, rows, pair = carve(whole, carved["pair"])
    kept = (pair,) + tuple(carved[k][rows] for k in ("branch", "overlap", "normal_force",
                                                     "contact_radius"))
    position, radius, free, band = position[whole], radius[whole], free[whole], band[whole]
    if p["shell_cloud_diameters"] > 0:
        # the outer layer put back as a loose cloud in a grown box, the walls on its faces (the
        # layer sized for the soft stage's radii instead, 2 % more volume, was measured with
        # the Hertz gain of 1.65 and dropped with it: docs/packings.md)
        layer_phi = shell.layer_solid_fraction(
            float(np.sum(4.0 / 3.0 * np.pi * radius ** 3)) / float(np.prod(box.size)),
            p["shell_cloud_diameters"])
        try:
            position, clouded, grown = shell.cloud_layer(
                box, position, radius, p["shell_cloud_diameters"] * 2.0 * float(radius.mean()),
                p["seed"] + 7, layer_phi, shrink=shell.CLOUD_SHRINK)
        except ValueError as e:
            fail(str(e), code=3)
        log(f"shell: {int(clouded.sum())} spheres of the outer "
            f"{p['shell_cloud_diameters']:g} mean diameters put back as a cloud, radii x "
            f"{shell.CLOUD_SHRINK} (they fill their layer at {layer_phi:.4f} at their own "
            f"radii); walls start {(grown[0] - box.size[0]) / 2:.4g} m outside the carved faces")
        box = shell.pressed_box(np.zeros(3), grown)
    else:
        clouded = np.zeros(len(radius), dtype=bool)
        # spheres that protrude past the surface (shell_cut_depth < 1): the walls start at
        # their extent, so that none overlaps a wall
        start_lo, start_hi = shell.walls_start(box, position, radius)
        position = position - start_lo
        box = shell.pressed_box(np.zeros(3), start_hi - start_lo)
    sub = np.flatnonzero(free | band)
    log(f"shell: {int((~whole).sum())} spheres cut by the surface removed; {int(free.sum())} "
        f"free in a shell of {shell_m:.4g} m ({p['shell_diameters']:g} mean diameters), "
        f"{int(band.sum())} frozen behind it ({band_m:.4g} m), {len(radius) - len(sub)} "
        f"interior spheres stay as tiled")
    pressed = press_shell(p, box, position[sub], radius[sub], band[sub], shell_m, clouded[sub])
    position = position.copy()
    position[sub] = pressed["position"]
    position -= pressed["lo"]
    new_box = shell.pressed_box(pressed["lo"], pressed["hi"])
    s_pair, s_branch, s_overlap, s_force, s_radius, n_untracked = relaxed_contacts(
        position[sub], radius[sub], p["gap_tolerance"], None, pressed["force"])
    pair, branch, overlap, normal_force, contact_radius = shell.merge_contacts(
        free, kept, (sub[s_pair], s_branch, s_overlap, s_force, s_radius))
    walls = new_box.walls()
    wall_particle, wall_index, wall_overlap, wall_force = relaxed_wall_contacts(
        new_box, walls, position[sub], radius[sub], p["wall_gap_tolerance"],
        pressed["wall_touch"])
    info = dict(cell_info, shell_diameters=float(p["shell_diameters"]),
                shell_cloud_diameters=float(p["shell_cloud_diameters"]),
                shell_thickness_m=shell_m, frozen_band_m=band_m,
                shell_free_particles=int(free.sum()),
                shell_frozen_particles=int(band.sum()),
                shell_cut_particles_removed=int((~whole).sum()),
                shell_steps=pressed["steps"], shell_seconds=pressed["seconds"],
                cell_steps=int(state["compress_steps"]),
                carved_size_m=np.asarray(box.size, dtype=float))
    log(f"shell: pressed in {pressed['seconds']:.1f} s, {pressed['steps']} DEM steps: domain "
        f"{new_box.size[0]:.5g} x {new_box.size[1]:.5g} x {new_box.size[2]:.5g} m (carved "
        f"{box.size[0]:.5g} x {box.size[1]:.5g} x {box.size[2]:.5g}), wall stress "
        f"{pressed['pressure']:.4g} Pa, unbalanced {pressed['unbalanced']:.3g}")
    return dict(state, box=new_box, position=position, radius=radius, pair=pair, branch=branch,
                overlap=overlap, normal_force=normal_force, contact_radius=contact_radius,
                walls=walls, wall_particle=sub[wall_particle], wall_index=wall_index,
                wall_overlap=wall_overlap, wall_force=wall_force, periodic=False,
                n=len(radius), sphere_ids=None, unbalanced=pressed["unbalanced"],
                pressure=pressed["pressure"], pressure_normal=pressed["pressure_normal"],
                compress_seconds=state["compress_seconds"] + pressed["seconds"],
                compress_steps=int(state["compress_steps"]) + pressed["steps"],
                n_untracked=n_untracked), info


def domain_attrs(p, state, phi, phi_bulk, n_dispersed, cell_info, t0):
    """The root attributes of packing.h5."""
    n, pair = state["n"], state["pair"]
    touching = state["overlap"] > 0
    return {
        "generator": "yade_scripts/dense_packing.py", "seed": int(p["seed"]),
        "shape": state["box"].shape, "solid_fraction": phi, "solid_fraction_bulk": phi_bulk,
        "domain_volume_m3": float(state["box"].volume),
        "mean_coordination": float(2.0 * touching.sum() / n),
        "mean_coordination_with_gaps": float(2.0 * len(pair) / n),
        "pressure_pa": float(state["pressure"]),
        "confining_pressure_pa": p["confining_pressure_pa"],
        "mean_stress_from_dumped_forces_pa": float(state["pressure_normal"]),
        "young_pa": p["young_pa"], "young_pa_used": p["young_pa"],
        "young_pa_softened_start": stiffness_stages(p)[0], "poisson": p["poisson"],
        "density": p["density"], "density_scaling": p["density_scaling"],
        "friction": p["friction"], "compaction_friction": p["compaction_friction"],
        "unbalanced_force_ratio": float(state["unbalanced"]),
        "neighbour_criterion": "centre distance < (1 + gap_tolerance)(r_i + r_j)",
        "gap_tolerance": p["gap_tolerance"], "wall_gap_tolerance": p["wall_gap_tolerance"],
        "wall_segments": p["wall_segments"],
        "sphere_facet_level": p["sphere_facet_level"],
        "wall_contact_model": "Hertz with R* = r and E* = E / (2 (1 - nu^2)): a flat wall of "
                              "the particles' material (curved walls: facets, locally flat)"
        if p["method"] in ("direct", "shell") else
        "cut surface of a tiled periodic packing: spheres within (1 + wall_gap_tolerance) r "
        "of it, overlap = r - distance, no force (nothing was pressed against them)",
        "method": p["method"], "time_step": p["time_step"], "cell_packing": p["cell_packing"],
        "stiffen_factor": p["stiffen_factor"], **cell_info,
        "contacts_touching_without_yade_force": state["n_untracked"],
        "radius_distribution": p["radius_distribution"],
        "radius_mean_requested_m": p["radius_mean_m"],
        "radius_growth_factor": float(state["radius"].mean() / state["radii_drawn"].mean()),
        "inclusions_dispersed": n_dispersed,
        "compression_seconds": state["compress_seconds"],
        "compression_steps": int(state["compress_steps"]),
        "yade_version": yade_version(), "wall_seconds": time.time() - t0,
    }


METHOD_LINE = {
    "direct": "the whole domain relaxed with its walls",
    "tiled": "copies of a relaxed periodic cell, carved: cut faces, no walls",
    "shell": "copies of a relaxed periodic cell, carved, walls pressed onto a shell along them",
}


def main():
    import_yade()
    p = read_params()
    t0 = time.time()
    tiled = p["method"] in ("tiled", "shell")       # both copy a relaxed periodic cell
    log(f"method: {p['method']} ({METHOD_LINE[p['method']]})")
    # build and relax (or read a relaxed cell)
    if tiled and p["cell_packing"]:
        state = read_cell_packing(p)
    else:
        state = relax_cell_or_domain(p)
    cell_info = {}
    if tiled:
        if not p["cell_packing"]:
            write_cell(p, state)
        state, cell_info = (shell_state if p["method"] == "shell" else tiled_state)(p, state)
    # measure
    position, radius, box, periodic = (state[k] for k in ("position", "radius", "box",
                                                           "periodic"))
    phase, n_dispersed = assign_phases(p, position, radius, box, periodic)
    phi, phi_bulk = solid_fractions(position, radius, box, periodic)
    attrs = domain_attrs(p, state, phi, phi_bulk, n_dispersed, cell_info, t0)
    # write
    out = os.path.join(p["output_dir"], "packing.h5")
    write_packing(out, position, radius, phase, state["pair"], state["overlap"],
                  state["normal_force"], state["branch"], state["walls"],
                  state["wall_particle"], state["wall_index"], state["wall_overlap"],
                  state["wall_force"], np.zeros(3), box.size.copy(), [periodic] * 3, attrs,
                  contact_radius=state["contact_radius"],
                  wall_contact_radius=np.zeros(len(state["wall_particle"])),
                  yade_id=state["sphere_ids"])
    log(f"wrote {out}: {state['n']} particles, phi {phi:.4f} (bulk {phi_bulk:.4f}), "
        f"Z {attrs['mean_coordination']:.3f} (with gaps "
        f"{attrs['mean_coordination_with_gaps']:.3f}), {time.time() - t0:.1f} s")


def yade_version():
    try:
        from yade import config
        return str(config.version)
    except Exception:   # noqa: BLE001 - version is informative only
        return "unknown"


if __name__ == "__main__":
    main()
    sys.exit(0)
