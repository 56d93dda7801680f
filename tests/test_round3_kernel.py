"""Reliability round 3 (issue 28), the thermal kernel's part: boundaries, sources, runs and the
``thermal.h5`` reader (../shared/bad-inputs/round3/cases.tsv, groups A/B "boundary:*",
"scheme:*", "signals:*", "run:*", "law_params:*", "numbers:*", "thermal.h5 tamper:*" and the
metamorphic checks C12, C20, C21, C22).

Two kinds of tests:

- a table of refusals: how the scene is made, the words its one line must hold (exit 2, one
  line naming the file and the scene key, nothing left in the output folder), run in-process
  through ``tdem.cli.main`` (each is refused before any solve); and a table of tampered
  ``thermal.h5`` files that :func:`thermal_kernel.output.read_thermal` must refuse;
- one test per physical rule, each failing on the code before this round: T >= 0 K or the run
  is flagged; a source's energy does not depend on the time step and equals the closed form;
  a periodic cell wraps its source (translating cell and source changes nothing); a flux on a
  cylinder bed's end face brings q pi R^2 t; the same source brings the same energy under
  every law; a steady run writes finite energies.
"""
import dataclasses
import math
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from tdem.committed_beds import BED_THERMAL
from tdem.cli import main as tdem_main
from thermal_kernel.laws import LAWS
from thermal_kernel.laws.base import sphere_volume
from thermal_kernel.network import assemble
from thermal_kernel.output import ThermalFileError, read_thermal
from thermal_kernel.packing import read_packing
from thermal_kernel.problem import build_problem
from thermal_kernel.run import run_scene
from thermal_kernel.scene import load_scene
from thermal_kernel.solvers import TEMPERATURE_MAX_K, check_physics
from thermal_kernel.solvers.implicit import run_implicit

DATA = Path(__file__).resolve().parent / "data"
BED = DATA / "bed_small_1.6e+06Pa.h5"           # a cylinder bed: R = 10 mm, walls zmin, plate
PERIODIC = DATA / "dense_periodic.h5"           # 400 spheres, periodic along x, y, z

EXPLICIT = 'method = "explicit"\nend_time = 2.0\noutput_times = [0.5, 1.0, 2.0]\n'
IMPLICIT = 'method = "implicit"\ndt = 0.5\nend_time = 2.0\noutput_times = [1.0, 2.0]\n'
ZMIN_ONLY = BED_THERMAL.split("[[boundary]]\nkind = \"temperature\"\non = \"plate\"")[0]


def bed_scene(solver=EXPLICIT, extra="", thermal=BED_THERMAL, packing=BED, law="pipe"):
    return f'packing = "{packing}"\nlaw = "{law}"\n{thermal}{extra}\n[solver]\n{solver}'


def boundary(kind, **keys):
    body = "".join(f"{k} = {v!r}\n".replace("'", '"') if not isinstance(v, list)
                   else f"{k} = {v!r}\n" for k, v in keys.items())
    return f'\n[[boundary]]\nkind = "{kind}"\n{body}'


def sphere_source(value, radius, centre, velocity=(0.0, 0.0, 0.0), **more):
    return boundary("source", shape="sphere", value=value, radius_m=radius,
                    centre_m=[float(x) for x in centre],
                    velocity_m_s=[float(x) for x in velocity], **more)


def law_scene(law, params):
    body = "".join(f"{k} = {v!r}\n" for k, v in params.items())
    return bed_scene(extra="", thermal=f"\n[law_params]\n{body}" + BED_THERMAL, law=law)


