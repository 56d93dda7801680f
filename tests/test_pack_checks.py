"""Every cross-field check of the generators runs in `tdem pack` before YADE starts.

The checks live in the pure schema modules (yade_scripts/bed_params.check,
yade_scripts/dense_params.check), which the YADE scripts run again on their own parameters.
Each bad combination below must be refused by `tdem pack` with exit status 2, one line on stderr
naming the scene and the key, no output folder and no YADE launched (the launchers are replaced
by ones that fail the test). No YADE is needed.
"""
from pathlib import Path

import pytest

from tdem import yade
from tdem.cli import main
from tdem.pack import read_pack_table

DATA = Path(__file__).resolve().parent / "data"

BED = [
    ("radius_spread = 0.5", "radius_spread"),
    ("poisson = 0.5", "poisson"),
    ("wall_poisson = 0.6", "wall_poisson"),
    ("restitution = 1.5", "restitution"),
    ("damping = 1.0", "damping"),
    ("settle_damping = 1.0", "settle_damping"),
    ("timestep_safety = 1.5", "timestep_safety"),
    ("pressure_tolerance = 0.5", "pressure_tolerance"),
    ("preload_fraction = 1.5", "preload_fraction"),
    ("cloud_solid_fraction = 0.4", "cloud_solid_fraction"),
    ("pressures_pa = []", "pressures_pa"),
    ("pressures_pa = [1e5, 1e4]", "pressures_pa"),
    ("settle_young_pa = 1e12", "settle_young_pa"),
    ("cylinder_radius_m = 0.005", "cylinder_radius_m"),
    ("wall_young_pa = 1e13", "wall_young_pa"),
]
DENSE = [
    ("inclusions = [{centre = [0.5, 0.5, 0.5]}]", "inclusions[0]"),
    ("inclusions = [{centre = [0.5, 0.5, 0.5], radius = 0.1, colour = 1}]", "inclusions[0]"),
    ('cell_packing = "cell.h5"', "cell_packing"),
    ('method = "tiled"\nshape = "periodic"', "method"),
    ('method = "tiled"\nn_particles = 5000', "cell_particles"),
    ("n_particles = 20\naspect = [1.0, 1.0, 0.1]", "n_particles"),
    ('method = "tiled"\nn_particles = 50000\ncell_particles = 20\naspect = [1.0, 1.0, 0.1]',
     "cell_particles"),
    ("aspect = [1.0, 1.0]", "aspect"),
    # issue 28 (round 3): caught by YADE's numpy late, or not at all
    ('method = "tiled"\ncell_particles = 20\nn_particles = 1000000000000', "n_particles"),
    ('method = "tiled"\ncell_particles = 20\naspect = [1.0, 1.0]', "aspect"),
    ('method = "tiled"\ncell_particles = 20\nn_particles = 21', "n_particles"),
    ('method = "shell"\ncell_particles = 20\nn_particles = 21', "n_particles"),
    ('method = "shell"\nshape = "periodic"', "method"),
    ('method = "shell"\nshape = "sphere"\nn_particles = 50000', "method"),
    # issue 24: the cloud must leave free shell behind it (not reach the frozen band)
    ('method = "shell"\nn_particles = 50000\nshell_cloud_diameters = 5.5', "shell_cloud_diameters"),
    # facets sagging more than the smallest cloud sphere: one would start outside them
    ('shape = "sphere"\nsphere_facet_level = 1', "sphere_facet_level"),
]


@pytest.fixture
def no_yade(monkeypatch):
    def launched(*args, **kwargs):
        raise AssertionError("YADE was launched")
    for name in ("yade_executable", "yade_batch_executable", "run_generator", "run_batch"):
        monkeypatch.setattr(yade, name, launched)


@pytest.mark.parametrize("generator, extra, key",
                         [("bed", e, k) for e, k in BED] + [("dense", e, k) for e, k in DENSE],
                         ids=[f"bed-{k}-{i}" for i, (_, k) in enumerate(BED)]
                         + [f"dense-{k}-{i}" for i, (_, k) in enumerate(DENSE)])
def test_bad_combination_refused_before_yade(tmp_path, capsys, no_yade, generator, extra, key):
    scene = tmp_path / "bad.toml"
    scene.write_text(f'[pack]\ngenerator = "{generator}"\n{extra}\n')
    out = tmp_path / "out"
    assert main(["pack", str(scene), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith(f"tdem: error: {scene}: pack.{key}: "), err
    assert not out.exists()


def test_good_combinations_pass_the_checks(tmp_path):
    """The checks refuse only what they say: the defaults, and a tiled box copying a cell file
    with fewer n_particles than the default cell_particles (the cell's size is the file's)."""
    scene = tmp_path / "ok.toml"
    for generator in ("bed", "dense"):
        scene.write_text(f'[pack]\ngenerator = "{generator}"\n')
        assert read_pack_table(scene)[0] == generator
    scene.write_text('[pack]\ngenerator = "dense"\nmethod = "tiled"\nn_particles = 5000\n'
                     f'gap_tolerance = 0.1\ncell_packing = "{DATA / "dense_periodic.h5"}"\n')
    _, params = read_pack_table(scene)
    assert params["cell_particles"] > params["n_particles"]


def test_scripts_run_the_same_checks():
    """The YADE scripts resolve their params.json with the same function tdem pack calls."""
    params = yade.scripts_module("params")
    with pytest.raises(params.ParamError, match=r"^settle_young_pa: "):
        params.resolve_and_check("bed", {"settle_young_pa": 1e12})
    with pytest.raises(params.ParamError, match=r"^n_particles: too few"):
        params.resolve_and_check("dense", {"n_particles": 20, "aspect": [1.0, 1.0, 0.1]})
    assert params.resolve_and_check("dense", {})["n_particles"] == 2000
