"""The boundary registry (thermal_kernel.boundaries.BOUNDARIES) and one end-to-end test per kind.

Every kind is run the way a user runs it (packing file + scene file -> load_scene -> run_scene
-> thermal.h5) on a chain of three touching spheres (thermal_kernel.lattice, shape (3, 1, 1)),
law `bob`, so that every answer has a closed form computed here from the geometry, not from the
assembled network:

    contact conductance  H = 2 a k,  a = sqrt(R* delta) = sqrt(r delta / 2)   (the lattice's
                                     Hertz force gives back a = sqrt(R* delta))
    wall conductance     g = 2 a_w k_h,  a_w = sqrt(r delta_w),  k_h = 2 k k_w / (k + k_w)
    capacity             C = rho c_p 4/3 pi r^3

Each kind asserts: the energy ledger closes (stored energy change = heat in through the
boundaries and the source), the maximum principle where it applies (the run checks it: no
power in) or, where power comes in, the comparison bounds it still obeys (between the initial
temperature and the steady field), and one hand-computed value.
"""
import dataclasses
import math
import tomllib
from pathlib import Path

import h5py
import numpy as np
import pytest

from thermal_kernel.boundaries import (BOUNDARIES, BoundaryKind, FluxBoundary, SourceBoundary,
                                       TemperatureBoundary, WallTemperatureBoundary, keys)
from thermal_kernel.lattice import simple_cubic_packing
from thermal_kernel.network import assemble
from thermal_kernel.packing import read_packing, write_packing
from thermal_kernel.problem import build_problem
from thermal_kernel.run import run_scene
from thermal_kernel.scene import SceneError, load_scene
from thermal_kernel.solvers import LEDGER_RTOL
from thermal_kernel.solvers.steady import solve_steady

ROOT = Path(__file__).resolve().parent.parent
R, DELTA = 1e-3, 1e-6                      # sphere radius, contact overlap (m)
PITCH = 2 * R - DELTA
K, RHO, CP, E, NU = 33.0, 7800.0, 500.0, 2e11, 0.3
T0 = 300.0
H = 2.0 * math.sqrt(R / 2 * DELTA) * K     # every contact of the chain (W/K)
C = RHO * CP * 4.0 / 3.0 * math.pi * R ** 3  # every sphere (J/K)


def chain(tmp_path, wall_overlap=0.0):
    """Three spheres along x; the xmin wall touches sphere 0 with overlap ``wall_overlap``
    (and its Hertz force), the other walls carry no force."""
    pk = simple_cubic_packing((3, 1, 1), PITCH, radius_m=R, young_pa=E, poisson=NU,
                              density=RHO)
    on_xmin = pk.wall_index == pk.wall_name.index("xmin")
    e_star = E / (2.0 * (1.0 - NU ** 2))
    overlap = np.where(on_xmin, wall_overlap, 0.0)
    force = 4.0 / 3.0 * e_star * math.sqrt(R) * overlap ** 1.5
    point = pk.wall_point.copy()      # the xmin plane moved in by the overlap (r - distance)
    point[pk.wall_name.index("xmin"), 0] = pk.position[:, 0].min() - (R - wall_overlap)
    pk = dataclasses.replace(pk, wall_overlap=overlap, wall_normal_force=force, wall_point=point)
    path = tmp_path / "chain.h5"
    write_packing(path, pk)
    return path


# the chain's time constant C / (2H) is ~5.5 s: forward Euler at 1/50 of its bound, Crank-Nicolson
# (Rannacher start) at 0.05 s, both accurate to well within the tolerances below
SOLVERS = {
    "explicit": 'method = "explicit"\nsafety = 0.02\nend_time = 20.0\n'
                'output_times = [2.0, 5.0, 20.0]\n',
    "implicit": 'method = "implicit"\ndt = 0.05\ntheta = 0.5\nend_time = 20.0\n'
                'output_times = [2.0, 5.0, 20.0]\n',
    "steady": 'method = "steady"\n',
}