# ---------------------------------------------------------------------------- refusals
# case: (scene text, the scene key the line names, words it must hold)
REFUSALS = {
    # boundary:src_zero_value -- a 0 W/m^3 source switched the maximum-principle check off
    "src_zero_value": (bed_scene(extra=sphere_source(0.0, 0.005, (0, 0, 0.03))),
                       "boundary[2].value", "a source of 0 heats nothing"),
    # boundary:bnd_name_empty
    "bnd_name_empty": (bed_scene(extra=boundary("flux", on="zmax", value=1e4, name="")),
                       "boundary[2].name", "expected a non-empty name"),
    # boundary:flux_neg_on_held_face / flux_pos_on_held_face: the flux went into held spheres
    "flux_neg_on_held_face": (bed_scene(extra=boundary("flux", on="zmin", value=-1e5)),
                              "boundary[2].on", "held at a temperature by boundary[0]"),
    "flux_pos_on_held_face": (bed_scene(extra=boundary("flux", on="zmin", value=1e5)),
                              "boundary[2].on", "would pass straight into that held"),
    # boundary:flux_on_zmax_face_plate_held
    "flux_on_zmax_plate_held": (bed_scene(extra=boundary("flux", on="zmax", value=1e5)),
                                "boundary[2].on", "held at a temperature by boundary[1]"),
    # A two_bnd_same_wall_named: the second boundary on zmin held nothing
    "two_bnd_same_wall": (bed_scene(extra=boundary("temperature", on="zmin", value=450.0,
                                                   name="second")),
                          "boundary[2].on", "is already held by boundary[0]"),
    # boundary:initial_1e308 / temp_value_1e308 / wallT_value_1e308: -inf written, warnings
    "initial_1e308": (bed_scene(thermal=BED_THERMAL.replace("temperature = 300.0",
                                                            "temperature = 1e308")),
                      "initial.temperature", "expected a temperature in (0, 10000] K"),
    "temp_value_1e308": (bed_scene(thermal=BED_THERMAL.replace("value = 400.0",
                                                               "value = 1e308")),
                         "boundary[1].value", "expected a temperature in (0, 10000] K"),
    "wallT_value_1e308": (bed_scene(extra=boundary("wall_temperature", on="plate",
                                                   value=1e308).replace("1e+308", "1e308"),
                                    thermal=ZMIN_ONLY),
                          "boundary[1].value", "expected a temperature in (0, 10000] K"),
    # a flux on a face whose section is not a box face or the cylinder's disc (was q (2R)^2)
    "flux_on_cylinder_side": (bed_scene(extra=boundary("flux", on="xmin", value=1e5),
                                        thermal=ZMIN_ONLY),
                              "boundary[1].on", "wall 'cylinder' is a cylinder along z"),
    # scheme:trbdf2_startup_huge: the whole run was backward-Euler half steps
    "trbdf2_startup_huge": (bed_scene(IMPLICIT + 'scheme = "tr-bdf2"\n'
                                      "startup_steps = 1000000000\n"),
                            "solver.startup_steps", "the whole run would be backward-Euler"),
    # law_params:* / numbers:*: the line named ThermalProblem.conductance_w_k / capacity_j_k
    "argento_beta_5e-324": (law_scene("argento", {"beta": 5e-324}), "material.conductivity",
                            "law_params.beta = 5e-324: law 'argento' gives a conductance"),
    "haddad_ct_huge": (law_scene("haddad", {"ct": 1.7976931348623157e308}),
                       "material.conductivity", "law 'haddad' gives a conductance H = inf"),
    "cp_1e308": (bed_scene(thermal=BED_THERMAL.replace("heat_capacity = 900.0",
                                                       "heat_capacity = 1e308")),
                 "material.density", "material.heat_capacity = 1e+308: law 'pipe' gives a heat "
                                     "capacity C = inf"),
    "rho_1e-320": (bed_scene(thermal=BED_THERMAL.replace("density = 2500.0",
                                                         "density = 1e-320")),
                   "material.density", "gives a heat capacity C = 0 J/K"),
    "young_1e-320": (bed_scene(thermal=BED_THERMAL.replace("young_pa = 5e10",
                                                           "young_pa = 1e-320")),
                     "material.conductivity", "gives a conductance H = inf"),
    # a periodic source wider than the cell would overlap its own image
    "periodic_source_wider_than_cell": (
        bed_scene(packing=PERIODIC, thermal=BED_THERMAL.split("[[boundary]]")[0],
                  extra=sphere_source(1e9, 0.008, (0.007, 0.007, 0.007))),
        "boundary[0].radius_m", "it would overlap its own periodic image"),
}


