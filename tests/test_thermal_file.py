"""A run folder is self-contained (issue 17 sec. 1): ``thermal.h5`` holds the scene (text and
resolved JSON), the run's arguments and the packing's content hash; ``read_thermal`` checks
every field; post-processing, export and the campaign read only the run's output.

Every check here is exact (same bits, or a refusal in one line): nothing is fitted."""
import dataclasses
import json
import re
from pathlib import Path

import h5py
import pytest

from tdem.committed_beds import BED_THERMAL
from tdem.cli import main
from thermal_kernel.lattice import simple_cubic_packing
from thermal_kernel.output import (ThermalFileError, read_run_packing, read_thermal,
                                   scene_from_json, scene_to_json)
from thermal_kernel.packing import PackingError, write_packing
from thermal_kernel.scene import load_scene

ROOT = Path(__file__).resolve().parent.parent
PITCH, DELTA = 4e-3, 4e-6
RADIUS = (PITCH + DELTA) / 2


def _lattice(layers=9, spacing=PITCH):
    return simple_cubic_packing((3, 3, layers), spacing_m=spacing, radius_m=(spacing + DELTA) / 2,
                                young_pa=5e10, poisson=0.2, density=2500.0)


@pytest.fixture
def run(tmp_path):
    """A short Crank-Nicolson run of a 3 x 3 x 9 lattice between zmin (500 K) and zmax (400 K);
    (scene path, run folder)."""
    write_packing(tmp_path / "lattice.h5", _lattice())
    scene = tmp_path / "lattice.toml"
    scene.write_text('packing = "lattice.h5"\nlaw = "haddad"\n[law_params]\nct = 0.8\n'
                     + BED_THERMAL.replace('on = "plate"', 'on = "zmax"')
                     + '[solver]\nmethod = "implicit"\ntheta = 0.5\ndt = 0.5\nend_time = 60.0\n'
                       'output_times = [5.0, 10.0, 20.0, 40.0, 60.0]\n')
    assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    return scene, tmp_path / "out"


def test_thermal_h5_holds_the_resolved_scene_and_the_run(run):
    scene_path, out = run
    r = read_thermal(out / "thermal.h5")
    scene = load_scene(scene_path, out_dir=out)
    assert r.format_version == 2 and r.scene.text == scene_path.read_text()
    # the resolved scene: every field as the parser gave it (defaults filled in)
    assert scene_to_json(r.scene) == scene_to_json(scene)
    stored = json.loads(r.scene_json)
    assert stored["solver"]["theta"] == 0.5 and stored["solver"]["safety"] == 0.9
    # each boundary stored with its kind (its class in thermal_kernel.boundaries)
    assert stored["boundaries"][0] == {"kind": "temperature", "name": "temperature:zmin",
                                       "on": "zmin", "value": 500.0}
    assert r.law_params == {"ct": 0.8, "interface_mean": "harmonic",      # JSON, not a repr
                            "mean_radius": "arithmetic"}
    assert r.dt == 0.5 and r.method.startswith("implicit")
    assert r.run_args["command"] == "run" and r.run_args["scene"] == str(scene_path)
    assert r.run_args["out"] == str(out) and r.run_args["checkpoint_every"] == 0
    assert r.temperature.shape == (5, 81) and r.times.tolist() == [5.0, 10.0, 20.0, 40.0, 60.0]
    assert read_run_packing(r).n_particles == 81


@pytest.mark.parametrize("name", sorted(p.name for p in (ROOT / "runs").glob("*.toml")))
def test_scene_json_round_trips(name):
    """Every scene of runs/ (campaign files as their case scenes): JSON -> Scene -> JSON is
    the identity, and the rebuilt scene equals the parsed one field by field."""
    from tdem.campaign import case_scenes, read_campaign
    path = ROOT / "runs" / name
    if "[campaign]" in path.read_text():
        conf, text = read_campaign(path)
        scenes = list(case_scenes(path, conf, text, Path("/tmp/x")).values())
    else:
        scenes = [load_scene(path)]

    def fail(field, what):
        raise AssertionError(f"{field}: {what}")
    for scene in scenes:
        text = scene_to_json(scene)
        back = scene_from_json(text, fail)
        assert scene_to_json(back) == text
        for f in dataclasses.fields(scene):
            a, b = getattr(back, f.name), getattr(scene, f.name)
            if f.name != "text":
                assert a == b if isinstance(b, dict) and f.name != "materials" \
                    else repr(a) == repr(b), f.name


