"""thermal_kernel/packing_stats.py, the statistics the YADE dump, the LIGGGHTS importer and
`tdem info` share: closed forms of the domain, the solid fraction with wall caps, the wall
pressure and the Hertz check; the importer and `tdem info` agree on the same file."""
import math
from pathlib import Path

import numpy as np
import pytest

from thermal_kernel import packing_stats as ps
from thermal_kernel.contact_check import effective_modulus, hertz_force
from thermal_kernel.packing import read_packing

DATA = Path(__file__).resolve().parent / "data"


def test_domain_between_the_walls_and_the_bounding_box_elsewhere():
    position = np.array([[0.0, 0.0, 1.0], [3.0, 1.0, 2.0]])
    radius = np.array([1.0, 0.5])
    lo, hi, inferred = ps.domain_box(position, radius, [("zmin", 2, "min", 0.2),
                                                        ("zmin_2", 2, "min", 0.4),
                                                        ("plate", 2, "max", 2.4)])
    assert lo.tolist() == [-1.0, -1.0, 0.4] and hi.tolist() == [3.5, 1.5, 2.4]
    assert inferred == "domain: x, y from the spheres' bounding box (no wall there)"
    _, hi, inferred = ps.domain_box(position, radius, [("zmin", 2, "min", 0.0)])
    assert hi[2] == 2.5 and inferred.endswith("x, y, z (max side) from the spheres' bounding "
                                              "box (no wall there)")
    lo, hi, inferred = ps.domain_box(position, radius, [], (True, True, True), np.zeros(3),
                                     np.full(3, 4.0))
    assert lo.tolist() == [0, 0, 0] and hi.tolist() == [4, 4, 4] and inferred is None


def test_solid_fraction_less_the_caps_beyond_the_walls():
    """One sphere of radius 1 in a box of volume 8: pi/6; a hemisphere cut off by a wall through
    its centre (cap height = radius: 2/3 pi r^3) halves it; a gap (overlap < 0) cuts nothing."""
    r = np.array([1.0])
    assert ps.solid_fraction(r, -np.ones(3), np.ones(3)) == pytest.approx(math.pi / 6)
    assert ps.solid_fraction(r, -np.ones(3), np.ones(3), [1.0], [1.0]) == pytest.approx(
        math.pi / 12)
    assert ps.solid_fraction(r, -np.ones(3), np.ones(3), [1.0], [-0.1]) == pytest.approx(
        math.pi / 6)


def test_wall_pressure_plate_else_mean_else_none():
    lo, hi = np.zeros(3), np.array([2.0, 1.0, 4.0])
    walls = [("zmin", 2), ("plate", 2), ("xmin", 0), ("cylinder", None)]
    index = np.array([0, 1, 1, 2, 3])
    force = np.array([4.0, 1.0, 3.0, 8.0, 100.0])
    p, how = ps.wall_pressure(walls, index, force, lo, hi)
    assert p == 2.0 and how.startswith("the plate's")            # (1 + 3) N over 2 x 1 m^2
    p, how = ps.wall_pressure([("zmin", 2), ("top", 2), ("xmin", 0), ("c", None)], index, force,
                              lo, hi)
    assert p == pytest.approx((2.0 + 2.0 + 2.0) / 3) and how.startswith("mean over 3 axis-")
    p, how = ps.wall_pressure([("c", None)], np.zeros(1, int), np.ones(1), lo, hi)
    assert math.isnan(p) and how is None


def test_hertz_check_reads_the_modulus_the_forces_were_made_with():
    rng = np.random.default_rng(3)
    r_i, r_j = rng.uniform(1e-3, 2e-3, (2, 200))
    delta = rng.uniform(1e-7, 1e-5, 200)
    r_star = r_i * r_j / (r_i + r_j)
    made = hertz_force(r_star, delta, effective_modulus(0.5 * 70e9, 0.3))
    check = ps.hertz_check(made, r_i, r_j, delta, 70e9, 0.3, "hertz")
    assert check["force_law_ratio_median"] == pytest.approx(0.5)
    assert check["force_law_contacts"] == 200
    same = ps.hertz_check(hertz_force(r_star, delta, effective_modulus(70e9, 0.3)), r_i, r_j,
                          delta, 70e9, 0.3, "hertz")
    assert same["force_law_mismatch_max"] < 1e-12


def test_info_rederives_a_walled_box_and_leaves_a_cylinder():
    box = read_packing(DATA / "dense_box.h5")
    again = ps.recheck(box)
    assert again["solid_fraction"] == pytest.approx(box.attrs["solid_fraction"], rel=1e-6)
    assert again["pressure_from"].startswith("mean over 6 axis-normal walls")
    assert ps.recheck(read_packing(DATA / "dense_cylinder.h5")) is None
    cell = ps.recheck(read_packing(DATA / "dense_periodic.h5"))
    assert "wall pressure none" in ps.describe_recheck(cell)


def test_the_liggghts_importer_and_info_give_the_same_numbers(tmp_path):
    """A LIGGGHTS import of the committed box's dumps stores phi and the wall pressure that
    `tdem info` re-derives from the file (one module: equal, not close)."""
    from test_round3_packing import write_dumps

    from tdem.liggghts import import_liggghts
    paths, walls, p = write_dumps(tmp_path / "dumps")
    out = tmp_path / "box.h5"
    for spec in (walls, walls.replace("zmax", "plate:zmax")):
        import_liggghts(*paths, out, walls=spec, young=float(p.attrs["young_pa"]),
                        poisson=float(p.attrs["poisson"]), density=7800.0)
        q = read_packing(out)
        again = ps.recheck(q)
        assert again["solid_fraction"] == q.attrs["solid_fraction"]
        assert again["pressure_pa"] == q.attrs["pressure_pa"]
        assert again["pressure_from"] in q.attrs["inferred"]
