"""The gravity-settled bed compressed by a plate (yade_scripts/compressed_bed.py), run by YADE for
real on a tiny bed (200 spheres in a cylinder of radius 9 mm, two pressures).

Tolerances, and why:
- plate pressure attribute vs the dumped plate contacts: 1e-3 relative (the attribute is YADE's
  plate force, which includes the viscous part of the contact damping, small at rest, and is one
  step older than the dumped positions);
- reached pressure: the generator's own ``pressure_tolerance`` (1 %);
- |branch| = r_i + r_j - overlap: 1e-12 m (overlaps are computed from the dumped positions);
- Hertz forces with the REAL modulus: 1e-9 relative (the dump takes YADE's own Hertz
  coefficients; any difference would be a modulus or radius error, not round-off);
- inside the cylinder: the prism's vertex radius (attribute) plus the largest wall overlap;
- inertial number (sampled every 10 steps): at most 1.5 x its target.
"""
import json
import math
import shutil
import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest

from tdem.yade import yade_environment

pytestmark = [pytest.mark.yade,
              pytest.mark.skipif(shutil.which("yade", path=yade_environment()["PATH"]) is None,
                                 reason="Debian's yade is not installed")]

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "yade_scripts" / "compressed_bed.py"
PRESSURES = [28e3, 1.6e6]          # 0.28 bar and 16 bar
TINY = dict(n_particles=200, cylinder_radius_m=0.009, pressures_pa=PRESSURES, seed=7,
            progress_seconds=1000.0)


def run_bed(directory, **overrides):
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    params = dict(TINY, output_dir=str(directory), **overrides)
    (directory / "params.json").write_text(json.dumps(params))
    return subprocess.run(["yade", "-n", "-j1", "-x", str(SCRIPT), "params.json"],
                          cwd=directory, env=yade_environment(), capture_output=True, text=True,
                          timeout=600, stdin=subprocess.DEVNULL)


def name(p):
    return f"packing_{p:.4g}Pa.h5"


def load(path):
    with h5py.File(path, "r") as f:
        data = {key: f[key][()] for key in (
            "particles/position", "particles/radius", "particles/phase", "particles/yade_id",
            "contacts/pair", "contacts/overlap", "contacts/normal_force", "contacts/branch",
            "contacts/contact_radius", "wall_contacts/particle", "wall_contacts/wall",
            "wall_contacts/overlap", "wall_contacts/normal_force", "walls/point",
            "walls/normal", "walls/radius")}
        data["walls/name"] = [x.decode() if isinstance(x, bytes) else x
                              for x in f["walls/name"][()]]
        data["walls/kind"] = [x.decode() if isinstance(x, bytes) else x
                              for x in f["walls/kind"][()]]
        data["attrs"] = dict(f.attrs)
        data["domain"] = dict(f["domain"].attrs)
    return data


@pytest.fixture(scope="module")
def bed(tmp_path_factory):
    directory = tmp_path_factory.mktemp("bed")
    proc = run_bed(directory)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return directory, proc


@pytest.fixture(scope="module", params=PRESSURES, ids=lambda p: f"{p:.4g}Pa")
def packing(request, bed):
    return load(bed[0] / name(request.param)), request.param


def test_files_and_reader(bed):
    directory, proc = bed
    for f in ["settled.h5", "settled.yade.gz"] + [name(p) for p in PRESSURES]:
        assert (directory / f).exists(), f
    assert "[bed" in proc.stdout and "wrote" in proc.stdout      # progress lines
    try:
        from thermal_kernel.packing import read_packing
    except ImportError:
        pytest.skip("thermal_kernel.packing.read_packing not available")
    for p in PRESSURES:
        packing = read_packing(directory / name(p))      # validates the whole file
        assert packing.n_particles == TINY["n_particles"]
        assert packing.wall_name == ["zmin", "plate", "cylinder"]
        assert packing.wall_kind == ["plane", "plane", "cylinder"]