@pytest.mark.parametrize("case", sorted(REFUSALS))
def test_refused_in_one_line(tmp_path, capsys, case):
    text, key, words = REFUSALS[case]
    scene = tmp_path / "scene.toml"
    scene.write_text(text)
    out = tmp_path / "out"
    code = tdem_main(["run", str(scene), "--out", str(out), "--quiet", "--threads", "1"])
    err = capsys.readouterr().err
    lines = [x for x in err.splitlines() if x.strip()]
    assert code == 2, err
    assert len(lines) == 1 and "Traceback" not in err and "Warning" not in err, err
    assert lines[0].startswith(f"tdem: error: {scene}: {key}"), lines[0]
    assert words in lines[0], lines[0]
    assert "ThermalProblem" not in lines[0]
    assert not out.exists() or not any(out.iterdir())


# ---------------------------------------------------------------------------- the reader
@pytest.fixture(scope="module")
def clean_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("clean")
    scene = tmp / "scene.toml"
    scene.write_text(bed_scene(IMPLICIT))
    assert tdem_main(["run", str(scene), "--out", str(tmp / "out"), "--quiet"]) == 0
    return tmp / "out" / "thermal.h5"


def _attr(key, value):
    def edit(f):
        f.attrs[key] = value
    return edit


def _dataset(key, change):
    def edit(f):
        data = change(f[key][()].copy())
        del f[key]
        f[key] = data
    return edit


def _nan(a):
    a[1, 5] = np.nan
    return a


def _scene_json(f):
    f.attrs["scene_json"] = f.attrs["scene_json"].replace('"value": 500.0', '"value": 600.0')


def _scene_text(f):
    f.attrs["scene"] = f.attrs["scene"].replace("value = 500.0", "value = 600.0")


# the thermal.h5 tamper rows of cases.tsv: (edit, field, words)
TAMPERS = {
    "dt_negative": (_attr("dt", -1.0), "dt", "a finite number > 0 s, got -1.0"),
    "time_decreasing": (_dataset("time", lambda t: t[::-1].copy()), "time",
                        "expected strictly increasing output times"),
    "temperature_nan": (_dataset("temperature", _nan), "temperature",
                        "expected finite temperatures, got nan"),
    "temperature_above_bounds": (_dataset("temperature", lambda t: t + 1000.0), "temperature",
                                 "outside the run's own maximum-principle bounds [300, 500] K"),
    "scene_garbage_toml": (_attr("scene", "[[[ not toml"), "scene", "not valid TOML"),
    "scene_json_value_changed": (_scene_json, "scene_json",
                                 "boundaries[0].value = 600.0, the stored scene text 500.0"),
    "scene_text_value_changed": (_scene_text, "scene_json",
                                 "boundaries[0].value = 500.0, the stored scene text 600.0"),
    "capacity_negative": (_dataset("capacity", lambda c: -c), "capacity",
                          "expected finite values > 0"),
}


@pytest.mark.parametrize("case", sorted(TAMPERS))
def test_read_thermal_refuses_a_tampered_file(tmp_path, clean_run, case):
    edit, field, words = TAMPERS[case]
    path = tmp_path / "thermal.h5"
    shutil.copy(clean_run, path)
    with h5py.File(path, "r+") as f:
        edit(f)
    for data in (True, False):
        with pytest.raises(ThermalFileError) as e:
            read_thermal(path, data=data)
        assert str(e.value).startswith(f"{path}: {field}: ") and words in str(e.value), e.value
        assert "\n" not in str(e.value)


def test_read_thermal_reads_the_clean_run_and_its_capacity(clean_run):
    run = read_thermal(clean_run)
    assert run.capacity.shape == (run.n_particles,) and np.all(run.capacity > 0)
    assert np.all(np.diff(run.times) > 0) and np.all(np.isfinite(run.temperature))


