"""`tdem import liggghts` on a bed that Debian's LIGGGHTS makes on 2 MPI ranks
(runs/liggghts/bed.in: ~300 spheres, Hertz, E 1e8 Pa, periodic in x and y, a floor and a plate
moved down in four stages), then the imported packings checked and heated.

Tolerances, and why:
- Hertz force vs overlap: median F / F_Hertz within 1e-4 of 1, 95 % of the contacts within 1e-2
  (the bed rests 10,000 steps before each dump; what is left is the viscous part of the normal
  force, largest right after the plate moved: measured 95 % quantiles 2.9e-3, 6.7e-5, 7.5e-7,
  4.6e-8 for the four stages, medians 1 - 4e-7 ... 1 + 3e-11);
- overlap (LIGGGHTS delta) vs r_i + r_j - |branch| from the dumped positions: 1e-9 m with
  17-digit dumps (round-off of positions ~1e-2 m);
- phi recomputed here (sphere volume minus the caps cut by the floor and the plate, over the
  periodic cell's area times the plate height): 1e-12 relative; phi in 0.55-0.66, Z in 4.5-7
  (a settled, compressed frictional bed);
- the thermal run: every temperature finite and within [300, 500] K (initial and boundary
  values), the run's own flags free of max_principle / energy_ledger.
"""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from thermal_kernel.packing import read_packing

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "runs" / "liggghts"
TDEM = [sys.executable, "-m", "tdem.cli"]
MISSING = [x for x in ("liggghts", "mpirun") if shutil.which(x) is None]

pytestmark = [pytest.mark.liggghts,
              pytest.mark.skipif(bool(MISSING), reason=f"{' and '.join(MISSING)} not installed "
                                 "(Debian: apt-get install liggghts openmpi-bin; `make test` "
                                 "installs them)")]
E, NU = 1e8, 0.2
L = 0.012


def mpi_env():
    env = dict(os.environ)
    if os.geteuid() == 0:            # Open MPI refuses root unless told
        env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    return env


def tdem(*args, **kw):
    return subprocess.run([*TDEM, *map(str, args)], capture_output=True, text=True,
                          timeout=600, **kw)


@pytest.fixture(scope="module")
def bed(tmp_path_factory):
    d = tmp_path_factory.mktemp("liggghts")
    r = subprocess.run(["mpirun", "-np", "2", "--oversubscribe", "liggghts", "-in",
                        str(EXAMPLE / "bed.in"), "-var", "src", str(EXAMPLE)],
                       cwd=d, env=mpi_env(), capture_output=True, text=True, timeout=1500,
                       stdin=subprocess.DEVNULL)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]
    assert "2 by 1 by 1 MPI processor grid" in r.stdout
    # both ranks held spheres in the last run (a bed on one rank would not test the gather)
    nlocal = [line for line in r.stdout.splitlines() if line.startswith("Nlocal:")][-1]
    assert float(nlocal.split()[-2]) > 0, nlocal              # "... ave MAX max MIN min"
    packings = []
    for k in range(1, 5):
        out = d / f"packing_{k}.h5"
        imp = tdem("import", "liggghts", d / f"atoms_{k}.dump", d / f"pairs_{k}.dump",
                   d / f"walls_{k}.dump", "--walls", "zmin,plate:zmax", "--young", E,
                   "--poisson", NU, "--density", 2500, "-o", out)
        assert imp.returncode == 0, imp.stderr
        assert "warning" not in imp.stderr
        packings.append(out)
    return d, packings, imp.stdout


def test_import_phi_z_and_pressures(bed):
    d, paths, stdout = bed
    assert "force law check      hertz" in stdout and "MISMATCH" not in stdout
    pressures = []
    for path in paths:
        p = read_packing(path)                    # the same validating reader
        n_atoms = int((d / path.name.replace("packing_", "atoms_").replace(".h5", ".dump"))
                      .read_text().splitlines()[3])
        assert p.n_particles == n_atoms > 250
        assert list(p.periodic) == [True, True, False]
        assert p.wall_name == ["zmin", "plate"]
        z_plate = p.wall_point[1][2]
        assert p.domain_hi[2] == z_plate and p.domain_lo[2] == pytest.approx(0, abs=1e-9)
        r, h = p.radius, p.wall_overlap
        v = (4 / 3 * np.pi * r ** 3).sum() - (np.pi * h ** 2 * (3 * r[p.wall_particle] - h)
                                              / 3).sum()
        phi = v / (L * L * (z_plate - p.domain_lo[2]))
        assert p.attrs["solid_fraction"] == pytest.approx(phi, rel=1e-12)
        assert 0.55 < phi < 0.66
        z = 2 * p.n_contacts / p.n_particles
        assert p.attrs["mean_coordination"] == pytest.approx(z) and 4.5 < z < 7
        # overlaps: LIGGGHTS' delta agrees with the dumped positions (17-digit dumps)
        geo = r[p.pair[:, 0]] + r[p.pair[:, 1]] - np.linalg.norm(p.branch, axis=1)
        assert np.abs(geo - p.overlap).max() < 1e-9
        # some contacts cross the periodic faces (branch is not x_j - x_i)
        plain = p.position[p.pair[:, 1]] - p.position[p.pair[:, 0]]
        assert np.any(np.abs(plain - p.branch).max(axis=1) > L / 2)
        pressures.append(p.attrs["pressure_pa"])
        plate = p.wall_normal_force[p.wall_index == 1].sum() / L ** 2
        assert p.attrs["pressure_pa"] == pytest.approx(plate, rel=1e-12)
    assert all(b > a for a, b in zip(pressures, pressures[1:])), pressures
    assert pressures[-1] > 1e4


