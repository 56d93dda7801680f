"""thermal_kernel/packing_ranks.py: the packing file read on 1, 2 and 3 MPI ranks, each rank its
block of the particles, against the whole reader (read_packing(path, contacts=False)) on the
same file (tests/mpi_packing_check.py, under mpirun): the same PackingError message on every rank
when it refuses the file, the same blocks, walls, wall contacts, domain, scales and content hash
when it reads it.

The files: every good packing of tests/data, and bad ones made here from dense_box.h5 (400
spheres; on 3 ranks the blocks 0-133, 134-266, 267-399; its 285 wall rows 0-94, 95-189,
190-284), each with two faults where the first the whole reader reports is not the first rank's
or not the first in the file's order: a radius <= 0 in the last block, a NaN in a later block's
centres before one in the first block's radii, a negative phase before a centre outside, the
first centre outside on the middle rank, coincident centres in the first and last blocks (one
pair -0.0 against 0.0), a wall overlap beyond the radius, the wall rows reordered so that a
later wall's fault comes first in the file (the whole reader reports the first wall's), a force
on a wall gap, a wrong solid_fraction, a wall row's particle out of range, no particles, fewer
particles than ranks, float32 centres, a missing file and a file that is not HDF5.

What could fail: a fault reported with a block's index instead of the file's, the highest or
the own rank's fault raised instead of the lowest's, a rank left waiting in a collective, equal
centres on two ranks never compared, a wall row checked against another particle, a tolerance
from one block's centres instead of all, the hash of other bytes or dtypes.
"""
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest

from thermal_kernel.packing import Packing, read_packing, write_packing
from thermal_kernel.solvers.mpi_launch import missing

DATA = Path(__file__).resolve().parent / "data"
BOX = DATA / "dense_box.h5"
WHY = missing()

# as tests/test_petsc_backend.py: mpirun of .venv-mpi, ~1.5 s a start
pytestmark = [pytest.mark.petsc, pytest.mark.slow,
              pytest.mark.skipif(WHY is not None, reason=f"PETSc backend unavailable: {WHY}")]


def _set(f, name, at, value):
    data = f[name][()]
    data[at] = value
    f[name][...] = data


def _interior(f):
    """Particles with no wall row (moving them breaks no wall check)."""
    n = f["particles/radius"].shape[0]
    return np.setdiff1d(np.arange(n), f["wall_contacts/particle"][()])


def _radius_last_block(f):
    _set(f, "particles/radius", 399, 0.0)
    _set(f, "particles/radius", 395, -1e-3)


def _nan_later_centre(f):
    _set(f, "particles/radius", 5, np.nan)
    _set(f, "particles/position", (350, 1), np.nan)


def _phase_before_centre(f):
    _set(f, "particles/phase", 390, -1)
    _set(f, "particles/position", (10, 0), -1.0)


def _centre_outside_middle(f):
    hi = f["domain"].attrs["hi"]
    _set(f, "particles/position", (380, 0), -1e-3)
    _set(f, "particles/position", (200, 2), hi[2] + 1e-3)


def _coincident(f, skip=0):
    """Eight pairs, each joining the first and the last block (their centres meet on several
    ranks); the pair of the lowest indices has not the smallest centre: the smallest centre's
    pair is the one reported, wherever it meets (``skip``: another eight)."""
    inner = _interior(f)
    x = f["particles/position"][()]
    first = inner[inner < 134][skip:skip + 8]
    last = inner[inner >= 267][::-1][skip:skip + 8]
    x[last] = x[first]
    c = min(range(8), key=lambda k: tuple(x[first[k]]))
    assert c != 0
    f["particles/position"][...] = x
    return f"particles/position: particles {first[c]} and {last[c]} have the same centre"


def _coincident_signed_zero(f):
    inner = _interior(f)
    a, b = inner[inner < 134][0], inner[inner >= 267][-1]
    x = f["particles/position"][()]
    x[a, 0], x[b] = -0.0, x[a]
    x[b, 0] = 0.0                  # equal under ==, other bits
    f["particles/position"][...] = x


def _wall_too_deep(f):
    r = f["particles/radius"][()][f["wall_contacts/particle"][()]]
    _set(f, "wall_contacts/overlap", [280, 283], 2 * r[[280, 283]])


def _wall_order(f):
    """Wall 0's rows moved to the end, then a row of wall 1 early in the file and one of
    wall 0 late: the whole reader reports wall 0's."""
    order = np.argsort(f["wall_contacts/wall"][()] == 0, kind="stable")
    for name in f["wall_contacts"]:
        f[f"wall_contacts/{name}"][...] = f[f"wall_contacts/{name}"][()][order]
    wall = f["wall_contacts/wall"][()]
    r = f["particles/radius"][()][f["wall_contacts/particle"][()]]
    late0, early1 = np.flatnonzero(wall == 0)[-1], np.flatnonzero(wall == 1)[0]
    assert early1 < 95 and late0 >= 190
    _set(f, "wall_contacts/overlap", [late0, early1], 0.9 * r[[late0, early1]])