def run(tmp_path, packing, boundaries, solver, name):
    scene = tmp_path / f"{name}.toml"
    scene.write_text(f'packing = "{packing}"\nlaw = "bob"\n[material]\nconductivity = {K!r}\n'
                     f'density = {RHO!r}\nheat_capacity = {CP!r}\nyoung_pa = {E!r}\n'
                     f'poisson = {NU!r}\n[initial]\ntemperature = {T0!r}\n{boundaries}\n'
                     f'[solver]\n{solver}')
    loaded = load_scene(scene, out_dir=tmp_path / name)
    summary = run_scene(loaded, quiet=True)
    with h5py.File(summary.output) as f:
        out = {k: f[k][()] for k in ("time", "temperature", "boundary_heat_flow",
                                     "boundary_energy", "source_energy",
                                     "stored_energy_change")}
        out["attrs"] = dict(f.attrs)
    out["scene"] = loaded
    return out


def flags(out):
    return set(filter(None, out["attrs"]["flags"].split(",")))


def assert_ledger(out, method):
    a = out["attrs"]
    assert a["ledger_residual_relative"] <= LEDGER_RTOL, a["ledger_residual_relative"]
    assert "energy_ledger" not in flags(out)
    if method == "steady":           # heat in = heat out
        flow = out["boundary_heat_flow"][-1]
        assert abs(flow.sum()) <= 1e-9 * np.abs(flow).max()
    else:                            # stored = boundaries + source (if it has no column)
        heat = out["boundary_energy"].sum(axis=1)
        scale = np.abs(out["boundary_energy"]).max() + np.abs(out["source_energy"]).max()
        np.testing.assert_allclose(out["stored_energy_change"], heat, rtol=0,
                                   atol=1e-9 * scale)


def assert_max_principle_checked(out, lo, hi):
    """No power in: the run checks the maximum principle itself, over [lo, hi]."""
    a, T = out["attrs"], out["temperature"]
    assert a["max_principle_checked"] == 1
    np.testing.assert_array_equal(a["max_principle_bounds_k"], [lo, hi])
    assert "max_principle" not in flags(out)
    assert T.min() >= lo - 1e-9 * (hi - lo) and T.max() <= hi + 1e-9 * (hi - lo)


# ---------------------------------------------------------------- temperature
@pytest.mark.parametrize("method", list(SOLVERS))
def test_temperature_boundary_end_to_end(tmp_path, method):
    """Sphere 0 held at 500 K, sphere 2 at 400 K: steady middle 450 K, heat H x 50 K in
    through the hot end and out through the cold one; the transient stays in [300, 500] K."""
    bounds = ('[[boundary]]\nkind = "temperature"\non = "xmin"\nvalue = 500.0\n'
              '[[boundary]]\nkind = "temperature"\non = "xmax"\nvalue = 400.0\n')
    out = run(tmp_path, chain(tmp_path), bounds, SOLVERS[method], method)
    assert isinstance(out["scene"].boundaries[0], TemperatureBoundary)
    assert_ledger(out, method)
    assert_max_principle_checked(out, 300.0, 500.0)
    T = out["temperature"]
    np.testing.assert_array_equal(T[:, 0], 500.0)
    np.testing.assert_array_equal(T[:, 2], 400.0)
    if method == "steady":
        np.testing.assert_allclose(T[-1, 1], 450.0, rtol=1e-12)
        np.testing.assert_allclose(out["boundary_heat_flow"][-1], [50.0 * H, -50.0 * H],
                                   rtol=1e-9)
    else:   # the middle sphere relaxes to 450 K: C dT/dt = H (500 - T) + H (400 - T)
        expect = 450.0 + (T0 - 450.0) * np.exp(-2.0 * H * out["time"] / C)
        np.testing.assert_allclose(T[:, 1], expect, rtol=2e-3)


def test_temperature_one_backward_euler_step_by_hand(tmp_path):
    """One backward-Euler step of the middle sphere: T1 = (C T0 + dt H (500 + 400)) /
    (C + 2 H dt)."""
    bounds = ('[[boundary]]\nkind = "temperature"\non = "xmin"\nvalue = 500.0\n'
              '[[boundary]]\nkind = "temperature"\non = "xmax"\nvalue = 400.0\n')
    dt = 0.05
    out = run(tmp_path, chain(tmp_path), bounds,
              f'method = "implicit"\ndt = {dt!r}\nend_time = {dt!r}\n', "be")
    np.testing.assert_allclose(out["temperature"][-1, 1],
                               (C * T0 + dt * H * 900.0) / (C + 2.0 * H * dt), rtol=1e-12)


