"""The dense polydisperse domain (yade_scripts/dense_packing.py), run by YADE for real on tiny
packings (150 spheres) of each shape: periodic cell, box, cylinder, sphere, with phases.

The tests use a softer material (E = 5e9 Pa) and an unbalanced-force target of 1e-2 so that each
packing builds in tens of seconds; the code path is the one of the real modulus (the generator
starts softened and re-stiffens anyway).

Tolerances, and why:
- |branch| = r_i + r_j - overlap: 1e-12 m (overlaps are computed from the dumped positions);
- normal force = 4/3 E* sqrt(R*) overlap^1.5, E* = E / (2 (1 - nu^2)): 1e-9 relative - the
  generator rebuilds every contact from the dumped geometry and computes YADE's force once with
  the integrator off, so any difference is a modulus, radius or geometry error, not round-off;
- plane walls: overlap = r - distance to the plane to 1e-12 m; curved walls are facet polygons
  with ``wall_segments`` sides: |overlap - (r - distance to the analytic surface)| is bounded by
  the polygon's sagitta R (1 - cos(2 pi / segments)); every wall force is YADE's and follows
  Hertz with R* = r and the particles' E* to 1e-9 (the generator gives the walls the modulus
  that corrects YADE's wall and facet contact radii, r/2 and 2r/3);
- mean stress: the generator's pressure_tolerance (2 %);
- solid fraction: periodic 0.62-0.68 (random close packing of frictionless polydisperse
  spheres); walled 150-sphere domains 0.50-0.66 (a wall layer of one diameter is ~40 % of such a
  small domain and is looser); non-rattler coordination of the periodic packing 5.5-6.8
  (compacted frictionless, friction switched on only at rest at the end: isostatic, 6 at
  jamming, a little more under pressure);
- mean stress of the dumped normal forces (no tangential forces in the dump): within 5 % of
  the pressure reached;
- radius statistics: mean within 3 standard errors of the requested mean times the reported
  growth factor; std/mean within 0.05 of the truncated distribution's exact value.
"""
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from tdem.yade import yade_environment
from thermal_kernel.packing import read_packing

pytestmark = [pytest.mark.yade,
              pytest.mark.skipif(shutil.which("yade", path=yade_environment()["PATH"]) is None,
                                 reason="Debian's yade is not installed")]

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "yade_scripts" / "dense_packing.py"
FAST = dict(n_particles=150, young_pa=5e9, unbalanced_force_target=1e-2, seed=11)
CASES = {
    "periodic": dict(shape="periodic", gap_tolerance=0.05, inclusion_volume_fraction=0.2,
                     inclusion_radius_over_mean=2.5),
    "box": dict(shape="box", radius_distribution="uniform", radius_spread=0.2,
                inclusions=[dict(centre=[0.5, 0.5, 0.5], radius=0.25, phase=2)]),
    "cylinder": dict(shape="cylinder", aspect=[1.0, 1.0, 1.5]),
    "sphere": dict(shape="sphere", gap_tolerance=0.1),
}


def run_dense(directory, **params):
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "params.json").write_text(json.dumps(dict(params, output_dir=str(directory))))
    return subprocess.run(["yade", "-n", "-j1", "-x", str(SCRIPT), "params.json"],
                          cwd=directory, env=yade_environment(), capture_output=True, text=True,
                          timeout=900, stdin=subprocess.DEVNULL)


@pytest.fixture(scope="module", params=list(CASES))
def case(request, tmp_path_factory):
    name = request.param
    params = dict(FAST, **CASES[name])
    directory = tmp_path_factory.mktemp(name)
    proc = run_dense(directory, **params)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return name, params, read_packing(directory / "packing.h5")


def test_contact_geometry_and_hertz_forces(case):
    name, params, p = case
    i, j = p.pair.T
    distance = np.linalg.norm(p.branch, axis=1)
    np.testing.assert_allclose(distance, p.radius[i] + p.radius[j] - p.overlap, rtol=0, atol=1e-12)
    touching = p.overlap > 0
    # a jammed packing, not a gas: > 4 touching neighbours (spheres and walls) per particle
    assert 2 * touching.sum() + np.sum(p.wall_overlap > 0) > 4 * p.n_particles
    e_star = params["young_pa"] / (2 * (1 - 0.3 ** 2))
    r_star = p.radius[i] * p.radius[j] / (p.radius[i] + p.radius[j])
    hertz = 4 / 3 * e_star * np.sqrt(r_star[touching]) * p.overlap[touching] ** 1.5
    np.testing.assert_allclose(p.normal_force[touching], hertz, rtol=1e-9)
    assert np.all(p.normal_force[~touching] == 0)
    # the neighbour criterion: exactly the pairs within (1 + gap_tolerance)(r_i + r_j)
    gap = params.get("gap_tolerance", 0.0)
    assert np.all(distance < (1 + gap) * (p.radius[i] + p.radius[j]))
    cell = (p.domain_hi - p.domain_lo) if name == "periodic" else None
    n_expected = 0
    for a in range(p.n_particles):
        d = p.position[a + 1:] - p.position[a]
        if cell is not None:
            d -= np.round(d / cell) * cell
        n_expected += np.sum(np.linalg.norm(d, axis=1)
                             < (1 + gap) * (p.radius[a + 1:] + p.radius[a]))
    assert len(p.pair) == n_expected
    z_gaps = p.attrs["mean_coordination_with_gaps"]
    assert z_gaps == pytest.approx(2 * len(p.pair) / p.n_particles)
    assert p.attrs["mean_coordination"] == pytest.approx(2 * touching.sum() / p.n_particles)
    if gap > 0:
        assert z_gaps > p.attrs["mean_coordination"]