def test_attributes(packing):
    data, target = packing
    a = data["attrs"]
    assert a["generator"] == "yade_scripts/compressed_bed.py"
    assert a["seed"] == TINY["seed"]
    assert a["young_pa"] == 5e10 and a["poisson"] == 0.2 and a["density"] == 2500.0
    assert a["young_pa_used"] == a["young_pa"]           # re-stiffened before the dump
    assert a["target_pressure_pa"] == target
    for key in ("density_scaling", "gravity_m_s2", "inertial_number", "unbalanced_force_ratio",
                "plate_force_n", "plate_displacement_m", "bed_height_m", "cylinder_radius_m",
                "wall_seconds", "yade_version", "solid_fraction", "mean_coordination"):
        assert key in a, key
    n = len(data["particles/radius"])
    assert a["mean_coordination"] == pytest.approx(2 * len(data["contacts/pair"]) / n, rel=1e-12)
    volume = 4 / 3 * math.pi * np.sum(data["particles/radius"] ** 3)
    cylinder = math.pi * a["cylinder_radius_m"] ** 2 * a["bed_height_m"]
    assert a["solid_fraction"] == pytest.approx(volume / cylinder, rel=1e-12)
    assert 0.3 < a["solid_fraction"] < 0.74
    assert np.all(data["particles/phase"] == 0)
    assert np.array_equal(data["particles/yade_id"], np.arange(n))


def test_settled_records_its_softened_modulus(bed):
    a = load(bed[0] / "settled.h5")["attrs"]
    assert a["young_pa_used"] == a["settle_young_pa"] < a["young_pa"]
    assert a["pressure_pa"] == 0.0 and a["unbalanced_force_ratio"] < 1e-3


def test_plate_pressure_matches_plate_contacts(packing):
    data, _ = packing
    a = data["attrs"]
    plate = data["walls/name"].index("plate")
    on_plate = data["wall_contacts/wall"] == plate
    area = math.pi * a["cylinder_radius_m"] ** 2
    from_contacts = data["wall_contacts/normal_force"][on_plate].sum() / area
    assert a["pressure_pa"] == pytest.approx(from_contacts, rel=1e-3)
    assert a["pressure_pa"] == pytest.approx(a["plate_force_n"] / area, rel=1e-12)


def test_pressure_reached(packing):
    data, target = packing
    assert abs(data["attrs"]["pressure_pa"] - target) <= 0.01 * target


def test_static_and_quasi_static(packing):
    a = packing[0]["attrs"]
    assert a["unbalanced_force_ratio"] < 1e-3
    # I is sampled every 10 steps: the plate is driven at the target I, then carries the load
    # with its speed capped at half of that; it may accelerate a little between two samples
    assert 0 < a["inertial_number"] <= 1.5 * a["inertial_number_target"]


def test_branch_is_centre_distance_minus_overlap(packing):
    data, _ = packing
    pair, r = data["contacts/pair"], data["particles/radius"]
    assert len(pair) > 0 and np.all(pair[:, 0] < pair[:, 1])
    assert np.all(data["contacts/overlap"] > 0)        # touching contacts only
    length = np.linalg.norm(data["contacts/branch"], axis=1)
    assert np.max(np.abs(length - (r[pair[:, 0]] + r[pair[:, 1]] - data["contacts/overlap"]))) \
        < 1e-12
    x = data["particles/position"]
    assert np.allclose(data["contacts/branch"], x[pair[:, 1]] - x[pair[:, 0]], rtol=0, atol=1e-15)


def test_hertz_forces_with_the_real_modulus(packing):
    data, _ = packing
    a = data["attrs"]
    e, nu = a["young_pa"], a["poisson"]
    pair, r = data["contacts/pair"], data["particles/radius"]
    r1, r2 = r[pair[:, 0]], r[pair[:, 1]]
    e_star = e / (2 * (1 - nu ** 2))
    hertz = 4 / 3 * e_star * np.sqrt(r1 * r2 / (r1 + r2)) * data["contacts/overlap"] ** 1.5
    assert np.max(np.abs(data["contacts/normal_force"] / hertz - 1)) < 1e-9
    assert np.allclose(data["contacts/contact_radius"],
                       np.sqrt(r1 * r2 / (r1 + r2) * data["contacts/overlap"]), rtol=1e-12)
    # walls: R* = r, E* of the particle and the wall material
    ew, nuw = a["wall_young_pa"], a["wall_poisson"]
    e_wall = 1 / ((1 - nu ** 2) / e + (1 - nuw ** 2) / ew)
    wp, wd = data["wall_contacts/particle"], data["wall_contacts/overlap"]
    assert len(wp) > 0 and np.all(wd > 0)
    hertz = 4 / 3 * e_wall * np.sqrt(r[wp]) * wd ** 1.5
    assert np.max(np.abs(data["wall_contacts/normal_force"] / hertz - 1)) < 1e-9
    assert set(np.unique(data["wall_contacts/wall"])) == {0, 1, 2}


