"""Thermal scene files (TOML) parsed into frozen dataclasses.

Reference: ``docs/scenes.md``. Every problem is a :class:`SceneError` whose one-line message
names the file and the key (``runs/x.toml: solver.dt: expected a number > 0, got -1``):
unknown keys, missing required keys, wrong types, unknown law names.
"""
from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from .errors import SceneError  # its home is below the boundary kinds, which raise it too
from .physical import TEMPERATURE_MAX_K


METHODS = ("explicit", "implicit", "steady")
# implicit time schemes (thermal_kernel/solvers/implicit.py); "auto": theta = 0.5 -> the default
# second-order scheme "rannacher" (Crank-Nicolson with backward-Euler start-up), else "theta"
SCHEMES = ("auto", "theta", "rannacher", "tr-bdf2")
# where the solve runs: "in-process" (numba / scipy, one machine, the default) or "petsc" (MPI
# ranks through PETSc, thermal_kernel/solvers/petsc_backend.py; `tdem run --ranks N`)
BACKENDS = ("in-process", "petsc")


@dataclass(frozen=True)
class Material:
    conductivity: float      # W/m/K
    density: float           # kg/m^3
    heat_capacity: float     # J/kg/K


@dataclass(frozen=True)
class SolverConfig:
    method: str
    end_time: float = math.nan
    output_times: tuple = ()
    dt: float = math.nan                   # NaN = from the stability bound (explicit) / required
    safety: float = 0.9                    # explicit: dt = safety * exact bound
    allow_unstable: bool = False
    theta: float = 1.0                     # implicit: 1 backward Euler, 0.5 second order
    scheme: str = "theta"                  # implicit: resolved scheme (theta|rannacher|tr-bdf2)
    startup_steps: int | None = None       # rannacher / tr-bdf2: backward-Euler start-up steps
    max_steps: float = 1e9                 # refuse a transient run of more steps, up front
    backend: str = "in-process"            # in-process | petsc (MPI ranks, docs/scaling.md)


@dataclass(frozen=True)
class NeighbourCriterion:
    """The ``[neighbours]`` table: which dumped pairs conduct (thermal_kernel/neighbours.py,
    docs/scenes.md). Exactly one of ``gap`` (pairs with d < (1 + gap)(r_i + r_j)) and
    ``target_z_with_gaps`` (the gap that gives this mean coordination over the bulk) is a
    number, the other NaN. Bulk: centres at least ``bulk_margin_diameters`` mean diameters from
    every wall and cut face (periodic axes have none)."""
    gap: float = math.nan
    target_z_with_gaps: float = math.nan
    bulk_margin_diameters: float = 2.0


@dataclass(frozen=True)
class Scene:
    path: Path
    packing: Path | None                   # resolved path, or None when built from [pack]
    pack: dict | None                      # the [pack] table, if the scene builds its packing
    law: str
    law_params: dict
    materials: dict                        # phase id -> Material (0 holds the defaults)
    young_pa: float                        # real modulus for force-based laws (NaN = packing's)
    poisson: float
    initial_temperature: float
    boundaries: tuple                      # thermal_kernel.boundaries kinds, scene order
    solver: SolverConfig
    output: Path
    neighbours: NeighbourCriterion | None = None   # None: every dumped pair conducts
    text: str = field(default="", repr=False)   # the scene file as read (stored in outputs)

    def material(self, phase: int) -> Material:
        return self.materials.get(int(phase), self.materials[0])


# ----------------------------------------------------------------------------- helpers

