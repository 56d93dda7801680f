"""Case 4 diagnostic (docs/validation.md): the STEADY profile of the cube slab against the linear
one, in % of dT, 20 partial-volume bins between the held planes. The steady calibration makes
the heat flow exact; this shows whether the profile is linear too (a boundary resistance or a
non-uniform conductivity along x bends it).

  .venv/bin/python validation/case4_steady_profile.py PACKING.h5
"""
import importlib.util
import sys
from pathlib import Path

import numpy as np

from tdem_post.profiles import binned_profile
from thermal_kernel.network import assemble
from thermal_kernel.packing import read_packing
from thermal_kernel.problem import boundary_particles, build_problem
from thermal_kernel.scene import load_scene
from thermal_kernel.solvers.steady import solve_steady

spec = importlib.util.spec_from_file_location("case4_slab", Path(__file__).with_name("case4_slab.py"))
c4 = importlib.util.module_from_spec(spec)
spec.loader.exec_module(c4)

path = str(Path(sys.argv[1]).resolve())
p = read_packing(path)
scene = load_scene("validation/case4_scene.toml", text=c4.scene_text(path, 0.64))
x0, x1 = (float(np.mean(p.position[boundary_particles(scene, p, on, "b")][:, 0]))
          for on in ("xmin", "xmax"))
length = x1 - x0
net = assemble(build_problem(scene, p)[0])
T = solve_steady(net, np.full(p.n_particles, 0.5 * (c4.T1 + c4.T2))).temperature_k[-1]
conducting = np.asarray(net.degree_w_k > 0) | np.asarray(net.held)
edges = np.linspace(0.0, length, 21)
prof = binned_profile(p.position[:, 0] - x0, p.radius, T, edges, weights=conducting)
linear = c4.T1 + (c4.T2 - c4.T1) * 0.5 * (edges[1:] + edges[:-1]) / length
print(path, "steady (T - linear) / dT, % per bin (cold -> hot):",
      " ".join(f"{v:+.3f}" for v in 100 * (prof - linear) / (c4.T2 - c4.T1)))
