"""tdem_yade.dump from an ordinary YADE script (tests/yade_user_scene.py: utils.sphere, utils.wall,
geom.facetBox, utils.box, a periodic cell), run by Debian's YADE; every contact of the dump is
compared with what YADE reports for the same interaction.

Tolerances, and why:
- normal forces: 1e-12 relative (the dump writes YADE's own phys.normalForce along geom.normal);
- overlaps: the dump recomputes them from the dumped positions, YADE's penetrationDepth is one
  step older; at rest they differ by the motion of one step: 1e-3 of the radius allowed (measured:
  2.2e-9 m on the box, 1.5e-7 m in the cell, radius 1 mm), and the largest difference is the
  attribute overlap_vs_yade_max_m;
- the set of contacts: identical, except pairs whose YADE depth is within that difference of 0;
- phi of the periodic cell: 1 - utils.porosity() to 1e-12; pressure: -trace/3 of
  utils.getStress() to 1e-9 relative (the same numbers, read back); the cell reaches the
  controller's 100 kPa to 2 %.
"""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tdem.yade import yade_environment
from thermal_kernel.packing import read_packing
import shutil

pytestmark = [pytest.mark.yade,
              pytest.mark.skipif(shutil.which("yade", path=yade_environment()["PATH"]) is None,
                                 reason="Debian's yade is not installed")]

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "tests" / "yade_user_scene.py"
TDEM = [sys.executable, "-m", "tdem.cli"]


def yade_path():
    out = subprocess.run([*TDEM, "yade-path"], capture_output=True, text=True, check=True)
    return out.stdout.strip()


def run_scene(scene, directory):
    env = dict(yade_environment(), TDEM_YADE_PATH=yade_path())
    return subprocess.run(["yade", "-n", "-j1", "-x", str(SCRIPT), scene, str(directory)],
                          cwd=directory, env=env, capture_output=True, text=True, timeout=600,
                          stdin=subprocess.DEVNULL)


@pytest.fixture(scope="module")
def box(tmp_path_factory):
    d = tmp_path_factory.mktemp("box")
    r = run_scene("box", d)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    return d, r


@pytest.fixture(scope="module")
def cell(tmp_path_factory):
    d = tmp_path_factory.mktemp("periodic")
    r = run_scene("periodic", d)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    return d, r


def compare_contacts(directory):
    """Every sphere-sphere and sphere-wall contact of the dump against YADE's list."""
    packing = read_packing(directory / "packing.h5")       # the same validating reader
    yade = json.loads((directory / "yade_contacts.json").read_text())
    index = {int(b): k for k, b in enumerate(packing.yade_id)}
    r = packing.radius
    slack = float(packing.attrs["overlap_vs_yade_max_m"])
    assert slack <= 1e-3 * r.min()
    dumped = {tuple(p): c for c, p in enumerate(packing.pair.tolist())}
    seen = set()
    walls_seen = {}
    for row in yade["contacts"]:
        s1, s2 = row["shape1"] == "Sphere", row["shape2"] == "Sphere"
        if s1 and s2:
            i, j = sorted((index[row["id1"]], index[row["id2"]]))
            if (i, j) not in dumped:
                assert row["depth"] <= slack, (i, j, row)     # not touching at the dump
                continue
            c = dumped[(i, j)]
            seen.add((i, j))
            assert packing.overlap[c] == pytest.approx(row["depth"], abs=1e-3 * r.min())
            assert packing.normal_force[c] == pytest.approx(max(row["fn"], 0.0), rel=1e-12,
                                                            abs=1e-300)
        else:
            k = index[row["id1"] if s1 else row["id2"]]
            shape = row["shape2"] if s1 else row["shape1"]
            want = {"Wall": ("zmin",), "Box": ("plate",),
                    "Facet": ("xmin", "xmax", "ymin", "ymax")}[shape]
            # the sphere's row on the plane the interaction's normal is normal to
            hit = [q for q in np.flatnonzero(packing.wall_particle == k)
                   if packing.wall_name[packing.wall_index[q]] in want
                   and abs(np.dot(packing.wall_normal[packing.wall_index[q]], row["normal"]))
                   > 0.99]
            if not hit:
                assert row["depth"] <= slack, (k, shape, row)
                continue
            assert len(hit) == 1
            # several facets of one plane touching one sphere: YADE has one row each
            walls_seen.setdefault(int(hit[0]), []).append(row)
    assert seen == set(dumped)
    for q, rows in walls_seen.items():
        assert packing.wall_overlap[q] == pytest.approx(max(x["depth"] for x in rows),
                                                        abs=1e-3 * r.min())
        assert packing.wall_normal_force[q] == pytest.approx(sum(max(x["fn"], 0.0)
                                                                 for x in rows), rel=1e-12)
    assert len(walls_seen) == len(packing.wall_particle)
    return packing, yade


