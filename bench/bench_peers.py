"""tdem against its peers, in one run on one machine (issue 27; not a test; `make bench-peers`):
YADE's ThermalEngine, LIGGGHTS' fix heat/gran/conduction and tdem (explicit, implicit, steady)
on the same packings, each peer with its own law and tdem with the same law.

    .venv/bin/python bench/bench_peers.py [--sizes 2e3,1e4,5e4] [--steps 400] [--fresh]

For each size: LIGGGHTS settles a bed (runs/liggghts_heat/pack.in, 2 ranks; kept in
bench/out/peers/<size>/ and reused unless --fresh), its bottom and top layers become types 2
and 3 (tdem.liggghts_heat.write_data), `tdem import liggghts` reads it. The question, for each
law: the particles at 300 K, the bottom layer held at 400 K and the top one at 350 K;
(transient) every temperature at t_end = steps x dt0, dt0 the power of two <= half tdem's
explicit bound dt_max of that law; (steady) the steady field. The answer is "within 1 %": the
largest |T - T_ref| over the particles below 1 % of the 100 K span.

References (converged, not timed): transient, tdem implicit Crank-Nicolson (Rannacher start)
at dt0/4, its own error estimated from dt0/2 (printed); steady, tdem's direct steady solve.

Measured, each in its own process (its peak RSS is the memory column):
- LIGGGHTS (law `liggghts`) on 1 and 2 MPI ranks: `steps` explicit steps at the explicit dt
  (static bed: no time integration of the motion, but the pair forces are computed every step);
  time = LIGGGHTS' "Loop time" (setup and reading excluded); contact-updates/s = contacts x
  steps / loop time (the whole step); its Pair share is printed.
- YADE 2023.02a (law `yade`) on 1 and 2 threads: the same march (bench/peers_yade.py); time
  = O.run's wall time (the whole step), and ThermalEngine's own execTime.
- tdem: explicit, the same march (1 and 2 numba threads); implicit, the fewest Crank-Nicolson
  steps over [0, t_end] (1, 2, 4, ...) within 1 %, with a direct factorisation and with AMG-CG;
  steady, one solve, direct and AMG-CG. Time = the solver call (the
  network assembled before it, excluded; its build time is printed).
Steady question: tdem's explicit march measured to within 1 % of the steady field (chunks of
`steps`); the peers' time is projected as that number of steps x their measured time per step
(they reproduce tdem's explicit answer step for step: the answer columns).

Writes bench/results/peers.csv, bench/results/peers.md and the table of docs/peers.md (between
its <!-- peers table --> markers).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tdem.liggghts_heat import (INPUTS, loop_times, read_temperatures,  # noqa: E402
                                run_liggghts, scene_text, write_data)

WORK = ROOT / "bench" / "out" / "peers"
RESULTS = ROOT / "bench" / "results"
DOC = ROOT / "docs" / "peers.md"
MARK_BEGIN, MARK_END = "<!-- peers table -->", "<!-- /peers table -->"
# box side lx and insertion height hz (m) of runs/liggghts_heat/pack.in for each size
SIZES = {"2e3": (0.012, 0.016), "1e4": (0.024, 0.022), "5e4": (0.048, 0.026)}
PACK_STEPS = 20000
K, CP, RHO, E_SOFT, NU = 10.0, 800.0, 2500.0, 1e7, 0.25
T0, T_HOT, T_COLD = 300.0, 400.0, 350.0
SPAN = T_HOT - T0
TOL = 0.01                      # "within 1 %" of the span
LAWS = ("liggghts", "yade")
PEER_OF = {"liggghts": "LIGGGHTS", "yade": "YADE"}



def log(*args):
    print(*args, flush=True)


# ------------------------------------------------------------------ tdem children (one task each)

def _tdem_setup(d: Path, law: str):
    from thermal_kernel.network import assemble
    from thermal_kernel.packing import read_packing
    from thermal_kernel.problem import build_problem
    from thermal_kernel.scene import load_scene
    scene = d / f"scene_{law}.toml"
    scene.write_text(scene_text(d / "packing.h5", law, conductivity=K, density=RHO,
                                heat_capacity=CP, young_pa=E_SOFT, poisson=NU, t_initial=T0,
                                t_hot=T_HOT, t_cold=T_COLD, solver='method = "steady"\n'))
    t = time.perf_counter()
    packing = read_packing(d / "packing.h5")
    problem, _ = build_problem(load_scene(scene), packing)
    net = assemble(problem)
    build = time.perf_counter() - t
    return net, packing, build


def _err(a, b):
    return float(np.abs(np.asarray(a) - np.asarray(b)).max() / SPAN)


def child(task: str, d: Path, law: str) -> dict:
    """One tdem task in this process: 'prep' (dt, references), 'explicit', 'implicit',
    'steady'. Returns a JSON-able dict (peak RSS included)."""
    import resource
    net, packing, build = _tdem_setup(d, law)
    n = packing.n_particles
    T_init = np.full(n, T0)
    out = {"task": task, "law": law, "build_s": build, "n_particles": n,
           "contacts": int(np.count_nonzero(net.problem.conductance_w_k > 0))}
    ref_path = d / f"ref_{law}.npz"
    if task == "prep":
        out.update(_child_prep(net, T_init, ref_path))
    else:
        prep = json.loads((d / f"prep_{law}.json").read_text())
        refs = np.load(ref_path)
        ref, steady = refs["transient"], refs["steady"]
        t_end, dt = prep["t_end"], prep["dt"]
        rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        if task == "explicit":
            timed, march = _child_explicit(net, T_init, t_end, dt, ref,
                                           d / f"tdem_explicit_{law}_{ARGS.threads}.npy")
            out.update(timed)
            if ARGS.threads == 1:
                out["peak_rss_kb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
                out["rss_before_solve_kb"] = rss_before
                return out
            out.update(_child_explicit_to_steady(net, march, out["time_s"], t_end, dt,
                                                 steady))
        elif task in ("implicit", "implicit_amg"):
            out.update(_child_implicit(net, T_init, t_end, ref,
                                       "amg" if task.endswith("amg") else "direct"))
        elif task in ("steady", "steady_amg"):
            out.update(_child_steady(net, T_init, steady,
                                     "amg" if task.endswith("amg") else "direct"))
        out["rss_before_solve_kb"] = rss_before
    out["peak_rss_kb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return out


def _child_prep(net, T_init, ref_path: Path) -> dict:
    """child's 'prep': dt0, the references (saved to ``ref_path``) and the explicit step."""
    from thermal_kernel.solvers.explicit import run_explicit
    from thermal_kernel.solvers.implicit import run_implicit
    from thermal_kernel.solvers.steady import solve_steady
    dt_max = float(net.dt_max_s)
    dt0 = 2.0 ** math.floor(math.log2(0.5 * dt_max))
    t_end = ARGS.steps * dt0
    ref = run_implicit(net, T_init, [t_end], dt=dt0 / 4, theta=0.5,
                       scheme="rannacher").temperature_k[-1]
    ref2 = run_implicit(net, T_init, [t_end], dt=dt0 / 2, theta=0.5,
                        scheme="rannacher").temperature_k[-1]
    steady = solve_steady(net, T_init, method="direct").temperature_k[-1]
    # the explicit step: dt0, halved until the march is within 1 % of the reference
    dt, steps = dt0, ARGS.steps
    while True:
        e = _err(run_explicit(net, T_init, [t_end], dt=dt).temperature_k[-1], ref)
        if e < TOL or steps >= 16 * ARGS.steps:
            break
        dt, steps = dt / 2, steps * 2
    np.savez(ref_path, transient=ref, steady=steady)
    return dict(dt_max=dt_max, dt0=dt0, t_end=t_end, dt=dt, steps=steps,
                explicit_error=e, ref_error_estimate=_err(ref, ref2) / 3)


