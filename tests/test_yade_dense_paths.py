"""The faster paths of the dense generator make the packing of the reference path (YADE for real).

Reference: time_step = "p_wave" (0.5 x the P-wave step of the smallest sphere, the generator
before the density-scaled step). The kept paths:

- time_step = "density_scaling" (the default): per-sphere masses from YADE's
  GlobalStiffnessTimeStepper. Compared with the reference on periodic cells of 400 spheres (no
  walls: every sphere is bulk), three seeds each, with the issue's tolerances on the means:
  solid fraction 0.005, touching Z of the non-rattlers 3 %, Z with gaps 2 %, rattler fraction
  2 points. The frictionless compaction at a fixed cell is the same quasi-static path whatever
  the masses, so the jammed states agree; the DEM steps needed fall (asserted: fewer steps).
- method = "tiled": the same periodic cell copied and carved to a box. Exact identities: every
  dumped force is the Hertz force of its overlap at the real modulus (copied, not recomputed),
  the carved domain's bulk coordination and solid fraction are the cell's (within the sampling of
  whole copies), and spheres on the seams have the coordination of the others.

Softened material (E = 5e9 Pa) and unbalanced-force target 1e-2 as in test_yade_dense.py, so each
packing builds in seconds; the code path is the one of the real modulus.
"""
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from tdem.yade import yade_environment
from tdem_post.packing_compare import packing_stats
from thermal_kernel.packing import read_packing

pytestmark = [pytest.mark.yade,
              pytest.mark.skipif(shutil.which("yade", path=yade_environment()["PATH"]) is None,
                                 reason="Debian's yade is not installed")]

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "yade_scripts" / "dense_packing.py"
FAST = dict(young_pa=5e9, unbalanced_force_target=1e-2, gap_tolerance=0.1)
SEEDS = (1, 2, 3)


def build(directory, **params):
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "params.json").write_text(json.dumps(dict(params, output_dir=str(directory))))
    proc = subprocess.run(["yade", "-n", "-j1", "-x", str(SCRIPT), "params.json"],
                          cwd=directory, env=yade_environment(), capture_output=True, text=True,
                          timeout=900, stdin=subprocess.DEVNULL)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return read_packing(directory / "packing.h5")


def build_all(jobs: dict) -> dict:
    """``build`` of each {key: (directory, params)}, two YADE processes at a time (each runs on
    one thread and the suite's own process waits: the machine's second core does the other)."""
    from concurrent.futures import ThreadPoolExecutor
    with ThreadPoolExecutor(max_workers=2) as pool:
        futures = {key: pool.submit(build, d, **params) for key, (d, params) in jobs.items()}
        return {key: f.result() for key, f in futures.items()}


@pytest.fixture(scope="module")
def cells(tmp_path_factory):
    """Periodic cells of 400 spheres, both time steps, three seeds."""
    return build_all({
        (step, seed): (tmp_path_factory.mktemp(f"{step}_{seed}"),
                       dict(shape="periodic", n_particles=400, seed=seed, time_step=step, **FAST))
        for step in ("p_wave", "density_scaling") for seed in SEEDS})


def _mean(cells, step, field):
    return float(np.mean([getattr(packing_stats(cells[step, s]), field) for s in SEEDS]))


def test_density_scaling_makes_the_reference_packing(cells):
    for step in ("p_wave", "density_scaling"):
        assert all(cells[step, s].attrs["time_step"] == step for s in SEEDS)
    ref, new = "p_wave", "density_scaling"
    phi = [float(np.mean([cells[k, s].attrs["solid_fraction"] for s in SEEDS])) for k in (ref, new)]
    assert abs(phi[1] - phi[0]) < 0.005, phi
    z = [_mean(cells, k, "z_nonrattler") for k in (ref, new)]
    assert abs(z[1] / z[0] - 1) < 0.03, z
    zg = [_mean(cells, k, "z_with_gaps") for k in (ref, new)]
    assert abs(zg[1] / zg[0] - 1) < 0.02, zg
    rattlers = [_mean(cells, k, "rattler_fraction") for k in (ref, new)]
    assert abs(rattlers[1] - rattlers[0]) < 0.02, rattlers


def test_density_scaling_needs_fewer_steps(cells):
    steps = {k: np.mean([cells[k, s].attrs["compression_steps"] for s in SEEDS])
             for k in ("p_wave", "density_scaling")}
    assert steps["density_scaling"] < steps["p_wave"], steps


@pytest.fixture(scope="module")
def tiled(tmp_path_factory):
    built = build_all({
        "carved": (tmp_path_factory.mktemp("tiled"),
                   dict(shape="box", method="tiled", n_particles=3000, cell_particles=300, seed=4,
                        **FAST)),
        "cell": (tmp_path_factory.mktemp("cell"),
                 dict(shape="periodic", n_particles=300, seed=4, **FAST))})
    return built["carved"], built["cell"]


