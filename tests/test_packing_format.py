"""The packing format: exact round trip, and one clear error per kind of corrupt file."""
import subprocess
import sys

import h5py
import numpy as np
import pytest

from thermal_kernel.lattice import simple_cubic_packing
from thermal_kernel.packing import PackingError, packing_statistics, read_packing, write_packing

# `make coverage` counts this module (marker kernel: its subject is thermal_kernel, and it is
# fast enough with NUMBA_DISABLE_JIT=1)
pytestmark = pytest.mark.kernel

ARRAYS = ("position", "radius", "phase", "pair", "overlap", "normal_force", "branch",
          "wall_point", "wall_normal", "wall_radius", "wall_particle", "wall_index",
          "wall_overlap", "wall_normal_force", "domain_lo", "domain_hi", "periodic",
          "contact_radius")


@pytest.fixture
def lattice_file(tmp_path):
    packing = simple_cubic_packing((3, 4, 5), spacing_m=2e-3, radius_m=1.001e-3)
    path = tmp_path / "packing.h5"
    write_packing(path, packing)
    return packing, path


def test_round_trip_is_exact(lattice_file, tmp_path):
    packing, path = lattice_file
    back = read_packing(path)
    for name in ARRAYS:
        a, b = getattr(packing, name), getattr(back, name)
        assert a.dtype.kind == b.dtype.kind, name
        np.testing.assert_array_equal(a, b, err_msg=name)
    assert back.wall_name == packing.wall_name and back.wall_kind == packing.wall_kind
    for key, value in packing.attrs.items():
        assert back.attrs[key] == value or (np.isnan(value) and np.isnan(back.attrs[key])), key
    # write(read(x)) reproduces the same arrays again (the reader adds nothing)
    again = tmp_path / "again.h5"
    write_packing(again, back)
    third = read_packing(again)
    for name in ARRAYS:
        np.testing.assert_array_equal(getattr(third, name), getattr(back, name), err_msg=name)
    assert not list(tmp_path.glob("*.tmp")), "temporary file left behind"


def test_a_failed_write_leaves_no_file_and_no_temporary(lattice_file, tmp_path):
    """The writer goes through thermal_kernel.atomic.replacing: a write that fails half-way
    leaves the previous file as it was and no packing.h5.tmp (it was left before)."""
    packing, path = lattice_file
    before = path.read_bytes()
    packing.wall_name = [1] * len(packing.wall_name)   # h5py refuses it, the file half written
    with pytest.raises(TypeError):
        write_packing(path, packing)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["packing.h5"]


def test_writer_puts_pairs_in_canonical_order(tmp_path):
    packing = simple_cubic_packing((2, 2, 2))
    # reverse the rows and flip i/j of each: the writer must restore i<j (and negate branch)
    packing.pair = packing.pair[::-1, ::-1].copy()
    packing.branch = -packing.branch[::-1]
    packing.overlap = packing.overlap[::-1].copy()
    packing.normal_force = packing.normal_force[::-1].copy()
    packing.contact_radius = packing.contact_radius[::-1].copy()
    write_packing(tmp_path / "p.h5", packing)
    back = read_packing(tmp_path / "p.h5")
    assert np.all(back.pair[:, 0] < back.pair[:, 1])
    np.testing.assert_allclose(back.branch,
                               back.position[back.pair[:, 1]] - back.position[back.pair[:, 0]])


def test_statistics_of_a_lattice():
    packing = simple_cubic_packing((3, 3, 3), spacing_m=1e-3, radius_m=0.51e-3)
    stats = packing_statistics(packing)
    # 3x3x3 lattice: 3 * (2*3*3) = 54 face contacts; Z = 2*54/27 = 4
    assert stats["n_contacts"] == 54
    assert stats["mean_z"] == pytest.approx(4.0)
    assert stats["rattler_fraction"] == 0.0
    assert stats["radius_std_m"] == 0.0


def _corrupt(path, edit):
    with h5py.File(path, "r+") as f:
        edit(f)


def _replace(name, data):
    def edit(f):
        del f[name]
        f[name] = data
    return edit


def _set_attr(key, value):
    def edit(f):
        f.attrs[key] = value
    return edit