class _Table:
    """Reads keys out of one TOML table, then complains about whatever is left."""

    def __init__(self, path, prefix, table):
        self.path, self.prefix = path, prefix
        if not isinstance(table, dict):
            self.fail("", f"expected a table, got {type(table).__name__}")
        self.table = dict(table)

    def where(self, key):
        return f"{self.prefix}.{key}" if self.prefix and key else (self.prefix or key)

    def fail(self, key, what):
        raise SceneError(f"{self.path}: {self.where(key)}: {what}")

    def has(self, key):
        return key in self.table

    def number(self, key, default=None, minimum=None, positive=False):
        if key not in self.table:
            if default is None:
                self.fail(key, "missing required key")
            return default
        value = self.table.pop(key)
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not math.isfinite(value):
            self.fail(key, f"expected a finite number, got {value!r}")
        if positive and value <= 0:
            self.fail(key, f"expected a number > 0, got {value!r}")
        if minimum is not None and value < minimum:
            self.fail(key, f"expected a number >= {minimum}, got {value!r}")
        return float(value)

    def string(self, key, default=None, choices=None):
        if key not in self.table:
            if default is None:
                self.fail(key, "missing required key")
            return default
        value = self.table.pop(key)
        if not isinstance(value, str):
            self.fail(key, f"expected a string, got {value!r}")
        if choices is not None and value not in choices:
            self.fail(key, f"expected one of {', '.join(choices)}, got {value!r}")
        return value

    def boolean(self, key, default):
        if key not in self.table:
            return default
        value = self.table.pop(key)
        if not isinstance(value, bool):
            self.fail(key, f"expected true or false, got {value!r}")
        return value

    def vector(self, key, default, length=3):
        if key not in self.table:
            return default
        value = self.table.pop(key)
        if not isinstance(value, list) or len(value) != length or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                for v in value):
            self.fail(key, f"expected a list of {length} numbers, got {value!r}")
        return tuple(float(v) for v in value)

    def numbers(self, key, default=()):
        if key not in self.table:
            return default
        value = self.table.pop(key)
        if not isinstance(value, list) or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                for v in value):
            self.fail(key, f"expected a list of numbers, got {value!r}")
        return tuple(float(v) for v in value)

    def sub(self, key, required=False):
        if key not in self.table:
            if required:
                self.fail(key, "missing required table")
            return None
        return _Table(self.path, self.where(key), self.table.pop(key))

    def done(self):
        if self.table:
            key = sorted(self.table)[0]
            self.fail(key, "unknown key")


# ----------------------------------------------------------------------------- parsing

def read_toml(path, text=None, error=SceneError, what="a scene TOML file") -> tuple[dict, str]:
    """Read and parse one TOML file: ``(table, text)``. The one TOML reader of the project
    (scenes, ``tdem pack``'s [pack], campaigns, validation, benchmarks). ``text``: the file's
    text, when it is not (yet) in ``path``. Every way this fails -- no such file, a folder, not
    UTF-8, not valid TOML (line and column) -- is one ``error`` (the caller's one-line error
    type) naming ``path`` and, where it helps, ``what`` was expected. Other OSErrors propagate
    (the command line turns them into one line)."""
    path = Path(path)
    try:
        if text is None:
            text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise error(f"{path}: file not found") from None
    except IsADirectoryError:
        raise error(f"{path}: is a folder; expected {what}") from None
    except UnicodeDecodeError as e:
        raise error(f"{path}: not UTF-8 text (byte 0x{e.object[e.start]:02x} at offset "
                    f"{e.start}); expected {what}") from None
    try:
        return tomllib.loads(text), text
    except tomllib.TOMLDecodeError as e:
        raise error(f"{path}: not valid TOML ({e})") from None


def toml_value(value) -> str:
    """One TOML value: a bool, string (a basic string), number (repr: read back bit for bit;
    nan, inf) or a list of them."""
    import json
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)            # a TOML basic string
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, float) and not value == value:
        return "nan"
    if isinstance(value, float) and abs(value) == float("inf"):
        return "inf" if value > 0 else "-inf"
    return repr(value)


def toml_text(tables: dict) -> str:
    """The TOML text of ``tables`` (what :func:`read_toml` parses back to them): the plain
    keys first, then each dict as a table ``[name]`` (a dict in it as ``[name.sub]``) and each
    list of dicts as an array of tables ``[[name]]``, in the order given. The one writer of a
    scene's text (validation's cases, the calibration's flux test)."""
    lines = []

    def key(name):
        bare = name.replace("_", "").replace("-", "").isalnum() and name.isascii()
        return name if bare else toml_value(name)

    def table(prefix, t):
        subs = []
        for name, value in t.items():
            if isinstance(value, dict):
                subs.append((name, value))
            elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
                subs.append((name, value))
            else:
                lines.append(f"{key(name)} = {toml_value(value)}")
        for name, value in subs:
            full = f"{prefix}{key(name)}"
            for t_ in (value if isinstance(value, list) else [value]):
                lines.append(f"[[{full}]]" if isinstance(value, list) else f"[{full}]")
                table(full + ".", t_)

    table("", tables)
    return "\n".join(lines) + "\n"


