"""ETC of a composite against contrast and volume fraction (002 sec. 4-5) on the committed YADE
dense box (400 spheres, law haddad): exact properties of the network, and the command.

Asserted, each exact for any conductance network (so any deviation is a bug, not a tolerance):
- homogeneity: every particle in phase 1 at contrast c gives k_eff = c k_m (to 1e-9);
- Rayleigh monotonicity: growing the centred inclusion (nested particle sets) raises k_eff when
  c > 1 and lowers it when c < 1; and min(1, c) <= k_eff / k_m <= max(1, c);
- first order in (c - 1) (Thomson's principle): d(k_eff/k_m)/dc at c = 1 equals the share of the
  homogeneous dissipation sum H dT^2 carried by the inclusion's contacts, an interface contact
  counting 1/2 (the derivative of the harmonic mean 2c/(1+c) at c = 1), checked by a centred
  difference to 1e-6;
- the dispersion's inclusions do not overlap and the same seed gives the same phases;
- `tdem etc` writes etc.csv / etc.png and an impossible volume fraction is a one-line error.
"""
import csv
import dataclasses
from pathlib import Path

import numpy as np
import pytest

from tdem.cli import main
from tdem_post.etc_sweep import (composite_conductivity, dispersion_phase,
                                 single_inclusion_phase)
from thermal_kernel.boundaries import TemperatureBoundary
from thermal_kernel.laws import LAWS
from thermal_kernel.network import assemble
from thermal_kernel.packing import read_packing
from thermal_kernel.problem import build_problem
from thermal_kernel.scene import SolverConfig, load_scene
from thermal_kernel.solvers.steady import solve_steady

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "runs" / "dense_box.toml"
DUMP = ROOT / "tests" / "data" / "dense_box.h5"


@pytest.fixture(scope="module")
def setup():
    return load_scene(SCENE, known_laws=LAWS), read_packing(DUMP)


def test_all_inclusion_scales_by_the_contrast(setup):
    scene, packing = setup
    zero = np.zeros(packing.n_particles, np.int32)
    k_m = composite_conductivity(scene, packing, zero, 1.0)
    for c in (0.01, 7.7, 100.0):
        assert composite_conductivity(scene, packing, zero + 1, c) == pytest.approx(c * k_m,
                                                                                  rel=1e-9)


def test_rayleigh_monotonicity_and_bounds(setup):
    scene, packing = setup
    k_m = composite_conductivity(scene, packing, np.zeros(packing.n_particles, np.int32), 1.0)
    fractions = (0.05, 0.1, 0.2, 0.3, 0.4)
    phases = [single_inclusion_phase(packing, f) for f in fractions]
    for a, b in zip(phases, phases[1:]):
        assert np.all(b >= a) and b.sum() > a.sum()          # nested, strictly growing
    for c in (0.1, 10.0):
        ratio = [composite_conductivity(scene, packing, p, c) / k_m for p in phases]
        assert all(min(1, c) <= r <= max(1, c) for r in ratio)
        steps = np.diff(ratio)
        assert np.all(steps > 0) if c > 1 else np.all(steps < 0)


def test_first_order_in_the_contrast_is_the_dissipation_share(setup):
    scene, packing = setup
    phase = single_inclusion_phase(packing, 0.2)
    k_m = composite_conductivity(scene, packing, np.zeros(packing.n_particles, np.int32), 1.0)
    eps = 1e-4
    slope = (composite_conductivity(scene, packing, phase, 1 + eps)
             - composite_conductivity(scene, packing, phase, 1 - eps)) / (2 * eps * k_m)
    # the homogeneous flux test's contact dissipation
    test = dataclasses.replace(scene, boundaries=(
        TemperatureBoundary(name="hot", on="xmin", value=1.0),
        TemperatureBoundary(name="cold", on="xmax", value=0.0)),
        solver=SolverConfig(method="steady"))
    problem, _ = build_problem(test, packing)
    t = solve_steady(assemble(problem), np.full(packing.n_particles, 0.5)).temperature_k[-1]
    i, j = problem.pair.T
    dissipation = problem.conductance_w_k * (t[i] - t[j]) ** 2
    share = (phase[i] + phase[j]) / 2.0
    assert slope == pytest.approx(float((share * dissipation).sum() / dissipation.sum()),
                                  rel=1e-6)


def test_dispersion_does_not_overlap_and_is_seeded(setup):
    _, packing = setup
    length = float(np.min(packing.domain_hi - packing.domain_lo))
    a = dispersion_phase(packing, 0.2, length / 6, seed=3)
    b = dispersion_phase(packing, 0.2, length / 6, seed=3)
    c = dispersion_phase(packing, 0.2, length / 6, seed=4)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert 0 < a.sum() < packing.n_particles


# slow: `tdem etc`: a sweep of whole runs;
# over ~1.3 s on the shared 2-core machine, warm numba cache (--durations, 2026-12-01)
@pytest.mark.slow
def test_etc_command(tmp_path, capsys):
    out = tmp_path / "etc"
    assert main(["etc", str(SCENE), "--packing", str(DUMP), "--out", str(out),
                 "--contrasts", "0.1,10", "--fractions", "0.1,0.2"]) == 0
    rows = list(csv.DictReader(open(out / "etc.csv")))
    assert [r["case"] for r in rows] == ["single"] * 2 + ["dispersion"] * 2
    for r in rows:
        k, low, high = float(r["k_over_km"]), float(r["hs_lower"]), float(r["hs_upper"])
        assert low <= float(r["maxwell"]) <= high
        assert (k > 1) == (float(r["contrast"]) > 1)
    assert (out / "etc.png").stat().st_size > 10_000
    assert "k_m (single phase)" in capsys.readouterr().out
    assert main(["etc", str(SCENE), "--packing", str(DUMP), "--out", str(tmp_path / "bad"),
                 "--fractions", "0.6"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "fractions" in err and "Traceback" not in err
    assert not (tmp_path / "bad" / "etc.csv").exists()
