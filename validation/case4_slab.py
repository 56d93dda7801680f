"""Case 4 of docs/validation.md: Haddad's cube slab (002 sec. 2.2, eq. 17) on a tdem packing.

The cube between two held faces normal to x (T = 25 C at xmin, 35 C at xmax, 25 C initially,
adiabatic sides), material of 002 Tab. 1 (rho 7800, lambda 33, c 0.9), law haddad with C_t
calibrated on the same packing by the steady flux test with the HELD-PLANE length (the distance
between the mean centre planes of the two held sets, the slab of the analytical solution, as
`tdem post` uses); the domain-length C_t (`tdem calibrate`, the paper's convention) is printed
beside it. The geometry is not rescaled to L = 10 cm: conduction depends only on the Fourier
number, so the outputs are at the paper's Fo = alpha t / L^2 with alpha = 33 / (7800 * 0.9) and
L = 10 cm at t = 0.05, 0.1, 0.2 s, i.e. Fo = 0.0235, 0.0470, 0.0940, with our L.

Forward Euler (as the paper) at 0.9 x the exact positivity bound. Profile: partial-volume
weighted means over n_bins equal bins of [0, L] (rattlers excluded), against the bin mean of
the slab series (tdem_post.analytic.slab_mean_temperature).

  .venv/bin/python validation/case4_slab.py PACKING.h5 [--bins 10] [--out DIR] [--name NAME]

Writes DIR/NAME.json (errors, C_t, timings) and DIR/NAME_profiles.csv.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from tdem_post.analytic import slab_mean_temperature
from tdem_post.profiles import binned_profile
from thermal_kernel.calibrate import cross_section, flux_test
from thermal_kernel.network import assemble
from thermal_kernel.packing import read_packing
from thermal_kernel.problem import boundary_particles, build_problem
from thermal_kernel.scene import load_scene
from thermal_kernel.solvers.explicit import run_explicit

RHO, LAMBDA, CAP = 7800.0, 33.0, 0.9          # 002 Tab. 1
ALPHA = LAMBDA / (RHO * CAP)
T1, T2 = 298.15, 308.15                         # 25 C at x = 0, 35 C at x = L
PAPER_L, PAPER_TIMES = 0.1, (0.05, 0.1, 0.2)
FOURIER = tuple(ALPHA * t / PAPER_L ** 2 for t in PAPER_TIMES)


def scene_text(packing: str, ct: float) -> str:
    return f"""
packing = "{packing}"
law = "haddad"
[law_params]
ct = {ct!r}
[material]
conductivity = {LAMBDA}
density = {RHO}
heat_capacity = {CAP}
[initial]
temperature = {T1}
[[boundary]]
kind = "temperature"
name = "cold"
on = "xmin"
value = {T1}
[[boundary]]
kind = "temperature"
name = "hot"
on = "xmax"
value = {T2}
[solver]
method = "steady"
"""


def slab_case(packing_path, n_bins: int = 10, threads: int = 1, ct_arb: float = 0.806):
    packing_path = str(Path(packing_path).resolve())
    scene_path = Path("validation/case4_scene.toml")
    packing = read_packing(packing_path)
    scene = load_scene(scene_path, text=scene_text(packing_path, ct_arb))
    c0 = time.perf_counter()
    # held-plane slab: mean centre planes of the two held sets
    x0, x1 = (float(np.mean(packing.position[boundary_particles(scene, packing, on, "b")][:, 0]))
              for on in ("xmin", "xmax"))
    length = x1 - x0
    domain_length = float(packing.domain_hi[0] - packing.domain_lo[0])
    # C_t from one steady flux test (002 eq. 8-9); lambda_e is proportional to the length used
    test = flux_test(scene, packing, "x")
    area = cross_section(packing, 0)
    ct_domain = ct_arb * LAMBDA / test.effective_w_mk
    ct_held = ct_domain * domain_length / length
    calib_s = time.perf_counter() - c0

    scene = load_scene(scene_path, text=scene_text(packing_path, ct_held))
    problem, _ = build_problem(scene, packing)
    net = assemble(problem)
    times = [fo * length ** 2 / ALPHA for fo in FOURIER]
    r0 = time.perf_counter()
    result = run_explicit(net, np.full(packing.n_particles, T1), times, threads=threads)
    run_s = time.perf_counter() - r0

    conducting = np.asarray(net.degree_w_k > 0) | np.asarray(net.held)
    x = packing.position[:, 0] - x0
    edges = np.linspace(0.0, length, n_bins + 1)
    prof = binned_profile(x, packing.radius, result.temperature_k, edges, weights=conducting)
    exact = np.array([slab_mean_temperature(edges[:-1], edges[1:], t, length, ALPHA, T1, T2, T1)
                      for t in times])
    err = prof - exact
    err_dt = np.abs(err) / (T2 - T1)                    # relative to the imposed difference
    err_c = np.abs(err) / (exact - 273.15)              # relative to T in C (the paper's, Fig. 5b)
    summary = {
        "packing": packing_path, "n_particles": int(packing.n_particles), "n_bins": n_bins,
        "length_held_m": length, "length_domain_m": domain_length,
        "ct_held_plane": ct_held, "ct_domain_length": ct_domain,
        "steady_balance": test.balance, "area_m2": area,
        "fourier": list(FOURIER), "times_s": times, "dt_s": result.dt, "steps": result.steps,
        "max_rel_error_celsius": float(err_c.max()),
        "max_rel_error_celsius_per_time": err_c.max(axis=1).tolist(),
        "max_error_over_dT": float(err_dt.max()),
        "max_error_over_dT_per_time": err_dt.max(axis=1).tolist(),
        "calibration_seconds": calib_s, "run_seconds": run_s, "threads": threads,
    }
    rows = []
    for k, t in enumerate(times):
        for b in range(n_bins):
            rows.append((FOURIER[k], t, 0.5 * (edges[b] + edges[b + 1]) / length,
                         prof[k, b] - 273.15, exact[k, b] - 273.15, err[k, b]))
    return summary, rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("packing")
    ap.add_argument("--bins", type=int, default=10)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--out", default="validation/out/case4")
    ap.add_argument("--name", default=None)
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    name = a.name or Path(a.packing).parent.name
    summary, rows = slab_case(a.packing, a.bins, a.threads)
    (out / f"{name}.json").write_text(json.dumps(summary, indent=1))
    with open(out / f"{name}_profiles.csv", "w") as f:
        f.write("fourier,time_s,x_over_L,T_dem_C,T_exact_C,error_K\n")
        for r in rows:
            f.write(",".join(f"{v:.10g}" for v in r) + "\n")
    print(f"{name}: N {summary['n_particles']}, C_t {summary['ct_held_plane']:.4f} (held plane) "
          f"/ {summary['ct_domain_length']:.4f} (domain), max |err|/T(C) "
          f"{100 * summary['max_rel_error_celsius']:.3f} %, max |err|/dT "
          f"{100 * summary['max_error_over_dT']:.3f} %, {summary['steps']} steps, "
          f"{summary['run_seconds']:.1f} s")


if __name__ == "__main__":
    main()