# ---------------------------------------------------------------------------- T >= 0 K
def _run(tmp_path, text, name="scene"):
    scene_path = tmp_path / f"{name}.toml"
    scene_path.write_text(text)
    scene = load_scene(scene_path, out_dir=tmp_path / name)
    summary = run_scene(scene, quiet=True, threads=1)
    with h5py.File(summary.output) as f:
        out = {k: f[k][()] for k in f}
        out["attrs"] = dict(f.attrs)
    return summary, out


def _flags(out):
    return set(filter(None, str(out["attrs"]["flags"]).split(",")))


@pytest.mark.parametrize("sink", ["source", "flux"])
def test_no_temperature_below_absolute_zero_unflagged(tmp_path, sink):
    """Rule: a run's temperatures are >= 0 K, or the run is flagged below_absolute_zero (a heat
    sink larger than the bed can give drives the linear model through 0 K; before: -327,572 K
    and -1.6e6 K, exit 0, no flag, the maximum-principle check skipped)."""
    extra = (sphere_source(-1e12, 0.005, (0, 0, 0.03)) if sink == "source"
             else boundary("flux", on="zmax", value=-1e9))
    _, out = _run(tmp_path, bed_scene(IMPLICIT, extra=extra, thermal=ZMIN_ONLY))
    T = out["temperature"]
    assert T.min() >= 0.0 or "below_absolute_zero" in _flags(out)
    assert T.min() < 0.0       # this scene does reach it: the flag, not luck, keeps the rule
    assert "below_absolute_zero" in out["attrs"]["check_messages"]


def test_no_temperature_above_the_physical_range_unflagged(tmp_path):
    """Rule: a temperature above TEMPERATURE_MAX_K (no solid there) is flagged (a 1e308 W/m^3
    source gave 3.3e301 K, no flag)."""
    _, out = _run(tmp_path, bed_scene(IMPLICIT, extra=sphere_source(1e308, 0.005,
                                                                     (0, 0, 0.03))))
    T = out["temperature"]
    assert T.max() <= TEMPERATURE_MAX_K or "above_physical_range" in _flags(out)
    assert T.max() > TEMPERATURE_MAX_K


def test_the_maximum_principle_is_checked_with_fluxes_and_sources(tmp_path):
    """Rule: with power in, the temperatures still lie within the initial and boundary range
    widened by what the power can add (comparison principle); a result outside it is flagged
    (before: with a flux or a source the check was skipped)."""
    summary, out = _run(tmp_path, bed_scene(IMPLICIT, extra=sphere_source(1e8, 0.005,
                                                                          (0, 0, 0.03))))
    assert "max_principle" not in _flags(out)
    T0 = np.full(summary.network.n, 300.0)
    lo, hi = out["attrs"]["max_principle_bounds_k"]
    assert np.isfinite(hi) and hi > 500.0 and lo == 300.0
    # the same result with one temperature pushed past the widened bound is flagged
    res = summary.result
    bad = res.temperature_k.copy()
    bad[-1, 7] = hi + 10.0
    check = check_physics(summary.network, T0, dataclasses.replace(res, temperature_k=bad))
    assert "max_principle" in check.flags


# ---------------------------------------------------------------------------- moving sources
V_SRC, R_SRC, Q_SRC = 0.24, 0.004, 1e9
C0 = np.array([-0.012, 0.0, 0.03])


def _chord_times(packing, centre0, velocity, radius, t_end):
    """The closed form: the time each centre spends in a ball of ``radius`` moving in a straight
    line from ``centre0`` at ``velocity`` during [0, t_end] (the chord of the ball along the
    path through the centre's closest approach, clipped to the window)."""
    v = np.asarray(velocity, float)
    speed = np.linalg.norm(v)
    u = v / speed
    d = packing.position - centre0
    s = d @ u                                 # distance along the path to closest approach
    rho2 = np.einsum("ij,ij->i", d, d) - s ** 2
    half = np.sqrt(np.clip(radius ** 2 - rho2, 0.0, None))
    enter, leave = (s - half) / speed, (s + half) / speed
    return np.clip(np.minimum(leave, t_end) - np.maximum(enter, 0.0), 0.0, None)


