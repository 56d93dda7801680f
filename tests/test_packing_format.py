"""The packing format: exact round trip, and one clear error per kind of corrupt file."""
import subprocess
import sys

import h5py
import numpy as np
import pytest

from thermal_kernel.lattice import simple_cubic_packing
from thermal_kernel.packing import PackingError, packing_statistics, read_packing, write_packing

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
