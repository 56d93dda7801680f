"""Issue 28 (reliability round 3), packing files: the reader's attribute and geometry checks, the
LIGGGHTS import's checks of the dumps against each other and against what the user gives.

Every bad input is made here from a committed file (tests/data): a packing edited with h5py, or
LIGGGHTS dumps written from tests/data/dense_box.h5 (400 spheres, six plane walls: its contacts
become a pairs dump, its wall contacts a walls dump with one mesh per wall) and then edited.
Each must give one line naming the file and the field, exit status 2, and leave no output file.

The physical rule behind two of the families (issue 28, item 7): a packing's solid_fraction is
the spheres' volume over the domain's, and a wall position given by the user must be where the
dump's wall contacts put it. Both tests below failed on the code before this round (tdem info
printed "solid fraction 7.0000"; --walls zmin=... against the floor contacts changed phi by
39 % without a word).
"""
import errno
import math
import os
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest

from faults import FullDiskFile
from tdem.cli import main
from thermal_kernel import atomic
from thermal_kernel.packing import (SOLID_FRACTION_RTOL, read_packing,
                                    solid_fraction_bounds)

DATA = Path(__file__).resolve().parent / "data"
BED = DATA / "bed_small_4.05e+07Pa.h5"
BOX = DATA / "dense_box.h5"


def tdem(capsys, *args):
    """``tdem ARGS`` in this process: (exit status, stdout, stderr)."""
    rc = main([str(a) for a in args])
    out = capsys.readouterr()
    return rc, out.out, out.err


def assert_refused(rc, err, *words):
    assert rc == 2, err
    assert "Traceback" not in err and err.count("\n") == 1, err
    assert err.startswith("tdem: error: "), err
    for w in words:
        assert w in err, (w, err)


# ----------------------------------------------------------------------------- packing files

def _attr(key, value):
    def edit(f):
        f.attrs[key] = value
    return edit


def _row(name, row, value):
    def edit(f):
        f[name][row] = value
    return edit


def _scale_attr(key, factor):
    def edit(f):
        f.attrs[key] = float(f.attrs[key]) * factor
    return edit


PACKING_CASES = {    # name: (source file, edit, words of the one line)
    "young_neg": (BED, _attr("young_pa", -5e10), ["young_pa", "-5e+10", "(0, inf)"]),
    "young_zero": (BED, _attr("young_pa", 0.0), ["young_pa", "(0, inf)"]),
    "poisson_1_5": (BED, _attr("poisson", 1.5), ["poisson", "(-1, 0.5)"]),
    "poisson_1": (BED, _attr("poisson", 1.0), ["poisson", "(-1, 0.5)"]),
    "poisson_0_7": (BED, _attr("poisson", 0.7), ["poisson", "(-1, 0.5)"]),
    "poisson_m2": (BED, _attr("poisson", -2.0), ["poisson", "(-1, 0.5)"]),
    "density_neg": (BED, _attr("density", -2500.0), ["density", "(0, inf)"]),
    "pressure_neg": (BED, _attr("pressure_pa", -5.0), ["pressure_pa", "[0, inf)"]),
    "solid_fraction_7": (BED, _attr("solid_fraction", 7.0), ["solid_fraction", "(0, 1]"]),
    "solid_fraction_x1.2": (BOX, _scale_attr("solid_fraction", 1.2),
                            ["solid_fraction", "the spheres' volume over the domain's"]),
    "overlap_negative": (BED, _row("contacts/overlap", 4, -1e-3),
                         ["contacts/overlap", "contact 4", "r_i + r_j - |branch|"]),
    "wall_contact_far": (BOX, lambda f: _wall_contact_on_farthest(f, 2),
                         ["wall_contacts/overlap", "row 2", "r - distance"]),
}


def _wall_contact_on_farthest(f, row):
    """A touching wall contact moved to the particle farthest from its wall."""
    w = int(f["wall_contacts/wall"][row])
    x = f["particles/position"][()]
    dist = (x - f["walls/point"][w]) @ f["walls/normal"][w]
    f["wall_contacts/particle"][row] = int(np.argmax(dist))
    f["wall_contacts/overlap"][row] = 1e-6


@pytest.mark.parametrize("case", sorted(PACKING_CASES))
def test_bad_packing_is_refused_by_info(tmp_path, capsys, case):
    source, edit, words = PACKING_CASES[case]
    path = tmp_path / f"{case}.h5"
    shutil.copy(source, path)
    with h5py.File(path, "r+") as f:
        edit(f)
    rc, _, err = tdem(capsys, "info", path)
    assert_refused(rc, err, f"{path}: ", *words)