def test_walls(case):
    name, params, p = case
    expected = {"periodic": [], "box": ["xmin", "xmax", "ymin", "ymax", "zmin", "zmax"],
                "cylinder": ["zmin", "zmax", "cylinder"], "sphere": ["surface"]}[name]
    assert sorted(p.wall_name) == sorted(expected)
    if not expected:
        assert len(p.wall_particle) == 0 and all(p.periodic)
        return
    e_star = params["young_pa"] / (2 * (1 - 0.3 ** 2))
    segments = 48
    for w, kind in enumerate(p.wall_kind):
        rows = np.flatnonzero(p.wall_index == w)
        assert len(rows) > 0, p.wall_name[w]
        q = p.wall_particle[rows]
        if kind == "plane":
            distance = (p.position[q] - p.wall_point[w]) @ p.wall_normal[w]
            tol = 1e-12
        elif kind == "cylinder":
            distance = p.wall_radius[w] - np.hypot(*(p.position[q, :2] - p.wall_point[w, :2]).T)
            tol = p.wall_radius[w] * (1 - math.cos(2 * math.pi / segments))
        else:
            distance = p.wall_radius[w] - np.linalg.norm(p.position[q] - p.wall_point[w], axis=1)
            tol = p.wall_radius[w] * (1 - math.cos(2 * math.pi / segments))
        r_star = p.radius[q]            # a flat wall of the particles' material
        overlap = p.wall_overlap[rows]
        touching = overlap > 0
        assert touching.sum() > 0
        geometric = p.radius[q] - distance
        assert np.all(np.abs(overlap[touching] - geometric[touching]) <= tol)
        hertz = 4 / 3 * e_star * np.sqrt(r_star[touching]) * overlap[touching] ** 1.5
        np.testing.assert_allclose(p.wall_normal_force[rows][touching], hertz, rtol=1e-9)
        assert np.all(p.wall_normal_force[rows][~touching] == 0)
    # every sphere inside its domain (up to the wall overlap and the polygon's sagitta)
    slack = 0.05 * p.radius.max()
    assert np.all(p.position - p.radius[:, None] >= p.domain_lo - slack)
    assert np.all(p.position + p.radius[:, None] <= p.domain_hi + slack)


def test_solid_fraction_coordination_pressure(case):
    name, params, p = case
    phi = p.attrs["solid_fraction"]
    volume = float(p.attrs["domain_volume_m3"])
    assert phi == pytest.approx(np.sum(4 / 3 * np.pi * p.radius ** 3) / volume, rel=1e-12)
    if name == "periodic":
        assert 0.62 <= phi <= 0.68
        assert volume == pytest.approx(np.prod(p.domain_hi - p.domain_lo), rel=1e-12)
        touching = p.overlap > 0
        degree = np.bincount(p.pair[touching].ravel(), minlength=p.n_particles)
        # frictionless compaction (friction switched on only at rest, at the end): isostatic
        assert 5.5 <= degree[degree > 0].mean() <= 6.8
    else:
        assert 0.50 <= phi <= 0.66
    assert p.attrs["pressure_pa"] == pytest.approx(params.get("confining_pressure_pa", 1e5),
                                                   rel=0.02)
    assert p.attrs["mean_stress_from_dumped_forces_pa"] == pytest.approx(p.attrs["pressure_pa"],
                                                                          rel=0.05)
    assert p.attrs["unbalanced_force_ratio"] < params["unbalanced_force_target"]
    assert p.attrs["young_pa"] == params["young_pa"]
    assert p.attrs["young_pa_softened_start"] < params["young_pa"]