# ---------------------------------------------------------------- flux
Q_FLUX = 2e4                                   # W/m^2 into xmin


@pytest.mark.parametrize("method", list(SOLVERS))
def test_flux_boundary_end_to_end(tmp_path, method):
    """q into the xmin face (area PITCH^2, all of it on sphere 0: P = q PITCH^2), sphere 2
    held at 400 K: steady T = 400 + 2P/H, 400 + P/H, 400; in a transient the flux's heat is
    exactly P t, and T stays between 300 K and the steady field (power in: no maximum
    principle, but the comparison bounds)."""
    bounds = (f'[[boundary]]\nkind = "flux"\non = "xmin"\nvalue = {Q_FLUX!r}\n'
              '[[boundary]]\nkind = "temperature"\non = "xmax"\nvalue = 400.0\n')
    out = run(tmp_path, chain(tmp_path), bounds, SOLVERS[method], method)
    assert isinstance(out["scene"].boundaries[0], FluxBoundary)
    power = Q_FLUX * PITCH ** 2
    steady = np.array([400.0 + 2 * power / H, 400.0 + power / H, 400.0])
    assert_ledger(out, method)
    assert out["attrs"]["max_principle_checked"] == 0
    T = out["temperature"]
    assert T.min() >= T0 - 1e-9 and np.all(T <= steady + 1e-9 * steady)
    if method == "steady":
        np.testing.assert_allclose(T[-1], steady, rtol=1e-12)
        np.testing.assert_allclose(out["boundary_heat_flow"][-1], [power, -power], rtol=1e-9)
    else:
        np.testing.assert_allclose(out["boundary_energy"][:, 0], power * out["time"],
                                   rtol=1e-9)


# ---------------------------------------------------------------- wall_temperature
DELTA_W, K_W = 4e-6, 11.0                      # wall overlap (m), wall conductivity (W/m/K)


@pytest.mark.parametrize("method", list(SOLVERS))
def test_wall_temperature_boundary_end_to_end(tmp_path, method):
    """A wall at 500 K touching sphere 0 (g = 2 sqrt(r delta_w) k_h(k, k_w)), sphere 2 held at
    400 K: steady heat Q = 100 K / (1/g + 2/H) through the series; sphere 0 is not held; the
    transient stays within [300, 500] K (checked by the run: no power in)."""
    bounds = ('[[boundary]]\nkind = "wall_temperature"\non = "xmin"\nvalue = 500.0\n'
              f'wall_conductivity = {K_W!r}\n'
              '[[boundary]]\nkind = "temperature"\non = "xmax"\nvalue = 400.0\n')
    out = run(tmp_path, chain(tmp_path, wall_overlap=DELTA_W), bounds, SOLVERS[method], method)
    assert isinstance(out["scene"].boundaries[0], WallTemperatureBoundary)
    g = 2.0 * math.sqrt(R * DELTA_W) * 2.0 * K * K_W / (K + K_W)
    q = 100.0 / (1.0 / g + 2.0 / H)
    assert_ledger(out, method)
    assert_max_principle_checked(out, 300.0, 500.0)
    T = out["temperature"]
    if method == "steady":
        np.testing.assert_allclose(T[-1], [500.0 - q / g, 500.0 - q / g - q / H, 400.0],
                                   rtol=1e-12)
        np.testing.assert_allclose(out["boundary_heat_flow"][-1], [q, -q], rtol=1e-9)
    else:   # heating from 300 K towards the steady field, never above it
        assert np.all(np.diff(out["stored_energy_change"]) > 0)
        assert T[:, 0].max() <= 500.0 - q / g + 1e-9


# ---------------------------------------------------------------- source
def phi(packing):
    """The packing's solid fraction: a source's q is per m^3 of bulk, V_p / phi per sphere."""
    return float(read_packing(packing).attrs["solid_fraction"])


