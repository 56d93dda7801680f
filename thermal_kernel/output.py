"""The run output ``thermal.h5``: temperatures, boundary heat flows, energy ledger, provenance.

Built in memory, written to ``<path>.tmp`` and renamed (:mod:`thermal_kernel.atomic`): a killed
run or a full disk never leaves a half-written file.
Layout (SI units, documented in docs/solvers.md):
  time (K,) s; temperature (K, N) K; boundary_heat_flow (K, B) W (heat entering through each
  boundary at that time); boundary_energy (K, B) J and source_energy (K,) J (cumulative since
  t0); stored_energy_change (K,) J = sum_p C_p (T_p - T0_p); capacity (N,) J/K;
  boundary_names (B,) str. Attributes: law, method, dt, dt_max, steps, wall_seconds,
  contact_updates_per_second, scene (TOML text), packing (path), packing_sha256 (content hash),
  tdem_version, git_hash, and the flags (comma-separated: the solver's, and ``max_principle`` /
  ``energy_ledger`` when the run's physics checks fail, with max_principle_checked,
  max_principle_bounds_k, max_principle_excess_relative, ledger_residual_relative and
  check_messages; see docs/solvers.md).
"""
from __future__ import annotations

import subprocess
from pathlib import Path

import h5py
import numpy as np

from . import __version__
from .atomic import write_h5_atomic


def git_hash() -> str:
    """The commit of the tdem checkout this runs from ('unknown' outside a git checkout)."""
    here = Path(__file__).resolve().parent
    try:
        out = subprocess.run(["git", "-C", str(here), "rev-parse", "HEAD"], capture_output=True,
                             text=True, timeout=5)
        if out.returncode == 0:
            dirty = subprocess.run(["git", "-C", str(here), "status", "--porcelain",
                                    "--untracked-files=no"], capture_output=True, text=True,
                                   timeout=5).stdout.strip()
            return out.stdout.strip() + ("-dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        pass
    return "unknown"


def write_thermal(path, *, times, temperatures, boundary_heat_flow_w, boundary_energy_j,
                  source_energy_j, capacity_j_k, initial_temperature_k, boundary_names,
                  attrs: dict) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    temperatures = np.asarray(temperatures, dtype=np.float64)
    if not np.all(np.isfinite(temperatures)):
        raise FloatingPointError(f"{path}: temperature: non-finite values; not written")
    stored = (temperatures - np.asarray(initial_temperature_k)[None, :]) @ capacity_j_k

    def fill(f):
        f.create_dataset("time", data=np.asarray(times, dtype=np.float64))
        f.create_dataset("temperature", data=temperatures, chunks=True if temperatures.size
                         else None)
        f.create_dataset("boundary_heat_flow", data=np.asarray(boundary_heat_flow_w, float))
        f.create_dataset("boundary_energy", data=np.asarray(boundary_energy_j, float))
        f.create_dataset("source_energy", data=np.asarray(source_energy_j, float))
        f.create_dataset("stored_energy_change", data=stored)
        f.create_dataset("capacity", data=np.asarray(capacity_j_k, float))
        f.create_dataset("initial_temperature", data=np.asarray(initial_temperature_k, float))
        f.create_dataset("boundary_names", data=np.array(list(boundary_names), dtype=object),
                         dtype=h5py.string_dtype())
        f.attrs["format"] = "tdem-thermal"
        f.attrs["format_version"] = 1
        f.attrs["units"] = ("time: s, temperature: K, boundary_heat_flow: W, boundary_energy: J,"
                            " source_energy: J, stored_energy_change: J, capacity: J/K")
        f.attrs["tdem_version"] = __version__
        f.attrs["git_hash"] = git_hash()
        for key, value in attrs.items():
            f.attrs[key] = value
    return write_h5_atomic(path, fill)