def test_packing_young_pa_refused_before_the_run(tmp_path, capsys):
    """A scene without young/poisson takes the packing's own: a negative modulus ended the run in
    a ValueError traceback from the law; now the reader refuses it, and no run folder is left."""
    path = tmp_path / "p.h5"
    shutil.copy(BED, path)
    with h5py.File(path, "r+") as f:
        f.attrs["young_pa"] = -5e10
    scene = tmp_path / "scene.toml"
    scene.write_text(f'packing = "{path}"\nlaw = "pipe"\n[material]\nconductivity = 205.0\n'
                     'density = 2500.0\nheat_capacity = 900.0\n[initial]\ntemperature = 300.0\n'
                     '[[boundary]]\nkind = "temperature"\non = "zmin"\nvalue = 500.0\n'
                     '[solver]\nmethod = "explicit"\nend_time = 1.0\noutput_times = [1.0]\n')
    rc, _, err = tdem(capsys, "run", scene, "--out", tmp_path / "run", "--quiet")
    assert_refused(rc, err, "young_pa", "(0, inf)")
    assert not (tmp_path / "run").exists()


def test_solid_fraction_is_the_spheres_volume_over_the_domains(tmp_path, capsys):
    """The rule: phi = the spheres' volume (whole, or less the caps beyond the walls) over the
    domain's volume (the box, pi R^2 L in a cylinder wall, the ball of a sphere wall). Every
    committed packing obeys it; the same file with phi 5 % off either way is refused."""
    for source in sorted(DATA.glob("*.h5")):
        p = read_packing(source)
        cut, whole = solid_fraction_bounds(p.radius, p.wall_kind, p.wall_normal, p.wall_radius,
                                           p.wall_particle, p.wall_overlap, p.domain_lo,
                                           p.domain_hi)
        phi = p.attrs["solid_fraction"]
        assert cut * (1 - SOLID_FRACTION_RTOL) <= phi <= whole * (1 + SOLID_FRACTION_RTOL)
        for factor in (0.95, 1.05):
            path = tmp_path / f"{source.stem}_{factor}.h5"
            shutil.copy(source, path)
            with h5py.File(path, "r+") as f:
                f.attrs["solid_fraction"] = phi * factor
            rc, _, err = tdem(capsys, "info", path)
            assert_refused(rc, err, f"{path}: solid_fraction: root attribute is")


# ----------------------------------------------------------------------------- LIGGGHTS dumps

def _dump_text(kind, timestep, bounds, boundary, header, rows):
    count = "ATOMS" if kind == "ATOMS" else "ENTRIES"
    lines = ["ITEM: TIMESTEP", str(timestep), f"ITEM: NUMBER OF {count}", str(len(rows)),
             f"ITEM: BOX BOUNDS {' '.join(boundary)}"]
    lines += [f"{lo:.17g} {hi:.17g}" for lo, hi in bounds]
    lines.append(f"ITEM: {kind} {header}")
    lines += [" ".join(x if isinstance(x, str) else f"{x:.17g}" for x in row) for row in rows]
    return "\n".join(lines) + "\n"


def write_dumps(folder, packing_path=BOX, timestep=1000):
    """atoms.dump, pairs.dump, walls.dump of a committed packing, as LIGGGHTS writes them (ids
    from 1, forces along the line of centres, one mesh per wall in file order); returns
    (paths, --walls value, the packing)."""
    p = read_packing(packing_path)
    bounds = np.column_stack([p.domain_lo, p.domain_hi])
    boundary = ["ff", "ff", "ff"]
    ids = np.arange(1, p.n_particles + 1)
    atoms = [(str(ids[k]), "1", *p.position[k], p.radius[k]) for k in range(p.n_particles)]
    touch = np.flatnonzero(p.overlap > 0)
    pairs = []
    for c in touch:
        i, j = p.pair[c]
        n = p.branch[c] / np.linalg.norm(p.branch[c])
        pairs.append((str(ids[i]), str(ids[j]), "0", *(-p.normal_force[c] * n), p.overlap[c]))
    walls = []
    for k in np.flatnonzero(p.wall_overlap > 0):
        w = p.wall_index[k]
        walls.append((str(w), "0", str(ids[p.wall_particle[k]]),
                      *(p.wall_normal_force[k] * p.wall_normal[w]), p.wall_overlap[k]))
    folder.mkdir(parents=True, exist_ok=True)
    paths = [folder / "atoms.dump", folder / "pairs.dump", folder / "walls.dump"]
    paths[0].write_text(_dump_text("ATOMS", timestep, bounds, boundary, "id type x y z radius",
                                   atoms))
    hdr = "c_pc[1] c_pc[2] c_pc[3] c_pc[4] c_pc[5] c_pc[6] c_pc[7]"
    paths[1].write_text(_dump_text("ENTRIES", timestep, bounds, boundary, hdr, pairs))
    paths[2].write_text(_dump_text("ENTRIES", timestep, bounds, boundary,
                                   hdr.replace("pc", "wc"), walls))
    return paths, ",".join(p.wall_name), p