@pytest.mark.parametrize("speed", [0.24, 1.0])
def test_moving_source_energy_does_not_depend_on_the_time_step(tmp_path, speed):
    """Rule: the energy a source delivers is q x the bulk volume V_p / phi of each particle x
    the time its centre is in the region -- independent of the time step. A sphere source
    crossing the bed, backward Euler at dt = 1e-3 s and at dt = 0.5 s (coarser than the 33 ms
    it takes to cross a sphere at 0.24 m/s; before: 13.15 J and 0 J), and the default explicit
    step: all equal the closed form (chord / speed per particle) to 1e-9 (the step sums are
    exact; 1e-9 leaves room for the summation order over 2,000 steps)."""
    text = bed_scene(extra=sphere_source(Q_SRC, R_SRC, C0, (speed, 0.0, 0.0)))
    scene_path = tmp_path / "scene.toml"
    scene_path.write_text(text)
    scene = load_scene(scene_path)
    packing = read_packing(BED)
    problem, _ = build_problem(scene, packing)
    net = assemble(problem)
    tau = _chord_times(packing, C0, (speed, 0, 0), R_SRC, 2.0)
    phi = float(packing.attrs["solid_fraction"])
    exact = Q_SRC * float(np.sum(sphere_volume(packing.radius) / phi * tau))
    assert exact > 0
    energies = []
    for dt in (1e-3, 0.5):
        res = run_implicit(net, np.full(net.n, 300.0), [0.5, 1.0, 2.0], dt=dt, theta=1.0)
        energies.append(res.source_energy_j[-1])
    summary = run_scene(dataclasses.replace(scene, output=tmp_path / "out" / "thermal.h5"),
                        quiet=True, threads=1)          # explicit at its default dt
    energies.append(summary.result.source_energy_j[-1])
    np.testing.assert_allclose(energies, exact, rtol=1e-9)


def _shifted(packing, fraction):
    """The periodic cell translated by ``fraction`` of its size along x, y and z (centres
    wrapped back into the cell; contacts and branch vectors unchanged)."""
    lo, size = packing.domain_lo, packing.domain_hi - packing.domain_lo
    pos = lo + np.mod(packing.position - lo + fraction * size, size)
    return dataclasses.replace(packing, position=pos)


def test_periodic_cell_wraps_the_source(tmp_path):
    """Rule: translating a periodic cell and its source together changes nothing. Shifted by
    0.37 L the source straddles the periodic faces (before: 41.51 J vs 31.95 J, one side
    heated only); its energy and every temperature must be the same. Backward Euler, dt
    0.05 s."""
    packing = read_packing(PERIODIC)
    size = packing.domain_hi - packing.domain_lo
    centre = np.array([0.007, 0.007, 0.007])
    thermal = BED_THERMAL.split("[[boundary]]")[0]
    results = []
    for fraction in (0.0, 0.37):
        c = packing.domain_lo + np.mod(centre - packing.domain_lo + fraction * size, size)
        text = bed_scene('method = "implicit"\ndt = 0.05\nend_time = 0.5\n'
                         'output_times = [0.1, 0.5]\n', packing=PERIODIC, thermal=thermal,
                         extra=sphere_source(1e9, 0.003, c.tolist()))
        path = tmp_path / f"s{fraction}.toml"
        path.write_text(text)
        problem, _ = build_problem(load_scene(path), _shifted(packing, fraction))
        net = assemble(problem)
        results.append(run_implicit(net, np.full(net.n, 300.0), [0.1, 0.5], dt=0.05,
                                    theta=1.0))
    a, b = results
    assert a.source_energy_j[-1] > 0
    np.testing.assert_allclose(b.source_energy_j, a.source_energy_j, rtol=1e-12)
    np.testing.assert_allclose(b.temperature_k, a.temperature_k, rtol=1e-10)
    straddles = np.any(np.abs(np.mod(centre + 0.37 * size, size) - 0.0) < 0.003) or np.any(
        np.abs(np.mod(centre + 0.37 * size, size) - size) < 0.003)
    assert straddles                       # the shifted source does cross the periodic faces


