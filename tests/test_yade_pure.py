"""The YADE side without YADE: the pure modules of yade_scripts/ (placement, dense_geometry,
bed_geometry) on the project's Python, and the generator scripts importable without running.

Exact properties (any failure is a bug, not a tolerance):
- random sequential addition: no two spheres closer than r_i + r_j + gap (minimum image in a
  periodic cell), every sphere inside its domain; the cell-grid search takes exactly the
  decisions of a test against every placed sphere (same candidate stream, same centres);
- the equal-area prism: polygon area = pi R^2 to 1e-12, vertex^2 = apothem^2 + half side^2;
- the simulated wall modulus makes YADE's wall contact (R* = r/2) Hertz with R* = r: the two
  Hertz coefficients agree to 1e-12;
- the contacts of a dump from interaction records: overlaps, forces = kno delta^1.5,
  branch = x_j - x_i, rows for walls, as computed by hand for a 3-sphere scene.
Statistical (with the reason for the tolerance): the phase fraction of a random dispersion on a
fine lattice of particles is its target to 0.03 (inclusions of 2.5 lattice spacings: the
centre-in-sphere assignment errs by the particles cut by each surface).
"""
import importlib
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from tdem.yade import scripts_module

placement = scripts_module("placement")
dense = scripts_module("dense_geometry")
bed = scripts_module("bed_geometry")
ROOT = Path(__file__).resolve().parent.parent


def min_image(d, cell):
    return d - np.round(d / cell) * cell if cell is not None else d


def assert_no_overlap(centres, radii, gap=0.0, cell=None):
    d = min_image(centres[None, :, :] - centres[:, None, :], cell)
    dist = np.linalg.norm(d, axis=2)
    limit = radii[:, None] + radii[None, :] + gap
    np.fill_diagonal(dist, np.inf)
    assert np.all(dist > limit)


def uniform_candidates(rng, size):
    def candidates(k, r):
        for _ in range(2000):
            yield tuple(rng.random(3) * size)
    return candidates


def all_pairs_addition(radii, candidates, inside, gap, cell):
    """The reference: each candidate tested against every sphere placed before."""
    placed = []
    for k, r in enumerate(radii):
        for c in candidates(k, r):
            c = np.asarray(c, float)
            if not inside(*c, r):
                continue
            ok = True
            for q, rq in placed:
                d = min_image(np.asarray(q) - c, cell)
                if d @ d - (rq + r + gap) ** 2 <= 0:
                    ok = False
                    break
            if ok:
                placed.append((c, r))
                break
        else:
            break
    return np.array([c for c, _ in placed]).reshape(-1, 3)


@pytest.mark.parametrize("periodic", [False, True])
def test_grid_search_takes_the_decisions_of_all_pairs(periodic):
    size = np.array([10.0, 8.0, 6.0])
    radii = np.sort(np.random.default_rng(1).uniform(0.3, 0.6, 150))[::-1]
    cell = size if periodic else None

    def inside(x, y, z, r):
        return periodic or (r <= x <= size[0] - r and r <= y <= size[1] - r
                            and r <= z <= size[2] - r)

    got = placement.random_sequential_addition(
        radii, uniform_candidates(np.random.default_rng(2), size), inside, gap=0.05, cell=cell)
    ref = all_pairs_addition(radii, uniform_candidates(np.random.default_rng(2), size), inside,
                             0.05, cell)
    assert len(got) == len(ref) == len(radii)
    assert np.array_equal(got, ref)
    assert_no_overlap(got, radii, 0.05, cell)


def test_placement_stops_when_the_candidates_run_out():
    size = np.array([3.0, 3.0, 3.0])
    radii = [1.0] * 10                      # at most a few unit spheres fit in a 3-cube
    got = placement.random_sequential_addition(
        radii, uniform_candidates(np.random.default_rng(0), size),
        lambda x, y, z, r: all(r <= v <= 3.0 - r for v in (x, y, z)))
    assert 1 <= len(got) < 10
    assert_no_overlap(got, np.ones(len(got)))


def test_equal_spheres_for_volume():
    assert placement.equal_spheres_for_volume(0.0, 1.0) == 0
    assert placement.equal_spheres_for_volume(3.0, 1.0) == 3
    assert placement.equal_spheres_for_volume(3.5, 1.0) == 4