CORRUPTIONS = {
    "missing dataset": (lambda f: f.__delitem__("contacts/overlap"),
                        "contacts/overlap", "missing dataset"),
    "misshapen dataset": (_replace("particles/position", np.zeros((60, 2))),
                          "particles/position", "expected shape (n, 3)"),
    "length mismatch": (_replace("particles/radius", np.full(59, 1e-3)),
                        "particles/radius", "expected shape (60,)"),
    "NaN": (lambda f: f["contacts/normal_force"].__setitem__(3, np.nan),
            "contacts/normal_force", "non-finite"),
    "negative radius": (lambda f: f["particles/radius"].__setitem__(7, -1e-3),
                        "particles/radius", "particle 7 has radius"),
    "index out of range": (lambda f: f["contacts/pair"].__setitem__((2, 1), 60),
                           "contacts/pair", "out of range 0..59"),
    "duplicate contact": (lambda f: f["contacts/pair"].__setitem__(1, f["contacts/pair"][0]),
                          "contacts/pair", "duplicates contact"),
    "self contact": (lambda f: f["contacts/pair"].__setitem__(4, [5, 5]),
                     "contacts/pair", "self contact (5, 5)"),
    "i > j": (lambda f: f["contacts/pair"].__setitem__(4, [9, 2]),
              "contacts/pair", "expected i < j"),
    "unknown version": (_set_attr("format_version", 2), "format_version",
                        "unknown format version 2"),
    "wrong format": (_set_attr("format", "something"), "format", "expected attribute format"),
    "missing attribute": (lambda f: f.attrs.__delitem__("young_pa"), "young_pa",
                          "missing root attribute"),
    "wall index": (lambda f: f["wall_contacts/wall"].__setitem__(0, 6),
                   "wall_contacts/wall", "out of range 0..5"),
    "wall kind": (_replace("walls/kind", np.array(["plane"] * 5 + ["torus"], dtype=object)),
                  "walls/kind", "expected one of plane, cylinder"),
    # impossible geometry (issue 16): each array well formed, the packing they describe is not
    "negative phase": (lambda f: f["particles/phase"].__setitem__(3, -1),
                       "particles/phase", "particle 3 has phase -1; expected a phase id >= 0"),
    "centre outside the domain": (lambda f: f["particles/position"].__setitem__(
        (5, 1), -0.5e-3), "particles/position", "particle 5 has its centre at y = -0.0005 m, "
                                                 "outside the domain [0, 0.008]"),
    "overlap beyond the radius": (lambda f: f["contacts/overlap"].__setitem__(2, 1.5e-3),
                                  "contacts/overlap", "contact 2 (0, 20) has overlap 0.0015 m, "
                                                      "larger than the smaller radius"),
    "wall overlap beyond the radius": (lambda f: f["wall_contacts/overlap"].__setitem__(
        4, 1.002e-3), "wall_contacts/overlap", "row 4 (particle 4) has overlap 0.001002 m, "
                                               "larger than its radius 0.001001 m"),
    "branch vector not joining the centres": (lambda f: f["contacts/branch"].__setitem__(
        6, [0.0, 0.0, -2e-3]), "contacts/branch", "contact 6 (2, 3): the branch vector is 4 "
                                                  "radii away from x_j - x_i"),
    "zero branch vector": (lambda f: f["contacts/branch"].__setitem__(0, [0.0, 0.0, 0.0]),
                           "contacts/branch", "contact 0 (0, 1)"),
}


@pytest.mark.parametrize("case", sorted(CORRUPTIONS))
def test_corrupt_file_gives_one_line_error(lattice_file, case):
    _, path = lattice_file
    edit, fieldname, message = CORRUPTIONS[case]
    _corrupt(path, edit)
    with pytest.raises(PackingError) as info:
        read_packing(path)
    text = str(info.value)
    assert "\n" not in text
    assert text.startswith(f"{path}: {fieldname}: "), text
    assert message in text, text


