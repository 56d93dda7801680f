"""Case 6 of docs/validation.md: C_t of the haddad law (002 sec. 2.1, eq. 8-9, Fig. 3) against
N and shape, in both slab-length conventions.

For each packing and each axis with a flux test: `thermal_kernel.calibrate.calibrate_axes` (what
`tdem calibrate` prints: lambda^e = Q L / (A dT) with L the DOMAIN length, the paper's sample
length of eq. 8) and the same C_t with L the HELD-PLANE distance (mean centre planes of the two
held sets, the slab `tdem post` and validation/case4_slab.py use): since lambda^e is
proportional to L and C_t to 1 / lambda^e, C_t(held) = C_t(domain) x L_domain / L_held.
Also the coordination with gaps (every dumped pair, gap contacts included), over all particles
and over the bulk (centres more than 3 mean radii from every face).

  .venv/bin/python validation/case6_calibrate.py NAME=PACKING.h5 [...] [--out validation/out/case6]

Appends one row per (packing, axis) to OUT/case6.csv (a packing already there is skipped).
"""
from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np

from thermal_kernel.calibrate import calibrate_axes
from thermal_kernel.packing import read_packing
from thermal_kernel.problem import boundary_particles
from thermal_kernel.scene import load_scene

FIELDS = ["name", "n_particles", "shape", "axis", "ct_domain", "ct_held", "length_domain_m",
          "length_held_m", "z_all", "z_bulk", "solid_fraction", "seconds"]


def coordination(packing):
    n = packing.n_particles
    deg = np.bincount(packing.pair.ravel(), minlength=n)
    r = float(packing.radius.mean())
    lo, hi = packing.domain_lo, packing.domain_hi
    p = packing.position
    bulk = np.all((p - lo > 3 * r) | packing.periodic, axis=1) & \
        np.all((hi - p > 3 * r) | packing.periodic, axis=1)
    if any(k == "cylinder" for k in packing.wall_kind):
        c = 0.5 * (lo + hi)
        k = [i for i, kind in enumerate(packing.wall_kind) if kind == "cylinder"][0]
        ax = int(np.argmax(np.abs(packing.wall_normal[k])))
        d = np.delete(p - c, ax, axis=1)
        bulk &= np.hypot(d[:, 0], d[:, 1]) < float(packing.wall_radius[k]) - 3 * r
    return float(deg.mean()), float(deg[bulk].mean())


def one(name, path, scene_path="runs/dense_box.toml"):
    packing = read_packing(path)
    scene = load_scene(scene_path)
    t0 = time.perf_counter()
    results, _, _ = calibrate_axes(scene, packing)
    seconds = time.perf_counter() - t0
    shape = "cylinder" if any(k == "cylinder" for k in packing.wall_kind) else "box"
    z_all, z_bulk = coordination(packing)
    rows = []
    for r in results:
        k = "xyz".index(r.axis)
        x0, x1 = (float(np.mean(packing.position[boundary_particles(scene, packing, f"{r.axis}{s}",
                                                                    "b")][:, k]))
                  for s in ("min", "max"))
        held = x1 - x0
        rows.append(dict(name=name, n_particles=packing.n_particles, shape=shape, axis=r.axis,
                         ct_domain=r.ct, ct_held=r.ct * r.length_m / held,
                         length_domain_m=r.length_m, length_held_m=held, z_all=z_all,
                         z_bulk=z_bulk, solid_fraction=float(packing.attrs["solid_fraction"]),
                         seconds=seconds))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("packings", nargs="+", help="NAME=PATH")
    ap.add_argument("--out", default="validation/out/case6")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    table = out / "case6.csv"
    done = set()
    if table.exists():
        with open(table) as f:
            done = {row["name"] for row in csv.DictReader(f)}
    for spec in a.packings:
        name, path = spec.split("=", 1)
        if name in done:
            continue
        rows = one(name, path)
        new = not table.exists()
        with open(table, "a", newline="") as f:
            w = csv.DictWriter(f, FIELDS)
            if new:
                w.writeheader()
            w.writerows(rows)
        print(f"case6 {name}: N {rows[0]['n_particles']}, C_t domain "
              f"{np.mean([r['ct_domain'] for r in rows]):.4f}, held "
              f"{np.mean([r['ct_held'] for r in rows]):.4f}, Z {rows[0]['z_all']:.2f} "
              f"(bulk {rows[0]['z_bulk']:.2f}), {rows[0]['seconds']:.1f} s", flush=True)


if __name__ == "__main__":
    main()