DENSE = dict(radius_mean_m=1e-3, radius_distribution="gaussian", radius_spread=0.2,
             radius_sigma_over_mean=0.3, radius_truncation_sigmas=2.0, aspect=[1.0, 1.0, 1.0],
             seed=3, method="direct", cell_particles=10000, inclusions=[],
             inclusion_volume_fraction=0.0, inclusion_radius_over_mean=3.0, inclusion_phase=1,
             wall_segments=48, sphere_facet_level=3)


@pytest.mark.parametrize("shape, aspect", [("periodic", [1, 1, 1]), ("box", [1, 2, 0.7]),
                                           ("cylinder", [1, 1, 1.5]), ("sphere", [1, 1, 1])])
def test_dense_cloud_is_inside_and_overlap_free(shape, aspect):
    p = dict(DENSE, shape=shape, aspect=aspect, n_particles=400)
    centres, small, box, radii = dense.make_cloud(p)
    assert len(centres) == 400 and np.all(np.diff(radii) <= 0)
    assert np.allclose(small / radii, (dense.CLOUD_SOLID_FRACTION
                                       / dense.EXPECTED_SOLID_FRACTION[shape]) ** (1 / 3))
    assert_no_overlap(centres, small, 0.0, box.size if shape == "periodic" else None)
    assert np.all(box.inside(centres, small))
    if shape != "periodic":                     # whole spheres inside the walls
        assert np.all(box.inside(centres, small))
        assert not np.all(box.inside(centres, small * 1.6))
    else:
        assert np.all((centres >= 0) & (centres <= box.size))
    # the domain holds the drawn radii at the expected final solid fraction
    assert box.volume == pytest.approx(np.sum(4 / 3 * np.pi * radii ** 3)
                                       / dense.EXPECTED_SOLID_FRACTION[shape], rel=1e-12)
    again = dense.make_cloud(p)[0]
    assert np.array_equal(again, centres)       # a seed gives one cloud


def test_container_volume_is_exact():
    for shape, aspect, volume in (("box", [1, 2, 3], lambda c: np.prod(c.size)),
                                  ("cylinder", [1, 1, 2],
                                   lambda c: math.pi * c.radius ** 2 * c.size[2]),
                                  ("sphere", [1, 1, 1], lambda c: 4 / 3 * math.pi * c.radius ** 3)):
        c = dense.Container(shape, 2.5e-6, aspect)
        assert volume(c) == pytest.approx(2.5e-6, rel=1e-12)
    c = dense.Container("cylinder", 1.0, [1, 1, 3])
    assert c.size[2] / (2 * c.radius) == pytest.approx(3.0, rel=1e-12)


def lattice(n_side, spacing):
    x = (np.indices((n_side,) * 3).reshape(3, -1).T + 0.5) * spacing
    return x, np.full(len(x), 0.45 * spacing)


@pytest.mark.parametrize("periodic", [False, True])
def test_dispersion_phase_fraction_and_inclusions(periodic):
    position, radius = lattice(24, 1e-3)
    size = 24e-3
    box = dense.Container("periodic" if periodic else "box", size ** 3, [1, 1, 1])
    p = dict(DENSE, inclusion_volume_fraction=0.2, inclusion_radius_over_mean=5.5,
             inclusion_phase=3)
    centres, r_inc = dense.dispersion_centres(p, float(radius.mean()), box, periodic)
    assert r_inc == pytest.approx(5.5 * 0.45e-3)
    assert len(centres) * 4 / 3 * math.pi * r_inc ** 3 >= 0.2 * size ** 3
    assert_no_overlap(centres, np.full(len(centres), r_inc), 0.0, box.size if periodic else None)
    if not periodic:
        assert np.all(box.inside(centres, r_inc))
    phase, n = dense.assign_phases(p, position, radius, box, periodic)
    assert n == len(centres) and set(np.unique(phase)) == {0, 3}
    volume = radius ** 3
    assert volume[phase == 3].sum() / volume.sum() == pytest.approx(0.2, abs=0.03)
    again, _ = dense.assign_phases(p, position, radius, box, periodic)
    assert np.array_equal(again, phase)