def test_radius_statistics(case):
    name, params, p = case
    growth = p.attrs["radius_growth_factor"]
    assert 0.9 < growth < 1.1
    mean = 1e-3 * growth
    if params.get("radius_distribution", "gaussian") == "uniform":
        s = params["radius_spread"]
        rel_std = s / math.sqrt(3)
        assert p.radius.min() >= mean * (1 - s) * (1 - 1e-9)
        assert p.radius.max() <= mean * (1 + s) * (1 + 1e-9)
    else:
        rel_std = 0.3 * stats.truncnorm(-2, 2).std()
        assert p.radius.min() >= mean * (1 - 2 * 0.3) * (1 - 1e-9)
        assert p.radius.max() <= mean * (1 + 2 * 0.3) * (1 + 1e-9)
    n = p.n_particles
    assert abs(p.radius.mean() - mean) <= 3 * rel_std * mean / math.sqrt(n)
    assert p.radius.std() / p.radius.mean() == pytest.approx(rel_std, abs=0.05)


def test_phases(case):
    name, params, p = case
    if name == "box":
        lo, hi = p.domain_lo, p.domain_hi
        centre = lo + 0.5 * (hi - lo)
        inside = np.linalg.norm(p.position - centre, axis=1) <= 0.25 * (hi - lo).min()
        assert inside.sum() > 5
        assert np.all(p.phase[inside] == 2) and np.all(p.phase[~inside] == 0)
    elif name == "periodic":
        n_inc = p.attrs["inclusions_dispersed"]
        assert n_inc >= 1
        volume = 4 / 3 * np.pi * p.radius ** 3
        fraction = volume[p.phase == 1].sum() / volume.sum()
        # particles by centre inside non-overlapping inclusions covering 20 % of the cell
        assert 0.1 <= fraction <= 0.3
        assert set(np.unique(p.phase)) == {0, 1}
    else:
        assert np.all(p.phase == 0)


def test_same_seed_same_packing_and_bad_parameter(tmp_path):
    params = dict(FAST, n_particles=100, shape="periodic", unbalanced_force_target=5e-2)
    runs = [run_dense(tmp_path / f"run{k}", **params) for k in range(2)]
    for proc in runs:
        assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    a, b = (read_packing(tmp_path / f"run{k}" / "packing.h5") for k in range(2))
    for field in ("position", "radius", "pair", "overlap", "normal_force", "branch"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    other = run_dense(tmp_path / "seed", **dict(params, seed=12))
    assert other.returncode == 0
    assert not np.array_equal(read_packing(tmp_path / "seed" / "packing.h5").radius, a.radius)

    bad = run_dense(tmp_path / "bad", **dict(params, shape="cube"))
    assert bad.returncode == 2
    lines = [x for x in bad.stderr.splitlines() if x.strip()]
    assert lines[-1].startswith("error: shape") and "cube" in lines[-1] and "box" in lines[-1]
    assert "Traceback" not in bad.stderr
    assert not (tmp_path / "bad" / "packing.h5").exists()
    os.remove(tmp_path / "bad" / "params.json")


def test_tdem_pack_builds_and_prints_statistics(tmp_path):
    """`tdem pack` end to end: YADE runs, the file is validated and its statistics printed.
    The scene and --out are given relative to the working folder (YADE runs in another one: a
    relative --out once made it miss params.json)."""
    scene = tmp_path / "tiny.toml"
    scene.write_text('[pack]\ngenerator = "dense"\nshape = "periodic"\nn_particles = 100\n'
                     'young_pa = 5e9\nunbalanced_force_target = 0.05\ngap_tolerance = 0.05\n'
                     'seed = 5\n')
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "tdem.cli", "pack", "tiny.toml", "--out",
                           "out"], capture_output=True, text=True, timeout=900, cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    p = read_packing(out / "packing.h5")
    params = json.loads((out / "params.json").read_text())
    assert params["n_particles"] == 100 and params["radius_mean_m"] == 1e-3   # defaults filled
    assert "  yade | compress:" in proc.stdout                                  # YADE streamed
    assert f"  particles            {p.n_particles}" in proc.stdout
    assert f"  solid fraction       {p.attrs['solid_fraction']:.4f}" in proc.stdout
    assert f"mean Z (with gaps)   {2 * len(p.pair) / p.n_particles:.3f}" in proc.stdout
    assert (out / "yade.log").stat().st_size > 0


def test_tdem_pack_bad_key_is_one_line(tmp_path):
    scene = tmp_path / "bad.toml"
    scene.write_text('[pack]\ngenerator = "dense"\nradius_spred = 0.1\n')
    proc = subprocess.run([sys.executable, "-m", "tdem.cli", "pack", str(scene), "--out",
                           str(tmp_path / "out")], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert f"{scene}: pack.radius_spred: unknown key" in proc.stderr
    assert not (tmp_path / "out" / "packing.h5").exists()