def test_tiled_forces_are_hertz_at_the_real_modulus(tiled):
    carved, _ = tiled
    e_star = carved.attrs["young_pa"] / (2.0 * (1.0 - carved.attrs["poisson"] ** 2))
    touch = carved.overlap > 0
    r_i, r_j = carved.radius[carved.pair[touch, 0]], carved.radius[carved.pair[touch, 1]]
    hertz = 4.0 / 3.0 * e_star * np.sqrt(r_i * r_j / (r_i + r_j)) * carved.overlap[touch] ** 1.5
    np.testing.assert_allclose(carved.normal_force[touch], hertz, rtol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(carved.branch, axis=1),
                               carved.radius[carved.pair[:, 0]] + carved.radius[carved.pair[:, 1]]
                               - carved.overlap, atol=1e-12)
    assert carved.attrs["method"] == "tiled" and carved.attrs["tiles"] >= 8


def test_tiled_bulk_is_the_cell(tiled):
    carved, cell = tiled
    a, b = packing_stats(carved), packing_stats(cell)
    assert abs(a.solid_fraction_bulk - cell.attrs["solid_fraction"]) < 0.005
    assert abs(a.z_nonrattler / b.z_nonrattler - 1) < 0.02
    assert abs(a.z_with_gaps / b.z_with_gaps - 1) < 0.02
    assert abs(a.rattler_fraction - b.rattler_fraction) < 0.02
    # the carved faces are cut surfaces: held spheres listed, no force, overlap <= r
    assert carved.wall_normal_force.max() == 0.0
    assert np.all(carved.wall_overlap <= carved.radius[carved.wall_particle] + 1e-15)


def test_seams_are_invisible(tiled):
    """Spheres within a mean radius of a seam plane have the touching coordination of those far
    from every seam (to the statistical error of the two groups)."""
    carved, _ = tiled
    cell = np.asarray(carved.attrs["cell_size_m"])
    frac = carved.position / cell - np.floor(carved.position / cell)
    seam = np.min(np.minimum(frac, 1 - frac) * cell, axis=1)
    touch = carved.overlap > 0
    z = np.bincount(carved.pair[touch].reshape(-1), minlength=carved.n_particles)
    from tdem_post.packing_compare import bulk_mask
    bulk = bulk_mask(carved, 4.0 * float(carved.radius.mean()))
    r = float(carved.radius.mean())
    near, far = z[bulk & (seam < r)], z[bulk & (seam > 3 * r)]
    err = 3 * np.hypot(near.std() / np.sqrt(len(near)), far.std() / np.sqrt(len(far)))
    assert abs(near.mean() - far.mean()) < err, (near.mean(), far.mean(), err)


TINY_SCENE = """law = "haddad"
[pack]
generator = "dense"
shape = "periodic"
n_particles = 150
young_pa = 5e9
unbalanced_force_target = 1e-2
gap_tolerance = 0.1
seed = {seed}
[material]
conductivity = 33.0
density = 7800.0
heat_capacity = 460.0
[initial]
temperature = 300.0
[solver]
method = "steady"
"""


def test_seeds_through_yade_batch_are_the_single_runs(tmp_path):
    """tdem pack --seeds runs one yade-batch table (two jobs at a time); each job's packing is
    bit for bit the packing of a plain tdem pack with that seed."""
    tdem = str(Path(ROOT / ".venv" / "bin" / "tdem")) \
        if (ROOT / ".venv" / "bin" / "tdem").exists() else "tdem"
    scene = tmp_path / "tiny.toml"
    scene.write_text(TINY_SCENE.format(seed=1))
    batch = subprocess.run([tdem, "pack", str(scene), "--seeds", "3,4", "--out",
                            str(tmp_path / "batch"), "--quiet"], capture_output=True, text=True)
    assert batch.returncode == 0, batch.stdout[-2000:] + batch.stderr[-2000:]
    assert (tmp_path / "batch" / "batch.table").read_text().splitlines()[0] == \
        "description params_json"
    single = tmp_path / "single.toml"
    single.write_text(TINY_SCENE.format(seed=4))
    one = subprocess.run([tdem, "pack", str(single), "--out", str(tmp_path / "one"), "--quiet"],
                         capture_output=True, text=True)
    assert one.returncode == 0, one.stdout[-2000:] + one.stderr[-2000:]
    a = read_packing(tmp_path / "batch" / "seed_4" / "packing.h5")
    b = read_packing(tmp_path / "one" / "packing.h5")
    for field in ("position", "radius", "pair", "overlap", "normal_force", "branch"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    c = read_packing(tmp_path / "batch" / "seed_3" / "packing.h5")
    assert c.attrs["seed"] == 3 and not np.array_equal(c.position, a.position)