def _wall_gap_force(f):
    _set(f, "wall_contacts/overlap", 270, -1e-9)
    _set(f, "wall_contacts/normal_force", 270, 1.0)


def _solid_fraction(f):
    f.attrs["solid_fraction"] = 0.5


def _wall_particle_range(f):
    _set(f, "wall_contacts/particle", 200, 400)


def _no_particles(f):
    for name, shape, dtype in (("position", (0, 3), float), ("radius", (0,), float),
                               ("phase", (0,), np.int32), ("yade_id", (0,), np.int64)):
        del f[f"particles/{name}"]
        f.create_dataset(f"particles/{name}", shape=shape, dtype=dtype)


def _float32_centres(f):
    x = f["particles/position"][()]
    del f["particles/position"]
    f.create_dataset("particles/position", data=x.astype(np.float32))


# each case: its change of dense_box.h5 (which may return the message itself) and the start of
# the message the whole reader gives (after the path): the check each case is meant to reach
CASES = {"radius_last_block": (_radius_last_block, "particles/radius: particle 395 "),
         "nan_later_centre": (_nan_later_centre, "particles/position: non-finite value (NaN "
                                                 "or inf) at flat index 1051"),
         "phase_before_centre": (_phase_before_centre, "particles/phase: particle 390 "),
         "centre_outside_middle": (_centre_outside_middle, "particles/position: particle 200 "),
         "coincident": (_coincident, None),
         "coincident_others": (lambda f: _coincident(f, skip=8), None),
         "coincident_signed_zero": (_coincident_signed_zero, "particles/position: particles "),
         "wall_too_deep": (_wall_too_deep, "wall_contacts/overlap: row 280 "),
         "wall_order": (_wall_order, "wall_contacts/overlap: row 284 (particle 398, wall 0)"),
         "wall_gap_force": (_wall_gap_force, "wall_contacts/normal_force: row 270 "),
         "solid_fraction": (_solid_fraction, "solid_fraction: root attribute is 0.5,"),
         "wall_particle_range": (_wall_particle_range, "wall_contacts/particle: row 200 "),
         "no_particles": (_no_particles, "particles/position: expected at least one particle"),
         "float32_centres": (_float32_centres, None)}


def _two_spheres(path):
    """A packing of 2 spheres (fewer than the ranks: a rank with an empty block)."""
    r = np.array([1e-3, 1e-3])
    lo, hi = np.zeros(3), np.full(3, 1e-2)
    phi = float(np.sum(4 / 3 * np.pi * r ** 3) / np.prod(hi - lo))
    e2, e3, z = np.zeros((0, 2), np.int64), np.zeros((0, 3)), np.zeros(0)
    write_packing(path, Packing(
        position=np.array([[3e-3, 5e-3, 5e-3], [7e-3, 5e-3, 5e-3]]), radius=r,
        phase=np.zeros(2, np.int32), pair=e2, overlap=z, normal_force=z, branch=e3,
        domain_lo=lo, domain_hi=hi,
        attrs=dict(generator="test", seed=0, solid_fraction=phi, mean_coordination=0.0,
                   pressure_pa=float("nan"), young_pa=1e9, poisson=0.3, density=2500.0)))


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """[(path, expected start of the message or None: reads)] of every case."""
    tmp = tmp_path_factory.mktemp("packings")
    out = [(p, None) for p in sorted(DATA.glob("*.h5"))]
    for name, (change, message) in CASES.items():
        path = tmp / f"{name}.h5"
        shutil.copyfile(BOX, path)
        with h5py.File(path, "r+") as f:
            message = change(f) or message     # a case's own, from its indices
        out.append((path, message))
    _two_spheres(tmp / "two_spheres.h5")
    out.append((tmp / "two_spheres.h5", None))
    (tmp / "not_hdf5.h5").write_text("not a packing\n")
    out += [(tmp / "not_hdf5.h5", "not an HDF5 file"), (tmp / "missing.h5", "file not found")]
    return out


def test_the_cases_reach_the_checks_they_are_made_for(files):
    """The whole reader's verdict on each file (so that the ranks are compared on each check)."""
    for path, message in files:
        try:
            read_packing(path, contacts=False)
            got = None
        except ValueError as e:
            got = str(e)
        if message is None:
            assert got is None, (path, got)
        else:
            assert got is not None and got.startswith(f"{path}: {message}"), (path, got)


@pytest.mark.parametrize("ranks", [1, 2, 3])
def test_the_ranks_read_what_the_whole_reader_reads(files, ranks):
    import subprocess

    from thermal_kernel.solvers.mpi_launch import MPIRUN_LOCAL, mpi_env, mpi_python
    check = Path(__file__).resolve().parent / "mpi_packing_check.py"
    done = subprocess.run(["mpirun", "-n", str(ranks), *MPIRUN_LOCAL, str(mpi_python()),
                           str(check), *(str(p) for p, _ in files)], env=mpi_env(),
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, (done.stdout[-3000:], done.stderr[-3000:])
    assert f"packing_ranks OK {ranks} {len(files)}" in done.stdout, done.stdout[-3000:]