def _material(p):
    return ["--young", p.attrs["young_pa"], "--poisson", p.attrs["poisson"]]


def _edit_rows(path, fn):
    """Apply fn(list of data rows as lists of strings) -> rows to a dump; fix its count."""
    lines = path.read_text().splitlines()
    head = next(k for k, x in enumerate(lines) if x.startswith("ITEM: ATOMS")
                or x.startswith("ITEM: ENTRIES"))
    rows = fn([x.split() for x in lines[head + 1:]])
    lines[3] = str(len(rows))
    path.write_text("\n".join(lines[:head + 1] + [" ".join(r) for r in rows]) + "\n")


def _set(row, col, value):
    def fn(rows):
        rows[row][col] = value
        return rows
    return fn


def _copy_atom_new_id(rows):                  # a second sphere in the place of the first
    return rows[:1] + [["99999"] + rows[0][1:]] + rows[1:]


def _far_pair(p):
    """A pairs row between the two atoms farthest apart along z, delta 2e-5 m, F 0.2 N."""
    a, b = int(np.argmin(p.position[:, 2])) + 1, int(np.argmax(p.position[:, 2])) + 1

    def fn(rows):
        return [[str(a), str(b), "0", "0", "0", "0.2", "2e-05"]] + rows
    return fn


def _far_wall_atom(p, paths):
    """The first walls row moved to the atom farthest from that row's wall."""
    w = int(paths[2].read_text().splitlines()[9].split()[0])
    dist = (p.position - p.wall_point[w]) @ p.wall_normal[w]
    return _set(0, 2, str(int(np.argmax(dist)) + 1))


def _import_cases(p, paths, walls):
    lo = p.domain_lo[2]
    shifted = walls.replace("zmin", f"zmin={lo - 0.25 * (p.domain_hi[2] - lo):.6g}")
    return {   # name: (edit of the dumps or None, extra options, words)
        "atoms_float_id": ((0, _set(5, 0, "6.5")), [], ["atoms.dump: id: atom id 6.5",
                                                        "not an integer"]),
        "atoms_huge_radius": ((0, _set(5, 5, "1e300")), [], ["atoms.dump: radius: atom 6",
                                                             "1e+300 m", "larger than"]),
        "atoms_coincident_new_id": ((0, _copy_atom_new_id), [],
                                    ["atoms 1 and 99999 overlap", "lists no contact"]),
        "pairs_far_apart": ((1, _far_pair(p)), [], ["pairs.dump: delta (column 7)",
                                                    "apart", "expected the overlap"]),
        "walls_far_atom": ((2, _far_wall_atom(p, paths)), [], ["walls.dump: atom (column 3)",
                                                               "touches", "from the wall"]),
        "walls_coord_contradicts": (None, ["--walls", shifted],
                                    ["--walls: zmin=", "contradicts", "put the wall at z"]),
        "density_negative": (None, ["--density", "-2500"], ["--density", "> 0"]),
        "density_zero": (None, ["--density", "0"], ["--density", "> 0"]),
        "pressure_negative": (None, ["--pressure-pa", "-5"], ["--pressure-pa", ">= 0"]),
        "pressure_nan": (None, ["--pressure-pa", "nan"], ["--pressure-pa", "got nan"]),
        "pressure_inf": (None, ["--pressure-pa", "inf"], ["--pressure-pa", "got inf"]),
    }


IMPORT_CASES = ("atoms_float_id", "atoms_huge_radius", "atoms_coincident_new_id",
                "pairs_far_apart", "walls_far_atom", "walls_coord_contradicts",
                "density_negative", "density_zero", "pressure_negative", "pressure_nan",
                "pressure_inf")


@pytest.fixture(scope="module")
def dumps(tmp_path_factory):
    return write_dumps(tmp_path_factory.mktemp("dumps"))


