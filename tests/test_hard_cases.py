"""Hard numerical cases (issue 16, sec. 4, second bullet), run the way a user runs them: a
packing file + a scene file -> load_scene / run_scene (or `tdem run`) -> thermal.h5.

Packings are small simple-cubic lattices (thermal_kernel.lattice) with the radii, phases and
contacts changed per case; law `bob` (H = 2 a k_h, a = sqrt(R* delta) for the lattice's Hertz
force, k_h the harmonic mean of the two conductivities), walls `xmin` at 500 K and `xmax` at
400 K held, everything at 300 K at t = 0. Every case asserts:

* the maximum principle: every recorded temperature in [300, 500] K to 1e-9 of the span (or,
  for a scheme that may overshoot, that the output is flagged exactly when it does);
* the energy ledger: `ledger_residual_relative` (thermal.h5) small and no `energy_ledger` flag;
* where a steady state exists, agreement of the steady solve and of the transient's late state
  with an independent closed form (series resistances along each lattice row, computed here
  from the geometry, not from the assembled network).
"""
import dataclasses
import math
import os
import subprocess
import sys

import h5py
import numpy as np
import pytest

from thermal_kernel.lattice import simple_cubic_packing
from thermal_kernel.packing import write_packing
from thermal_kernel.run import run_scene
from thermal_kernel.scene import SceneError, load_scene
from thermal_kernel.solvers import LEDGER_RTOL, MAX_PRINCIPLE_RTOL

# `make coverage` counts this module (marker kernel: its subject is thermal_kernel, and it is
# fast enough with NUMBA_DISABLE_JIT=1)
pytestmark = pytest.mark.kernel

T_INIT, T_HOT, T_COLD = 300.0, 500.0, 400.0          # xmin hot, xmax cold
LO, HI = 300.0, 500.0
SPAN = HI - LO
K0, RHO, CP, E, NU = 33.0, 7800.0, 500.0, 2e11, 0.3
OVERLAP = 1e-3                                      # delta / r of every lattice contact

BOUNDS = f'''
[[boundary]]
kind = "temperature"
on = "xmin"
value = {T_HOT!r}

[[boundary]]
kind = "temperature"
on = "xmax"
value = {T_COLD!r}
'''


def lattice(shape, radius_m=1e-3, phase_of_layer=None):
    """Touching spheres of radius r on a pitch 2 r (1 - OVERLAP / 2): overlap OVERLAP * r.
    ``phase_of_layer``: phase id of each x-layer."""
    pitch = 2.0 * radius_m * (1.0 - OVERLAP / 2.0)
    pk = simple_cubic_packing(shape, pitch, radius_m=radius_m, young_pa=E, poisson=NU,
                              density=RHO)
    if phase_of_layer is not None:
        layer = np.rint(pk.position[:, 0] / pitch - 0.5).astype(int)
        pk = dataclasses.replace(pk, phase=np.asarray(phase_of_layer, np.int32)[layer])
    return pk


def bob_h(radius_m, k_i, k_j):
    """Independent closed form of one lattice contact: a = sqrt(R* delta), H = 2 a k_h."""
    a = math.sqrt(radius_m / 2.0 * OVERLAP * radius_m)
    return 2.0 * a * 2.0 * k_i * k_j / (k_i + k_j)


def series_profile(h_layers):
    """Steady T of the x-layers of a row of contacts h_layers (W/K) between T_HOT and T_COLD."""
    r = np.r_[0.0, np.cumsum(1.0 / np.asarray(h_layers))]
    return T_HOT + (T_COLD - T_HOT) * r / r[-1]


def scene_text(packing, solver, *, k1=None, boundaries=BOUNDS, initial=T_INIT):
    mat1 = "" if k1 is None else f"\n[material.1]\nconductivity = {k1!r}\n"
    return (f'packing = "{packing}"\nlaw = "bob"\n\n[material]\nconductivity = {K0!r}\n'
            f"density = {RHO!r}\nheat_capacity = {CP!r}\nyoung_pa = {E!r}\npoisson = {NU!r}\n"
            f"{mat1}\n[initial]\ntemperature = {initial!r}\n{boundaries}\n[solver]\n{solver}")


