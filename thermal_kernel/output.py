"""The run output ``thermal.h5``: temperatures, boundary heat flows, energy ledger, provenance.

Read back by :func:`read_thermal` (the one reader: every field checked) and
:func:`read_run_packing` (the packing, checked against the stored content hash).
Built in memory (or, when large, on disk in room reserved first), written to ``<path>.tmp`` and
renamed (:mod:`thermal_kernel.atomic`): a killed run or a full disk never leaves a half-written
file. A long run's temperatures at its output times are kept in
:func:`~thermal_kernel.atomic.history_rows` until then: on disk when they are large.
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
  ``energy_ledger`` / ``below_absolute_zero`` / ``above_physical_range`` when the run's physics
  checks fail, with max_principle_checked (1: the plain principle, no flux and no source; with
  them the bounds are widened by what they can add, and checked all the same),
  max_principle_bounds_k (at the last output time), max_principle_excess_relative,
  ledger_residual_relative and check_messages; see docs/solvers.md). A steady solve has no
  time: its boundary_energy and source_energy have no rows (attribute ``energies`` says so).
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


def stored_energy_change(temperatures, initial_temperature_k, capacity_j_k) -> np.ndarray:
    """(K,) J: sum_p C_p (T_p - T0_p) at each output time, a row at a time (no (K, N)
    temporary: a long run's rows may be on disk, :func:`~.atomic.history_rows`)."""
    t0 = np.asarray(initial_temperature_k, dtype=np.float64)
    cap = np.asarray(capacity_j_k, dtype=np.float64)
    with np.errstate(over="ignore", invalid="ignore"):   # a flagged run's huge values
        return np.array([float(np.dot(row - t0, cap)) for row in temperatures],
                        dtype=np.float64)


def write_thermal(path, *, times, temperatures, boundary_heat_flow_w, boundary_energy_j,
                  source_energy_j, capacity_j_k, initial_temperature_k, boundary_names,
                  attrs: dict) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    temperatures = np.asarray(temperatures, dtype=np.float64)
    if not all(np.all(np.isfinite(row)) for row in temperatures):
        raise FloatingPointError(f"{path}: temperature: non-finite values; not written")
    stored = stored_energy_change(temperatures, initial_temperature_k, capacity_j_k)

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
    return write_h5_atomic(path, fill, data_bytes=temperatures.nbytes)


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
    capacity: np.ndarray | None = None            # (N,) J/K: the law's C_p, as the run used it


def _text(value):
    return value.decode() if isinstance(value, bytes) else value


def read_thermal(path, *, data: bool = True) -> ThermalRun:
    """Read and check a run's ``thermal.h5`` (with ``data``: also its times, temperatures and
    capacities). A missing, malformed or tampered field is a :class:`ThermalFileError` naming
    the file and field (one line). Besides each field's presence, type and shape it checks
    (always, also with ``data=False``; :func:`check_run_values`): dt > 0 (inf for a steady
    solve), the output times finite (inf for a steady solve), >= 0 and strictly increasing,
    the temperatures, initial temperatures and capacities finite (capacities > 0), the
    temperatures within the run's own stored maximum-principle bounds when the run checked
    them and within (0, TEMPERATURE_MAX_K] K -- unless the run's own flags say otherwise -- and,
    in a version-2 file, that the stored scene text still parses and agrees with the resolved
    scene (scene_json) on every key but the paths."""
    path = Path(path)

    def fail(field, what):
        raise ThermalFileError(f"{path}: {field}: {what}")

    with _open_thermal(path) as f:
        attrs = {k: _text(v) for k, v in f.attrs.items()}
        version = _format_version(f, attrs, fail)

        def attr(key, kind, missing=""):
            return _attr(attrs, key, kind, fail, missing)

        prov = _provenance(attrs, version, attr, fail)
        n = attr("n_particles", int)
        names = _check_datasets(f, n, fail)
        run = dict(method=attr("method", str), dt=attr("dt", float), flags=attr("flags", str),
                   wall_seconds=float(attrs.get("wall_seconds", math.nan)))
        check_run_values(f, attrs, run["method"], run["dt"], run["flags"], fail)
        arrays = {}
        if data:
            arrays = dict(times=f["time"][()], temperature=f["temperature"][()],
                          initial_temperature=f["initial_temperature"][()],
                          capacity=f["capacity"][()])
        scene_path = attr("scene_path", str)
        agreed = attrs.get("scene_text_agrees")
        agreed = (isinstance(agreed, (int, np.integer)) and not isinstance(agreed, bool)
                  and int(agreed) == 1)
    scene = _stored_scene(path, version, prov, scene_path, agreed, fail)
    return ThermalRun(path=path, format_version=version, scene=scene,
                      scene_json=prov["scene_json"], packing_path=Path(prov["packing"]),
                      packing_sha256=prov["sha"], law=prov["law"],
                      law_params=prov["law_params"], run_args=prov["run_args"], n_particles=n,
                      boundary_names=names, **run, **arrays)


# read_thermal's pieces, in the order it checks the file (the first fault found is reported):
# the file itself, its format and version, the provenance attributes, the datasets' shapes,
# the stored scene against the run.

_RERUN = " (a run made by an older tdem: run it again)"


def _open_thermal(path: Path):
    """The file open for reading (h5py.File), or a ThermalFileError: missing, a folder, not
    HDF5."""
    if not path.is_file():
        raise ThermalFileError(f"{path}: file not found" + (" (a folder; expected a run's "
                               "thermal.h5)" if path.is_dir() else ""))
    try:
        return h5py.File(path, "r")
    except OSError:
        raise ThermalFileError(f"{path}: not an HDF5 file; expected a run's thermal.h5") \
            from None


def _format_version(f, attrs: dict, fail) -> int:
    """The run output's format (not a packing's) and its version, 1 or 2."""
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
    return int(version)


def _attr(attrs: dict, key: str, kind, fail, missing=""):
    """Attribute ``key``, present and of ``kind`` (str, float or int; a bool is neither
    number)."""
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
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
            fail(key, f"expected an integer, got {value!r}")
        value = int(value)
    return value


def _provenance(attrs: dict, version: int, attr, fail) -> dict:
    """The run's provenance attributes: the scene text, the packing and its hash, the law and
    its parameters, the resolved scene and the run's arguments (version 2; a version-1 file
    has its law_params as a Python repr and neither of the last two)."""
    scene_text = attr("scene", str)
    packing = attr("packing", str)
    sha = attr("packing_sha256", str, _RERUN)
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
                           f"{raw_params!r}" + ("" if version >= 2 else _RERUN))
    return dict(scene_text=scene_text, packing=packing, sha=sha, law=law,
                law_params=law_params, scene_json=scene_json, run_args=run_args)