def test_a_moving_source_wraps_across_the_periodic_faces(tmp_path):
    """A source moving along x through a periodic cell for 3 cell lengths meets every centre
    within its reach three times: the energy is the closed form summed over the periodic
    images, whatever the step (0.01 s and 1 s)."""
    packing = read_packing(PERIODIC)
    L = float(packing.domain_hi[0] - packing.domain_lo[0])
    speed, r = 3 * L / 1.0, 0.002
    c0 = np.array([0.0, 0.007, 0.007])
    text = bed_scene('method = "implicit"\ndt = 0.01\nend_time = 1.0\n', packing=PERIODIC,
                     thermal=BED_THERMAL.split("[[boundary]]")[0],
                     extra=sphere_source(1e9, r, c0.tolist(), (speed, 0, 0)))
    path = tmp_path / "s.toml"
    path.write_text(text)
    problem, _ = build_problem(load_scene(path), packing)
    net = assemble(problem)
    # closed form: unwrap the path into images of the cell along x
    tau = sum(_chord_times(dataclasses.replace(packing, position=packing.position
                                               + np.array([k * L, 0, 0])), c0,
                           (speed, 0, 0), r, 1.0) for k in range(-1, 5))
    pos = packing.position.copy()
    for axis in (1, 2):             # the path's y, z: nearest image of each centre
        d = pos[:, axis] - c0[axis]
        pos[:, axis] -= L * np.round(d / L)
    tau = sum(_chord_times(dataclasses.replace(packing, position=pos + np.array([k * L, 0, 0])),
                           c0, (speed, 0, 0), r, 1.0) for k in range(-1, 5))
    phi = float(packing.attrs["solid_fraction"])
    exact = 1e9 * float(np.sum(sphere_volume(packing.radius) / phi * tau))
    for dt in (0.01, 1.0):
        res = run_implicit(net, np.full(net.n, 300.0), [1.0], dt=dt, theta=1.0)
        assert res.source_energy_j[-1] == pytest.approx(exact, rel=1e-9)


@pytest.mark.parametrize("law", [name for name, law in LAWS.items() if not law.diagnostic])
def test_the_same_source_brings_the_same_energy_under_every_law(tmp_path, law):
    """Rule: a source's power is q x the bulk volume of the particles in its region, whatever
    the law's capacity rule (before: 1178 / 2186 / 2620 J under pipe / haddad / terreros for
    the same 1e9 W/m^3 sphere): the energy over 2 s is q x sum over centres inside of
    V_p / phi x 2 s, for every law, to round-off."""
    packing = read_packing(BED)
    centre, r, q = np.array([0.0, 0.0, 0.03]), 0.006, 1e9
    inside = np.sum((packing.position - centre) ** 2, axis=1) <= r ** 2
    phi = float(packing.attrs["solid_fraction"])
    exact = q * float(np.sum(sphere_volume(packing.radius[inside]))) / phi * 2.0
    _, out = _run(tmp_path, bed_scene(IMPLICIT, extra=sphere_source(q, r, centre.tolist()),
                                      law=law))
    assert out["source_energy"][-1] == pytest.approx(exact, rel=1e-12)


# ---------------------------------------------------------------------------- flux, steady
def test_end_face_flux_of_a_cylinder_bed_brings_q_pi_r2_t(tmp_path):
    """Rule: a flux q on the end face of a cylinder bed of radius R brings q pi R^2 t (the bed's
    section, as calibrate and post use; before: q (2R)^2 t, +27 %)."""
    q = 1e5
    summary, out = _run(tmp_path, bed_scene(IMPLICIT, extra=boundary("flux", on="zmax", value=q),
                                            thermal=ZMIN_ONLY))
    packing = read_packing(BED)
    radius = float(packing.wall_radius[packing.wall_name.index("cylinder")])
    np.testing.assert_allclose(out["boundary_energy"][:, 1],
                               q * math.pi * radius ** 2 * out["time"], rtol=1e-12)