def load_scene(path, known_laws=None, out_dir=None, text=None, data=None) -> Scene:
    """Parse and check a scene file. ``known_laws``: names accepted for ``law`` (default: the
    registry). ``out_dir``: folder for a relative ``[output] path`` (default
    ``<scene folder>/out/<scene name>/``). ``text``: the scene's text, when it is not (yet) in
    ``path`` (a campaign checks its cases before they exist; errors name ``path``). ``data``:
    its tables already parsed (a campaign's case: the campaign file's tables with ``law`` and
    ``packing`` set), checked as they are; ``text`` is then stored as the scene's text."""
    path = Path(path)
    if data is None:
        data, text = read_toml(path, text)
    if known_laws is None:
        from .laws import LAWS
        known_laws = tuple(LAWS)
    top = _Table(path, "", data)
    base = path.resolve().parent
    out_dir = Path(out_dir) if out_dir else base / "out" / path.stem

    packing, pack = _packing_or_pack(top, base)
    law, law_params = _law(top, known_laws)
    materials, young, poisson = _materials(top.sub("material", required=True))
    initial_temperature = _initial(top.sub("initial", required=True))
    boundaries = _boundaries(top)
    solver = _solver(top.sub("solver", required=True))
    neighbours = _neighbours(top.sub("neighbours"))
    output = _output(top.sub("output"), out_dir)
    top.done()
    return Scene(path=path, packing=packing, pack=pack, law=law, law_params=law_params,
                 materials=materials, young_pa=young, poisson=poisson,
                 initial_temperature=initial_temperature, boundaries=tuple(boundaries),
                 solver=solver, output=output, neighbours=neighbours, text=text)


# One helper per table of the scene, called by load_scene in the order the tables are read
# (the first error found is the one reported); each pops its keys and refuses the unknown ones.

def _packing_or_pack(top: _Table, base: Path) -> tuple[Path | None, dict | None]:
    """``packing = "file.h5"`` (resolved against the scene's folder) or a ``[pack]`` table:
    ``(packing, pack)``, one of them None."""
    pack = None
    packing = None
    if top.has("packing") and top.has("pack"):
        top.fail("pack", "give either packing = \"file.h5\" or a [pack] table, not both")
    if top.has("pack"):
        pack = top.table.pop("pack")
        if not isinstance(pack, dict):
            top.fail("pack", "expected a table")
    else:
        packing = base / top.string("packing")
    return packing, pack


def _law(top: _Table, known_laws) -> tuple[str, dict]:
    """``law`` (one of ``known_laws``) and its ``[law_params]``, checked against the law."""
    law = top.string("law")
    if law not in known_laws:
        top.fail("law", f"unknown law {law!r} (known: {', '.join(known_laws)})")
    law_params = top.table.pop("law_params", {})
    if not isinstance(law_params, dict):
        top.fail("law_params", "expected a table")
    _check_law_params(_Table(top.path, "law_params", law_params), law)
    return law, law_params


def _materials(mat: _Table) -> tuple[dict, float, float]:
    """``[material]`` and its phases ``[material.N]`` (each phase's missing keys from the
    default): ``({phase id: Material}, young_pa, poisson)``, NaN where not given."""
    phases = {}
    for key in [k for k, v in mat.table.items() if isinstance(v, dict)]:
        try:
            phase_id = int(key)
        except ValueError:
            mat.fail(key, "expected a phase id (an integer, e.g. [material.1]) or a key "
                          "conductivity | density | heat_capacity | young_pa | poisson")
        phases[phase_id] = _Table(mat.path, mat.where(key), mat.table.pop(key))
    default = Material(conductivity=mat.number("conductivity", positive=True),
                       density=mat.number("density", positive=True),
                       heat_capacity=mat.number("heat_capacity", positive=True))
    young = mat.number("young_pa", default=math.nan) if mat.has("young_pa") else math.nan
    if mat.has("poisson"):
        poisson = mat.number("poisson")
        if not -1.0 < poisson < 0.5:
            mat.fail("poisson", f"expected a number in (-1, 0.5), got {poisson!r}")
    else:
        poisson = math.nan
    if not math.isnan(young) and young <= 0:
        mat.fail("young_pa", f"expected a number > 0, got {young!r}")
    mat.done()
    materials = {0: default}
    for phase_id, t in phases.items():
        materials[phase_id] = Material(
            conductivity=t.number("conductivity", default=default.conductivity, positive=True),
            density=t.number("density", default=default.density, positive=True),
            heat_capacity=t.number("heat_capacity", default=default.heat_capacity,
                                   positive=True))
        t.done()
    return materials, young, poisson