def run(tmp_path, pk, solver, name, **kw):
    """Write the packing and the scene, run_scene it; (summary, attrs, times, T)."""
    packing = tmp_path / f"{name}.h5"
    if not packing.exists():
        write_packing(packing, pk)
    scene = tmp_path / f"{name}.toml"
    scene.write_text(scene_text(packing, solver, **kw))
    summary = run_scene(load_scene(scene, out_dir=tmp_path / name), quiet=True)
    with h5py.File(summary.output) as f:
        attrs = dict(f.attrs)
        times, T = f["time"][()], f["temperature"][()]
    return summary, attrs, times, T


def flags(attrs):
    return set(filter(None, attrs["flags"].split(",")))


def assert_bounded(attrs, T, rtol=1e-9):
    """The maximum principle, exactly as a bounded scheme must keep it, and checked by the run."""
    assert np.all(np.isfinite(T))
    assert T.min() >= LO - rtol * SPAN and T.max() <= HI + rtol * SPAN, (T.min(), T.max())
    assert attrs["max_principle_checked"] == 1
    np.testing.assert_array_equal(attrs["max_principle_bounds_k"], [LO, HI])
    assert "max_principle" not in flags(attrs)


def assert_ledger(attrs, rtol=LEDGER_RTOL):
    """Implicit and steady: the run's own tolerance; explicit callers ask for round-off."""
    assert attrs["ledger_residual_relative"] <= rtol, attrs["ledger_residual_relative"]
    assert "energy_ledger" not in flags(attrs)


def steady_reference(pk, radius_m, k_of_phase):
    """Closed-form steady T of every particle of a lattice held at its x faces: each x-row is
    a series of contacts (no heat crosses rows: all rows are alike)."""
    pitch = 2.0 * radius_m * (1.0 - OVERLAP / 2.0)
    layer = np.rint(pk.position[:, 0] / pitch - 0.5).astype(int)
    nx = layer.max() + 1
    k_layer = np.array([k_of_phase[pk.phase[np.flatnonzero(layer == i)[0]]] for i in range(nx)])
    return series_profile([bob_h(radius_m, k_layer[i], k_layer[i + 1])
                           for i in range(nx - 1)])[layer]


def slowest_time(radius_m, k_min):
    """C / H of the weakest contact: an upper scale of the slow time constants."""
    c = RHO * CP * 4.0 / 3.0 * math.pi * radius_m ** 3
    return c / bob_h(radius_m, k_min, k_min)


def fl(x):
    return repr(float(x))


# ---------------------------------------------------------------- conductivity contrast 1e+-6
@pytest.mark.parametrize("contrast", [1e6, 1e-6])
def test_conductivity_contrast(tmp_path, contrast):
    """Two phases, conductivities K0 and contrast x K0 in x-layers: the steady solve and the
    late state of backward Euler and of the default second-order scheme equal the series
    closed form; a short explicit run at the default dt (set by the fast phase) is bounded."""
    phases = [0, 0, 1, 1, 1, 0]
    pk = lattice((6, 2, 2), phase_of_layer=phases)
    k1 = K0 * contrast
    ref = steady_reference(pk, 1e-3, {0: K0, 1: k1})
    assert np.ptp(ref[pk.phase == 1]) < 1e-3 * SPAN or contrast < 1   # a real contrast
    _, a, _, T = run(tmp_path, pk, 'method = "steady"\n', "steady", k1=k1)
    np.testing.assert_allclose(T[0], ref, rtol=0, atol=1e-9 * SPAN)
    assert_bounded(a, T)
    assert_ledger(a)
    dt_max = a["dt_max"]
    tau = slowest_time(1e-3, min(K0, k1))
    assert tau > 1e5 * dt_max                       # stiff: 6 decades between time scales
    for name, theta in (("be", "1.0"), ("cn", "0.5")):
        _, a, _, T = run(tmp_path, pk, f'method = "implicit"\ntheta = {theta}\n'
                         f'dt = {fl(tau)}\nend_time = {fl(300 * tau)}\n'
                         f'output_times = [{fl(tau)}, {fl(10 * tau)}, {fl(300 * tau)}]\n',
                         name, k1=k1)
        assert_bounded(a, T)
        assert_ledger(a)
        np.testing.assert_allclose(T[-1], ref, rtol=0, atol=1e-6 * SPAN)
    _, a, _, T = run(tmp_path, pk, f'method = "explicit"\nend_time = {fl(500 * dt_max)}\n',
                     "explicit", k1=k1)
    assert a["dt"] == pytest.approx(0.9 * dt_max)
    assert_bounded(a, T)
    assert_ledger(a, rtol=1e-12)       # explicit: round-off
    assert T[-1].max() > T_INIT + 1e-3 * SPAN       # heat did move in


