"""The scene's [neighbours] criterion (issue 23) and the haddad law's mean_radius.

- The filter keeps exactly the pairs with centre distance < (1 + gap)(r_i + r_j): checked
  against a brute-force search over every pair of particles (minimum image on periodic axes) of
  the committed dumps, which hold every pair within their gap_tolerance 0.1.
- ``target_z_with_gaps``: the chosen gap gives the target bulk Z to within one pair's worth
  (2 / n_bulk) above it; bulk Z never falls as the gap grows, and the chosen gap grows with the
  target; a target above what the dump holds, a gap beyond its gap_tolerance, a target below
  the touching contacts alone are each refused in one line naming the file and the key.
- R_m arithmetic / geometric / harmonic against conductances computed by hand.
- On a filtered network the steady flux test balances and a transient run keeps the maximum
  principle and the energy ledger; thermal.h5 records the gap used and the bulk Z reached.
"""
import dataclasses
import itertools
import json
import math
from pathlib import Path

import h5py
import numpy as np
import pytest

from thermal_kernel.calibrate import calibrate_ct
from thermal_kernel.laws import LAWS
from thermal_kernel.laws.base import ContactInput
from thermal_kernel.laws.haddad import haddad_conductance, mean_radius
from thermal_kernel.neighbours import (bulk_coordination, bulk_particles, choose_neighbours,
                                       distance_ratio)
from thermal_kernel.network import assemble
from thermal_kernel.output import read_thermal
from thermal_kernel.packing import read_packing
from thermal_kernel.problem import build_problem
from thermal_kernel.run import run_scene
from thermal_kernel.scene import NeighbourCriterion, SceneError, load_scene

DATA = Path(__file__).resolve().parent / "data"
DUMPS = ("dense_periodic", "dense_box", "dense_cylinder", "dense_sphere")
SCENE = '''packing = "{packing}"
law = "haddad"
[law_params]
ct = 0.806
{params}
{neighbours}
[material]
conductivity = 33.0
density = 7800.0
heat_capacity = 460.0
[initial]
temperature = 300.0
{boundaries}
[solver]
{solver}
'''
FACES = '''[[boundary]]
kind = "temperature"
on = "xmin"
value = 310.0
[[boundary]]
kind = "temperature"
on = "xmax"
value = 300.0
'''


def scene(tmp_path, dump, neighbours="", params="", boundaries="", solver='method = "steady"',
          name="scene.toml"):
    path = tmp_path / name
    path.write_text(SCENE.format(packing=DATA / f"{dump}.h5", params=params,
                                 neighbours=neighbours, boundaries=boundaries, solver=solver))
    return load_scene(path, known_laws=LAWS)


def with_criterion(sc, **kw):
    return dataclasses.replace(sc, neighbours=NeighbourCriterion(**kw))


def brute_force_pairs(packing, gap):
    """Every pair i < j with minimum-image centre distance < (1 + gap)(r_i + r_j)."""
    p, r = packing.position, packing.radius
    ext = packing.domain_hi - packing.domain_lo
    d = p[None, :, :] - p[:, None, :]
    for k in np.flatnonzero(packing.periodic):
        d[..., k] -= ext[k] * np.round(d[..., k] / ext[k])
    dist = np.linalg.norm(d, axis=2)
    within = dist < (1 + gap) * (r[:, None] + r[None, :])
    i, j = np.nonzero(np.triu(within, 1))
    return set(zip(i.tolist(), j.tolist()))


@pytest.mark.parametrize("dump", DUMPS)
@pytest.mark.parametrize("gap", [0.0, 0.02, 0.041, 0.07, 0.1])
def test_filter_keeps_exactly_the_pairs_within_the_gap(tmp_path, dump, gap):
    packing = read_packing(DATA / f"{dump}.h5")
    sc = with_criterion(scene(tmp_path, dump), gap=gap, bulk_margin_diameters=0.5)
    choice = choose_neighbours(sc, packing)
    kept = {tuple(map(int, row)) for row in packing.pair[choice.keep]}
    assert kept == brute_force_pairs(packing, gap)
    assert choice.n_kept == len(kept) and choice.gap == gap
    # the rows left out get H = 0 and no other row does; the law's neighbour counts are the kept
    problem, info = build_problem(sc, packing)
    assert info["neighbours"] is choice or info["neighbours"].n_kept == choice.n_kept
    np.testing.assert_array_equal(problem.conductance_w_k > 0, choice.keep)
    assert assemble(problem).n_active_contacts == len(kept)


@pytest.mark.parametrize("dump,margin", [("dense_periodic", 2.0), ("dense_box", 1.0),
                                         ("dense_cylinder", 0.5), ("dense_sphere", 1.0)])