def test_cli_reports_corrupt_file_without_traceback(lattice_file):
    _, path = lattice_file
    _corrupt(path, lambda f: f["particles/radius"].__setitem__(0, np.nan))
    proc = subprocess.run([sys.executable, "-m", "tdem.cli", "info", str(path)],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "particles/radius" in lines[0] and "non-finite" in lines[0]


def test_not_hdf5(tmp_path):
    path = tmp_path / "text.h5"
    path.write_text("hello")
    with pytest.raises(PackingError, match="not an HDF5 file"):
        read_packing(path)


# ---- valid geometry that the checks above must keep accepting

DATA = __import__("pathlib").Path(__file__).resolve().parent / "data"


@pytest.mark.parametrize("name", sorted(p.name for p in DATA.glob("*.h5")))
def test_every_committed_packing_loads(name):
    packing = read_packing(DATA / name)
    assert packing.n_particles > 0 and packing.phase.min() >= 0


def _tiling():
    import importlib.util
    path = __import__("pathlib").Path(__file__).resolve().parent.parent / "yade_scripts" / \
        "tiling.py"
    spec = importlib.util.spec_from_file_location("tdem_test_tiling_fmt", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _periodic_cell():
    """A jittered simple-cubic periodic cell with its minimum-image neighbour pairs (all pairs
    within 1.1 (r_i + r_j)): many contacts cross the periodic boundary."""
    rng = np.random.default_rng(7)
    shape, a = np.array([5, 4, 4]), 1e-3
    cell = shape * a
    position = np.indices(shape).reshape(3, -1).T * a + 0.5 * a \
        + rng.uniform(-0.08, 0.08, (int(np.prod(shape)), 3)) * a
    position -= np.floor(position / cell) * cell
    radius = 0.5 * a * rng.uniform(0.9, 1.1, len(position))
    d = position[None, :, :] - position[:, None, :]
    d -= np.round(d / cell) * cell
    dist = np.linalg.norm(d, axis=2)
    i, j = np.nonzero((dist < 1.1 * (radius[:, None] + radius[None, :]))
                      & np.triu(np.ones_like(dist, bool), 1))
    branch = d[i, j]
    overlap = radius[i] + radius[j] - np.linalg.norm(branch, axis=1)
    return position, radius, cell, np.stack([i, j], 1), branch, overlap


def _write(path, position, radius, pair, branch, overlap, walls, wp, wi, wo, lo, hi, periodic):
    from thermal_kernel import packing_h5
    n, m, k = len(radius), len(pair), len(wp)
    packing_h5.write_packing(
        path, position, radius, np.zeros(n, np.int32), pair, overlap,
        np.where(overlap > 0, 1e-3, 0.0), branch, walls, np.asarray(wp, np.int64),
        np.asarray(wi, np.int32), np.asarray(wo, float), np.zeros(k), lo, hi, periodic,
        # phi as the generators measure it: the spheres' volume over the domain's (checked)
        dict(generator="test", seed=0, mean_coordination=2.0 * m / n,
             solid_fraction=float(np.sum(4 / 3 * np.pi * radius ** 3) / np.prod(np.subtract(hi,
                                                                                         lo))),
             pressure_pa=float("nan"), young_pa=2.1e11, poisson=0.3, density=7800.0))


def test_periodic_cell_branch_is_the_minimum_image(tmp_path):
    position, radius, cell, pair, branch, overlap = _periodic_cell()
    crossing = np.abs(position[pair[:, 1]] - position[pair[:, 0]] - branch).max(axis=1) > 1e-4
    assert crossing.sum() > 10           # contacts across the periodic boundary are tested
    _write(tmp_path / "cell.h5", position, radius, pair, branch, overlap, [], [], [], [],
           np.zeros(3), cell, [True] * 3)
    assert read_packing(tmp_path / "cell.h5").n_contacts == len(pair)
    # the same cell declared non-periodic: its wrapped branches no longer join the centres
    _write(tmp_path / "flat.h5", position, radius, pair, branch, overlap, [], [], [], [],
           np.zeros(3), cell, [False] * 3)
    with pytest.raises(PackingError, match="contacts/branch: contact .* radii away from "
                                           "x_j - x_i; expected"):
        read_packing(tmp_path / "flat.h5")


def test_tiled_and_carved_packing_loads(tmp_path):
    """yade_scripts/tiling.py: copies of a periodic cell carved to a box. Spheres cut by the
    faces stick out of the domain (centre inside) and their "wall contacts" on the cut surface
    have overlap r - distance in [0, r] and no force; one centre lies exactly on a face
    (overlap = r). All valid; an overlap beyond r or a centre outside is not."""
    tiling = _tiling()
    position, radius, cell, pair, branch, overlap = _periodic_cell()
    reps = np.array([3, 2, 2])
    pos_t, source, pair_t, pair_source = tiling.tile(position, cell, pair, branch, reps)
    hi = reps * cell - 0.37e-3
    hi[0] = pos_t[np.argmin(np.abs(pos_t[:, 0] - hi[0])), 0]      # a centre exactly on xmax
    lo = np.full(3, 0.41e-3)
    keep = np.all((pos_t >= lo) & (pos_t <= hi), axis=1)
    new_index, rows, pair_c = tiling.carve(keep, pair_t)
    pos_c, rad_c = pos_t[keep], radius[source[keep]]
    walls, wp, wi, wo = [], [], [], []
    for axis in range(3):
        for side, bound in ((+1, lo), (-1, hi)):
            normal = np.zeros(3)
            normal[axis] = side
            point = np.zeros(3)
            point[axis] = bound[axis]
            walls.append(dict(name=f"{'xyz'[axis]}{'min' if side > 0 else 'max'}", kind="plane",
                              point=point, normal=normal, radius=float("nan")))
            dist = (pos_c - point) @ normal
            near = np.flatnonzero(dist < 1.1 * rad_c)
            wp += near.tolist()
            wi += [len(walls) - 1] * len(near)
            wo += (rad_c[near] - dist[near]).tolist()
    wo = np.array(wo)
    assert np.any(wo == rad_c[wp]) and np.all(wo <= rad_c[wp]) and np.any(wo > 0.5 * rad_c[wp])
    assert np.any(np.any((pos_c - rad_c[:, None] < lo) | (pos_c + rad_c[:, None] > hi), axis=1))
    args = (pos_c, rad_c, pair_c, branch[pair_source[rows]], overlap[pair_source[rows]], walls,
            wp, wi, wo, lo, hi, [False] * 3)
    _write(tmp_path / "tiled.h5", *args)
    back = read_packing(tmp_path / "tiled.h5")
    assert back.n_particles == keep.sum() and back.n_contacts == len(pair_c)
    # beyond round-off the same file is refused: an overlap 1e-6 r beyond the radius ...
    deeper = wo.copy()
    deeper[np.argmax(wo / rad_c[wp])] *= 1 + 1e-6
    _write(tmp_path / "deep.h5", *args[:8], deeper, *args[9:])
    with pytest.raises(PackingError, match="wall_contacts/overlap: .* larger than its radius"):
        read_packing(tmp_path / "deep.h5")
    # ... and a domain 1e-6 of a radius short of the centre on xmax
    short = hi.copy()
    short[0] -= 1e-6 * rad_c.min()
    _write(tmp_path / "short.h5", *args[:10], short, args[11])
    with pytest.raises(PackingError, match="particles/position: particle .* outside the domain"):
        read_packing(tmp_path / "short.h5")


def test_coincident_centres_name_the_first_pair_in_x_y_z_order(tmp_path):
    """Two spheres in one place are refused, naming the pair of the group that comes first in
    x, then y, then z (its two lowest indices), checked against every pair compared directly.
    The lattice ties every x (and y, z) with many others, as a tiled packing does: the search
    must not take a tie in x alone, or in x and y, for a coincidence. What could fail: a pair
    equal in two columns reported, the groups taken in another order, a pair of one group
    named by its later indices."""
    import dataclasses
    base = simple_cubic_packing((4, 4, 4), spacing_m=2e-3, radius_m=0.9e-3)
    empty = dict(pair=np.zeros((0, 2), np.int64), overlap=np.zeros(0), normal_force=np.zeros(0),
                 branch=np.zeros((0, 3)), contact_radius=None, wall_particle=np.zeros(0, np.int64),
                 wall_index=np.zeros(0, np.int32), wall_overlap=np.zeros(0),
                 wall_normal_force=np.zeros(0))
    rng = np.random.default_rng(7)
    for trial in range(6):
        position = base.position.copy()
        # two or three coincident groups, each of a lattice site and moved spheres
        for _ in range(int(rng.integers(2, 4))):
            site, *moved = rng.choice(base.n_particles, size=int(rng.integers(2, 4)),
                                      replace=False)
            position[moved] = position[site]
        p = dataclasses.replace(base, position=position, **empty)
        path = tmp_path / f"coincident_{trial}.h5"
        write_packing(path, p)
        groups = {}
        for i in range(p.n_particles):
            groups.setdefault(tuple(position[i]), []).append(i)
        first = min(k for k, v in groups.items() if len(v) > 1)
        a, b = sorted(groups[first])[:2]
        with pytest.raises(PackingError) as info:
            read_packing(path)
        assert f"particles/position: particles {a} and {b} have the same centre" in \
            str(info.value), (trial, str(info.value), a, b)