def _set(path, **attrs):
    with h5py.File(path, "r+") as f:
        for key, value in attrs.items():
            if value is None:
                del f.attrs[key]
            else:
                f.attrs[key] = value


@pytest.mark.parametrize("attrs, field", [
    (dict(scene_json=None), "scene_json: missing"),
    (dict(packing_sha256=None), "packing_sha256: missing (a run made by an older tdem"),
    (dict(law_params="{'ct': 0.8}"), "law_params: expected a JSON object"),
    (dict(scene_json='{"law": "haddad"}'), "scene_json.path: missing"),
    (dict(scene_json="not json"), "scene_json: expected the resolved scene as JSON"),
    (dict(run_args="[1, 2]"), "run_args: expected a JSON object"),
    (dict(n_particles=80), "temperature: expected shape (5, 80)"),
    (dict(format_version=7), "format_version: expected 1 or 2, got 7"),
    (dict(dt="soon"), "dt: expected a number"),
    (dict(format="tdem-packing"), "format: expected a run's output"),
])
def test_read_thermal_refuses_a_bad_field_in_one_line(run, capsys, attrs, field):
    _, out = run
    thermal = out / "thermal.h5"
    _set(thermal, **attrs)
    with pytest.raises(ThermalFileError) as e:
        read_thermal(thermal)
    assert str(e.value).startswith(f"{thermal}: {field}") and "\n" not in str(e.value)
    assert main(["post", str(out)]) == 2
    assert capsys.readouterr().err == f"tdem: error: {e.value}\n"


def test_a_bad_field_inside_the_stored_scene(run):
    _, out = run
    thermal = out / "thermal.h5"
    with h5py.File(thermal, "r") as f:
        data = json.loads(f.attrs["scene_json"])
    data["solver"]["dt"] = [0.5]
    _set(thermal, scene_json=json.dumps(data))
    with pytest.raises(ThermalFileError, match=re.escape(
            f"{thermal}: scene_json.solver.dt: expected a number, got [0.5]")):
        read_thermal(thermal)


def test_post_uses_the_stored_scene_not_the_edited_file(run, capsys):
    """Edit the scene after the run (another wall temperature, law parameter and material):
    post gives the same summary, bit for bit, as before the edit."""
    scene_path, out = run
    assert main(["post", str(out)]) == 0
    before = (out / "post" / "summary.json").read_text()
    profiles = (out / "post" / "profiles.csv").read_text()
    scene_path.write_text(scene_path.read_text().replace("ct = 0.8", "ct = 0.3")
                          .replace("500.0", "900.0").replace("205.0", "20.0"))
    assert main(["post", str(out)]) == 0
    assert (out / "post" / "summary.json").read_text() == before
    assert (out / "post" / "profiles.csv").read_text() == profiles
    scene_path.unlink()                     # and the scene file gone altogether
    assert main(["post", str(out)]) == 0
    assert (out / "post" / "summary.json").read_text() == before
    capsys.readouterr()