def _child_explicit(net, T_init, t_end, dt, ref, answer: Path):
    """child's 'explicit': the timed march to t_end, its answer saved to ``answer``; returns
    its columns and the march's result (the steady question continues it)."""
    from thermal_kernel.solvers.explicit import run_explicit
    run_explicit(net, T_init, [dt], dt=dt)            # numba compilation, untimed
    t = time.perf_counter()
    r = run_explicit(net, T_init, [t_end], dt=dt)
    out = {"time_s": time.perf_counter() - t}
    out.update(steps=r.steps, cu_per_s=r.contact_updates_per_second,
               error=_err(r.temperature_k[-1], ref))
    np.save(answer, r.temperature_k[-1])
    return out, r


def _child_explicit_to_steady(net, r, time_s, t_end, dt, steady) -> dict:
    """The steady question by the same march ``r`` (``time_s`` its seconds): chunks of
    `steps` until within 1 %."""
    from thermal_kernel.solvers.explicit import run_explicit
    state, total, t_total, chunks = r.state, r.steps, time_s, 1
    while _err(state.temperature_k, steady) >= TOL and chunks < 4000:
        t = time.perf_counter()
        r = run_explicit(net, state, [state.time_s + t_end], dt=dt)
        t_total += time.perf_counter() - t
        state, total, chunks = r.state, total + r.steps, chunks + 1
    return dict(steady_steps=total, steady_time_s=t_total,
                steady_error=_err(state.temperature_k, steady))