def test_dumps_of_a_committed_packing_import_to_the_same_packing(dumps, tmp_path, capsys):
    """The baseline of the table: the unedited dumps import with no warning, and the packing
    has the original's contacts and phi (to 1e-3: caps at the walls cut off here)."""
    paths, walls, p = dumps
    out = tmp_path / "p.h5"
    rc, _, err = tdem(capsys, "import", "liggghts", *paths, "--walls", walls, *_material(p),
                      "--density", p.attrs["density"], "-o", out)
    assert rc == 0 and err == "", err
    q = read_packing(out)
    assert q.n_particles == p.n_particles and q.n_contacts == int((p.overlap > 0).sum())
    assert q.attrs["solid_fraction"] == pytest.approx(p.attrs["solid_fraction"], rel=1e-3)
    np.testing.assert_allclose(q.wall_point, p.wall_point, atol=1e-12)


@pytest.mark.parametrize("case", IMPORT_CASES)
def test_bad_import_is_refused(dumps, tmp_path, capsys, case):
    paths, walls, p = dumps
    edit, extra, words = _import_cases(p, paths, walls)[case]
    local = []
    for k, path in enumerate(paths):
        local.append(tmp_path / path.name)
        shutil.copy(path, local[-1])
        if edit is not None and edit[0] == k:
            _edit_rows(local[-1], edit[1])
    out = tmp_path / "out.h5"
    args = ["import", "liggghts", *local, "--walls", walls, *_material(p), "--density",
            p.attrs["density"], "-o", out]
    if "--walls" in extra:                      # the case's own --walls replaces the default
        args[args.index("--walls") + 1] = extra[extra.index("--walls") + 1]
        extra = []
    if "--density" in extra:
        args = args[:args.index("--density")] + args[args.index("--density") + 2:]
    rc, _, err = tdem(capsys, *args, *extra)
    assert_refused(rc, err, *words)
    assert sorted(x.name for x in tmp_path.iterdir()) == sorted(x.name for x in local)


def test_walls_given_must_agree_with_the_dumps(dumps, tmp_path, capsys):
    """The rule: a wall's position is where its contacts in the walls dump put it. Given at that
    position the import goes through with the same phi; given 1 % of the bed height lower it
    is refused (it was imported with phi changed by the same ratio, and post's gamma with it)."""
    paths, walls, p = dumps
    lo, height = p.domain_lo[2], p.domain_hi[2] - p.domain_lo[2]
    same = walls.replace("zmin", f"zmin={float(lo)!r}")
    out = tmp_path / "same.h5"
    rc, _, err = tdem(capsys, "import", "liggghts", *paths, "--walls", same, *_material(p),
                      "--density", p.attrs["density"], "-o", out)
    assert rc == 0, err
    assert read_packing(out).attrs["solid_fraction"] == pytest.approx(
        p.attrs["solid_fraction"], rel=1e-3)
    lower = walls.replace("zmin", f"zmin={float(lo - 0.01 * height)!r}")
    rc, _, err = tdem(capsys, "import", "liggghts", *paths, "--walls", lower, *_material(p),
                      "--density", p.attrs["density"], "-o", tmp_path / "lower.h5")
    assert_refused(rc, err, "--walls: zmin=", "contradicts", f"put the wall at z = {lo:.9g} m")
    assert not (tmp_path / "lower.h5").exists()


def test_output_that_is_an_input_dump_is_refused(dumps, tmp_path, capsys):
    paths, walls, p = dumps
    atoms = tmp_path / "atoms_copy.h5"            # a dump with a packing's name
    shutil.copy(paths[0], atoms)
    before = atoms.read_bytes()
    rc, _, err = tdem(capsys, "import", "liggghts", atoms, *paths[1:], "--walls", walls,
                      *_material(p), "--density", p.attrs["density"], "-o", atoms)
    assert_refused(rc, err, f"{atoms}: -o: is the atoms dump given as input")
    assert atoms.read_bytes() == before


def test_full_disk_while_writing_the_packing(dumps, tmp_path, capsys, monkeypatch):
    """write() of the packing raises ENOSPC (what a full disk does; it was 14 h5py tracebacks
    and a segfault): one line naming the file, exit 2, no file and no temporary left."""
    paths, walls, p = dumps

    monkeypatch.setattr(atomic, "open", FullDiskFile, raising=False)
    out = tmp_path / "out" / "p.h5"
    out.parent.mkdir()
    rc, _, err = tdem(capsys, "import", "liggghts", *paths, "--walls", walls, *_material(p),
                      "--density", p.attrs["density"], "-o", out)
    assert_refused(rc, err, f"{out}: {os.strerror(errno.ENOSPC)}")
    assert list(out.parent.iterdir()) == []