def test_a_changed_packing_is_refused_in_one_line(run, tmp_path, capsys):
    _, out = run
    thermal = out / "thermal.h5"
    packing = tmp_path / "lattice.h5"
    # the same content written again (attributes aside) is the same packing
    write_packing(packing, _lattice())
    assert main(["post", str(out)]) == 0
    capsys.readouterr()
    write_packing(packing, _lattice(spacing=PITCH * 1.001))   # same size, other content
    assert main(["post", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"tdem: error: {packing}: packing_sha256: "
                                                   f"not the packing {thermal} was run on")
    assert "changed since the run" in err
    with pytest.raises(PackingError):
        read_run_packing(read_thermal(thermal))
    assert main(["export", str(packing), "--thermal", str(thermal), "-o",
                 str(tmp_path / "x.vtu")]) == 2
    assert not (tmp_path / "x.vtu").exists()


def test_a_version_1_file_is_read_from_its_stored_text(run, capsys):
    """thermal.h5 before issue 17: no scene_json / run_args, law_params a Python repr. Read from
    its stored scene text (the scene file is not read): the same scene and summary."""
    scene_path, out = run
    assert main(["post", str(out)]) == 0
    before = json.loads((out / "post" / "summary.json").read_text())
    thermal = out / "thermal.h5"
    new = read_thermal(thermal)
    _set(thermal, format_version=1, scene_json=None, run_args=None,
         law_params=repr({"ct": 0.8, "interface_mean": "harmonic"}))
    scene_path.write_text("this is not TOML")
    old = read_thermal(thermal)
    # mean_radius came later (issue 23); a version-1 file ran with the arithmetic mean
    assert new.law_params.pop("mean_radius") == "arithmetic"
    assert old.format_version == 1 and old.law_params == new.law_params
    assert scene_to_json(old.scene) == new.scene_json
    assert main(["post", str(out)]) == 0
    capsys.readouterr()
    after = json.loads((out / "post" / "summary.json").read_text())
    assert after == before
    _set(thermal, scene="law = 1")                  # stored text that does not parse
    with pytest.raises(ThermalFileError, match=re.escape(f"{thermal}: scene: the stored scene "
                                                         "text no longer parses")):
        read_thermal(thermal)
    _set(thermal, law_params="{'ct': inf}")         # a repr that is not a literal: refused
    with pytest.raises(ThermalFileError, match="law_params: .* run it again"):
        read_thermal(thermal)


# --------------------------------------------------------------------------- campaign variants
def _old_scene_text(campaign_text, packing, law):
    """The campaign's case scene as tdem wrote it before issue 17 (regular expressions on the
    TOML text), kept here as the reference the dataclasses.replace variants must equal."""
    out, skip = [], False
    for line in campaign_text.splitlines():
        header = re.match(r"^\s*\[\[?\s*([A-Za-z0-9_.]+)\s*\]\]?", line)
        if header:
            skip = header.group(1) in ("pack", "campaign")
        elif not skip and re.match(r"^\s*law\s*=", line):
            continue
        if not skip:
            out.append(line)
    return f'packing = "{packing}"\nlaw = "{law}"\n' + "\n".join(out) + "\n"


@pytest.mark.parametrize("name", ["demo.toml", "campaign_7500.toml", "campaign_7500_diag.toml",
                                  "campaign_7500_seeds.toml", "inline"])
def test_campaign_variants_equal_the_old_regex_variants(tmp_path, name):
    from tdem.campaign import case_scene, case_scenes, read_campaign
    from thermal_kernel.laws import LAWS
    if name == "inline":        # law_params, a second phase, an [output] path, a top-level law
        path = tmp_path / "c.toml"
        path.write_text('law = "haddad"\n[campaign]\nlaws = ["haddad", "terreros"]\n[pack]\n'
                        'generator = "bed"\npressures_pa = [1e5]\n[law_params]\n'
                        'interface_mean = "harmonic"\n'
                        + BED_THERMAL + '[solver]\nmethod = "steady"\n[output]\n'
                        'path = "t/run.h5"\n[material.1]\nconductivity = 2.0\n')
    else:
        path = ROOT / "runs" / name
    conf, text = read_campaign(path)
    out = tmp_path / "out"
    packing = tmp_path / "packings" / "packing_1e+05Pa.h5"
    case_dir = out / "cases" / "1e+05Pa_x"
    for law, base in case_scenes(path, conf, text, out).items():
        new = case_scene(base, packing, case_dir)
        old = load_scene(case_dir / "scene.toml", known_laws=LAWS, out_dir=case_dir,
                         text=_old_scene_text(text, packing.resolve(), law))
        assert new.law == law
        for field in ("packing", "pack", "law", "law_params", "materials", "young_pa",
                      "poisson", "initial_temperature", "boundaries", "solver", "output"):
            assert repr(getattr(new, field)) == repr(getattr(old, field)), (law, field)
        assert new.text == text and new.path == path