# ---------------------------------------------------------------- radii 1e-9 m and 1e3 m
# slow: whole explicit and implicit runs, per radius;
# over ~1.3 s on the shared 2-core machine, warm numba cache (--durations, 2026-12-01)
@pytest.mark.slow
@pytest.mark.parametrize("radius_m", [1e-9, 1e3])
def test_extreme_radii(tmp_path, radius_m):
    """A uniform lattice of nanometre or kilometre spheres: linear steady profile along x
    (closed form), reached by backward Euler; explicit at the default dt bounded; ledgers
    closed although the energies are ~1e-19 J or ~1e19 J."""
    pk = lattice((5, 2, 2), radius_m=radius_m)
    ref = steady_reference(pk, radius_m, {0: K0})
    _, a, _, T = run(tmp_path, pk, 'method = "steady"\n', "steady")
    np.testing.assert_allclose(T[0], ref, rtol=0, atol=1e-9 * SPAN)
    assert_bounded(a, T)
    assert_ledger(a)
    dt_max = a["dt_max"]
    assert math.isfinite(dt_max) and dt_max > 0
    tau = slowest_time(radius_m, K0)
    _, a, _, T = run(tmp_path, pk, f'method = "implicit"\ntheta = 1.0\ndt = {fl(tau)}\n'
                     f'end_time = {fl(300 * tau)}\n', "be")
    assert_bounded(a, T)
    assert_ledger(a)
    np.testing.assert_allclose(T[-1], ref, rtol=0, atol=1e-6 * SPAN)
    _, a, times, T = run(tmp_path, pk, f'method = "explicit"\nend_time = {fl(2000 * dt_max)}\n'
                         f'output_times = [{fl(20 * dt_max)}, {fl(2000 * dt_max)}]\n',
                         "explicit")
    assert_bounded(a, T)
    assert_ledger(a, rtol=1e-12)
    np.testing.assert_allclose(T[-1], ref, rtol=0, atol=1e-2 * SPAN)   # close to steady


# ---------------------------------------------------------------- one isolated particle
FLUX = 1e3     # W/m^2 on xmin


@pytest.mark.parametrize("method", ["steady", "explicit", "implicit"])
def test_one_isolated_particle(tmp_path, method):
    """One sphere, no contact. Adiabatic: it keeps its temperature (flagged a rattler, dt_max
    infinite, never a NaN). Heated through a face: T = T0 + P t / C exactly in a transient; the
    steady solve has no steady state and says so."""
    pk = lattice((1, 1, 1))
    sol = {"steady": 'method = "steady"\n',
           "explicit": 'method = "explicit"\nend_time = 10.0\noutput_times = [2.0, 10.0]\n',
           "implicit": 'method = "implicit"\ndt = 1.0\nend_time = 10.0\n'
                       'output_times = [2.0, 10.0]\n'}[method]
    _, a, times, T = run(tmp_path, pk, sol, "adiabatic", boundaries="")
    np.testing.assert_array_equal(T, T_INIT)
    assert "rattlers" in flags(a) and a["n_rattlers"] == 1
    assert a["max_principle_checked"] == 1 and "max_principle" not in flags(a)
    assert_ledger(a)
    flux = f'[[boundary]]\nkind = "flux"\non = "xmin"\nvalue = {FLUX!r}\n'
    _, a, times, T = run(tmp_path, pk, sol, "heated", boundaries=flux)
    assert np.all(np.isfinite(T))
    assert a["max_principle_checked"] == 0            # power in: no maximum principle
    if method == "steady":
        assert "no_steady_state_in_floating_cluster" in flags(a)
        return
    area = float(np.prod((pk.domain_hi - pk.domain_lo)[1:]))
    c = RHO * CP * 4.0 / 3.0 * math.pi * 1e-3 ** 3
    np.testing.assert_allclose(T[:, 0], T_INIT + FLUX * area * times / c, rtol=1e-12)
    assert_ledger(a)