def test_hertz_force_vs_overlap(bed):
    _, paths, _ = bed
    for path in paths:
        p = read_packing(path)
        ri, rj = p.radius[p.pair[:, 0]], p.radius[p.pair[:, 1]]
        e_star = E / (2 * (1 - NU ** 2))
        hertz = 4 / 3 * e_star * np.sqrt(ri * rj / (ri + rj)) * p.overlap ** 1.5
        dev = np.abs(p.normal_force / hertz - 1)
        assert np.percentile(dev, 95) < 1e-2
        assert abs(np.median(p.normal_force / hertz) - 1) < 1e-4
        assert p.attrs["force_law_ratio_median"] == pytest.approx(
            np.median(p.normal_force / hertz), rel=1e-12)


def test_softened_modulus_is_reported(bed, tmp_path):
    """Stating the real modulus (5e10) for a bed made at 1e8: the check says by how much."""
    d, _, _ = bed
    out = tmp_path / "p.h5"
    r = tdem("import", "liggghts", d / "atoms_4.dump", d / "pairs_4.dump", d / "walls_4.dump",
             "--walls", "zmin,plate:zmax", "--young", 5e10, "--poisson", NU, "--density", 2500,
             "-o", out)
    assert r.returncode == 0
    assert "warning" in r.stderr and "MISMATCH" in r.stderr
    p = read_packing(out)
    assert p.attrs["force_law_ratio_median"] == pytest.approx(1e8 / 5e10, rel=1e-3)
    info = tdem("info", out)
    assert "MISMATCH" in info.stdout and "inferred             wall zmin" in info.stdout


def test_thermal_run_respects_the_maximum_principle(bed, tmp_path):
    _, paths, _ = bed
    scene = tmp_path / "scene.toml"
    scene.write_text(f'''packing = "{paths[-1]}"
law = "pipe"
[material]
conductivity = 205.0
density = 2500.0
heat_capacity = 900.0
young_pa = {E}
poisson = {NU}
[initial]
temperature = 300.0
[[boundary]]
kind = "temperature"
on = "zmin"
value = 500.0
[[boundary]]
kind = "temperature"
on = "plate"
value = 400.0
[solver]
method = "implicit"
theta = 0.5
dt = 0.5
end_time = 200.0
output_times = [10.0, 50.0, 200.0]
''')
    r = tdem("run", scene, "--out", tmp_path / "run", "--quiet", "--threads", 1,
             env=dict(os.environ, NUMBA_NUM_THREADS="1"))
    assert r.returncode == 0, r.stderr
    with h5py.File(tmp_path / "run" / "thermal.h5") as f:
        t = f["temperature"][()]
        flags = f.attrs.get("flags", "")
    flags = flags.decode() if isinstance(flags, bytes) else str(flags)
    assert np.all(np.isfinite(t))
    assert t.min() >= 300.0 - 1e-9 and t.max() <= 500.0 + 1e-9
    assert "max_principle" not in flags and "energy_ledger" not in flags
    assert t[-1].mean() > 350.0          # heat got in


def test_bad_inputs_one_line_nothing_written(bed, tmp_path):
    d, _, _ = bed
    out = tmp_path / "p.h5"
    cases = [
        (["--walls", "zmin"], "mesh id 1, but --walls names 1 mesh(es)"),
        (["--walls", "zmin,plate:up"], "--walls: wall 1 (plate): expected a side xmin"),
        (["--walls", "xmin,plate:zmax"], "a periodic axis"),
    ]
    for extra, words in cases:
        r = tdem("import", "liggghts", d / "atoms_4.dump", d / "pairs_4.dump",
                 d / "walls_4.dump", "--young", E, "--poisson", NU, "--density", 2500,
                 "-o", out, *extra)
        assert r.returncode == 2 and "Traceback" not in r.stderr
        assert len(r.stderr.strip().splitlines()) == 1 and words in r.stderr, r.stderr
        assert not list(tmp_path.iterdir())
    r = tdem("import", "liggghts", d / "pairs_4.dump", d / "pairs_4.dump", "--young", E,
             "--poisson", NU, "-o", out)
    assert r.returncode == 2 and "ITEM: ATOMS: missing" in r.stderr and "dump local" in r.stderr
    assert not list(tmp_path.iterdir())
