# An ordinary YADE script, written the way YADE's own examples are (utils.sphere, utils.wall,
# geom.facetBox, utils.box, a periodic cell, the usual engines), that calls tdem_yade.dump at
# the end. tests/test_tdem_yade.py runs it with Debian's YADE:
#
#   yade -n -x tests/yade_user_scene.py SCENE OUT_DIR     (SCENE: box, periodic, clump, sheared)
#
# It writes OUT_DIR/packing.h5 (tdem_yade.dump) and OUT_DIR/yade_contacts.json: every real
# interaction as YADE reports it (ids, penetrationDepth, normal force along the normal, the
# bodies' shapes), for the test to compare with the dump.
import json
import os
import sys

from yade import utils, pack, geom
from yade.wrapper import (Omega, FrictMat, ForceResetter, InsertionSortCollider, Bo1_Sphere_Aabb,
                          Bo1_Facet_Aabb, Bo1_Wall_Aabb, Bo1_Box_Aabb, InteractionLoop,
                          Ig2_Sphere_Sphere_ScGeom, Ig2_Facet_Sphere_ScGeom,
                          Ig2_Wall_Sphere_ScGeom, Ig2_Box_Sphere_ScGeom,
                          Ip2_FrictMat_FrictMat_FrictPhys, Law2_ScGeom_FrictPhys_CundallStrack,
                          Ip2_FrictMat_FrictMat_MindlinPhys, Law2_ScGeom_MindlinPhys_Mindlin,
                          NewtonIntegrator, PeriTriaxController)
from yade.minieigenHP import Matrix3

sys.path.insert(0, os.environ["TDEM_YADE_PATH"])     # the folder `tdem yade-path` prints
import tdem_yade  # noqa: E402

O = Omega()
scene, out = sys.argv[1], sys.argv[2]
r = 0.001

if scene in ("box", "clump"):
    # linear Cundall law, a floor (utils.wall), four facet walls (facetBox), a heavy lid (box)
    O.materials.append(FrictMat(young=5e7, poisson=0.3, density=2600, frictionAngle=0.4))
    L = 0.012
    O.bodies.append(utils.wall(0.0, axis=2))
    O.bodies.append(geom.facetBox((L / 2, L / 2, L), (L / 2, L / 2, L), wallMask=15))
    sp = pack.SpherePack()
    sp.makeCloud((0, 0, 0), (L, L, 2 * L), rMean=r, rRelFuzz=0.2, num=240, seed=3)
    sp.toSimulation()
    if scene == "clump":         # refused: dumped at once (no need to settle first)
        O.bodies.appendClumped([utils.sphere((L / 2, L / 2, 2.2 * L), r),
                                utils.sphere((L / 2 + r, L / 2, 2.2 * L), r)])
        tdem_yade.dump(os.path.join(out, "packing.h5"), young_pa=5e7, poisson=0.3)
    O.engines = [
        ForceResetter(),
        InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Facet_Aabb(), Bo1_Wall_Aabb(),
                               Bo1_Box_Aabb()]),
        InteractionLoop([Ig2_Sphere_Sphere_ScGeom(), Ig2_Facet_Sphere_ScGeom(),
                         Ig2_Wall_Sphere_ScGeom(), Ig2_Box_Sphere_ScGeom()],
                        [Ip2_FrictMat_FrictMat_FrictPhys()],
                        [Law2_ScGeom_FrictPhys_CundallStrack()]),
        NewtonIntegrator(gravity=(0, 0, -9.81), damping=0.4),
    ]
    O.dt = 0.5 * utils.PWaveTimeStep()
    O.run(40000, True)
    # a lid of 2 kPa (its weight) on top of the settled spheres
    top = max(b.state.pos[2] + b.shape.radius for b in O.bodies
              if type(b.shape).__name__ == "Sphere")
    lid = utils.box((L / 2, L / 2, top + 0.0005), (L / 2 - 0.0001, L / 2 - 0.0001, 0.0005),
                    fixed=False)
    O.bodies.append(lid)
    lid.state.blockedDOFs = "xyXYZ"
    lid.state.mass = 2000.0 * L * L / 9.81
    O.engines[-1].damping = 0.8                     # come to rest under the lid
    O.run(30000, True)
    tdem_yade.dump(os.path.join(out, "packing.h5"), young_pa=5e7, poisson=0.3,
                   wall_names={lid.id: "plate"}, seed=3)
elif scene in ("periodic", "sheared"):
    # Hertz-Mindlin in a periodic cell compressed to 100 kPa by PeriTriaxController
    O.materials.append(FrictMat(young=1e8, poisson=0.25, density=2600, frictionAngle=0.3))
    O.periodic = True
    sp = pack.SpherePack()
    sp.makeCloud((0, 0, 0), (0.014, 0.014, 0.014), rMean=r, rRelFuzz=0.2, num=220, periodic=True,
                 seed=5)
    sp.toSimulation()
    O.engines = [
        ForceResetter(),
        InsertionSortCollider([Bo1_Sphere_Aabb()]),
        InteractionLoop([Ig2_Sphere_Sphere_ScGeom()], [Ip2_FrictMat_FrictMat_MindlinPhys()],
                        [Law2_ScGeom_MindlinPhys_Mindlin()]),
        PeriTriaxController(goal=(-1e5, -1e5, -1e5), stressMask=7, maxUnbalanced=0.01,
                            relStressTol=0.01, maxStrainRate=(5, 5, 5), mass=1e-4,
                            doneHook="O.pause()", label="triax"),
        NewtonIntegrator(damping=0.4),
    ]
    if scene == "sheared":       # refused: dumped at once
        h = O.cell.hSize
        O.cell.hSize = Matrix3(h[0, 0], 0.1 * h[0, 0], 0, 0, h[1, 1], 0, 0, 0, h[2, 2])
        tdem_yade.dump(os.path.join(out, "packing.h5"), young_pa=1e8, poisson=0.25)
    O.dt = 0.5 * utils.PWaveTimeStep()
    O.run(80000, True)
    tdem_yade.dump(os.path.join(out, "packing.h5"), young_pa=1e8, poisson=0.25, seed=5)
else:
    raise SystemExit(f"unknown scene {scene}")

rows = []
for i in O.interactions.all():
    if not i.isReal:
        continue
    rows.append(dict(id1=i.id1, id2=i.id2, depth=float(i.geom.penetrationDepth),
                     fn=float(i.phys.normalForce.dot(i.geom.normal)),
                     normal=[float(x) for x in i.geom.normal],
                     shape1=type(O.bodies[i.id1].shape).__name__,
                     shape2=type(O.bodies[i.id2].shape).__name__))
stress = utils.getStress() if O.periodic else None
with open(os.path.join(out, "yade_contacts.json"), "w") as f:
    json.dump(dict(contacts=rows, iterations=O.iter, porosity=utils.porosity() if O.periodic
                   else None,
                   mean_stress=-float(stress.trace()) / 3 if stress is not None else None), f)