def test_listed_inclusions_take_the_particles_inside():
    position, radius = lattice(10, 1e-3)
    box = dense.Container("box", 1e-6, [1, 1, 1])
    p = dict(DENSE, inclusions=[dict(centre=[0.5, 0.5, 0.5], radius=0.25, phase=2),
                                dict(centre=[0.1, 0.1, 0.1], radius=0.1)])
    phase, n = dense.assign_phases(p, position, radius, box, False)
    inside = np.linalg.norm(position - 5e-3, axis=1) <= 2.5e-3
    corner = np.linalg.norm(position - 1e-3, axis=1) <= 1e-3
    assert n == 0 and inside.sum() > 20 and corner.sum() > 0
    assert np.all(phase[inside] == 2) and np.all(phase[corner] == 1)
    assert np.all(phase[~inside & ~corner] == 0)


def test_solid_fractions_of_a_lattice():
    position, radius = lattice(10, 1e-3)
    box = dense.Container("periodic", 1e-6, [1, 1, 1])
    phi, bulk = dense.solid_fractions(position, radius, box, True)
    assert phi == bulk == pytest.approx(1000 * 4 / 3 * math.pi * 0.45e-3 ** 3 / 1e-6, rel=1e-12)
    box = dense.Container("box", 1e-6, [1, 1, 1])
    radius = np.full(len(position), 0.5e-3)
    phi, bulk = dense.solid_fractions(position, radius, box, False)
    # the bulk box leaves out 2 mean diameters (2 mm) along each wall: 6 x 6 x 6 whole lattice
    # cells, the same fraction as the whole box
    assert phi == pytest.approx(math.pi / 6, rel=1e-12)
    assert bulk == pytest.approx(phi, rel=1e-12)


def test_relaxed_contacts_from_arrays():
    position = np.array([[0.0, 0, 0], [1.9, 0, 0], [0, 2.1, 0], [5, 5, 5]])
    radius = np.ones(4)
    force = {(0, 1): 7.0}
    pair, branch, overlap, f, contact_radius, untracked = dense.relaxed_contacts(
        position, radius, 0.1, None, force)
    assert pair.tolist() == [[0, 1], [0, 2]]
    np.testing.assert_allclose(overlap, [0.1, -0.1], atol=1e-15)
    np.testing.assert_array_equal(f, [7.0, 0.0])
    np.testing.assert_allclose(contact_radius, [math.sqrt(0.5 * 0.1), 0.0])
    assert untracked == 0
    *_, untracked = dense.relaxed_contacts(position, radius, 0.1, None, {})
    assert untracked == 1          # touching, but YADE had no force for it
    box = dense.Container("box", 1000.0, [1, 1, 1])
    walls = box.walls()
    pos = np.array([[0.9, 5, 5], [5, 5, 5], [5, 1.05, 5]])
    part, wall, over, wf = dense.relaxed_wall_contacts(box, walls, pos, np.ones(3), 0.1,
                                                       {(0, 0): (0.1, 3.0)})
    assert list(zip(part.tolist(), wall.tolist())) == [(0, 0), (2, 2)]
    np.testing.assert_allclose(over, [0.1, -0.05])
    np.testing.assert_array_equal(wf, [3.0, 0.0])


def test_stiffness_stages():
    p = dict(young_pa=2.1e11, softening_factor=1e3, confining_pressure_pa=1e5,
             stiffen_factor=10.0)
    assert dense.stiffness_stages(p) == pytest.approx([1e8, 1e9, 1e10, 1e11, 2.1e11])
    assert dense.stiffness_stages(dict(p, young_pa=5e7)) == [5e7]


@pytest.mark.parametrize("segments", [12, 48])
def test_prism_has_the_area_of_the_circle(segments):
    vertex, apothem, half = bed.prism(0.0305, segments)
    assert segments * apothem * half == pytest.approx(math.pi * 0.0305 ** 2, rel=1e-12)
    assert vertex ** 2 == pytest.approx(apothem ** 2 + half ** 2, rel=1e-12)
    assert apothem < 0.0305 < vertex


