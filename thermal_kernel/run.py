"""Running a scene: packing + law -> network -> solver -> ``thermal.h5``."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .network import assemble
from .output import write_thermal
from .packing import read_packing
from .problem import build_problem
from .scene import Scene, SceneError
from .solvers import UnstableTimeStepError
from .solvers.explicit import run_explicit
from .solvers.implicit import run_implicit
from .solvers.steady import solve_steady


@dataclass
class RunSummary:
    output: Path
    result: object
    network: object
    scene: Scene


def _progress_bar(total_steps, end_time, quiet):
    """A tqdm bar over steps showing simulated time; None when quiet."""
    if quiet:
        return None, None
    from tqdm import tqdm
    bar = tqdm(total=total_steps, unit="step", unit_scale=True, dynamic_ncols=True,
               mininterval=0.5, desc="explicit")

    def progress(done, n_total, t):
        bar.total = n_total
        bar.n = done
        bar.set_postfix_str(f"t = {t:.4g} / {end_time:.4g} s", refresh=False)
        bar.refresh()
    return bar, progress


def run_scene(scene: Scene, packing_path: Path | None = None, *, quiet: bool = False,
              threads: int | None = None) -> RunSummary:
    """Run ``scene`` (its packing, or ``packing_path``) and write its output file."""
    packing = read_packing(packing_path or scene.packing)
    problem, info = build_problem(scene, packing)
    t_assemble = time.perf_counter()
    net = assemble(problem)
    assemble_seconds = time.perf_counter() - t_assemble
    solver = scene.solver
    T0 = np.full(packing.n_particles, scene.initial_temperature)
    if not quiet:
        print(f"tdem run: {scene.path}: law {scene.law}, method {solver.method}, "
              f"{packing.n_particles} particles, {net.n_active_contacts} conducting contacts "
              f"({net.n_zero_contacts} with H = 0)", flush=True)
        print(f"  network: {net.clusters.summary()}", flush=True)
    if solver.method == "steady":
        result = solve_steady(net, T0)
    elif solver.method == "explicit":
        dt = None if math.isnan(solver.dt) else solver.dt
        bar, progress = _progress_bar(0, solver.end_time, quiet)
        try:
            result = run_explicit(net, T0, solver.output_times, dt=dt, safety=solver.safety,
                                  allow_unstable=solver.allow_unstable, progress=progress,
                                  threads=threads)
        except UnstableTimeStepError as e:
            raise SceneError(f"{scene.path}: solver.dt: {e}") from None
        finally:
            if bar is not None:
                bar.close()
    else:
        bar, progress = _progress_bar(0, solver.end_time, quiet)
        try:
            result = run_implicit(net, T0, solver.output_times, dt=solver.dt,
                                  theta=solver.theta, progress=progress)
        finally:
            if bar is not None:
                bar.close()
    attrs = {
        "law": scene.law, "method": result.method, "dt": float(result.dt),
        "dt_max": float(result.dt_max), "dt_paper": float(result.dt_paper),
        "steps": int(result.steps), "wall_seconds": float(result.wall_seconds),
        "assemble_seconds": float(assemble_seconds),
        "contact_updates_per_second": float(result.contact_updates_per_second),
        "flags": ",".join(result.flags), "scene": scene.text, "scene_path": str(scene.path),
        "packing": str(packing.path), "n_particles": packing.n_particles,
        "n_conducting_contacts": int(net.n_active_contacts),
        "n_floating_clusters": net.clusters.n_floating, "n_rattlers": net.clusters.n_rattlers,
        "law_params": repr(info["law_params"]),
    }
    out = write_thermal(scene.output, times=result.times, temperatures=result.temperature_k,
                        boundary_heat_flow_w=result.boundary_heat_flow_w,
                        boundary_energy_j=result.boundary_energy_j,
                        source_energy_j=result.source_energy_j,
                        capacity_j_k=net.capacity_j_k, initial_temperature_k=T0,
                        boundary_names=result.boundary_names, attrs=attrs)
    if not quiet:
        _print_summary(result, out)
    return RunSummary(output=out, result=result, network=net, scene=scene)


def _print_summary(result, out):
    last = result.temperature_k[-1]
    print(f"  {result.method}: dt = {result.dt:.4g} s (bound {result.dt_max:.4g} s, paper "
          f"estimate {result.dt_paper:.4g} s), {result.steps} steps, "
          f"{result.wall_seconds:.3g} s, {result.contact_updates_per_second:.3g} "
          "contact-updates/s", flush=True)
    if result.flags:
        print(f"  flags: {', '.join(result.flags)}")
    print(f"  T at t = {result.times[-1]:.4g} s: min {last.min():.6g} K, mean {last.mean():.6g} K,"
          f" max {last.max():.6g} K")
    flows = ", ".join(f"{n} {q:+.4g} W" for n, q in zip(result.boundary_names,
                                                         result.boundary_heat_flow_w[-1]))
    print(f"  heat in through boundaries: {flows or 'none'}")
    resid = result.ledger_residual_j()[-1]
    scale = max(np.abs(result.boundary_energy_j[-1]).max(initial=0.0),
                abs(result.stored_energy_j[-1]), 1e-300)
    print(f"  energy ledger: stored {result.stored_energy_j[-1]:+.6g} J, residual "
          f"{resid:+.3g} J ({abs(resid) / scale:.2g} relative)")
    print(f"  wrote {out}", flush=True)