@pytest.mark.parametrize("target", [5.9, 6.5, 7.0, 7.4])
def test_chosen_gap_reaches_the_target_within_one_pair(tmp_path, dump, margin, target):
    packing = read_packing(DATA / f"{dump}.h5")
    sc = with_criterion(scene(tmp_path, dump), target_z_with_gaps=target,
                        bulk_margin_diameters=margin)
    choice = choose_neighbours(sc, packing)
    one_pair = 2.0 / choice.n_bulk
    assert target <= choice.bulk_z + 1e-12 < target + one_pair
    # the same Z recomputed from scratch, and the chosen gap given back keeps the same pairs
    bulk = bulk_particles(packing, margin)
    assert bulk.sum() == choice.n_bulk
    assert bulk_coordination(packing, bulk, distance_ratio(packing) < 1 + choice.gap) \
        == choice.bulk_z
    again = choose_neighbours(with_criterion(sc, gap=choice.gap, bulk_margin_diameters=margin),
                              packing)
    np.testing.assert_array_equal(again.keep, choice.keep)
    # one pair fewer (the last one kept) falls below the target
    ratio = distance_ratio(packing)
    below = ratio < ratio[choice.keep].max()
    assert bulk_coordination(packing, bulk, below) < target


def test_periodic_cell_is_all_bulk(tmp_path):
    packing = read_packing(DATA / "dense_periodic.h5")
    assert bulk_particles(packing, 5.0).all()
    box = read_packing(DATA / "dense_box.h5")
    assert 0 < bulk_particles(box, 1.0).sum() < bulk_particles(box, 0.5).sum() < box.n_particles


@pytest.mark.parametrize("dump", ["dense_periodic", "dense_box"])
def test_bulk_z_monotone_in_gap_and_gap_in_target(tmp_path, dump):
    packing = read_packing(DATA / f"{dump}.h5")
    sc = scene(tmp_path, dump)
    zs = [choose_neighbours(with_criterion(sc, gap=g, bulk_margin_diameters=1.0), packing).bulk_z
          for g in np.linspace(0.0, 0.1, 41)]
    assert all(b >= a for a, b in itertools.pairwise(zs))
    assert zs[-1] > zs[0] + 1.0                 # the gaps do matter
    gaps = [choose_neighbours(with_criterion(sc, target_z_with_gaps=t,
                                             bulk_margin_diameters=1.0), packing).gap
            for t in np.linspace(6.5, 8.0, 16)]
    assert all(b >= a for a, b in itertools.pairwise(gaps))


def test_target_above_the_dump_is_refused_in_one_line(tmp_path):
    sc = scene(tmp_path, "dense_periodic", neighbours="[neighbours]\ntarget_z_with_gaps = 9.5")
    packing = read_packing(DATA / "dense_periodic.h5")
    with pytest.raises(SceneError) as e:
        build_problem(sc, packing)
    msg = str(e.value)
    assert "\n" not in msg
    assert msg.startswith(f"{sc.path}: neighbours.target_z_with_gaps: 9.5 is above the bulk Z")
    assert str(packing.path) in msg and "gap_tolerance 0.1" in msg
    # the most it can give is accepted: every row kept
    z_max = bulk_coordination(packing, np.ones(packing.n_particles, bool))
    choice = choose_neighbours(with_criterion(sc, target_z_with_gaps=z_max), packing)
    assert choice.keep.all()


def test_gap_beyond_tolerance_and_target_below_touching_are_refused(tmp_path):
    packing = read_packing(DATA / "dense_box.h5")
    sc = scene(tmp_path, "dense_box")
    with pytest.raises(SceneError, match=r"neighbours\.gap: 0\.2 is beyond the gap_tolerance "
                                         r"0\.1 .*dense_box\.h5"):
        choose_neighbours(with_criterion(sc, gap=0.2), packing)
    with pytest.raises(SceneError, match=r"neighbours\.target_z_with_gaps: 2 is below the bulk Z"):
        choose_neighbours(with_criterion(sc, target_z_with_gaps=2.0,
                                         bulk_margin_diameters=1.0), packing)
    with pytest.raises(SceneError, match=r"neighbours\.bulk_margin_diameters: no particle"):
        choose_neighbours(with_criterion(sc, target_z_with_gaps=7.5,
                                         bulk_margin_diameters=50.0), packing)


@pytest.mark.parametrize("table,message", [
    ("[neighbours]\ngap = 0.04\ntarget_z_with_gaps = 7.5", "neighbours: expected exactly one"),
    ("[neighbours]\nbulk_margin_diameters = 2", "neighbours: expected exactly one"),
    ("[neighbours]\ngap = -0.01", "neighbours.gap: expected a number >= 0"),
    ("[neighbours]\ntarget_z_with_gaps = 0",
     "neighbours.target_z_with_gaps: expected a number > 0"),
    ("[neighbours]\ngap = 0.04\nmargin = 2", "neighbours.margin: unknown key"),
])
def test_bad_neighbours_tables(tmp_path, table, message):
    with pytest.raises(SceneError, match=message) as e:
        scene(tmp_path, "dense_box", neighbours=table)
    assert "\n" not in str(e.value) and str(tmp_path / "scene.toml") in str(e.value)