def test_bed_cloud_is_inside_and_overlap_free():
    vertex, apothem, half = bed.prism(0.009, 48)
    pos, radii, height = bed.random_cloud(300, 0.001, 0.05, apothem, 0.3, 7)
    gap = 1e-3 * 0.001
    assert len(pos) == 300 and np.all(np.diff(pos[:, 2]) >= 0)     # sorted by height
    assert_no_overlap(pos, radii, gap)
    assert np.all(np.hypot(pos[:, 0], pos[:, 1]) + radii <= apothem)
    assert np.all(pos[:, 2] - radii >= 0) and np.all(pos[:, 2] + radii <= height)
    assert np.all(np.abs(radii / 0.001 - 1) <= 0.05)
    volume = 4 / 3 * math.pi * np.sum(radii ** 3)
    assert volume / (math.pi * apothem ** 2 * height) == pytest.approx(0.3, rel=1e-12)
    again = bed.random_cloud(300, 0.001, 0.05, apothem, 0.3, 7)
    assert np.array_equal(again[0], pos) and again[2] == height


def test_bed_cloud_grows_its_height_when_jammed():
    vertex, apothem, half = bed.prism(0.004, 12)
    pos, radii, height = bed.random_cloud(200, 0.001, 0.0, apothem, 0.35, 1)
    volume = 4 / 3 * math.pi * np.sum(radii ** 3)
    assert height >= volume / (0.35 * math.pi * apothem ** 2)
    assert_no_overlap(pos, radii, 1e-6)


def test_wall_modulus_makes_yade_wall_contacts_hertz_with_r():
    e, nu, ew, nuw = 5e10, 0.2, 7e10, 0.25
    e_sim = bed.wall_sim_modulus(e, nu, ew, nuw)
    star_sim = 1 / ((1 - nu ** 2) / e + (1 - nuw ** 2) / e_sim)
    star_real = 1 / ((1 - nu ** 2) / e + (1 - nuw ** 2) / ew)
    r = 2e-3
    assert star_sim * math.sqrt(r / 2) == pytest.approx(star_real * math.sqrt(r), rel=1e-12)
    assert bed.wall_sim_modulus(e, nu, 1e13, nuw) is None       # too stiff: no finite modulus


def test_damping_ratio():
    assert bed.damping_ratio(1.0) == 0.0
    log_e = math.log(0.5)
    assert bed.damping_ratio(0.5) == pytest.approx(
        math.sqrt(5 / 6) * -log_e / math.sqrt(log_e ** 2 + math.pi ** 2), rel=1e-15)
    assert bed.damping_ratio(0.1) > bed.damping_ratio(0.9) > 0


def test_dump_contacts_from_records():
    """Three spheres (0-1 overlapping, real; 1-2 overlapping, not yet real; 0-2 apart), a
    bottom plane (body 3), a plate (body 4) at z = 1.95 and a cylinder box (body 5)."""
    pos = np.array([[0.0, 0, 1], [1.9, 0, 1], [1.9, 1.95, 1.0]])
    radii = np.ones(3)
    e_pp, e_pw = bed.hertz_moduli(5e7, 5e10, 0.2, 5e10, 0.2)
    assert e_pp == pytest.approx(5e7 / (2 * (1 - 0.04)))
    k01 = 4 / 3 * e_pp * math.sqrt(0.5)
    records = [(0, 1, True, 0.09, k01), (2, 1, False, None, None), (0, 2, False, None, None),
               (3, 0, True, 0.0, 4 / 3 * e_pw), (4, 2, True, 0.05, 4 / 3 * e_pw),
               (0, 5, True, 0.02, 4 / 3 * e_pw), (1, 5, False, None, None)]
    c = bed.dump_contacts(records, pos, radii, {3: 0, 4: 1, 5: 2}, 1.95, e_pp, e_pw)
    assert c["pairs"].tolist() == [[0, 1], [1, 2]]
    np.testing.assert_allclose(c["overlaps"], [0.1, 0.05], rtol=1e-12)
    np.testing.assert_allclose(c["forces"], [k01 * 0.1 ** 1.5,
                                             4 / 3 * e_pp * math.sqrt(0.5) * 0.05 ** 1.5])
    np.testing.assert_array_equal(c["branch"], [pos[1] - pos[0], pos[2] - pos[1]])
    np.testing.assert_allclose(np.linalg.norm(c["branch"], axis=1), 2 - c["overlaps"])
    # bottom: r - z = 0 (no overlap, skipped); plate: r - (1.95 - 1.0) = 0.05; box: YADE's depth
    assert c["w_particle"].tolist() == [2, 0] and c["w_index"].tolist() == [1, 2]
    np.testing.assert_allclose(c["w_overlap"], [0.05, 0.02])
    np.testing.assert_allclose(c["w_force"], 4 / 3 * e_pw * np.array([0.05, 0.02]) ** 1.5)
    assert c["undetected"] == 1 and c["kno_mismatch"] < 1e-12
    bad = [(0, 1, True, 0.09, 2 * k01)]
    assert bed.dump_contacts(bad, pos, radii, {}, 1.95, e_pp, e_pw)["kno_mismatch"] \
        == pytest.approx(1.0)


