"""Scene files: a good one parses into the documented values; each mistake is a one-line error
naming the file and the key."""
import dataclasses
import math

import pytest

from thermal_kernel.scene import SceneError, load_scene, read_toml

# `make coverage` counts this module (marker kernel: its subject is thermal_kernel, and it is
# fast enough with NUMBA_DISABLE_JIT=1)
pytestmark = pytest.mark.kernel

LAWS = ("haddad", "pipe")

GOOD = """
packing = "packing.h5"
law = "haddad"
[law_params]
ct = 0.8
[material]
conductivity = 33.0
density = 7800.0
heat_capacity = 900.0
[material.1]
conductivity = 0.33
[initial]
temperature = 298.15
[[boundary]]
kind = "temperature"
on = "ymin"
value = 308.15
[[boundary]]
kind = "flux"
on = "ymax"
value = -1000.0
[solver]
method = "explicit"
end_time = 0.2
output_times = [0.05, 0.1, 0.2]
[output]
path = "t.h5"
"""


def _write(tmp_path, text, name="scene.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_good_scene(tmp_path):
    scene = load_scene(_write(tmp_path, GOOD), known_laws=LAWS)
    assert scene.packing == tmp_path / "packing.h5"
    assert scene.law == "haddad" and scene.law_params == {"ct": 0.8}
    assert scene.material(0).conductivity == 33.0
    assert scene.material(1).conductivity == 0.33 and scene.material(1).density == 7800.0
    assert scene.material(7) == scene.material(0)
    assert [b.name for b in scene.boundaries] == ["temperature:ymin", "flux:ymax"]
    assert scene.solver.output_times == (0.05, 0.1, 0.2)
    assert math.isnan(scene.solver.dt) and scene.solver.safety == 0.9
    assert scene.solver.backend == "in-process"          # the default (issue 25)
    petsc = load_scene(_write(tmp_path, GOOD.replace("end_time = 0.2", 'end_time = 0.2\n'
                                                     'backend = "petsc"'), "p.toml"),
                       known_laws=LAWS)
    assert petsc.solver.backend == "petsc"
    assert scene.output == tmp_path / "out" / "scene" / "t.h5"
    with pytest.raises(dataclasses.FrozenInstanceError):
        scene.law = "pipe"   # frozen


SOURCE = """
[[boundary]]
kind = "source"
shape = "sphere"
value = 1e9
radius_m = 0.002
"""

BAD = {
    "unknown top key": (GOOD + "\nfoo = 1\n", "foo: unknown key"),
    "unknown solver key": (GOOD.replace("end_time = 0.2", "end_time = 0.2\nend_tme = 3"),
                           "solver.end_tme: unknown key"),
    "missing law": (GOOD.replace('law = "haddad"', ""), "law: missing required key"),
    "unknown law": (GOOD.replace('law = "haddad"', 'law = "magic"'),
                    "law: unknown law 'magic' (known: haddad, pipe)"),
    "wrong type": (GOOD.replace("conductivity = 33.0", 'conductivity = "high"'),
                   "material.conductivity: expected a finite number"),
    "negative": (GOOD.replace("conductivity = 33.0", "conductivity = -1.0"),
                 "material.conductivity: expected a number > 0"),
    "bad kind": (GOOD.replace('kind = "flux"', 'kind = "convection"'),
                 "boundary[1].kind: expected one of temperature, flux"),
    "bad method": (GOOD.replace('"explicit"', '"rk4"'), "solver.method: expected one of"),
    "bad backend": (GOOD.replace("end_time = 0.2", 'end_time = 0.2\nbackend = "mpi"'),
                    "solver.backend: expected one of in-process, petsc"),
    "decreasing outputs": (GOOD.replace("[0.05, 0.1, 0.2]", "[0.1, 0.05]"),
                           "solver.output_times: expected increasing times"),
    "outputs past end": (GOOD.replace("[0.05, 0.1, 0.2]", "[0.1, 0.3]"),
                         "solver.output_times: expected times in [0, end_time"),
    "implicit without dt": (GOOD.replace('"explicit"', '"implicit"'),
                            "solver.dt: missing required key"),
    "missing initial": (GOOD.replace("[initial]\ntemperature = 298.15", ""),
                        "initial: missing required table"),
    "bad phase": (GOOD.replace("[material.1]", "[material.glass]"), "material.glass: expected"),
    "safety above 1": (GOOD.replace("end_time = 0.2", "end_time = 0.2\nsafety = 1.5"),
                       "solver.safety: expected a number <= 1"),
    "not toml": ("law = = 3", "not valid TOML"),
    "pack and packing": (GOOD + "\n[pack]\ngenerator = 'dense'\n", "pack: give either"),
    "duplicate boundary names": (GOOD.replace('kind = "flux"\non = "ymax"\nvalue = -1000.0',
                                              'kind = "temperature"\non = "ymin"\nvalue = 300.0'),
                                 "two boundaries share the name"),
    # silent accepts refused (issue 16)
    "theta for explicit": (GOOD.replace("end_time = 0.2", "end_time = 0.2\ntheta = 0.5"),
                           'solver.theta: only for method = "implicit" (method is \'explicit\''),
    "theta for steady": (GOOD.replace('method = "explicit"\nend_time = 0.2\n'
                                      'output_times = [0.05, 0.1, 0.2]',
                                      'method = "steady"\ntheta = 1.0'),
                         'solver.theta: only for method = "implicit" (method is \'steady\''),
    "dt for steady": (GOOD.replace('method = "explicit"\nend_time = 0.2\n'
                                   'output_times = [0.05, 0.1, 0.2]',
                                   'method = "steady"\ndt = 5.0'),
                      "solver.dt: a steady solve has no time step"),
    "source stops before it starts": (GOOD + SOURCE + "start_time = 0.1\nstop_time = 0.05\n",
                                      "boundary[2].stop_time: expected a time after start_time "
                                      "= 0.1 s, got 0.05 s"),
    # law and material values checked on load, not inside the law (issue 16, sec. 2)
    "ct negative": (GOOD.replace("ct = 0.8", "ct = -0.8"),
                    "law_params.ct: expected a number > 0, got -0.8"),
    "ct text": (GOOD.replace("ct = 0.8", 'ct = "big"'),
                "law_params.ct: expected a finite number, got 'big'"),
    "interface mean": (GOOD.replace("ct = 0.8", 'interface_mean = "median"'),
                       "law_params.interface_mean: expected one of harmonic, arithmetic"),
    "unknown law parameter": (GOOD.replace("ct = 0.8", "beta = 0.9"),
                              "law_params.beta: unknown parameter of law 'haddad'"),
    "poisson above 0.5": (GOOD.replace("heat_capacity = 900.0", "heat_capacity = 900.0\n"
                                       "poisson = 0.6", 1),
                          "material.poisson: expected a number in (-1, 0.5), got 0.6"),
    "source stops when it starts": (GOOD + SOURCE + "start_time = 0.1\nstop_time = 0.1\n",
                                    "boundary[2].stop_time: expected a time after start_time"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_scene(tmp_path, case):
    text, message = BAD[case]
    path = _write(tmp_path, text)
    with pytest.raises(SceneError) as info:
        load_scene(path, known_laws=LAWS)
    assert "\n" not in str(info.value)
    assert str(info.value).startswith(f"{path}: ")
    assert message in str(info.value), str(info.value)


@pytest.mark.parametrize("shape", ["sphere", "box", "cylinder"])
def test_source_time_intervals_match_the_sampled_region(shape):
    """boundaries.source_time_intervals (the exact times a centre spends in a moving source, used
    to refuse a source that never reaches a particle) against MovingSource.inside sampled on a
    fine time grid: every sampled inside-time lies in the interval, and every interval longer
    than two samples holds a sampled inside-time."""
    import numpy as np
    from thermal_kernel.boundaries import MovingSource, SourceBoundary, source_time_intervals
    rng = np.random.default_rng(3)
    position = rng.uniform(-1.0, 1.0, (4000, 3))
    b = SourceBoundary(name="s", value=1.0, shape=shape, centre_m=(-0.8, 0.1, -0.2),
                       radius_m=0.3, depth_m=0.4, axis=(0.3, 0.2, 1.0),
                       half_size_m=(0.2, 0.3, 0.25), velocity_m_s=(0.5, -0.1, 0.2))
    t0, t1 = 0.2, 3.0
    first, last = source_time_intervals(b, position, t0, t1)
    times = np.linspace(t0, t1, 1401)
    src = MovingSource(b, position, np.ones(len(position)))
    inside = np.array([src.inside(t) for t in times])          # (times, particles)
    hit = inside.any(axis=0)
    assert 50 < hit.sum() < len(position) - 50
    eps = 1e-9
    for p in np.flatnonzero(hit):
        ts = times[inside[:, p]]
        assert first[p] - eps <= ts.min() and ts.max() <= last[p] + eps
    step = times[1] - times[0]
    long = (last - first) > 2 * step
    assert np.all(hit[long])
    # a source that is still touches only the centres inside it, at every time
    still = dataclasses.replace(b, velocity_m_s=(0.0, 0.0, 0.0))
    f, l_ = source_time_intervals(still, position, t0, t1)
    np.testing.assert_array_equal(f <= l_, MovingSource(still, position, np.ones(4000)).inside(1.0))


@pytest.mark.parametrize("shape", ["sphere", "box", "cylinder"])
@pytest.mark.parametrize("periodic", [False, True], ids=["open", "periodic"])
def test_a_source_restricted_to_a_block_gives_its_particles_powers_bit_for_bit(shape, periodic):
    """MovingSource.restricted (what a rank of the PETSc backend evaluates for its block): over
    any subset of the particles, in any order, the powers of the whole source's particles, bit
    for bit: moving across several cells, still, at an instant, outside its on-time."""
    import numpy as np
    from thermal_kernel.boundaries import MovingSource, SourceBoundary
    rng = np.random.default_rng(5)
    position = rng.uniform(-1.0, 1.0, (3000, 3))
    volume = rng.uniform(0.5, 1.5, 3000)
    b = SourceBoundary(name="s", value=2.0, shape=shape, centre_m=(-0.8, 0.1, -0.2),
                       radius_m=0.3, depth_m=0.4, axis=(0.3, 0.2, 1.0),
                       half_size_m=(0.2, 0.3, 0.25), velocity_m_s=(1.5, -0.1, 0.2),
                       start_time=0.1, stop_time=2.5)
    cell = dict(periodic=(True, True, False), length=(2.0, 2.0, 2.0)) if periodic else {}
    block = rng.permutation(3000)[:1100]
    for boundary in (b, dataclasses.replace(b, velocity_m_s=(0.0, 0.0, 0.0))):
        whole = MovingSource(boundary, position, volume, **cell)
        part = whole.restricted(block)
        heated = 0
        for t0, t1 in ((0.0, 0.05), (0.2, 0.3), (0.3, 2.0), (1.0, 1.0), (2.4, 3.0), (2.6, 2.7)):
            w = whole(t0, t1)
            np.testing.assert_array_equal(part(t0, t1), w[block])
            heated += int(np.count_nonzero(w[block]))
        assert heated > 20          # the source reaches the block: the comparison means it


def test_read_toml_is_the_one_reader(tmp_path):
    """One TOML reader (tdem pack, campaigns, scenes): each failure is one line of the caller's
    error type, naming the file."""
    class Mine(Exception):
        pass

    good = tmp_path / "good.toml"
    good.write_text('a = 1\n[pack]\nb = "x"\n')
    assert read_toml(good) == ({"a": 1, "pack": {"b": "x"}}, 'a = 1\n[pack]\nb = "x"\n')
    assert read_toml(tmp_path / "not_yet.toml", text="c = 2\n")[0] == {"c": 2}
    (tmp_path / "bad.toml").write_text("a = = 1\n")
    (tmp_path / "bin.toml").write_bytes(b"\xffa = 1")
    (tmp_path / "dir.toml").mkdir()
    cases = {"missing.toml": "file not found", "bad.toml": "not valid TOML (",
             "bin.toml": "not UTF-8 text (byte 0xff at offset 0); expected a campaign TOML file",
             "dir.toml": "is a folder; expected a campaign TOML file"}
    for name, words in cases.items():
        with pytest.raises(Mine) as e:
            read_toml(tmp_path / name, error=Mine, what="a campaign TOML file")
        assert str(e.value).startswith(f"{tmp_path / name}: {words}") and "\n" not in str(e.value)
    with pytest.raises(SceneError, match="line 1"):
        read_toml(tmp_path / "bad.toml")


def test_toml_text_is_read_back_as_the_tables_it_was_given():
    """thermal_kernel.scene.toml_text, the one writer of a scene's text (validation's cases,
    the calibration's flux test on MPI ranks): read_toml gives back the very tables, floats bit
    for bit, nested tables ([material.1]) and arrays of tables ([[boundary]]) included."""
    import math

    from thermal_kernel.scene import read_toml, toml_text
    tables = {"packing": 'a "quoted" name.h5', "law": "haddad",
              "law_params": {"ct": 0.1 + 0.2, "tiny": 5e-324, "big": 1.7976931348623157e308},
              "material": {"conductivity": 33.0, "1": {"conductivity": 1e-3}},
              "initial": {"temperature": 298.15},
              "boundary": [{"kind": "temperature", "on": "xmin", "value": 308.15},
                           {"kind": "source", "centre_m": [0.0, -1.5, 2.25], "value": 1e9,
                            "stop_time": math.inf}],
              "solver": {"method": "implicit", "output_times": [1.0, 2.0], "on": True}}
    back, _ = read_toml("t.toml", toml_text(tables))
    assert back == tables
    assert back["law_params"]["ct"] == 0.1 + 0.2