def test_box_every_contact_matches_yade(box):
    directory, run = box
    packing, yade = compare_contacts(directory)
    assert packing.wall_name == ["zmin", "plate", "xmin", "xmax", "ymin", "ymax"]
    assert not packing.periodic.any()
    # domain: floor (utils.wall at z = 0), facetBox sides (0 ... 12 mm), the lid's underside
    assert packing.domain_lo == pytest.approx([0, 0, 0], abs=1e-12)
    assert packing.domain_hi[:2] == pytest.approx([0.012, 0.012], abs=1e-12)
    plate = packing.wall_id("plate")
    assert packing.domain_hi[2] == pytest.approx(packing.wall_point[plate][2], abs=1e-15)
    # phi and Z measured by the dump, recomputed here (sphere volume minus the wall caps)
    r = packing.radius
    h = packing.wall_overlap
    v = (4 / 3 * np.pi * r ** 3).sum() - (np.pi * h ** 2 * (3 * r[packing.wall_particle] - h)
                                          / 3).sum()
    assert packing.attrs["solid_fraction"] == pytest.approx(
        v / np.prod(packing.domain_hi - packing.domain_lo), rel=1e-12)
    assert packing.attrs["mean_coordination"] == pytest.approx(2 * packing.n_contacts
                                                               / packing.n_particles)
    assert packing.n_contacts > 300 and len(packing.wall_particle) > 50
    # the plate's pressure: the lid's weight (2 kPa) carried by its contacts, at rest to 10 %
    area = 0.012 ** 2
    p_plate = packing.wall_normal_force[packing.wall_index == plate].sum() / area
    assert packing.attrs["pressure_pa"] == pytest.approx(p_plate, rel=1e-12)
    assert p_plate == pytest.approx(2000.0, rel=0.1)
    assert packing.attrs["force_law"].startswith("linear")
    assert "tdem_yade: wrote" in run.stdout


def test_periodic_cell_every_contact_matches_yade(cell):
    directory, run = cell
    packing, yade = compare_contacts(directory)
    assert packing.periodic.all() and packing.wall_name == []
    assert packing.attrs["solid_fraction"] == pytest.approx(1 - yade["porosity"], rel=1e-12)
    assert packing.attrs["pressure_pa"] == pytest.approx(yade["mean_stress"], rel=1e-9)
    assert packing.attrs["pressure_pa"] == pytest.approx(1e5, rel=0.02)
    # contacts across the cell's faces: branch vectors longer than half the cell never occur
    # and some branch vectors join a centre to the image of the other
    plain = packing.position[packing.pair[:, 1]] - packing.position[packing.pair[:, 0]]
    assert np.any(np.abs(plain - packing.branch).max(axis=1) > 1e-4)
    assert packing.attrs["force_law"].startswith("hertz")
    assert abs(packing.attrs["force_law_ratio_median"] - 1) < 0.01     # measured 0.9997
    assert packing.attrs["mean_coordination"] > 5


def test_info_prints_what_was_inferred(cell):
    directory, _ = cell
    out = subprocess.run([*TDEM, "info", str(directory / "packing.h5")], capture_output=True,
                         text=True)
    assert out.returncode == 0, out.stderr
    assert "inferred             density: the spheres' material density" in out.stdout
    assert "utils.getStress()" in out.stdout
    assert "force law check      hertz" in out.stdout and "MISMATCH" not in out.stdout


@pytest.mark.parametrize("scene, words", [
    ("clump", "is a clump of 2 spheres"),
    ("sheared", "O.cell.hSize is sheared"),
])
def test_refusals_are_one_line(tmp_path, scene, words):
    r = run_scene(scene, tmp_path)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith("tdem_yade: error: ") and words in last
    assert str(tmp_path / "packing.h5") in last
    assert not list(tmp_path.glob("packing.h5*"))