# ---------------------------------------------------------------- all rattlers
@pytest.mark.parametrize("method", ["steady", "explicit", "implicit"])
def test_all_rattlers(tmp_path, method):
    """Spheres that do not touch (gaps, no force, H = 0): every particle is a rattler; the
    held ones are held, the others keep their initial temperature bit for bit."""
    pitch = 2e-3
    pk = simple_cubic_packing((4, 2, 2), pitch, radius_m=0.45 * pitch, young_pa=E,
                              poisson=NU, density=RHO)
    sol = {"steady": 'method = "steady"\n',
           "explicit": 'method = "explicit"\nend_time = 10.0\n',
           "implicit": 'method = "implicit"\ntheta = 0.5\ndt = 1.0\nend_time = 10.0\n'}[method]
    _, a, _, T = run(tmp_path, pk, sol, "rattlers")
    x = pk.position[:, 0]
    expect = np.where(x == x.min(), T_HOT, np.where(x == x.max(), T_COLD, T_INIT))
    np.testing.assert_array_equal(T, np.broadcast_to(expect, T.shape))
    assert a["n_conducting_contacts"] == 0 and a["n_rattlers"] == (x != x.min()).sum() - (
        x == x.max()).sum()
    assert "rattlers" in flags(a)
    assert_bounded(a, T)
    assert_ledger(a)


# ---------------------------------------------------------------- floating cluster + source
@pytest.mark.parametrize("method", ["steady", "explicit", "implicit"])
def test_floating_cluster_with_a_source(tmp_path, method):
    """An 8-layer lattice cut between layers 3 and 4: layers 0-3 hang on the 500 K wall, layers
    4-7 float, all inside a box source of Q W/m^3 from t = 0. The floating block heats
    uniformly at Q / (rho c_p) (closed form; no steady state); the tied block stays within
    [300, 500] K; the ledger closes with the source's energy in it."""
    pk = lattice((8, 2, 2))
    x = pk.position[:, 0]
    pitch = 2.0 * x.min()
    layer = np.rint(x / pitch - 0.5).astype(int)
    cut = (layer[pk.pair[:, 0]] == 3) & (layer[pk.pair[:, 1]] == 4)
    keep = ~cut
    pk = dataclasses.replace(pk, pair=pk.pair[keep], overlap=pk.overlap[keep],
                             normal_force=pk.normal_force[keep], branch=pk.branch[keep],
                             contact_radius=pk.contact_radius[keep])
    q = 1e6
    bounds = (f'[[boundary]]\nkind = "temperature"\non = "xmin"\nvalue = {T_HOT!r}\n\n'
              f'[[boundary]]\nkind = "source"\nshape = "box"\nvalue = {q!r}\n'
              f'centre_m = [{fl(6 * pitch)}, {fl(pitch)}, {fl(pitch)}]\n'
              f'half_size_m = [{fl(2 * pitch)}, {fl(2 * pitch)}, {fl(2 * pitch)}]\n')
    sol = {"steady": 'method = "steady"\n',
           "explicit": 'method = "explicit"\nend_time = 10.0\noutput_times = [1.0, 5.0, 10.0]\n',
           "implicit": 'method = "implicit"\ntheta = 0.5\ndt = 1.0\nend_time = 10.0\n'
                       'output_times = [1.0, 5.0, 10.0]\n'}[method]
    _, a, times, T = run(tmp_path, pk, sol, "floating", boundaries=bounds)
    assert np.all(np.isfinite(T))
    assert a["n_floating_clusters"] == 1 and "floating_clusters" in flags(a)
    assert a["max_principle_checked"] == 0            # a source: not the run's check ...
    tied, floating = layer <= 3, layer >= 4
    assert T[:, tied].min() >= LO - 1e-9 * SPAN and T[:, tied].max() <= HI + 1e-9 * SPAN
    assert_ledger(a)                                 # ... but the ledger is
    if method == "steady":   # no steady state: the source is left out, and said so
        assert "source_ignored" in flags(a)
        np.testing.assert_allclose(T[0, floating], T_INIT, rtol=1e-14)
        return
    # a source's value is W per m^3 of bed: each particle gets q V_p / phi (issue 28, C22)
    expect = T_INIT + q * times / (RHO * CP * float(pk.attrs["solid_fraction"]))
    np.testing.assert_allclose(T[:, floating], np.repeat(expect[:, None], floating.sum(), 1),
                               rtol=1e-12)
    with h5py.File(tmp_path / "floating" / "thermal.h5") as f:
        src = f["source_energy"][()]
    c = RHO * CP * 4.0 / 3.0 * math.pi * 1e-3 ** 3
    np.testing.assert_allclose(src, c * floating.sum() * (expect - T_INIT), rtol=1e-9)