def _child_implicit(net, T_init, t_end, ref, how: str) -> dict:
    """child's 'implicit' / 'implicit_amg': the fewest Crank-Nicolson steps within 1 %."""
    from thermal_kernel.solvers.implicit import run_implicit
    run_implicit(net, T_init, [t_end], dt=t_end, theta=0.5, scheme="rannacher", method=how)
    for m in range(0, 14):
        t = time.perf_counter()
        r = run_implicit(net, T_init, [t_end], dt=t_end / 2 ** m, theta=0.5,
                         scheme="rannacher", method=how)
        sec = time.perf_counter() - t
        e = _err(r.temperature_k[-1], ref)
        if e < TOL:
            break
    return dict(time_s=sec, steps=r.steps, error=e)


def _child_steady(net, T_init, steady, how: str) -> dict:
    """child's 'steady' / 'steady_amg': one timed solve after a warm one."""
    from thermal_kernel.solvers.steady import solve_steady
    solve_steady(net, T_init, method=how)                # warm (imports, JIT)
    t = time.perf_counter()
    r = solve_steady(net, T_init, method=how)
    return dict(time_s=time.perf_counter() - t,
                steady_error=_err(r.temperature_k[-1], steady))


def run_child(task, d, law, threads=2):
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads), OMP_NUM_THREADS="1",
               OPENBLAS_NUM_THREADS="1")
    r = subprocess.run([sys.executable, __file__, "--child", task, "--dir", str(d), "--law", law,
                        "--steps", str(ARGS.steps), "--threads", str(threads)],
                       capture_output=True, text=True, env=env)
    if r.returncode != 0:
        sys.exit(f"bench_peers: tdem {task} ({law}) failed: {r.stderr[-2000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


# ------------------------------------------------------------------ peers

def peak_rss_of(cmd, cwd, env=None):
    """Run cmd; return (CompletedProcess, peak RSS in kB of its largest process)."""
    wrapper = ("import json, resource, subprocess, sys\n"
               "r = subprocess.run(sys.argv[1:], capture_output=True, text=True, "
               "stdin=subprocess.DEVNULL)\n"
               "print(json.dumps([r.returncode, r.stdout[-200000:], r.stderr[-5000:], "
               "resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss]))\n")
    p = subprocess.run([sys.executable, "-c", wrapper, *cmd], cwd=cwd, env=env,
                       capture_output=True, text=True)
    rc, out, err, rss = json.loads(p.stdout)
    return rc, out, err, rss


def liggghts(d: Path, ranks: int, prep: dict, every: int):
    from tdem.liggghts_heat import mpi_env
    run = d / f"liggghts_{ranks}"
    run.mkdir(exist_ok=True)
    shutil.copy(d / "data.txt", run / "data.txt")
    cmd = ["liggghts", "-in", str(INPUTS / "heat.in")]
    for key, value in dict(px=ranks, corr="no", dt=prep["dt"], steps=prep["steps"], every=every,
                           k=K, cp=CP, t0=T0, t_hot=T_HOT, t_cold=T_COLD, young=E_SOFT).items():
        cmd += ["-var", key, str(value)]
    if ranks > 1:
        cmd = ["mpirun", "-np", str(ranks), "--oversubscribe", *cmd]
    rc, out, err, rss = peak_rss_of(cmd, run, env=mpi_env())
    if rc != 0:
        sys.exit(f"bench_peers: LIGGGHTS failed in {run}: {out[-1500:]} {err[-500:]}")
    total, steps, parts = loop_times(out)
    temps = read_temperatures(run / "temps.dump")
    return dict(time_s=total, steps=steps, parts=parts, peak_rss_kb=rss,
                temperature_k=temps[max(temps)][2])


def yade(d: Path, threads: int, prep: dict, packing):
    run = d / f"yade_{threads}"
    run.mkdir(exist_ok=True)
    types = np.array([int(t) for t in packing.attrs["liggghts_atom_types"].split()])[
        packing.phase]
    with open(run / "spheres.txt", "w") as f:
        for (x, y, z), r, t in zip(packing.position, packing.radius, types):
            f.write(f"{float(x)!r} {float(y)!r} {float(z)!r} {float(r)!r} {int(t)}\n")
    lx, ly = (packing.domain_hi - packing.domain_lo)[:2]
    height = float((packing.position[:, 2] + packing.radius).max())
    params = dict(spheres=str(run / "spheres.txt"), cell_m=[float(lx), float(ly), 3 * height],
                  k=K, cp=CP, density=RHO, young_pa=E_SOFT, poisson=NU, dt=prep["dt"],
                  steps=prep["steps"], t0=T0, t_hot=T_HOT, t_cold=T_COLD,
                  out=str(run / "out.json"))
    (run / "params.json").write_text(json.dumps(params))
    (run / "out.json").unlink(missing_ok=True)
    from tdem.yade import yade_environment
    env = yade_environment()
    rc, out, err, _ = peak_rss_of(["yade", "-n", f"-j{threads}", "-x",
                                   str(ROOT / "bench" / "peers_yade.py"),
                                   str(run / "params.json")], run, env=env)
    if not (run / "out.json").exists():      # (YADE may abort at exit after writing: ignored)
        sys.exit(f"bench_peers: YADE failed in {run}: {out[-1500:]} {err[-1500:]}")
    res = json.loads((run / "out.json").read_text())
    return dict(time_s=res["wall_s"], engine_s=res["thermal_engine_s"], steps=res["steps"],
                real=res["real_interactions"], peak_rss_kb=res["peak_rss_kb"],
                temperature_k=np.array(res["temperature_k"]))


# ------------------------------------------------------------------ one size

def prepare(size: str) -> Path:
    from tdem.liggghts import import_liggghts
    d = WORK / size
    if ARGS.fresh and d.exists():
        shutil.rmtree(d)
    d.mkdir(parents=True, exist_ok=True)
    lx, hz = SIZES[size]
    if not (d / "packed.dump").exists():
        t = time.perf_counter()
        run_liggghts(INPUTS / "pack.in", d, ranks=2,
                     variables={"lx": lx, "hz": hz, "steps": PACK_STEPS})
        log(f"  {size}: LIGGGHTS settled the bed in {time.perf_counter() - t:.0f} s")
    write_data(d / "packed.dump", d / "data.txt")
    if not (d / "packing.h5").exists():
        run_liggghts(INPUTS / "heat.in", d, ranks=1, variables={"steps": 0, "every": 1})
        import_liggghts(d / "atoms.dump", d / "pairs.dump", None, d / "packing.h5",
                        young=E_SOFT, poisson=NU)
    return d


def measure(size: str) -> list[dict]:
    from thermal_kernel.packing import read_packing
    d = prepare(size)
    packing = read_packing(d / "packing.h5")
    rows = []
    for law in LAWS:
        prep = run_child("prep", d, law)
        (d / f"prep_{law}.json").write_text(json.dumps(prep))
        log(f"  {size} {law}: N {prep['n_particles']}, contacts {prep['contacts']}, dt_max "
            f"{prep['dt_max']:.4g} s, dt {prep['dt']:.4g} s x {prep['steps']} steps, explicit "
            f"error {100 * prep['explicit_error']:.3f} %, reference error ~"
            f"{100 * prep['ref_error_estimate']:.1e} %, build {prep['build_s']:.2f} s")
        tdem = {m: run_child(m, d, law) for m in ("explicit", "implicit", "implicit_amg",
                                                  "steady", "steady_amg")}
        tdem["explicit1"] = run_child("explicit", d, law, threads=1)
        ref = np.load(d / f"ref_{law}.npz")["transient"]
        t_expl = np.load(d / f"tdem_explicit_{law}_2.npy")
        t_expl1 = np.load(d / f"tdem_explicit_{law}_1.npy")
        contacts, steps = prep["contacts"], prep["steps"]
        steady_steps = tdem["explicit"]["steady_steps"]
        base = dict(size=size, n_particles=prep["n_particles"], contacts=contacts, law=law,
                    dt_s=prep["dt"], steps=steps, t_end_s=prep["t_end"],
                    steady_steps=steady_steps)
        if law == "liggghts":
            peers = [(f"LIGGGHTS {r} rank{'s' * (r > 1)}", liggghts(d, r, prep, steps))
                     for r in (1, 2)]
        else:
            peers = [(f"YADE {j} thread{'s' * (j > 1)}", yade(d, j, prep, packing))
                     for j in (1, 2)]
        for name, p in peers:
            per_step = p["time_s"] / p["steps"]
            extra = (f"pair {100 * p['parts'].get('Pair', math.nan) / p['time_s']:.0f} %"
                     if "parts" in p else
                     f"ThermalEngine alone {contacts * steps / p['engine_s']:.3g} cu/s")
            rows.append(dict(base, code=name, method="explicit (its own)",
                             time_s=p["time_s"], cu_per_s=contacts * steps / p["time_s"],
                             error_pct=100 * _err(p["temperature_k"], ref),
                             transient_1pct_s=p["time_s"],
                             steady_1pct_s=per_step * steady_steps, steady_projected=True,
                             peak_rss_mb=p["peak_rss_kb"] / 1024,
                             answer_vs_tdem=_err(p["temperature_k"], t_expl) * SPAN
                             / float(np.abs(t_expl).max()),
                             note=f"{extra}; load {os.getloadavg()[0]:.1f}"))
        e, e1 = tdem["explicit"], tdem["explicit1"]
        rows.append(dict(base, code="tdem 1 thread", method="explicit", time_s=e1["time_s"],
                         cu_per_s=e1["cu_per_s"], error_pct=100 * e1["error"],
                         transient_1pct_s=e1["time_s"], steady_1pct_s=math.nan,
                         steady_projected=False, peak_rss_mb=e1["peak_rss_kb"] / 1024,
                         answer_vs_tdem=float(np.abs(t_expl1 - t_expl).max()
                                              / np.abs(t_expl).max()),
                         note=f"load {os.getloadavg()[0]:.1f}"))
        rows.append(dict(base, code="tdem 2 threads", method="explicit", time_s=e["time_s"],
                         cu_per_s=e["cu_per_s"], error_pct=100 * e["error"],
                         transient_1pct_s=e["time_s"], steady_1pct_s=e["steady_time_s"],
                         steady_projected=False, peak_rss_mb=e["peak_rss_kb"] / 1024,
                         answer_vs_tdem=0.0,
                         note=f"RSS before the solve {e['rss_before_solve_kb'] / 1024:.0f} MB"))
        for key, how in (("implicit", "direct"), ("implicit_amg", "AMG-CG")):
            i = tdem[key]
            rows.append(dict(base, code="tdem 2 threads",
                             method=f"implicit CN ({how}), {i['steps']} steps",
                             time_s=i["time_s"], cu_per_s=math.nan, error_pct=100 * i["error"],
                             transient_1pct_s=i["time_s"], steady_1pct_s=math.nan,
                             steady_projected=False, peak_rss_mb=i["peak_rss_kb"] / 1024,
                             answer_vs_tdem=math.nan, note=""))
        for key, how in (("steady", "direct"), ("steady_amg", "AMG-CG")):
            s = tdem[key]
            rows.append(dict(base, code="tdem 2 threads", method=f"steady ({how})",
                             time_s=s["time_s"], cu_per_s=math.nan, error_pct=math.nan,
                             transient_1pct_s=math.nan, steady_1pct_s=s["time_s"],
                             steady_projected=False, peak_rss_mb=s["peak_rss_kb"] / 1024,
                             answer_vs_tdem=math.nan,
                             note=f"steady error {100 * s['steady_error']:.1e} %"))
        for row in rows[-(len(peers) + 6):]:
            log(f"    {row['code']:<18} {row['method']:<24} {row['time_s']:9.4f} s  "
                f"{row['cu_per_s']:9.3g} cu/s  err {row['error_pct']:.3g} %  "
                f"{row['peak_rss_mb']:.0f} MB  answer {row['answer_vs_tdem']:.2g}  "
                f"{row['note']}")
    return rows


# ------------------------------------------------------------------ output

COLUMNS = ("size", "n_particles", "contacts", "law", "code", "method", "dt_s", "steps",
           "time_s", "cu_per_s", "error_pct", "transient_1pct_s", "steady_steps",
           "steady_1pct_s", "steady_projected", "peak_rss_mb", "answer_vs_tdem", "note")


def fmt(v):
    if isinstance(v, float):
        return "–" if math.isnan(v) else f"{v:.3g}"
    return str(v)


def ratio_lines(rows):
    """One line per size and peer: each side's best configuration (threads, ranks) named."""
    out = []
    for size in dict.fromkeys(r["size"] for r in rows):
        for law in LAWS:
            sel = [r for r in rows if r["size"] == size and r["law"] == law]
            if not sel:
                continue
            expl = [r for r in sel if r["code"].startswith("tdem") and r["method"] == "explicit"]
            t_e = max(expl, key=lambda r: r["cu_per_s"])
            t_i = min((r for r in sel if r["method"].startswith("implicit")),
                      key=lambda r: r["time_s"])
            t_s = min((r for r in sel if r["method"].startswith("steady")),
                      key=lambda r: r["time_s"])
            peers = [r for r in sel if not r["code"].startswith("tdem")]
            p = max(peers, key=lambda r: r["cu_per_s"])
            fastest = min((t_e, t_i), key=lambda r: r["transient_1pct_s"])
            alone = ""
            if "ThermalEngine alone" in p["note"]:
                engine = max(float(r["note"].split("ThermalEngine alone ")[1].split()[0])
                             for r in peers)
                alone = f" ({t_e['cu_per_s'] / engine:.0f} x ThermalEngine alone)"
            out.append(
                f"| {size} | {p['contacts']} | {p['code']} | {t_e['code']} | "
                f"{t_e['cu_per_s'] / p['cu_per_s']:.0f}{alone} | "
                f"{p['transient_1pct_s'] / fastest['transient_1pct_s']:.0f} "
                f"({fastest['method'].split(',')[0]}, {fastest['code'][5:]}) | "
                f"{min(r['steady_1pct_s'] for r in peers) / t_s['steady_1pct_s']:.0f} "
                f"({t_s['method']}) | "
                f"{p['peak_rss_mb'] / t_e['peak_rss_mb']:.2f} | "
                f"{max(r['answer_vs_tdem'] for r in peers):.1e} |")
    return out


def write_outputs(rows, elapsed):
    import csv
    RESULTS.mkdir(parents=True, exist_ok=True)
    with open(RESULTS / "peers.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(COLUMNS)
        for r in rows:
            w.writerow([r[c] for c in COLUMNS])
    when = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    host = (f"{platform.node()}, {os.cpu_count()} cores, {platform.platform()}; one run of "
            f"`make bench-peers` ({elapsed / 60:.1f} min), {when}; load average (1 min) at the "
            f"end {os.getloadavg()[0]:.1f} (other jobs shared the 2 cores)")
    table = ["| size | N | contacts | law | code | method | dt (s) | steps | time (s) | "
             "contact-updates/s | error (% of span) | to 1 %: transient (s) | to 1 %: steady "
             "(s) | peak RSS (MB) | answer vs tdem explicit (rel.) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        steady = fmt(r["steady_1pct_s"]) + (" (proj.)" if r["steady_projected"] else "")
        table.append(f"| {r['size']} | {r['n_particles']} | {r['contacts']} | {r['law']} | "
                     f"{r['code']} | {r['method']} | {r['dt_s']:.3g} | {r['steps']} | "
                     f"{fmt(r['time_s'])} | {fmt(r['cu_per_s'])} | {fmt(r['error_pct'])} | "
                     f"{fmt(r['transient_1pct_s'])} | {steady} | {fmt(r['peak_rss_mb'])} | "
                     f"{fmt(r['answer_vs_tdem'])} |")
    ratios = ["| size | contacts | peer (its fastest) | tdem explicit (its fastest) | "
              "contact-updates/s, tdem / peer (whole step) | time to 1 %, transient: peer / "
              "tdem (tdem's fastest way) | time to 1 %, steady: peer (projected) / tdem steady | "
              "peak RSS, peer / tdem | answer: peer vs tdem, same law (max rel.) |",
              "|---|---|---|---|---|---|---|---|---|"] + ratio_lines(rows)
    block = "\n".join([f"Measured on {host}.", "", "**Ratios**:", "",
                       *ratios, "", "**All rows** (bench/results/peers.csv):", "", *table])
    (RESULTS / "peers.md").write_text(
        "# Peers side by side (bench/bench_peers.py; docs/peers.md explains)\n\n" + block + "\n")
    if DOC.exists():
        text = DOC.read_text()
        if MARK_BEGIN in text and MARK_END in text:
            head, rest = text.split(MARK_BEGIN, 1)
            _, tail = rest.split(MARK_END, 1)
            DOC.write_text(f"{head}{MARK_BEGIN}\n{block}\n{MARK_END}{tail}")


def main():
    missing = [x for x in ("liggghts", "mpirun", "yade") if shutil.which(x) is None]
    if missing:
        sys.exit(f"bench_peers: {', '.join(missing)}: not installed (make deps)")
    sizes = [s.strip() for s in ARGS.sizes.split(",")]
    for s in sizes:
        if s not in SIZES:
            sys.exit(f"--sizes: {s!r}: expected some of {', '.join(SIZES)}")
    start = time.perf_counter()
    rows = []
    for size in sizes:
        log(f"size {size}")
        rows += measure(size)
        write_outputs(rows, time.perf_counter() - start)
    log(f"done in {(time.perf_counter() - start) / 60:.1f} min: bench/results/peers.md")


def parse():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="2e3,1e4,5e4")
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--fresh", action="store_true", help="rebuild the packings")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--dir", help=argparse.SUPPRESS)
    ap.add_argument("--law", help=argparse.SUPPRESS)
    ap.add_argument("--threads", type=int, default=2, help=argparse.SUPPRESS)
    return ap.parse_args()


ARGS = None
if __name__ == "__main__":
    ARGS = parse()
    if ARGS.child:
        from thermal_kernel.threading_layer import prefer_openmp
        prefer_openmp()
        print(json.dumps(child(ARGS.child, Path(ARGS.dir), ARGS.law)))
    else:
        main()