def test_mean_radius_against_hand_computed_conductances():
    r_i, r_j, d = np.array([1e-3, 1e-3]), np.array([2e-3, 1e-3]), np.array([3.1e-3, 2e-3])
    lam, ct = 33.0, 0.8
    contacts = ContactInput(radius_i_m=r_i, radius_j_m=r_j, distance_m=d, overlap_m=r_i + r_j - d,
                            normal_force_n=np.zeros(2), conductivity_i=np.full(2, lam),
                            conductivity_j=np.full(2, lam), neighbours_i=np.ones(2),
                            neighbours_j=np.ones(2), young_pa=2e11, poisson=0.3)
    hand = {"arithmetic": 1.5e-3, "geometric": math.sqrt(2) * 1e-3, "harmonic": 4e-3 / 3}
    for rule, rm in hand.items():
        h = haddad_conductance(contacts, dict(ct=ct, interface_mean="harmonic", mean_radius=rule))
        assert h[0] == pytest.approx(lam * ct * math.pi * rm ** 2 / 3.1e-3, rel=1e-14)
        assert h[1] == pytest.approx(lam * ct * math.pi * 1e-6 / 2e-3, rel=1e-14)   # equal radii
    assert mean_radius(1.0, 4.0, "geometric") == 2.0
    with pytest.raises(ValueError, match="mean_radius"):
        mean_radius(1.0, 2.0, "quadratic")


def test_mean_radius_in_a_scene(tmp_path):
    packing = read_packing(DATA / "dense_periodic.h5")
    ri, rj = packing.radius[packing.pair[:, 0]], packing.radius[packing.pair[:, 1]]
    base, _ = build_problem(scene(tmp_path, "dense_periodic"), packing)
    for rule, rm in (("geometric", np.sqrt(ri * rj)), ("harmonic", 2 * ri * rj / (ri + rj))):
        sc = scene(tmp_path, "dense_periodic", params=f'mean_radius = "{rule}"')
        problem, info = build_problem(sc, packing)
        assert info["law_params"]["mean_radius"] == rule
        np.testing.assert_allclose(problem.conductance_w_k / base.conductance_w_k,
                                   (rm / (0.5 * (ri + rj))) ** 2, rtol=1e-13)
        assert np.all(problem.conductance_w_k <= base.conductance_w_k * (1 + 1e-15))
    with pytest.raises(SceneError, match=r"law_params\.mean_radius: expected one of arithmetic, "
                                         r"geometric, harmonic"):
        scene(tmp_path, "dense_periodic", params='mean_radius = "quadratic"')


def test_calibrate_honours_criterion_and_mean_radius(tmp_path):
    packing = read_packing(DATA / "dense_box.h5")
    table = "[neighbours]\ntarget_z_with_gaps = 7.5\nbulk_margin_diameters = 1.0"
    every = calibrate_ct(scene(tmp_path, "dense_box"), packing, "x")
    cut = calibrate_ct(scene(tmp_path, "dense_box", neighbours=table), packing, "x")
    assert every.neighbours is None and cut.neighbours.bulk_z >= 7.5
    assert cut.ct > every.ct * 1.05            # fewer links: a larger C_t
    same = calibrate_ct(scene(tmp_path, "dense_box", neighbours=f"[neighbours]\ngap = "
                              f"{cut.neighbours.gap!r}"), packing, "x")
    assert same.ct == pytest.approx(cut.ct, rel=1e-12)
    harm = calibrate_ct(scene(tmp_path, "dense_box", neighbours=table,
                              params='mean_radius = "harmonic"'), packing, "x")
    assert harm.ct > cut.ct
    assert cut.balance < 1e-9 and harm.balance < 1e-9       # heat in = heat out, filtered


def test_transient_run_on_a_filtered_network(tmp_path):
    table = "[neighbours]\ntarget_z_with_gaps = 7.0\nbulk_margin_diameters = 1.0"
    sc = scene(tmp_path, "dense_box", neighbours=table, boundaries=FACES,
               solver='method = "explicit"\nend_time = 0.02\noutput_times = [0.005, 0.02]')
    out = run_scene(sc, quiet=True)
    run = read_thermal(out.output)
    t = np.asarray(run.temperature)
    assert t.min() >= 300.0 - 1e-9 and t.max() <= 310.0 + 1e-9       # maximum principle
    assert "max_principle" not in run.flags and "energy_ledger" not in run.flags
    with h5py.File(out.output, "r") as f:
        attrs = dict(f.attrs)
    assert float(attrs["ledger_residual_relative"]) < 1e-9
    rec = json.loads(attrs["neighbours"])
    assert rec["mode"] == "target_z_with_gaps" and rec["target_z_with_gaps"] == 7.0
    assert 7.0 <= rec["bulk_z"] < 7.0 + 2.0 / rec["n_bulk"]
    assert rec["n_kept"] == out.network.n_active_contacts < rec["n_dumped"]
    kept = run.scene.neighbours                            # the resolved scene keeps it
    assert math.isnan(kept.gap) and kept.target_z_with_gaps == 7.0
    assert kept.bulk_margin_diameters == 1.0
    plain = run_scene(dataclasses.replace(sc, neighbours=None,
                                          output=tmp_path / "plain" / "thermal.h5"), quiet=True)
    with h5py.File(plain.output, "r") as f:
        assert json.loads(f.attrs["neighbours"]) is None
    assert read_thermal(plain.output).scene.neighbours is None