def test_the_round_trip_dumps_are_what_liggghts_writes(dumps):
    """(The table's source is sound: every pairs row's delta is r_i + r_j - distance of its
    atoms, every walls row's atom is at its wall.)"""
    paths, _, p = dumps
    rows = np.loadtxt(paths[1], skiprows=9, ndmin=2)
    i, j = rows[:, 0].astype(int) - 1, rows[:, 1].astype(int) - 1
    geo = p.radius[i] + p.radius[j] - np.linalg.norm(p.position[j] - p.position[i], axis=1)
    assert np.abs(geo - rows[:, 6]).max() < 1e-12
    assert math.isclose(np.linalg.norm(rows[:, 3:6], axis=1).sum(),
                        p.normal_force[p.overlap > 0].sum(), rel_tol=1e-12)


# ----------------------------------------------------------------------------- tdem_yade.dump

YADE_SCRIPT = r'''
import errno, json, os, sys
from yade import utils, geom
from yade.wrapper import (Omega, FrictMat, ForceResetter, InsertionSortCollider, Bo1_Sphere_Aabb,
                          Bo1_Facet_Aabb, Bo1_Wall_Aabb, InteractionLoop, Ig2_Sphere_Sphere_ScGeom,
                          Ig2_Facet_Sphere_ScGeom, Ig2_Wall_Sphere_ScGeom,
                          Ip2_FrictMat_FrictMat_MindlinPhys, Law2_ScGeom_MindlinPhys_Mindlin,
                          Ip2_FrictMat_FrictMat_FrictPhys, Law2_ScGeom_FrictPhys_CundallStrack,
                          NewtonIntegrator)
sys.path.insert(0, os.environ["TDEM_YADE_PATH"])
import tdem_yade
O = Omega()
out = sys.argv[1]
P = os.path.join(out, "packing.h5")
O.materials.append(FrictMat(young=5e7, poisson=0.3, density=2600, frictionAngle=0.4))
L, r = 0.006, 0.0005
O.bodies.append(utils.wall(0.0, axis=2))                                    # body 0: zmin
O.bodies.append(geom.facetBox((L / 2, L / 2, L), (L / 2, L / 2, L), wallMask=15))
spheres = [O.bodies.append(utils.sphere((x, y, 0.0006 + 0.0011 * k), r))
           for x in (0.0015, 0.003, 0.0045) for y in (0.0015, 0.0045) for k in range(3)]
def engines(linear):
    ip, law = ((Ip2_FrictMat_FrictMat_FrictPhys(), Law2_ScGeom_FrictPhys_CundallStrack())
               if linear else (Ip2_FrictMat_FrictMat_MindlinPhys(),
                               Law2_ScGeom_MindlinPhys_Mindlin()))
    O.engines = [ForceResetter(), InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Facet_Aabb(),
                                                         Bo1_Wall_Aabb()]),
                 InteractionLoop([Ig2_Sphere_Sphere_ScGeom(), Ig2_Facet_Sphere_ScGeom(),
                                  Ig2_Wall_Sphere_ScGeom()], [ip], [law]),
                 NewtonIntegrator(gravity=(0, 0, -9.81), damping=0.4)]
engines(False)
O.dt = 0.5 * utils.PWaveTimeStep()
O.run(1, True)
kw = dict(young_pa=5e7, poisson=0.3, exit_on_error=False, quiet=True)
result = {}
def case(name, *args, **kwargs):
    try:
        tdem_yade.dump(*args, **kwargs)
        result[name] = "written"
    except tdem_yade.DumpError as e:
        result[name] = str(e)
    result[name + ":left"] = sorted(os.listdir(out))
    if name == "ok":
        os.replace(P, os.path.join(os.path.dirname(out), "ok.h5"))
    for f in os.listdir(out):
        os.remove(os.path.join(out, f))
class Full:
    def __init__(self, path, mode):
        self.f = open(path, mode)
    def __enter__(self):
        return self
    def __exit__(self, *exc):
        self.f.close()
    def write(self, data):
        self.f.write(bytes(data)[:100])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
case("ok", P, seed=3, **kw)
case("poisson_0_7", P, young_pa=5e7, poisson=0.7, exit_on_error=False)
case("wall_names_unknown_body", P, wall_names={9999: "plate"}, **kw)
case("wall_names_sphere_body", P, wall_names={spheres[0]: "plate"}, **kw)
case("wall_names_nonstring", P, wall_names={0: 5}, **kw)
case("wall_names_dup", P, wall_names={0: "xmax"}, **kw)
case("wall_names_list", P, wall_names=["plate"], **kw)
case("pressure_negative", P, pressure_pa=-5.0, **kw)
case("seed_text", P, seed="abc", **kw)
case("attrs_override_format", P, attrs={"format": "junk"}, **kw)
case("attrs_override_young", P, attrs={"young_pa": -1.0, "solid_fraction": 3.0}, **kw)
case("attrs_object", P, attrs={"obj": object()}, **kw)
case("positional_args", P, 5e7, 0.3, exit_on_error=False)
case("unknown_kwarg", P, youngs=5e7, **kw)
case("no_path", **kw)
tdem_yade._writer._atomic.open = Full
case("full_disk", P, **kw)
del tdem_yade._writer._atomic.open
engines(True)
case("linear_no_poisson", P, young_pa=5e7, exit_on_error=False, quiet=True)
engines(False)
O.bodies.append(utils.sphere(tuple(O.bodies[spheres[0]].state.pos), r))
case("overlapping_spheres", P, **kw)
O.bodies[spheres[1]].state.pos = (float("nan"), 0, 0)
case("nan_position", P, **kw)
with open(os.path.join(os.path.dirname(out), "result.json"), "w") as f:
    json.dump(result, f)
'''