def _initial(init: _Table) -> float:
    """``[initial] temperature`` (K)."""
    initial_temperature = init.number("temperature", positive=True)
    if initial_temperature > TEMPERATURE_MAX_K:
        init.fail("temperature", f"expected a temperature in (0, {TEMPERATURE_MAX_K:g}] K (no "
                                 f"solid above), got {initial_temperature!r}")
    init.done()
    return initial_temperature


def _boundaries(top: _Table) -> list:
    """The ``[[boundary]]`` entries, each parsed by its kind; their names distinct."""
    from .boundaries import parse_boundary     # each kind parses its own table
    raw_boundaries = top.table.pop("boundary", [])
    if not isinstance(raw_boundaries, list):
        top.fail("boundary", "expected [[boundary]] entries (an array of tables)")
    boundaries = []
    for k, raw in enumerate(raw_boundaries):
        boundaries.append(parse_boundary(_Table(top.path, f"boundary[{k}]", raw)))
    names = [b.name for b in boundaries]
    if len(set(names)) != len(names):
        dup = sorted(n for n in names if names.count(n) > 1)[0]
        top.fail("boundary", f"two boundaries share the name {dup!r}"
                             " (give each a distinct name = \"...\")")
    return boundaries


def _solver(sol: _Table) -> SolverConfig:
    """``[solver]``: the method, times, step, scheme and limits, checked together."""
    method = sol.string("method", choices=METHODS)
    if method == "steady":
        end_time = sol.number("end_time", default=math.nan) if sol.has("end_time") else math.nan
        output_times = ()
    else:
        end_time = sol.number("end_time", positive=True)
        output_times = sol.numbers("output_times", default=(end_time,))
        if not output_times:
            sol.fail("output_times", "expected at least one time")
        if any(b <= a for a, b in zip(output_times, output_times[1:])):
            sol.fail("output_times", "expected increasing times")
        if output_times[0] < 0 or output_times[-1] > end_time * (1 + 1e-12):
            sol.fail("output_times", f"expected times in [0, end_time = {end_time}]")
    if method == "steady" and sol.has("dt"):
        sol.fail("dt", "a steady solve has no time step (dt is for method = \"explicit\" or "
                       "\"implicit\")")
    if method != "implicit" and sol.has("theta"):
        sol.fail("theta", f"only for method = \"implicit\" (method is {method!r}: theta would "
                          "be ignored)")
    dt = sol.number("dt", positive=True) if sol.has("dt") else math.nan
    if method == "implicit" and math.isnan(dt):
        sol.fail("dt", "missing required key (the implicit method needs a time step)")
    theta_given = sol.has("theta")
    solver = SolverConfig(
        method=method, end_time=end_time, output_times=output_times, dt=dt,
        safety=sol.number("safety", default=0.9, positive=True),
        allow_unstable=sol.boolean("allow_unstable", False),
        theta=sol.number("theta", default=1.0, minimum=0.5),
        backend=sol.string("backend", default="in-process", choices=BACKENDS))
    if solver.theta > 1.0:
        sol.fail("theta", f"expected 0.5 <= theta <= 1, got {solver.theta}")
    scheme, startup = _scheme(sol, method, solver.theta, theta_given)
    if startup and method == "implicit" and sol_has_times(end_time, dt):
        from .solvers import interval_steps
        steps, t_prev = 0, 0.0
        for t in output_times:
            steps += interval_steps(t_prev, t, dt)[0]
            t_prev = t
        if startup >= steps:
            sol.fail("startup_steps", f"{startup} start-up steps, and the run has {steps} "
                                      f"steps of dt = {dt:g} s: the whole run would be "
                                      f"backward-Euler half steps (first order), not {scheme}; "
                                      f"expected fewer than {steps}")
    solver = dataclasses.replace(solver, scheme=scheme, startup_steps=startup)
    if solver.safety > 1.0 and not solver.allow_unstable:
        sol.fail("safety", f"expected a number <= 1 (the bound is exact), got {solver.safety}")
    max_steps = sol.number("max_steps", default=1e9, minimum=1) if method != "steady" else 1e9
    solver = dataclasses.replace(solver, max_steps=max_steps)
    if method != "steady" and not math.isnan(dt) and not end_time / dt <= max_steps:
        sol.fail("dt", f"end_time = {end_time:g} s in steps of dt = {dt:g} s is "
                       f"{end_time / dt:.3g} steps; expected at most solver.max_steps = "
                       f"{max_steps:.6g} (a longer dt, a shorter end_time, or a larger "
                       "max_steps)")
    sol.done()
    return solver