@pytest.mark.parametrize("script", ["dense_packing", "compressed_bed"])
def test_scripts_import_without_yade_and_do_not_run(script, monkeypatch):
    """Importing a generator neither needs YADE nor runs it: YADE is imported by main()."""
    monkeypatch.syspath_prepend(str(ROOT))
    monkeypatch.setattr(sys, "argv", ["pytest"])       # main() would fail on these
    module = importlib.import_module(f"yade_scripts.{script}")
    assert callable(module.main) and callable(module.import_yade)
    assert "yade" not in sys.modules
    assert module.O is None


def test_facet_sag_is_the_cylinder_polygon_and_the_icospheres_inradius():
    """The cylinder's sag is the regular polygon's; the icosphere's at level 0 is the regular
    icosahedron's, 1 - inradius/circumradius = 1 - sqrt((5 + 2 sqrt 5) / 15) (closed form),
    and each split into four roughly quarters it (the edges halve). Every icosphere vertex is
    on the sphere, with 10 4^L + 2 vertices and 20 4^L triangles (Euler)."""
    from yade_scripts.dense_geometry import facet_sag, icosphere
    for n in (8, 16, 48, 96):
        apothem = math.cos(math.pi / n)        # polygon of n sides inscribed in the unit circle
        assert facet_sag("cylinder", 1.0, segments=n) == pytest.approx(1.0 - apothem, rel=1e-12)
    inradius = math.sqrt((5.0 + 2.0 * math.sqrt(5.0)) / 15.0)
    assert facet_sag("sphere", 1.0, level=0) == pytest.approx(1.0 - inradius, rel=1e-12)
    sags = [facet_sag("sphere", 2.0, level=level) / 2.0 for level in range(5)]
    for coarse, fine in zip(sags[1:], sags[2:]):
        assert 3.5 < coarse / fine < 4.5
    for level in range(4):
        v, f = icosphere(level)
        assert len(v) == 10 * 4 ** level + 2 and len(f) == 20 * 4 ** level
        assert np.allclose(np.linalg.norm(v, axis=1), 1.0, atol=1e-14)
        edges = {tuple(sorted(e)) for t in f for e in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))}
        assert len(edges) == 30 * 4 ** level        # closed surface: V - E + F = 2
    assert facet_sag("box", 1.0) == 0.0


def test_a_coarse_facet_container_is_refused_and_a_fine_one_accepted():
    """The facets must keep every cloud sphere's centre inside them: the check names the
    smallest wall_segments (cylinder) / sphere_facet_level (sphere) that does, which passes."""
    from yade_scripts import dense_geometry, dense_params
    p = {k: v["default"] for k, v in dense_params.PARAMS.items()}
    p.update(shape="sphere", n_particles=2000, sphere_facet_level=1)
    with pytest.raises(ValueError, match=r"^sphere_facet_level: .* expected at least 2, got 1"):
        dense_geometry.cloud_domain(p)
    dense_geometry.cloud_domain(dict(p, sphere_facet_level=2))
    dense_geometry.cloud_domain(dict(p, sphere_facet_level=3))        # the default: accepted
    c = dict(p, shape="cylinder", aspect=[1.0, 1.0, 4.0], n_particles=20000, wall_segments=8)
    with pytest.raises(ValueError, match=r"^wall_segments: .* expected at least (\d+), got 8"):
        dense_geometry.cloud_domain(c)
    try:
        dense_geometry.cloud_domain(c)
    except ValueError as e:
        need = int(str(e).split("expected at least ")[1].split(",")[0])
    dense_geometry.cloud_domain(dict(c, wall_segments=need))          # accepted
    with pytest.raises(ValueError):
        dense_geometry.cloud_domain(dict(c, wall_segments=need - 2))