YADE_CASES = {
    "poisson_0_7": "poisson: expected Poisson's ratio in (-1, 0.5), got 0.7",
    "wall_names_unknown_body": "wall_names: body 9999: no such body",
    "wall_names_sphere_body": "is a Sphere, not a wall body",
    "wall_names_nonstring": "wall_names[0]: expected a wall name",
    "wall_names_dup": "wall_names: body 0 named 'xmax', the name of another wall",
    "wall_names_list": "wall_names: expected a dict",
    "pressure_negative": "pressure_pa: expected a pressure >= 0",
    "seed_text": "seed: expected an integer, got 'abc'",
    "attrs_override_format": "attrs['format']: an attribute dump() writes itself",
    "attrs_override_young": "attrs['young_pa']: an attribute dump() writes itself",
    "attrs_object": "attrs['obj']: a value of type object",
    "positional_args": "dump(): 3 positional arguments; the file name is the only one",
    "unknown_kwarg": "unknown argument 'youngs' (did you mean young_pa?)",
    "no_path": "dump(): missing the file name",
    "full_disk": "cannot write the file: No space left on device",
    "linear_no_poisson": "poisson: not given, and the contact law is not Hertz-Mindlin",
    "overlapping_spheres": "overlap by 0.001 m",
    "nan_position": "has position [nan, 0.0, 0.0]: expected finite numbers",
}


@pytest.mark.yade
def test_tdem_yade_dump_refusals_are_one_line(tmp_path):
    """One small YADE scene (18 spheres, a floor, a facet box, one step), dump() called with each
    bad argument or scene state (exit_on_error=False: the DumpError's one line): the message
    names the argument, and nothing is left in the folder. The good call passes the reader."""
    import subprocess

    from tdem.yade import yade_environment
    if shutil.which("yade", path=yade_environment()["PATH"]) is None:
        pytest.skip("Debian's yade is not installed")
    import json
    script = tmp_path / "scene.py"
    script.write_text(YADE_SCRIPT)
    out = tmp_path / "out"
    out.mkdir()
    env = dict(yade_environment(), TDEM_YADE_PATH=str(Path(__file__).resolve().parent.parent
                                                      / "yade_scripts"))
    r = subprocess.run(["yade", "-n", "-j1", "-x", str(script), str(out)], cwd=tmp_path,
                       env=env, capture_output=True, text=True, timeout=600,
                       stdin=subprocess.DEVNULL)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    result = json.loads((tmp_path / "result.json").read_text())
    assert result["ok"] == "written" and result["ok:left"] == ["packing.h5"]
    ok = read_packing(tmp_path / "ok.h5")                   # the stricter reader takes it
    assert ok.n_particles == 18 and 0 < ok.attrs["solid_fraction"] < 1
    for case, words in YADE_CASES.items():
        assert words in result[case], (case, result[case])
        assert "\n" not in result[case]
        assert result[case + ":left"] == [], (case, result[case + ":left"])
