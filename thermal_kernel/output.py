"""The run output ``thermal.h5``: temperatures, boundary heat flows, energy ledger, provenance.

Read back by :func:`read_thermal` (the one reader: every field checked) and
:func:`read_run_packing` (the packing, checked against the stored content hash).
Built in memory, written to ``<path>.tmp`` and renamed (:mod:`thermal_kernel.atomic`): a killed
run or a full disk never leaves a half-written file.
Layout (SI units, documented in docs/solvers.md):
  time (K,) s; temperature (K, N) K; boundary_heat_flow (K, B) W (heat entering through each
  boundary at that time); boundary_energy (K, B) J and source_energy (K,) J (cumulative since
  t0); stored_energy_change (K,) J = sum_p C_p (T_p - T0_p); capacity (N,) J/K;
  boundary_names (B,) str. Attributes: law, method, dt, dt_max, steps, wall_seconds,
  contact_updates_per_second, scene (TOML text), scene_json (the resolved scene, every default
  filled in), run_args (how the run was started, JSON), law_params (JSON), neighbours (JSON: the
  scene's [neighbours] criterion on the packing -- gap used, bulk Z reached -- or null),
  scene_path, packing
  (path), packing_sha256 (content hash),
  tdem_version, git_hash, and the flags (comma-separated: the solver's, and ``max_principle`` /
  ``energy_ledger`` when the run's physics checks fail, with max_principle_checked,
  max_principle_bounds_k, max_principle_excess_relative, ledger_residual_relative and
  check_messages; see docs/solvers.md).
"""
from __future__ import annotations

import ast
import dataclasses
import json
import math
import subprocess
from dataclasses import dataclass
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
    with np.errstate(over="ignore", invalid="ignore"):   # a flagged run's huge values
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
        f.attrs["format"] = FORMAT
        f.attrs["format_version"] = FORMAT_VERSION
        f.attrs["units"] = ("time: s, temperature: K, boundary_heat_flow: W, boundary_energy: J,"
                            " source_energy: J, stored_energy_change: J, capacity: J/K")
        f.attrs["tdem_version"] = __version__
        f.attrs["git_hash"] = git_hash()
        for key, value in attrs.items():
            f.attrs[key] = value
    return write_h5_atomic(path, fill)


# ----------------------------------------------------------------------------- the resolved scene
# The scene as the run used it, every default filled in: dataclasses.asdict of the parsed
# Scene (its text aside: stored as its own attribute) as strict JSON. A float that is not
# finite (NaN: "not given"; inf: "never") is written as the string "NaN", "Infinity" or
# "-Infinity", which float() reads back.

def _jsonable(value):
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return v if math.isfinite(v) else ("NaN" if v != v else "Infinity" if v > 0
                                            else "-Infinity")
    return value


def scene_to_json(scene) -> str:
    """The resolved scene (every default filled in) as strict JSON, its text left out."""
    data = dataclasses.asdict(dataclasses.replace(scene, text=""))
    data.pop("text")
    # a boundary's kind is its class (thermal_kernel.boundaries), not a field: stored by name
    data["boundaries"] = [{"kind": b.kind, **d}
                          for b, d in zip(scene.boundaries, data["boundaries"])]
    return json.dumps(_jsonable(data), sort_keys=True, default=str)   # a TOML date: its text


def _field_value(kind: str, value, fail):
    """``value`` read back as the annotated ``kind`` of a scene dataclass field."""
    optional = kind.endswith(" | None")
    kind = kind.removesuffix(" | None")
    if value is None and optional:
        return None
    if kind == "float":
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            fail(f"expected a number, got {value!r}")
        try:
            return float(value)
        except ValueError:
            fail(f"expected a number, got {value!r}")
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            fail(f"expected an integer, got {value!r}")
        return value
    if kind == "bool":
        if not isinstance(value, bool):
            fail(f"expected true or false, got {value!r}")
        return value
    if kind in ("str", "Path"):
        if not isinstance(value, str):
            fail(f"expected a string, got {value!r}")
        return Path(value) if kind == "Path" else value
    if kind == "tuple":
        if not isinstance(value, list):
            fail(f"expected a list, got {value!r}")
        return tuple(_field_value("float", v, fail) for v in value)
    if kind == "dict":
        if not isinstance(value, dict):
            fail(f"expected an object, got {value!r}")
        return value
    fail(f"cannot read a field of type {kind}")


def _dataclass_from_json(cls, data, where, fail, special=None):
    """``cls(**data)`` with every field checked against its annotation; ``special`` maps a
    field name to its own reader."""
    if not isinstance(data, dict):
        fail(where, f"expected an object, got {data!r}")
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    unknown = sorted(set(data) - set(fields))
    if unknown:
        fail(f"{where}.{unknown[0]}", f"unknown field of {cls.__name__}")
    kwargs = {}
    for name, f in fields.items():
        here = f"{where}.{name}"
        if name not in data:
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                fail(here, "missing")
            continue
        if special and name in special:
            kwargs[name] = special[name](data[name], here)
        else:
            kwargs[name] = _field_value(str(f.type), data[name],
                                        lambda what, here=here: fail(here, what))
    return cls(**kwargs)


