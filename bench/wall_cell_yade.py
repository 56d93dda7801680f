# Experiment of issue 24 (docs/packings.md, "a wall cell"): a packing periodic in x and y
# between two flat walls at z0 and z1 (thin Box bodies larger than the period, which YADE's
# InsertionSortCollider accepts with allowBiggerThanPeriod = True, where it refuses a Wall),
# compacted from a loose cloud exactly as the direct walled box is (dense_packing.compress:
# radius growth at fixed walls, the softened-modulus stages; the mean stress over the slab's
# volume). Writes the relaxed state as an .npz (position, radius, z0, z1, L, steps, seconds,
# wall_force_z) that bench/wall_cell_compare.py reads.
#
#   yade -n -j1 -x bench/wall_cell_yade.py BASE_PARAMS.json N SEED OUT.npz
#
# BASE_PARAMS.json: a dense box's params.json (e.g. bench/out/walled/direct_10000_s1/, written
# by tdem pack); its shape and n_particles are replaced.
import json
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(sys.argv[0]))))
import numpy as np  # noqa: E402
from yade_scripts import dense_packing as D  # noqa: E402
from yade_scripts.dense_geometry import make_cloud  # noqa: E402

D.import_yade()
from yade import O, utils  # noqa: E402
from yade.minieigenHP import Matrix3  # noqa: E402
from yade.wrapper import Bo1_Box_Aabb, Ig2_Box_Sphere_ScGeom, InteractionLoop  # noqa: E402

base, n, seed, out = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
p = json.load(open(base))
p.update(shape="periodic", n_particles=n, seed=seed, aspect=[1.0, 1.0, 1.0], method="direct",
         max_seconds=14400.0)
centres, radii0, box, radii_drawn = make_cloud(p)
rmax = float(radii0.max())
L = float(box.size[0])
z0, z1 = -1.01 * rmax, float(box.size[2]) + 1.01 * rmax
slab_volume = L * float(box.size[1]) * (z1 - z0)
period_z = (z1 - z0) + 20 * rmax
D.log(f"wall cell: {n} spheres, L {L:.4g} m, walls at z {z0:.4g}, {z1:.4g} m")
orig_build = D.build_scene
state = {}

def build_scene(p, centres, radii, box, young):
    """dense_packing.build_scene's periodic cell, its z period widened past the walls, and the
    two walls: boxes 1e-3 mean radii thick (the stress's branch vectors then end on the wall
    planes, as a Wall's do) of the plane walls' material."""
    mats, ids, wall_of_body, collider = orig_build(p, centres, radii, box, young)
    O.cell.hSize = Matrix3(box.size[0], 0, 0, 0, box.size[1], 0, 0, 0, period_z)
    t = 1e-3 * float(np.mean(radii))
    lo = O.bodies.append(utils.box((L / 2, box.size[1] / 2, z0 - t), (2 * L, 2 * box.size[1], t),
                                   fixed=True, material=mats[1]))
    hi = O.bodies.append(utils.box((L / 2, box.size[1] / 2, z1 + t), (2 * L, 2 * box.size[1], t),
                                   fixed=True, material=mats[1]))
    state["walls"] = (lo, hi)
    collider.boundDispatcher.functors = list(collider.boundDispatcher.functors) + [Bo1_Box_Aabb()]
    collider.allowBiggerThanPeriod = True
    loop = [e for e in O.engines if isinstance(e, InteractionLoop)][0]
    loop.geomDispatcher.functors = list(loop.geomDispatcher.functors) + [Ig2_Box_Sphere_ScGeom()]
    return mats, ids, wall_of_body, collider

def mean_stress(box):
    """The mean stress over the slab between the walls (not the widened cell)."""
    s = utils.getStress(slab_volume)
    return -(s[0, 0] + s[1, 1] + s[2, 2]) / 3.0


D.build_scene = build_scene
D.mean_stress = mean_stress
t0 = time.time()
secs, ids, _, collider = D.compress(p, centres, radii0, box)
pos = np.array([[O.bodies[int(b)].state.pos[j] for j in range(3)] for b in ids])
rad = np.array([O.bodies[int(b)].shape.radius for b in ids])
pos[:, :2] -= np.floor(pos[:, :2] / box.size[:2]) * box.size[:2]
fz = [O.forces.f(w)[2] for w in state["walls"]]
np.savez(out, position=pos, radius=rad, z0=z0, z1=z1, L=np.asarray(box.size[:2]), steps=O.iter,
         seconds=time.time() - t0, wall_force_z=np.array(fz))
D.log(f"wall cell done: {O.iter} steps, {time.time() - t0:.0f} s, wall stress "
      f"{fz[0] / (L * box.size[1]):.4g} {fz[1] / (L * box.size[1]):.4g} Pa")