def _check_datasets(f, n: int, fail) -> tuple:
    """The datasets' shapes against ``n`` particles (time, temperature, initial temperature,
    capacity) and the boundaries' names, which it returns."""
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
    if "capacity" not in f or f["capacity"].shape != (n,):
        fail("capacity", f"expected a dataset of shape ({n},) (J/K)")
    return names


def _stored_scene(path: Path, version: int, prov: dict, scene_path: str, agreed: bool, fail):
    """The run's scene: from its resolved JSON, its stored text checked against it (version
    2), or the stored text parsed (version 1); its law the run's."""
    scene_text, scene_json, law = prov["scene_text"], prov["scene_json"], prov["law"]
    if version >= 2:
        scene = dataclasses.replace(scene_from_json(scene_json, fail), text=scene_text)
        _check_scene_text(path, scene_text, scene_path, scene_json, law, agreed, fail)
    else:           # the stored text, parsed as it was then
        from .scene import SceneError, load_scene
        try:
            scene = load_scene(scene_path, out_dir=path.parent, text=scene_text)
        except SceneError as e:
            fail("scene", f"the stored scene text no longer parses ({e}){_RERUN}")
    if scene.law != law:
        fail("scene_json" if version >= 2 else "scene",
             f"the scene's law {scene.law!r} is not the run's law {law!r}")
    return scene


def _numeric(ds, field, fail):
    if not np.issubdtype(ds.dtype, np.floating):
        fail(field, f"expected floating-point values, got {ds.dtype}")