def test_a_steady_run_writes_finite_energies_and_prints_no_nan(tmp_path, capsys):
    """Rule: never a silent NaN -- a steady run (which has no time: no energy rows) writes only
    finite numbers and prints its heat balance, not 'residual +nan J' (before: boundary_energy
    [[nan nan]], source_energy [nan], 'nan contact-updates/s')."""
    path = tmp_path / "steady.toml"
    path.write_text(bed_scene('method = "steady"\n'))
    run_scene(load_scene(path, out_dir=tmp_path / "out"), quiet=False, threads=1)
    printed = capsys.readouterr().out
    assert "nan" not in printed.lower() and "heat balance" in printed
    with h5py.File(tmp_path / "out" / "thermal.h5") as f:
        for key in ("boundary_energy", "source_energy", "stored_energy_change",
                    "boundary_heat_flow", "temperature"):
            assert np.all(np.isfinite(f[key][()])), key
        assert f["boundary_energy"].shape == (0, 2) and "steady" in f.attrs["energies"]


def test_an_implicit_runs_progress_bar_names_its_scheme(tmp_path, capsys):
    path = tmp_path / "cn.toml"
    path.write_text(bed_scene(IMPLICIT + "theta = 0.5\n"))
    run_scene(load_scene(path, out_dir=tmp_path / "out"), quiet=False, threads=1)
    err = capsys.readouterr().err
    assert "implicit(rannacher)" in err and "explicit:" not in err


# ---------------------------------------------------------------------------- SIGTERM
def _default_signals():
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


@pytest.mark.slow
def test_sigterm_ends_a_run_like_ctrl_c(tmp_path):
    """signals:SIGTERM explicit run: killed silently, a stale thermal.h5.lock left. Now one
    line, no traceback, nothing left in the output folder."""
    scene = tmp_path / "slow.toml"
    scene.write_text(bed_scene('method = "explicit"\nsafety = 1e-6\nend_time = 2.0\n'))
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "tdem.cli", "run", str(scene), "--out",
                             str(out), "--quiet", "--threads", "1"], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, preexec_fn=_default_signals)
    while not (out / "thermal.h5.lock").exists():
        assert proc.poll() is None, proc.communicate()[1]
        time.sleep(0.05)
    time.sleep(1.5)
    proc.send_signal(signal.SIGTERM)
    err = proc.communicate(timeout=120)[1]
    lines = [x for x in err.splitlines() if x.strip()]
    assert proc.returncode in (130, 143), err
    assert len(lines) == 1 and lines[0].startswith("tdem: ") and "SIGTERM" in lines[0], err
    assert lines[0].endswith(f"{out / 'thermal.h5'} not written") and "Traceback" not in err
    assert not out.exists() or not any(out.iterdir())


def test_a_scene_changed_through_the_api_is_read_by_its_resolved_scene(tmp_path, clean_run):
    """A run of a scene changed after it was read (dataclasses.replace: validation, tests) stores
    scene_text_agrees = 0 and is read by its resolved scene; a `tdem run` stores 1, and its
    text and resolved scene are then cross-checked (the tamper cases above)."""
    with h5py.File(clean_run) as f:
        assert int(f.attrs["scene_text_agrees"]) == 1
    path = tmp_path / "s.toml"
    path.write_text(bed_scene(IMPLICIT))
    scene = dataclasses.replace(load_scene(path), initial_temperature=310.0,
                                output=tmp_path / "out" / "thermal.h5")
    summary = run_scene(scene, quiet=True, threads=1)
    with h5py.File(summary.output) as f:
        assert int(f.attrs["scene_text_agrees"]) == 0
    assert read_thermal(summary.output).scene.initial_temperature == 310.0