Q_SRC = 1e8                                    # W/m^3, box around sphere 2, on 0.1 .. 0.3 s
SOURCE = (f'[[boundary]]\nkind = "source"\nshape = "box"\nvalue = {Q_SRC!r}\n'
          f'centre_m = [{2.5 * PITCH!r}, {0.5 * PITCH!r}, {0.5 * PITCH!r}]\n'
          f'half_size_m = [{0.5 * PITCH!r}, {0.5 * PITCH!r}, {0.5 * PITCH!r}]\n'
          'start_time = 0.1\nstop_time = 0.3\n')
HELD = '[[boundary]]\nkind = "temperature"\non = "xmin"\nvalue = 300.0\n'


@pytest.mark.parametrize("method", ["explicit", "implicit"])
def test_source_boundary_end_to_end(tmp_path, method):
    """q W/m^3 on sphere 2 between 0.1 and 0.3 s (S = q 4/3 pi r^3 / phi W: the bulk volume
    the sphere stands for, phi the packing's solid fraction), sphere 0 held at the initial
    300 K: the source's heat is S x 0.2 s exactly (the source is integrated over each step),
    the ledger closes with it, and T stays between 300 K and the steady field of a source that
    never stops (T = 300 + 2S/H, 300 + S/H)."""
    packing = chain(tmp_path)
    out = run(tmp_path, packing, HELD + SOURCE, SOLVERS[method], method)
    assert isinstance(out["scene"].boundaries[1], SourceBoundary)
    s = Q_SRC * 4.0 / 3.0 * math.pi * R ** 3 / phi(packing)
    assert_ledger(out, method)
    assert out["attrs"]["max_principle_checked"] == 0
    T = out["temperature"]
    bound = np.array([300.0, 300.0 + s / H, 300.0 + 2 * s / H])
    assert T.min() >= T0 - 1e-9 and np.all(T <= bound + 1e-9 * bound)
    energy = out["boundary_energy"][:, 1]          # the source's column
    np.testing.assert_allclose(out["source_energy"], energy, rtol=1e-12)
    np.testing.assert_allclose(energy, 0.2 * s, rtol=1e-9)   # any dt: integrated over steps


def test_source_steady_by_hand(tmp_path):
    """`tdem run` of a steady scene leaves a source out (flag source_ignored); with the
    source's power included (solve_steady's source_interval) the steady field is
    300 + S/H and 300 + 2S/H, all of S leaving through the held sphere."""
    packing = chain(tmp_path)
    out = run(tmp_path, packing, HELD + SOURCE, SOLVERS["steady"], "steady")
    assert "source_ignored" in flags(out)
    np.testing.assert_array_equal(out["temperature"][-1], T0)
    problem, _ = build_problem(out["scene"], read_packing(packing))
    res = solve_steady(assemble(problem), np.full(3, T0), source_interval=(0.2, 0.2))
    s = Q_SRC * 4.0 / 3.0 * math.pi * R ** 3 / phi(packing)
    np.testing.assert_allclose(res.temperature_k[-1], [300.0, 300.0 + s / H, 300.0 + 2 * s / H],
                               rtol=1e-12)
    np.testing.assert_allclose(res.boundary_heat_flow_w[-1], [-s, s], rtol=1e-9)


# ---------------------------------------------------------------- the registry
def test_every_declared_kind_is_registered():
    import importlib
    import inspect
    import pkgutil

    import thermal_kernel.boundaries as package
    declared = {}
    for info in pkgutil.iter_modules(package.__path__):
        module = importlib.import_module(f"{package.__name__}.{info.name}")
        declared.update({cls.kind: cls for cls in vars(module).values()
                         if inspect.isclass(cls) and issubclass(cls, BoundaryKind)
                         and cls.__module__ == module.__name__ and cls.kind})
    assert len(declared) >= 2 and declared == BOUNDARIES


def test_registry_is_explicit_and_every_kind_documents_itself():
    # each kind declares the unit of its value, a minimal table and that table's default name
    # (ClassVars: thermal_kernel/boundaries/base.py); its docstring's Keys line states the unit
    for kind, cls in BOUNDARIES.items():
        assert cls.kind == kind
        assert "name" in keys(cls) and "kind" not in keys(cls)
        assert cls.unit and cls.example and cls.example_name, kind
        doc = cls.__doc__ or ""
        assert f"({cls.unit}" in doc and "Keys:" in doc, kind
        assert f"``value`` ({cls.unit}" in doc.split("Keys:")[1], kind
        with pytest.raises(dataclasses.FrozenInstanceError):
            cls.__new__(cls).__setattr__("name", "x")