# ---------------------------------------------------------------- dt at 1.0 / 1.5 / 2.5 x the bound
def bound_lattice(tmp_path, mixed=False):
    """The uniform 6x3x3 lattice, or (mixed) one with a seeded random half of its spheres
    4x more conductive: a uniform lattice with uniform rows excites only the modes constant
    across the rows, which stay stable up to 3 dt_max; the mixed one excites them all.
    Returns (packing, dt_max, phase-1 conductivity, steady temperatures of the run)."""
    pk = lattice((6, 3, 3))
    k1 = None
    if mixed:
        rng = np.random.default_rng(16)
        pk = dataclasses.replace(pk, phase=(rng.random(pk.n_particles) < 0.5).astype(np.int32))
        k1 = 4.0 * K0
    _, a, _, T = run(tmp_path, pk, 'method = "steady"\n', "bound", k1=k1)
    if not mixed:
        np.testing.assert_allclose(T[0], steady_reference(pk, 1e-3, {0: K0}), rtol=0,
                                   atol=1e-9 * SPAN)
    return pk, float(a["dt_max"]), k1, T[0]


@pytest.mark.filterwarnings("error::RuntimeWarning")
@pytest.mark.parametrize("factor", [1.0, 1.5, 2.5])
def test_explicit_dt_at_multiples_of_the_bound(tmp_path, factor):
    """At the bound the explicit run is bounded (the exact positivity bound is allowed); above
    it the scene is refused in one line naming solver.dt and the bound, nothing written; with
    allow_unstable it either stops in one line (diverged, nothing written) or is written
    flagged dt_above_bound (and max_principle if it left the bounds): never a NaN."""
    pk, dt_max, k1, steady = bound_lattice(tmp_path, mixed=True)
    dt = factor * dt_max
    n = 1500
    every = ", ".join(fl(dt * i) for i in range(10, n + 1, 10))
    solver = (f'method = "explicit"\ndt = {fl(dt)}\nend_time = {fl(n * dt)}\n'
              f'output_times = [{every}]\n')
    if factor == 1.0:
        _, a, _, T = run(tmp_path, pk, solver, "at", k1=k1)
        assert a["dt"] == dt_max and "dt_above_bound" not in flags(a)
        assert_bounded(a, T)
        assert_ledger(a, rtol=1e-12)
        np.testing.assert_allclose(T[-1], steady, rtol=0, atol=1e-6 * SPAN)
        return
    with pytest.raises(SceneError, match="solver.dt") as err:
        run(tmp_path, pk, solver, "refused", k1=k1)
    msg = str(err.value)
    assert "\n" not in msg and f"{dt_max:.6g}" in msg and "allow_unstable" in msg
    assert not (tmp_path / "refused" / "thermal.h5").exists()
    try:
        _, a, _, T = run(tmp_path, pk, solver + "allow_unstable = true\n", "unstable", k1=k1)
    except SceneError as e:
        assert "\n" not in str(e) and "solver.allow_unstable" in str(e) and "diverged" in str(e)
        assert not (tmp_path / "unstable" / "thermal.h5").exists()
        return
    assert np.all(np.isfinite(T)) and "dt_above_bound" in flags(a)
    outside = T.min() < LO - MAX_PRINCIPLE_RTOL * SPAN or T.max() > HI + MAX_PRINCIPLE_RTOL * SPAN
    assert ("max_principle" in flags(a)) == outside
    if factor > 2.0:     # lambda_max >= max D / C: some mode grows by >= 1.5 a step
        assert outside