def test_particles_inside_the_container(packing):
    data, _ = packing
    a = data["attrs"]
    x, r = data["particles/position"], data["particles/radius"]
    slack = a["cylinder_vertex_radius_m"] - a["cylinder_radius_m"] \
        + data["wall_contacts/overlap"].max()
    cyl = data["walls/name"].index("cylinder")
    assert data["walls/radius"][cyl] == a["cylinder_radius_m"]
    assert np.allclose(data["walls/normal"][cyl], (0, 0, 1))
    assert np.max(np.hypot(x[:, 0], x[:, 1]) + r) <= a["cylinder_radius_m"] + slack
    assert np.min(x[:, 2] - r) >= -data["wall_contacts/overlap"].max()
    assert np.max(x[:, 2] + r) <= a["bed_height_m"] + data["wall_contacts/overlap"].max()
    plate = data["walls/name"].index("plate")
    assert data["walls/point"][plate][2] == a["bed_height_m"]
    assert np.allclose(data["walls/normal"][plate], (0, 0, -1))
    assert np.allclose(data["domain"]["lo"], (-a["cylinder_radius_m"], -a["cylinder_radius_m"], 0))
    assert np.allclose(data["domain"]["hi"], (a["cylinder_radius_m"], a["cylinder_radius_m"],
                                              a["bed_height_m"]))
    assert not np.any(data["domain"]["periodic"])


def test_higher_pressure_compresses_more(bed):
    low, high = (load(bed[0] / name(p))["attrs"] for p in PRESSURES)
    assert high["plate_displacement_m"] > low["plate_displacement_m"] > 0
    assert high["solid_fraction"] > low["solid_fraction"]


def test_same_seed_same_arrays(bed, tmp_path):
    proc = run_bed(tmp_path, pressures_pa=PRESSURES[:1])
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    for f in ("settled.h5", name(PRESSURES[0])):
        a, b = load(bed[0] / f), load(tmp_path / f)
        for key, value in a.items():
            if key in ("attrs", "domain", "walls/name", "walls/kind"):
                continue
            assert np.array_equal(value, b[key], equal_nan=True), (f, key)
        assert a["attrs"]["pressure_pa"] == b["attrs"]["pressure_pa"]


def test_reuse_settled(bed, tmp_path):
    shutil.copy(bed[0] / "settled.yade.gz", tmp_path / "settled.yade.gz")
    proc = run_bed(tmp_path, pressures_pa=PRESSURES[:1], reuse_settled=True)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "reusing the settled bed" in proc.stdout
    assert not (tmp_path / "settled.h5").exists()           # no settling, no new settled dump
    a = load(tmp_path / name(PRESSURES[0]))["attrs"]
    assert abs(a["pressure_pa"] - PRESSURES[0]) <= 0.01 * PRESSURES[0]
    assert a["unbalanced_force_ratio"] < 1e-3
    # a saved bed made with other bed parameters is not reused
    (tmp_path / "other").mkdir()
    shutil.copy(bed[0] / "settled.yade.gz", tmp_path / "other" / "settled.yade.gz")
    proc = run_bed(tmp_path / "other", n_particles=150, pressures_pa=PRESSURES[:1],
                   reuse_settled=True)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "settling again" in proc.stdout and "n_particles" in proc.stdout
    assert len(load(tmp_path / "other" / "settled.h5")["particles/radius"]) == 150


@pytest.mark.parametrize("overrides, key", [
    (dict(n_particles="many"), "n_particles"),
    (dict(pressures_pa=[1e5, 1e4]), "pressures_pa"),
    (dict(radius_spread=0.7), "radius_spread"),
    (dict(settle_young_pa=1e12), "settle_young_pa"),
    (dict(colour="red"), "colour"),
])
def test_bad_parameter_exits_2_naming_the_key(tmp_path, overrides, key):
    proc = run_bed(tmp_path, **overrides)
    assert proc.returncode == 2
    # YADE itself prints its banner on stderr; the script adds exactly one line, no traceback
    lines = [line for line in proc.stderr.splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and lines[0].startswith(f"error: {key}: "), proc.stderr
    assert "Traceback" not in proc.stderr
    assert not any(tmp_path.glob("*.h5"))