def check_run_values(f, attrs, method, dt, flags, fail) -> None:
    """The values of an open ``thermal.h5`` ``f`` against what a run can write (see
    :func:`read_thermal`); ``fail(field, what)`` raises the caller's one-line error."""
    from .solvers import MAX_PRINCIPLE_RTOL, TEMPERATURE_MAX_K
    steady = method == "steady"
    if steady:
        if not (math.isinf(dt) and dt > 0) and not math.isnan(dt):
            fail("dt", f"expected inf for a steady solve, got {dt!r}")
    elif not (math.isfinite(dt) and dt > 0):
        fail("dt", f"expected the run's time step, a finite number > 0 s, got {dt!r}")
    time = f["time"]
    _numeric(time, "time", fail)
    t = time[()]
    if steady:
        if t.shape != (1,) or not (np.isinf(t[0]) and t[0] > 0):
            fail("time", f"expected [inf] for a steady solve, got {t.tolist()[:4]}")
    else:
        if t.size == 0:
            fail("time", "expected at least one output time")
        if not np.all(np.isfinite(t)):
            k = int(np.flatnonzero(~np.isfinite(t))[0])
            fail("time", f"expected finite times, got {float(t[k])!r} at row {k}")
        if t[0] < 0:
            fail("time", f"expected times >= 0 s, got {float(t[0])!r} at row 0")
        if t.size > 1 and np.any(np.diff(t) <= 0):
            k = int(np.flatnonzero(np.diff(t) <= 0)[0])
            fail("time", f"expected strictly increasing output times, got {float(t[k])!r} "
                         f"then {float(t[k + 1])!r} at rows {k}, {k + 1}")
    for key, positive in (("initial_temperature", True), ("capacity", True)):
        ds = f[key]
        _numeric(ds, key, fail)
        v = ds[()]
        bad = ~np.isfinite(v) | ((v <= 0) if positive else False)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            fail(key, f"expected finite values > 0, got {float(v[k])!r} at particle {k}")
    flagged = set(filter(None, str(flags).split(",")))
    temperature = f["temperature"]
    _numeric(temperature, "temperature", fail)
    lo, hi = 0.0, TEMPERATURE_MAX_K
    why = f"the physical range (0, {TEMPERATURE_MAX_K:g}] K"
    if "below_absolute_zero" in flagged:
        lo = -math.inf
    if "above_physical_range" in flagged:
        hi = math.inf
    bounds = attrs.get("max_principle_bounds_k")
    if (int(attrs.get("max_principle_checked", 0) or 0) == 1 and "max_principle" not in flagged
            and bounds is not None and np.shape(bounds) == (2,)
            and np.all(np.isfinite(bounds))):
        b_lo, b_hi = float(bounds[0]), float(bounds[1])
        tol = MAX_PRINCIPLE_RTOL * (b_hi - b_lo) + 1e-12 * max(abs(b_lo), abs(b_hi))
        lo, hi = max(lo, b_lo - tol), min(hi, b_hi + tol)
        why = (f"the run's own maximum-principle bounds [{b_lo:.6g}, {b_hi:.6g}] K "
               "(max_principle_bounds_k; the run was not flagged max_principle)")
    rows = max(1, int(2 ** 24 // max(temperature.shape[1], 1)))     # ~128 MB at a time
    for k0 in range(0, temperature.shape[0], rows):
        block = temperature[k0:k0 + rows]
        finite = np.isfinite(block)
        if not finite.all():
            k, p = np.argwhere(~finite)[0]
            fail("temperature", f"expected finite temperatures, got {float(block[k, p])!r} at time "
                                f"row {k0 + k}, particle {p} (a run writes none: the file was "
                                "changed after the run)")
        out = (block < lo) | (block > hi)
        if out.any():
            k, p = np.argwhere(out)[0]
            fail("temperature", f"T = {block[k, p]:.6g} K at time row {k0 + k}, particle {p} "
                                f"is outside {why}: the file was changed after the run")


def scene_text_difference(text, scene_path, scene_json, law, out_dir):
    """Where the scene ``text`` (a campaign's file: as its case scene, ``law`` set) disagrees
    with the resolved scene ``scene_json`` on a key other than the paths (path, packing,
    output: a run may be moved, its packing given on the command line): ``(what, key, text's
    value, scene_json's value)``, or None when they agree. ``what`` is "toml" or "scene" when
    the text does not parse (the message in the value)."""
    import tomllib

    from .scene import SceneError, load_scene
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        return "toml", "scene", str(e), None
    if "campaign" in data:             # a campaign's case: tdem.campaign.case_scenes
        data = {k: v for k, v in data.items() if k not in ("pack", "campaign", "law")}
        data = {"packing": "packing.h5", "law": law, **data}
    try:
        scene = load_scene(scene_path, out_dir=out_dir, text=text, data=data)
    except SceneError as e:
        return "scene", "scene", str(e), None
    ignore = ("path", "packing", "output")
    mine = {k: v for k, v in json.loads(scene_to_json(scene)).items() if k not in ignore}
    try:
        theirs = json.loads(scene_json)
    except (TypeError, json.JSONDecodeError):
        theirs = None
    theirs = {k: v for k, v in theirs.items() if k not in ignore} if isinstance(
        theirs, dict) else theirs
    if mine == theirs:
        return None
    where, a, b = _first_difference(mine, theirs)
    return "value", where, a, b


def _check_scene_text(path, text, scene_path, scene_json, law, agreed, fail) -> None:
    """The stored scene text is valid TOML; when the run recorded that it agreed with the
    resolved scene (attribute scene_text_agrees = 1: the scene ran as its file says, not
    changed through the API), it still parses and agrees (:func:`scene_text_difference`)."""
    diff = scene_text_difference(text, scene_path, scene_json, law, path.parent)
    if diff is None:
        return
    what, where, a, b = diff
    if what == "toml":
        fail("scene", f"the stored scene text is not valid TOML ({a}); a run stores the "
                      "scene it read: the file was changed after the run")
    if not agreed:
        return
    if what == "scene":
        fail("scene", f"the stored scene text no longer parses as a scene ({a})")
    fail("scene_json", f"the resolved scene says {where} = {b!r}, the stored scene text "
                       f"{a!r}: the run found them in agreement, so the file was changed "
                       "after it")


def _first_difference(a, b, where=""):
    """(key path, a's value, b's value) of the first place two JSON values differ."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if a.get(k, "<missing>") != b.get(k, "<missing>"):
                return _first_difference(a.get(k, "<missing>"), b.get(k, "<missing>"),
                                         f"{where}.{k}" if where else k)
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b)):
            if x != y:
                return _first_difference(x, y, f"{where}[{i}]")
    return where or "scene", a, b


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