@pytest.mark.parametrize("unstable", [False, True])
def test_explicit_dt_above_the_bound_from_the_command_line(tmp_path, unstable):
    """`tdem run` at 2.5 x the bound: refused, or (allow_unstable) diverged: exit 2, exactly one
    line on stderr (a diverging run used to print numpy's RuntimeWarning first), nothing
    written."""
    pk, dt_max, k1, _ = bound_lattice(tmp_path, mixed=True)
    scene = tmp_path / "cli.toml"
    scene.write_text(scene_text(tmp_path / "bound.h5", f'method = "explicit"\n'
                                f'dt = {fl(2.5 * dt_max)}\nend_time = {fl(3750 * dt_max)}\n'
                                + ("allow_unstable = true\n" if unstable else ""), k1=k1))
    p = subprocess.run([sys.executable, "-m", "tdem.cli", "run", str(scene), "--quiet",
                        "--out", str(tmp_path / "cli")], capture_output=True, text=True,
                       env={**os.environ, "NUMBA_NUM_THREADS": "1"})
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("tdem: error:"), p.stderr
    assert ("solver.allow_unstable" if unstable else "solver.dt") in lines[0]
    assert not (tmp_path / "cli" / "thermal.h5").exists()


# ---------------------------------------------------------------- theta-scheme at 100 x tau_fast
@pytest.mark.parametrize("scheme", ["backward-euler", "default", "tr-bdf2", "plain-cn"])
def test_theta_scheme_at_100_times_the_fastest_time_constant(tmp_path, scheme):
    """dt = 100 dt_max (dt_max = min C / D, the fastest time constant), an output after every
    step: backward Euler is bounded; the default second-order scheme (CN + Rannacher start-up)
    is not flagged; TR-BDF2 and plain Crank-Nicolson are flagged max_principle exactly when
    they leave the bounds, and plain CN does ring here (stiff modes -> -1 per step). The late
    state of the bounded ones is the closed-form steady field."""
    pk, dt_max, _, _ = bound_lattice(tmp_path)
    dt = 100.0 * dt_max
    extra = {"backward-euler": "theta = 1.0\n", "default": "theta = 0.5\n",
             "tr-bdf2": 'scheme = "tr-bdf2"\n', "plain-cn": 'theta = 0.5\nscheme = "theta"\n'}
    n = 150
    times = ", ".join(fl(dt * i) for i in range(1, n + 1))
    _, a, _, T = run(tmp_path, pk, f'method = "implicit"\ndt = {fl(dt)}\n'
                     f'end_time = {fl(n * dt)}\noutput_times = [{times}]\n' + extra[scheme],
                     scheme)
    assert np.all(np.isfinite(T))
    assert_ledger(a)
    assert a["max_principle_checked"] == 1
    excess = max(T.max() - HI, LO - T.min(), 0.0) / SPAN
    assert a["max_principle_excess_relative"] == pytest.approx(excess, abs=1e-12)
    assert ("max_principle" in flags(a)) == (excess > MAX_PRINCIPLE_RTOL)
    ref = steady_reference(pk, 1e-3, {0: K0})
    if scheme == "backward-euler":
        assert_bounded(a, T)
    if scheme in ("backward-euler", "default"):
        assert "max_principle" not in flags(a)
        np.testing.assert_allclose(T[-1], ref, rtol=0, atol=1e-6 * SPAN)
    if scheme == "plain-cn":
        assert "max_principle" in flags(a)
