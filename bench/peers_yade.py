"""YADE's ThermalEngine on a tdem packing, for bench/bench_peers.py (runs inside Debian's YADE:
``yade -n -jT -x bench/peers_yade.py params.json``; no tdem import, no venv).

params.json: ``spheres`` (a text file, one ``x y z r type`` line per sphere, tdem's order),
``cell_m`` (the periodic cell: the packing is periodic along x and y; z is made 3x the bed so
that nothing touches across it), ``k``, ``cp``, ``density``, ``young_pa``, ``poisson``, ``dt``,
``steps``, ``t0``, ``t_hot``, ``t_cold`` (types 2 and 3 held: ``Tcondition``), ``out``.

Engines: the usual DEM loop (ForceResetter, InsertionSortCollider, InteractionLoop with
Ig2_Sphere_Sphere_ScGeom / FrictPhys / CundallStrack, a dead FlowEngine that ThermalEngine
needs, ThermalEngine, NewtonIntegrator) with every sphere's motion blocked: a static packing.
``tsSafetyFactor = 0``: one O.step() is one conduction step at O.dt (../shared/FINDINGS.md);
``advection = fluidConduction = False`` (their default True leaves every particle a cavity body
that no conduction reaches: measured with YADE 2023.02a, 0 K moved) and ``thermoMech = False``,
``particleAlpha = 0`` (else the radii grow with the temperature: the answer drifted from tdem's
``yade`` law by 1.7e-6 after two steps, 4 % after 100).
Its law is the default one (G = 2 (k_i + k_j) r_i r_j / d, tdem's ``yade`` law).

Written to ``out`` (JSON): the final temperatures in the file's order, the wall time of the
``steps`` steps, ThermalEngine's own execTime over them, the number of real interactions, the
peak RSS of the process (kB).
"""
import json
import resource
import sys
import time

from yade import utils
from yade.wrapper import (Omega, FrictMat, ForceResetter, InsertionSortCollider, Bo1_Sphere_Aabb,
                          InteractionLoop, Ig2_Sphere_Sphere_ScGeom,
                          Ip2_FrictMat_FrictMat_FrictPhys, Law2_ScGeom_FrictPhys_CundallStrack,
                          FlowEngine, ThermalEngine, NewtonIntegrator)

O = Omega()          # noqa: E741  (YADE's own name)

params = json.load(open(sys.argv[-1]))
rows = [line.split() for line in open(params["spheres"]) if line.strip()]
mat = O.materials.append(FrictMat(young=params["young_pa"], poisson=params["poisson"],
                                  density=params["density"], frictionAngle=0.5))
O.periodic = True
lx, ly, lz = params["cell_m"]
O.cell.setBox(lx, ly, lz)
ids = O.bodies.append([utils.sphere((float(r[0]), float(r[1]), float(r[2])), float(r[3]),
                                    material=mat, fixed=True) for r in rows])
types = [int(r[4]) for r in rows]
te = ThermalEngine(particleCp=params["cp"], particleK=params["k"], particleT0=params["t0"],
                   particleDensity=0, tsSafetyFactor=0, boundarySet=True,
                   advection=False, fluidConduction=False, thermoMech=False, particleAlpha=0.0)
O.engines = [
    ForceResetter(),
    InsertionSortCollider([Bo1_Sphere_Aabb()]),
    InteractionLoop([Ig2_Sphere_Sphere_ScGeom()], [Ip2_FrictMat_FrictMat_FrictPhys()],
                    [Law2_ScGeom_FrictPhys_CundallStrack()]),
    FlowEngine(dead=True),
    te,
    NewtonIntegrator(damping=0.0),
]
O.dt = params["dt"]
O.step()                     # interactions made, thermal states set up (all at t0: no change)
for b, t in zip(ids, types):
    s = O.bodies[b].state
    s.temp = params["t0"]
    if t == 2:
        s.temp, s.Tcondition = params["t_hot"], True
    elif t == 3:
        s.temp, s.Tcondition = params["t_cold"], True
real = sum(1 for i in O.interactions if i.isReal)
O.timingEnabled = True
te.execTime = 0
start = time.perf_counter()
O.run(int(params["steps"]), True)
wall = time.perf_counter() - start
out = {"temperature_k": [O.bodies[b].state.temp for b in ids], "wall_s": wall,
       "thermal_engine_s": te.execTime * 1e-9, "steps": int(params["steps"]),
       "real_interactions": real,
       "peak_rss_kb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss}
json.dump(out, open(params["out"], "w"))
sys.exit(0)