def scene_from_json(text: str, fail):
    """The :class:`~thermal_kernel.scene.Scene` written by :func:`scene_to_json` (its ``text``
    empty). ``fail(field, what)`` raises the caller's one-line error."""
    from .boundaries import BOUNDARIES
    from .scene import Material, NeighbourCriterion, Scene, SolverConfig
    try:
        data = json.loads(text)
    except (TypeError, json.JSONDecodeError) as e:
        fail("scene_json", f"expected the resolved scene as JSON ({e})")

    def materials(value, where):
        if not isinstance(value, dict) or "0" not in value:
            fail(where, "expected an object of phases holding phase 0")
        out = {}
        for key, m in value.items():
            try:
                phase = int(key)
            except ValueError:
                fail(f"{where}.{key}", "expected an integer phase id")
            out[phase] = _dataclass_from_json(Material, m, f"{where}.{key}", fail)
        return out

    def boundaries(value, where):
        if not isinstance(value, list):
            fail(where, f"expected a list, got {value!r}")
        out = []
        for k, b in enumerate(value):
            here = f"{where}[{k}]"
            if not isinstance(b, dict) or b.get("kind") not in BOUNDARIES:
                fail(f"{here}.kind", f"expected one of {', '.join(BOUNDARIES)}")
            fields = {key: v for key, v in b.items() if key != "kind"}
            out.append(_dataclass_from_json(BOUNDARIES[b["kind"]], fields, here, fail))
        return tuple(out)

    def solver(value, where):
        return _dataclass_from_json(SolverConfig, value, where, fail)

    def neighbours(value, where):       # absent (None) in files written before issue 23
        if value is None:
            return None
        return _dataclass_from_json(NeighbourCriterion, value, where, fail)

    return _dataclass_from_json(Scene, data, "scene_json", fail,
                                special=dict(materials=materials, boundaries=boundaries,
                                             solver=solver, neighbours=neighbours))


# ----------------------------------------------------------------------------- the reader
class ThermalFileError(ValueError):
    """A ``thermal.h5`` that is not a complete run output; ``str(e)`` is one line naming the
    file, the field and what was expected."""


FORMAT = "tdem-thermal"
FORMAT_VERSION = 2      # 2: scene_json, run_args, law_params as JSON; 1: law_params a repr


@dataclass(frozen=True, eq=False)
class ThermalRun:
    """What :func:`read_thermal` returns: everything post-processing needs from a run, from the
    run's output alone (the scene as it ran, not the scene file as it is now)."""
    path: Path
    format_version: int
    scene: object                 # thermal_kernel.scene.Scene, resolved; .text the TOML read
    scene_json: str               # the resolved scene as stored ("" in a version-1 file)
    packing_path: Path            # the packing the run read
    packing_sha256: str           # its content hash (thermal_kernel.checkpoint.packing_sha256)
    law: str
    law_params: dict              # the law's parameters, defaults filled in
    method: str
    dt: float                     # the time step the solver used (s; NaN for a steady solve)
    run_args: dict                # how the run was started (the CLI's arguments)
    flags: str                    # comma-separated; "" for a clean run
    wall_seconds: float
    n_particles: int
    boundary_names: tuple
    times: np.ndarray | None = None               # (K,) s; None with data=False
    temperature: np.ndarray | None = None         # (K, N) K
    initial_temperature: np.ndarray | None = None  # (N,) K


def _text(value):
    return value.decode() if isinstance(value, bytes) else value