def _output(outt: _Table | None, out_dir: Path) -> Path:
    """``[output] path`` (relative to ``out_dir``; default ``out_dir/thermal.h5``)."""
    output = out_dir / "thermal.h5"
    if outt is not None:
        rel = outt.string("path", default="thermal.h5")
        output = Path(rel) if Path(rel).is_absolute() else out_dir / rel
        outt.done()
    return output


def sol_has_times(end_time: float, dt: float) -> bool:
    """A transient with a time step: its step count is known from the scene."""
    return math.isfinite(end_time) and math.isfinite(dt) and dt > 0


def _neighbours(t: _Table | None) -> NeighbourCriterion | None:
    """``[neighbours]``: gap = g, or target_z_with_gaps = Z (bulk), and bulk_margin_diameters."""
    if t is None:
        return None
    if t.has("gap") == t.has("target_z_with_gaps"):
        t.fail("", "expected exactly one of gap = <number >= 0> (pairs with centre distance "
                   "< (1 + gap)(r_i + r_j)) and target_z_with_gaps = <bulk coordination>")
    gap = t.number("gap", minimum=0) if t.has("gap") else math.nan
    target = (t.number("target_z_with_gaps", positive=True) if t.has("target_z_with_gaps")
              else math.nan)
    margin = t.number("bulk_margin_diameters", default=2.0, minimum=0)
    t.done()
    return NeighbourCriterion(gap=gap, target_z_with_gaps=target, bulk_margin_diameters=margin)


def _check_law_params(t: _Table, law_name: str) -> None:
    """The ``[law_params]`` of a registered law, checked here rather than inside the law (where
    a bad value was a traceback): every key one of the law's parameters, a numeric parameter a
    finite number > 0 (ct, beta), a text one a string, ``interface_mean`` one of its rules."""
    from .laws import LAWS
    law = LAWS.get(law_name)
    if law is None:                  # a law outside the registry (tests): the law checks
        return
    for key in sorted(t.table):
        if key not in law.defaults:
            t.fail(key, f"unknown parameter of law {law_name!r} (known: "
                        f"{', '.join(sorted(law.defaults)) or 'none'})")
        default = law.defaults[key]
        if key == "interface_mean":
            from .laws.haddad import INTERFACE_MEANS
            t.string(key, choices=INTERFACE_MEANS)
        elif key == "mean_radius":
            from .laws.haddad import MEAN_RADII
            t.string(key, choices=MEAN_RADII)
        elif isinstance(default, str):
            t.string(key)
        elif isinstance(default, (int, float)) and not isinstance(default, bool):
            t.number(key, positive=True)


def _scheme(sol: _Table, method: str, theta: float, theta_given: bool):
    """(scheme, startup_steps) of the implicit solver: ``scheme = "auto"`` (default) gives the
    default second-order scheme "rannacher" for theta = 0.5 and the plain theta-scheme
    otherwise; ``scheme = "theta"`` with theta = 0.5 is plain Crank-Nicolson (can ring)."""
    given = sol.has("scheme")
    scheme = sol.string("scheme", default="auto", choices=SCHEMES)
    startup = None
    if sol.has("startup_steps"):
        value = sol.table["startup_steps"]
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            sol.fail("startup_steps", f"expected an integer >= 0, got {value!r}")
        sol.table.pop("startup_steps")
        startup = int(value)
    if method != "implicit":
        if given:
            sol.fail("scheme", f"only for method = \"implicit\" (method is {method!r})")
        if startup is not None:
            sol.fail("startup_steps", f"only for method = \"implicit\" (method is {method!r})")
        return "theta", None
    if scheme == "auto":
        scheme = "rannacher" if theta == 0.5 else "theta"
    if scheme in ("rannacher", "tr-bdf2") and theta_given and theta != 0.5:
        sol.fail("theta", f"theta = {theta} is for scheme = \"theta\"; scheme = {scheme!r} is "
                          "second order (leave theta out or give 0.5)")
    if startup is not None and scheme == "theta":
        sol.fail("startup_steps", "only for scheme = \"rannacher\" or \"tr-bdf2\"")
    return scheme, startup