def _scene(tmp_path, boundary):
    path = tmp_path / "s.toml"
    path.write_text('packing = "p.h5"\nlaw = "bob"\n[material]\nconductivity = 1.0\n'
                    'density = 1.0\nheat_capacity = 1.0\n[initial]\ntemperature = 300.0\n'
                    f'[[boundary]]\n{boundary}\n[solver]\nmethod = "steady"\n')
    return path


@pytest.mark.parametrize("kind", list(BOUNDARIES))
def test_each_kind_parses_its_own_table_and_refuses_the_others_keys(tmp_path, kind):
    example = BOUNDARIES[kind].example
    scene = load_scene(_scene(tmp_path, f'kind = "{kind}"\n{example}'))
    (b,) = scene.boundaries
    assert type(b) is BOUNDARIES[kind]
    table = tomllib.loads(example)
    assert "value" in table and "kind" not in table and "name" not in table
    for key, value in table.items():
        got = getattr(b, key)
        assert got == value, (key, got, value)
    assert b.name == BOUNDARIES[kind].example_name
    if "on" in table:
        assert b.name == f"{kind}:{table['on']}"
    # a key of another kind: refused, naming the kind it belongs to
    for other, cls in BOUNDARIES.items():
        for key in set(keys(cls)) - set(keys(BOUNDARIES[kind])):
            value = '"x"' if key in ("on", "shape") else "1.0"
            with pytest.raises(SceneError) as e:
                load_scene(_scene(tmp_path, f'kind = "{kind}"\n{example}\n{key} = {value}'))
            assert f"boundary[0].{key}: only for kind = " in str(e.value)
            assert f'"{other}"' in str(e.value)
    with pytest.raises(SceneError, match=r"boundary\[0\]\.colour: unknown key"):
        load_scene(_scene(tmp_path, f'kind = "{kind}"\n{example}\ncolour = 1'))


def test_the_solvers_do_not_know_the_boundary_kinds():
    """thermal_kernel/solvers/* see rows of a ThermalProblem only: they import nothing that
    knows a kind (boundaries, scene, problem) and name no kind."""
    import ast
    for path in sorted((ROOT / "thermal_kernel" / "solvers").glob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                mod = ("." * node.level) + (node.module or "")
                assert not any(w in mod for w in ("boundaries", "scene", "problem")), \
                    (path.name, mod)
            if isinstance(node, ast.Constant) and isinstance(node.value, str):
                assert node.value not in BOUNDARIES, (path.name, node.value)


# ---------------------------------------------------------------- every scene in runs/
RUN_FILES = sorted(ROOT.glob("runs/*.toml")) + sorted(ROOT.glob("runs/*/*.toml"))


@pytest.mark.parametrize("path", RUN_FILES, ids=[str(p.relative_to(ROOT)) for p in RUN_FILES])
def test_every_scene_in_runs_loads(tmp_path, path):
    """A thermal scene (packing = or [pack]) loads with load_scene; a campaign file
    ([campaign]: load_scene refuses it, it has no law of its own) loads its case scene of
    every law the way `tdem campaign` does before building anything. Every boundary is a
    registered kind."""
    from tdem.campaign import case_scenes, check_case_scenes, read_campaign
    data = tomllib.loads(path.read_text())
    if "campaign" not in data:
        scene = load_scene(path, out_dir=tmp_path)
        assert (scene.packing is None) == (scene.pack is not None)
        scenes = [scene]
    else:
        with pytest.raises(SceneError):        # not a scene by itself
            load_scene(path, out_dir=tmp_path)
        laws = data["campaign"]["laws"]
        if "packings" not in data["campaign"]:     # read_campaign also needs its packing files
            conf, text = read_campaign(path)
            check_case_scenes(path, conf, text, tmp_path)
        scenes = list(case_scenes(path, {"laws": laws}, path.read_text(), tmp_path).values())
    for scene in scenes:
        assert scene.boundaries
        for b in scene.boundaries:
            assert type(b) is BOUNDARIES[b.kind]