def read_thermal(path, *, data: bool = True) -> ThermalRun:
    """Read and check a run's ``thermal.h5`` (with ``data``: also its times and temperatures).
    A missing or malformed field is a :class:`ThermalFileError` naming the file and field."""
    path = Path(path)

    def fail(field, what):
        raise ThermalFileError(f"{path}: {field}: {what}")

    if not path.is_file():
        raise ThermalFileError(f"{path}: file not found" + (" (a folder; expected a run's "
                               "thermal.h5)" if path.is_dir() else ""))
    try:
        f = h5py.File(path, "r")
    except OSError:
        raise ThermalFileError(f"{path}: not an HDF5 file; expected a run's thermal.h5") \
            from None
    with f:
        attrs = {k: _text(v) for k, v in f.attrs.items()}
        fmt = attrs.get("format", "")
        if fmt != FORMAT or "time" not in f or "temperature" not in f:
            what = (" (a packing: run a scene on it with `tdem run`, then post the run)"
                    if fmt == "tdem-packing" else "")
            fail("format", f"expected a run's output ({FORMAT}, with datasets time and "
                           f"temperature), got {fmt or 'no format'!r}{what}")
        version = attrs.get("format_version")
        version = int(version) if isinstance(version, np.integer) else version
        if version not in (1, 2) or isinstance(version, (bool, np.bool_)):
            fail("format_version", f"expected 1 or {FORMAT_VERSION}, got {version!r}")
        version = int(version)

        def attr(key, kind, missing=""):
            if key not in attrs:
                fail(key, "missing" + missing)
            value = attrs[key]
            if kind is str and not isinstance(value, str):
                fail(key, f"expected a string, got {value!r}")
            if kind is float:
                if isinstance(value, (bool, np.bool_)) or not isinstance(
                        value, (int, float, np.integer, np.floating)):
                    fail(key, f"expected a number, got {value!r}")
                value = float(value)
            if kind is int:
                if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int,
                                                                                 np.integer)):
                    fail(key, f"expected an integer, got {value!r}")
                value = int(value)
            return value

        rerun = " (a run made by an older tdem: run it again)"
        scene_text = attr("scene", str)
        packing = attr("packing", str)
        sha = attr("packing_sha256", str, rerun)
        if len(sha) != 64 or any(c not in "0123456789abcdef" for c in sha):
            fail("packing_sha256", f"expected a sha256 in hex (64 digits), got {sha!r}")
        law = attr("law", str)
        raw_params = attr("law_params", str)
        if version >= 2:
            try:
                law_params = json.loads(raw_params)
            except json.JSONDecodeError:
                law_params = None
            scene_json = attr("scene_json", str)
            try:
                run_args = json.loads(attr("run_args", str))
            except json.JSONDecodeError:
                run_args = None
            if not isinstance(run_args, dict):
                fail("run_args", f"expected a JSON object, got {attrs['run_args']!r}")
        else:       # law_params was a Python repr of a dict of numbers and strings
            try:
                law_params = ast.literal_eval(raw_params)
            except (ValueError, SyntaxError):
                law_params = None
            scene_json, run_args = "", {}
        if not isinstance(law_params, dict):
            fail("law_params", f"expected a JSON object of the law's parameters, got "
                               f"{raw_params!r}" + ("" if version >= 2 else rerun))
        n = attr("n_particles", int)
        time = f["time"]
        temperature = f["temperature"]
        if time.ndim != 1:
            fail("time", f"expected a 1-D dataset, got shape {time.shape}")
        if temperature.shape != (time.shape[0], n):
            fail("temperature", f"expected shape ({time.shape[0]}, {n}) (output times, "
                                f"n_particles), got {temperature.shape}")
        if "initial_temperature" not in f or f["initial_temperature"].shape != (n,):
            fail("initial_temperature", f"expected a dataset of shape ({n},)")
        if "boundary_names" not in f:
            fail("boundary_names", "missing")
        names = tuple(_text(s) for s in f["boundary_names"][()])
        arrays = {}
        if data:
            arrays = dict(times=time[()], temperature=temperature[()],
                          initial_temperature=f["initial_temperature"][()])
        run = dict(method=attr("method", str), dt=attr("dt", float), flags=attr("flags", str),
                   wall_seconds=float(attrs.get("wall_seconds", math.nan)))
        scene_path = attr("scene_path", str)
    if version >= 2:
        scene = dataclasses.replace(scene_from_json(scene_json, fail), text=scene_text)
    else:           # the stored text, parsed as it was then
        from .scene import SceneError, load_scene
        try:
            scene = load_scene(scene_path, out_dir=path.parent, text=scene_text)
        except SceneError as e:
            fail("scene", f"the stored scene text no longer parses ({e}){rerun}")
    if scene.law != law:
        fail("scene_json" if version >= 2 else "scene",
             f"the scene's law {scene.law!r} is not the run's law {law!r}")
    return ThermalRun(path=path, format_version=version, scene=scene, scene_json=scene_json,
                      packing_path=Path(packing), packing_sha256=sha, law=law,
                      law_params=law_params, run_args=run_args, n_particles=n,
                      boundary_names=names, **run, **arrays)


def read_run_packing(run: ThermalRun, path=None):
    """The packing ``run`` was made on (``path``, else the one it recorded), read and checked
    against the content hash the run stored: a packing changed since the run is refused
    (:class:`~thermal_kernel.packing.PackingError`, one line)."""
    from .checkpoint import packing_sha256
    from .packing import PackingError, read_packing
    recorded = path is None
    path = run.packing_path if recorded else Path(path)
    packing = read_packing(path)
    sha = packing_sha256(packing)
    if sha != run.packing_sha256:
        why = ("it changed since the run; restore it, or run the scene again" if recorded
               else f"give the packing the run recorded, {run.packing_path}")
        raise PackingError(f"{path}: packing_sha256: not the packing {run.path} was run on "
                           f"(content sha256 {sha[:12]}, the run's {run.packing_sha256[:12]}): "
                           f"{why}")
    return packing
