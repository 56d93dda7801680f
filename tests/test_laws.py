"""Conductance laws: one battery over every registered law (symmetry, sign, finiteness, no area
-> no heat where the law says so, scaling), one value per law computed here by hand from the
paper's formula, the 7-point stencil of Terreros on a simple-cubic lattice, Table 1 at its nodes,
and one step of YADE's ThermalEngine reproduced from hard-coded YADE output."""
import dataclasses
import math
import re
from pathlib import Path

import numpy as np
import pytest

from thermal_kernel.hand_inputs import POISSON, YOUNG_PA
from thermal_kernel.hand_inputs import capacity as _c
from thermal_kernel.hand_inputs import conductance as _h
from thermal_kernel.hand_inputs import hertz_radius_equal_spheres as _zeta
from thermal_kernel.hand_inputs import lattice_inputs as _lattice
from thermal_kernel.hand_inputs import one_contact as _one
from thermal_kernel.hand_inputs import wall_conductance as _g
from thermal_kernel.laws import LAWS, UnknownLawError, get_law
from thermal_kernel.laws.base import (LAW_KINDS, ContactInput, Law, ParticleInput,
                                      WallContactInput)
from thermal_kernel.laws.terreros import local_volume_fraction, transmission_surface_nd

# `make coverage` counts this module (marker kernel: its subject is thermal_kernel, and it is
# fast enough with NUMBA_DISABLE_JIT=1)
pytestmark = pytest.mark.kernel

# Which rows conduct is declared by each law (Law.kind, thermal_kernel/laws/base.py LAW_KINDS):
# "geometric" (every row of the dump, gaps included), "force" (no force -> H = 0) or "overlap"
# (no overlap -> H = 0, no force enters). The battery below checks each law's behaviour against
# its declaration, so a law declared wrongly fails.
# Hypothesis tools, not physical laws (law.diagnostic): the battery runs on them too, except the
# linear scaling with conductivity (a resistance used as a conductance scales as 1/k: tested).
DIAGNOSTIC = {name for name, law in LAWS.items() if law.diagnostic}

E, NU = YOUNG_PA, POISSON                  # the hand-computed values' material (003 Table 1)
E_STAR = E / (2 * (1 - NU ** 2))           # two bodies of one material


def _contacts(seed=0, m=40):
    """Random contacts: radii 0.8-1.2 mm, half of them overlapping with their Hertz force,
    the rest gaps (F = 0); conductivities 1-200 W/m/K; neighbour counts 0-25 (beyond Table 1
    on both sides)."""
    rng = np.random.default_rng(seed)
    r_i = rng.uniform(0.8e-3, 1.2e-3, m)
    r_j = rng.uniform(0.8e-3, 1.2e-3, m)
    overlap = np.where(np.arange(m) % 2 == 0, rng.uniform(1e-7, 2e-5, m),
                       -rng.uniform(1e-7, 5e-5, m))
    r_star = r_i * r_j / (r_i + r_j)
    force = np.where(overlap > 0, 4 / 3 * E_STAR * np.sqrt(r_star)
                     * np.clip(overlap, 0, None) ** 1.5, 0.0)
    return ContactInput(
        radius_i_m=r_i, radius_j_m=r_j, distance_m=r_i + r_j - overlap, overlap_m=overlap,
        normal_force_n=force, conductivity_i=rng.uniform(1, 200, m),
        conductivity_j=rng.uniform(1, 200, m), neighbours_i=rng.integers(0, 26, m),
        neighbours_j=rng.integers(0, 26, m), young_pa=E, poisson=NU)


def _swapped(c: ContactInput) -> ContactInput:
    return dataclasses.replace(
        c, radius_i_m=c.radius_j_m, radius_j_m=c.radius_i_m, conductivity_i=c.conductivity_j,
        conductivity_j=c.conductivity_i, neighbours_i=c.neighbours_j,
        neighbours_j=c.neighbours_i)


def _particles(seed=1, n=30):
    rng = np.random.default_rng(seed)
    return ParticleInput(
        radius_m=rng.uniform(0.8e-3, 1.2e-3, n), density=rng.uniform(1000, 8000, n),
        heat_capacity=rng.uniform(100, 1000, n), conductivity=rng.uniform(1, 200, n),
        neighbours=rng.integers(0, 26, n), solid_fraction=0.6)


def _walls(seed=2, k=20):
    rng = np.random.default_rng(seed)
    r = rng.uniform(0.8e-3, 1.2e-3, k)
    overlap = np.where(np.arange(k) % 2 == 0, rng.uniform(1e-7, 2e-5, k),
                       -rng.uniform(1e-7, 5e-5, k))
    force = np.where(overlap > 0, 4 / 3 * E_STAR * np.sqrt(r) * np.clip(overlap, 0, None) ** 1.5,
                     0.0)
    return WallContactInput(radius_m=r, overlap_m=overlap, normal_force_n=force,
                            conductivity_particle=rng.uniform(1, 200, k),
                            conductivity_wall=rng.uniform(1, 200, k), young_pa=E, poisson=NU)


# --- registry ---------------------------------------------------------------------------------

def test_every_declared_law_is_registered():
    import importlib
    import pkgutil

    import thermal_kernel.laws as package
    declared = {}
    for info in pkgutil.iter_modules(package.__path__):
        module = importlib.import_module(f"{package.__name__}.{info.name}")
        declared.update({id(v): v for v in vars(module).values() if isinstance(v, Law)})
    assert len(declared) >= 2 and {law.name for law in declared.values()} == set(LAWS)
    assert all(LAWS[law.name] is law for law in declared.values())


def test_every_law_is_classified_and_documented():
    kinds = {name: law.kind for name, law in LAWS.items()}
    assert set(kinds.values()) <= set(LAW_KINDS), kinds
    # the battery sees both sides: laws whose gaps conduct and laws whose gaps do not
    assert "geometric" in kinds.values() and set(kinds.values()) - {"geometric"}
    assert DIAGNOSTIC
    for name, law in LAWS.items():     # a diagnostic says so first, and only a diagnostic
        assert law.formula.startswith("DIAGNOSTIC, not a physical law") == (name in DIAGNOSTIC)
    for name, law in LAWS.items():
        assert law.name == name
        assert law.formula and "\n" not in law.formula
        assert law.reference and law.wall_conductance is not None
    # docs/laws.md's table gives each law the kind it declares (its last column)
    text = (Path(__file__).resolve().parents[1] / "docs" / "laws.md").read_text()
    documented = dict(re.findall(r"^\| `(\w+)` \|.*\| (\w+) \|$", text, re.M))
    assert documented == kinds


def test_unknown_law_lists_the_names():
    with pytest.raises(UnknownLawError) as err:
        get_law("nope")
    assert isinstance(err.value, KeyError)
    message = str(err.value)
    assert message.startswith("unknown law 'nope'")
    for name in LAWS:
        assert name in message


# --- battery over every law -------------------------------------------------------------------

@pytest.mark.parametrize("name", sorted(LAWS))
def test_conductance_is_symmetric_finite_and_nonnegative(name):
    c = _contacts()
    h = _h(name, c)
    assert h.shape == (c.distance_m.size,) and h.dtype == np.float64
    assert np.all(np.isfinite(h)) and np.all(h >= 0)
    np.testing.assert_allclose(_h(name, _swapped(c)), h, rtol=1e-14, atol=0)


@pytest.mark.parametrize("name", sorted(LAWS))
def test_no_contact_area_no_heat_where_the_law_says_so(name):
    """What the law declares (Law.kind) is what it does: on the gap rows (F = 0, overlap < 0)
    a force or overlap law gives H = 0 exactly, a geometric one H > 0, less the farther apart;
    with every force set to 0 a force law gives 0 everywhere, the others the same H."""
    kind = LAWS[name].kind
    c = _contacts()
    h = _h(name, c)
    gap = c.normal_force_n == 0
    assert np.array_equal(gap, c.overlap_m < 0) and gap.any() and (~gap).any()
    assert np.all(h[~gap] > 0)
    no_force = _h(name, dataclasses.replace(c, normal_force_n=np.zeros_like(c.normal_force_n)))
    if kind == "geometric":
        assert np.all(h[gap] > 0)           # gap neighbours in the dump conduct
        # ... and the farther apart, the less they conduct
        far = dataclasses.replace(c, distance_m=c.distance_m * 1.5)
        assert np.all(_h(name, far) < h)
    else:
        assert np.all(h[gap] == 0)          # no force (no overlap), no contact spot
    if kind == "force":
        assert np.all(no_force == 0)        # the area comes from the force alone
    else:
        np.testing.assert_array_equal(no_force, h)      # no force enters


@pytest.mark.parametrize("name", sorted(LAWS))
def test_degenerate_rows_give_zero_not_nan(name):
    c = _contacts(m=4)
    c = dataclasses.replace(c, distance_m=np.zeros(4), conductivity_i=np.zeros(4),
                            conductivity_j=np.zeros(4))
    h = _h(name, c)
    assert np.all(np.isfinite(h)) and np.all(h == 0)


@pytest.mark.parametrize("name", sorted(set(LAWS) - DIAGNOSTIC))
def test_conductance_scales_linearly_with_conductivity(name):
    c = _contacts()
    s = 3.7
    scaled = dataclasses.replace(c, conductivity_i=s * c.conductivity_i,
                                 conductivity_j=s * c.conductivity_j)
    np.testing.assert_allclose(_h(name, scaled), s * _h(name, c), rtol=1e-13)


@pytest.mark.parametrize("name", sorted(LAWS))
def test_capacity_is_positive_and_scales_with_rho_cp(name):
    p = _particles()
    c = _c(name, p)
    assert c.shape == (p.radius_m.size,) and np.all(np.isfinite(c)) and np.all(c > 0)
    np.testing.assert_allclose(_c(name, dataclasses.replace(p, density=2 * p.density)), 2 * c,
                               rtol=1e-14)
    np.testing.assert_allclose(
        _c(name, dataclasses.replace(p, heat_capacity=0.5 * p.heat_capacity)), 0.5 * c,
        rtol=1e-14)
    # the capacity is at least the sphere's own rho c_p V (the continuum laws add the pores)
    assert np.all(c >= p.density * p.heat_capacity * 4 / 3 * np.pi * p.radius_m ** 3
                  * (1 - 1e-14))


@pytest.mark.parametrize("name", sorted(LAWS))
def test_wall_conductance_battery(name):
    w = _walls()
    g = _g(name, w)
    assert g.shape == (w.radius_m.size,) and np.all(np.isfinite(g)) and np.all(g >= 0)
    kind = LAWS[name].kind
    gap = w.normal_force_n == 0
    assert np.array_equal(gap, w.overlap_m < 0)
    assert np.all(g[~gap] > 0)
    if kind == "geometric":
        assert np.all(g[gap] > 0)
    else:
        assert np.all(g[gap] == 0)
    no_force = _g(name, dataclasses.replace(w, normal_force_n=np.zeros_like(w.normal_force_n)))
    if kind == "force":
        assert np.all(no_force == 0)
    else:
        np.testing.assert_array_equal(no_force, g)
    s = 2.5
    scaled = dataclasses.replace(w, conductivity_particle=s * w.conductivity_particle,
                                 conductivity_wall=s * w.conductivity_wall)
    power = -1 if name in DIAGNOSTIC else 1          # a resistance: 1/k
    np.testing.assert_allclose(_g(name, scaled), s ** power * g, rtol=1e-13)


# --- hand-computed values, one (or more) per law -----------------------------------------------

def test_terreros_by_hand():
    # 000, sec. 4.4: S_i = S^nd R_i^2 with S^nd(6) = 4.0, S^nd(9) = 2.29545 (Table 1)
    c = _one(1e-3, 0.8e-3, 1.75e-3, 10.0, 10.0, n_i=6, n_j=9)
    expected = 10.0 * math.sqrt(4.0 * 1e-6 * 2.29545 * 0.64e-6) / 1.75e-3
    assert _h("terreros", c)[0] == pytest.approx(expected, rel=1e-12)
    # between rows 6 and 7: S^nd = (4.0 + 3.29903) / 2 for both
    c = _one(1e-3, 1e-3, 2e-3, 10.0, 10.0, n_i=6.5, n_j=6.5)
    assert _h("terreros", c)[0] == pytest.approx(10.0 * (4.0 + 3.29903) / 2 * 1e-6 / 2e-3,
                                                 rel=1e-12)
    # two phases: harmonic mean 2*33*165/198 = 55 W/m/K by default
    c = _one(1e-3, 1e-3, 2e-3, 33.0, 165.0)
    assert _h("terreros", c)[0] == pytest.approx(55.0 * 4e-6 / 2e-3, rel=1e-12)


def test_haddad_by_hand():
    # 002, eq. 3, 7, 24: R_m = 0.9 mm, lambda = 2*33*165/(33+165) = 55, C_t = 0.806
    c = _one(1e-3, 0.8e-3, 1.78e-3, 33.0, 165.0)
    expected = 55.0 * 0.806 * math.pi * 0.9e-3 ** 2 / 1.78e-3
    assert _h("haddad", c)[0] == pytest.approx(expected, rel=1e-12)
    assert _h("haddad", c, interface_mean="arithmetic")[0] == pytest.approx(
        99.0 * 0.806 * math.pi * 0.9e-3 ** 2 / 1.78e-3, rel=1e-12)
    assert _h("haddad", c, ct=0.75)[0] == pytest.approx(expected * 0.75 / 0.806, rel=1e-12)
    with pytest.raises(ValueError, match="interface_mean"):
        _h("haddad", c, interface_mean="geometric")
    # 002, eq. 1, 5 (Table 1 material): C = c rho_c V / phi
    p = ParticleInput(radius_m=np.array([1e-3]), density=np.array([7800.0]),
                      heat_capacity=np.array([0.9]), conductivity=np.array([33.0]),
                      neighbours=np.array([7]), solid_fraction=0.64)
    assert _c("haddad", p)[0] == pytest.approx(0.9 * 7800 * 4 / 3 * math.pi * 1e-9 / 0.64,
                                               rel=1e-12)


def test_pipe_by_hand_equal_spheres():
    # 003, Table 1 particle (R_P = 2 mm, kappa = 205), F_n = 10 N; chain of eq. 36-39:
    r, kappa, force = 2e-3, 205.0, 10.0
    k_n = 4 * E / (6 * (1 - NU ** 2)) * math.sqrt(r / 2)           # eq. 39
    r_dphi = math.sqrt(r) * (force / k_n) ** (1 / 3)                 # eq. 38
    expected = kappa / 0.6846 * r_dphi                               # eq. 37 (lambda = -0.6846)
    c = _one(r, r, 2 * r - 1e-6, kappa, kappa, force=force)
    h = _h("pipe", c)[0]
    assert h == pytest.approx(expected, rel=1e-12)
    assert h == pytest.approx(2.066 * kappa * _zeta(force, r), rel=2e-4)   # eq. 40, rounded


def test_pipe_by_hand_unequal_spheres():
    # eq. 18-20 with one contact disc: R_e = 0.6846 / (2 kappa a_l) per sphere, a_l the lens
    # radius at the Hertz overlap, sqrt(2) (3 F R*/(4 E*))^(1/3)
    r_i, r_j, k_i, k_j, force = 1e-3, 2e-3, 10.0, 40.0, 3.0
    r_star = 2e-3 / 3
    a_l = math.sqrt(2) * (3 * force * r_star / (4 * E_STAR)) ** (1 / 3)
    expected = 1 / (0.6846 / (2 * k_i * a_l) + 0.6846 / (2 * k_j * a_l))
    c = _one(r_i, r_j, 3e-3 - 1e-6, k_i, k_j, force=force)
    assert _h("pipe", c)[0] == pytest.approx(expected, rel=1e-12)


def test_bob_argento_ott_by_hand():
    r, kappa, force = 2e-3, 205.0, 10.0
    c = _one(r, r, 2 * r - 1e-6, kappa, kappa, force=force)
    zeta = _zeta(force, r)
    assert _h("bob", c)[0] == pytest.approx(2 * kappa * zeta, rel=1e-12)           # eq. 34
    assert _h("argento", c)[0] == pytest.approx(math.pi / (2 * 0.899) * kappa * zeta,
                                                rel=1e-12)                          # eq. 35
    assert _h("ott", c)[0] == pytest.approx(math.pi / (2 * 0.952) * kappa * zeta, rel=1e-12)
    assert _h("argento", c, beta=0.952)[0] == pytest.approx(_h("ott", c)[0], rel=1e-14)


def test_pipe_is_1033_times_bob_for_equal_spheres():
    # 003, eq. 40 vs eq. 34: 2.066 / 2 = 1.033 whatever the force, radius and conductivity
    for r, kappa, force in [(2e-3, 205.0, 10.0), (5e-4, 1.0, 1e-3), (1e-2, 50.0, 1e4)]:
        c = _one(r, r, 2 * r, kappa, kappa, force=force)
        ratio = _h("pipe", c)[0] / _h("bob", c)[0]
        assert ratio == pytest.approx(1.033, abs=5e-4)
        assert ratio == pytest.approx(math.sqrt(2) / (2 * 0.6846), rel=1e-12)


def test_pipe_resistance_as_conductance_by_hand():
    """The diagnostic law (issue 15): the resistance sum of 003 eq. 18-20 as a number, for the
    Table 1 particle at F_n = 10 N and for unequal spheres; equal spheres give 1/H_pipe; it
    scales as 1/k and as F_n^(-1/3) (so gamma would fall as p^(-1/3))."""
    r, kappa, force = 2e-3, 205.0, 10.0
    k_n = 4 * E / (6 * (1 - NU ** 2)) * math.sqrt(r / 2)           # eq. 39
    r_dphi = math.sqrt(r) * (force / k_n) ** (1 / 3)                 # eq. 38: R_P dphi
    r_e = 0.6846 / (2 * kappa * r_dphi)                              # eq. 17-19: R_eP = R_eL
    c = _one(r, r, 2 * r - 1e-6, kappa, kappa, force=force)
    h = _h("pipe_resistance_as_conductance", c)[0]
    assert h == pytest.approx(2 * r_e, rel=1e-12)
    assert h == pytest.approx(1 / _h("pipe", c)[0], rel=1e-12)
    assert h == pytest.approx(0.6846 / (math.sqrt(2) * kappa * _zeta(force, r)), rel=1e-12)
    r_i, r_j, k_i, k_j, f = 1e-3, 2e-3, 10.0, 40.0, 3.0
    a_l = math.sqrt(2) * (3 * f * (2e-3 / 3) / (4 * E_STAR)) ** (1 / 3)
    c2 = _one(r_i, r_j, 3e-3 - 1e-6, k_i, k_j, force=f)
    assert _h("pipe_resistance_as_conductance", c2)[0] == pytest.approx(
        0.6846 / (2 * k_i * a_l) + 0.6846 / (2 * k_j * a_l), rel=1e-12)
    contacts = _contacts()
    scaled = dataclasses.replace(contacts, conductivity_i=3.7 * contacts.conductivity_i,
                                 conductivity_j=3.7 * contacts.conductivity_j)
    np.testing.assert_allclose(_h("pipe_resistance_as_conductance", scaled),
                               _h("pipe_resistance_as_conductance", contacts) / 3.7, rtol=1e-13)
    c8 = _one(r, r, 2 * r - 1e-6, kappa, kappa, force=8 * force)
    assert _h("pipe_resistance_as_conductance", c8)[0] == pytest.approx(h / 2, rel=1e-12)


def test_chaudhuri_by_hand():
    # 004: 4 k1 k2/(k1+k2) (3 F r*/(4 E*))^(1/3); k 1 and 3 -> 3; r* = (1*2/3) mm
    c = _one(1e-3, 2e-3, 3e-3 - 1e-6, 1.0, 3.0, force=5.0)
    r_star = 1e-3 * 2e-3 / 3e-3
    e_star = 1 / ((1 - NU ** 2) / E + (1 - NU ** 2) / E)
    expected = 3.0 * (3 * 5.0 * r_star / (4 * e_star)) ** (1 / 3)
    assert _h("chaudhuri", c)[0] == pytest.approx(expected, rel=1e-12)
    # one material: Chaudhuri is Batchelor-O'Brien written with the Hertz radius
    cs = _contacts()
    np.testing.assert_allclose(_h("chaudhuri", cs), _h("bob", cs), rtol=1e-13)


def test_yade_by_hand():
    # Thermal.cpp, default branch: 2 (k1 + k2) r1 r2 / (r1 + r2 - pd)
    c = _one(1e-3, 0.6e-3, 1.58e-3, 3.0, 50.0)
    assert _h("yade", c)[0] == pytest.approx(2 * 53.0 * 0.6e-6 / 1.58e-3, rel=1e-12)
    p = ParticleInput(radius_m=np.array([1e-3]), density=np.array([2500.0]),
                      heat_capacity=np.array([900.0]), conductivity=np.array([3.0]),
                      neighbours=np.array([1]), solid_fraction=0.6)
    assert _c("yade", p)[0] == pytest.approx(2500 * 4 / 3 * math.pi * 1e-9 * 900, rel=1e-12)


@pytest.mark.parametrize("pd, t1_yade, t2_yade", [
    (2e-5, 399.95729006590443, 300.1977311763683),      # overlapping
    (-5e-5, 399.95910200250245, 300.18934258100717),    # gap, a real interaction in YADE
])
def test_yade_law_reproduces_one_thermal_engine_step(pd, t1_yade, t2_yade):
    """Reference values printed by Debian's YADE 2023.02a (one thread): two fixed spheres of
    radii 1 and 0.6 mm, FrictMat density 2500, ThermalEngine(particleCp=900, tsSafetyFactor=0,
    boundarySet=True) with FlowEngine(dead=True), O.dt = 1e-4; after a first O.step() the
    states were set to k = 3 and 50 W/m/K, T = 400 and 300 K, and one more O.step() gave these
    temperatures (the gap case with interactionDetectionFactor = aabbEnlargeFactor = 1.2 and
    Law2_ScGeom_FrictPhys_CundallStrack(neverErase=True))."""
    r1, r2 = 1e-3, 0.6e-3
    c = _one(r1, r2, r1 + r2 - pd, 3.0, 50.0)
    p = ParticleInput(radius_m=np.array([r1, r2]), density=np.full(2, 2500.0),
                      heat_capacity=np.full(2, 900.0), conductivity=np.array([3.0, 50.0]),
                      neighbours=np.array([1, 1]), solid_fraction=0.5)
    g = _h("yade", c)[0]
    cap = _c("yade", p)
    flow = g * (400.0 - 300.0) * 1e-4
    assert 400.0 - flow / cap[0] == pytest.approx(t1_yade, rel=1e-14)
    assert 300.0 + flow / cap[1] == pytest.approx(t2_yade, rel=1e-14)


# --- Terreros: Table 1 and the simple-cubic lattice --------------------------------------------

@pytest.mark.parametrize("n, s_nd, f_vl", [
    (1, 19.98076, 0.08502), (5, 7.19615, 0.43184), (6, 4.0, 0.52359), (8, 2.59807, 0.68017),
    (12, 1.38757, 0.74048), (17, 0.99415, 0.81586), (20, 0.75810, 0.86109)])
def test_terreros_table_exact_at_nodes(n, s_nd, f_vl):
    # through the law: H of two equal particles (R = 1, d = 1, lambda = 1) is S^nd; the
    # capacity with rho c_p V = 1 is 1 / f_vl
    c = _one(1.0, 1.0, 1.0, 1.0, 1.0, n_i=n, n_j=n)
    assert _h("terreros", c)[0] == s_nd
    p = ParticleInput(radius_m=np.array([(3 / (4 * math.pi)) ** (1 / 3)]),
                      density=np.array([1.0]), heat_capacity=np.array([1.0]),
                      conductivity=np.array([1.0]), neighbours=np.array([n]),
                      solid_fraction=0.6)
    assert _c("terreros", p)[0] == pytest.approx(1 / f_vl, rel=1e-14)


def test_terreros_table_interpolates_and_clamps():
    assert transmission_surface_nd(8.5) == pytest.approx((2.59807 + 2.29545) / 2, rel=1e-14)
    assert local_volume_fraction(6.25) == pytest.approx(0.52359 + 0.25 * (0.60188 - 0.52359),
                                                        rel=1e-14)
    # outside the table: clamped to rows 1 and 20
    assert transmission_surface_nd(0) == 19.98076 and local_volume_fraction(0) == 0.08502
    assert transmission_surface_nd(30) == 0.75810 and local_volume_fraction(30) == 0.86109


def test_terreros_on_a_simple_cubic_lattice_is_the_7_point_stencil():
    a, lam, rho, cp = 2e-3, 134.0, 2790.0, 880.0      # 000, Table 2 material
    pk, nb, contacts, particles = _lattice(a=a, lam=lam, rho=rho, cp=cp)
    h = _h("terreros", contacts)
    cap = _c("terreros", particles)
    interior = (contacts.neighbours_i == 6) & (contacts.neighbours_j == 6)
    assert interior.sum() > 0
    np.testing.assert_allclose(h[interior], lam * a, rtol=1e-14)       # lambda a^2 / a
    # f_vl(6) = 0.52359 as printed, pi/6 to 1.7e-5
    np.testing.assert_allclose(cap[nb == 6], rho * cp * a ** 3, rtol=2e-5)
    # the balance of the centre particle is the finite-difference Laplacian of a quadratic
    # field: (sum_j H (T_j - T_i)) / C_i = alpha (2 + 4 - 2) for T = x^2 + 2 y^2 - z^2
    x, y, z = pk.position.T
    temp = x ** 2 + 2 * y ** 2 - z ** 2
    centre = int(np.argmin(np.linalg.norm(pk.position - pk.position.mean(axis=0), axis=1)))
    rows = (pk.pair[:, 0] == centre) | (pk.pair[:, 1] == centre)
    other = np.where(pk.pair[rows, 0] == centre, pk.pair[rows, 1], pk.pair[rows, 0])
    rate = np.sum(h[rows] * (temp[other] - temp[centre])) / cap[centre]
    assert rows.sum() == 6
    assert rate == pytest.approx(lam / (rho * cp) * 4.0, rel=2e-5)


def test_geometric_walls_on_the_lattice_are_the_half_cell_boundary():
    # a wall of fixed temperature half a pitch from the centre: H = lambda a^2 / (a / 2)
    a, lam = 2e-3, 134.0
    w = WallContactInput(radius_m=np.array([a / 2]), overlap_m=np.array([0.0]),
                         normal_force_n=np.array([0.0]), conductivity_particle=np.array([lam]),
                         conductivity_wall=np.array([1e3]), young_pa=E, poisson=NU)
    assert _g("terreros", w)[0] == pytest.approx(2 * lam * a, rel=1e-14)
    assert _g("yade", w)[0] == pytest.approx(2 * lam * a, rel=1e-14)
    # haddad: lambda C_t pi r^2 / r
    assert _g("haddad", w)[0] == pytest.approx(lam * 0.806 * math.pi * (a / 2), rel=1e-14)
    # a gap of 10 % of r: the plane is farther
    wg = dataclasses.replace(w, overlap_m=np.array([-0.1 * a / 2]))
    assert _g("terreros", wg)[0] == pytest.approx(lam * a ** 2 / (1.1 * a / 2), rel=1e-14)


def test_force_based_walls_by_hand():
    # sphere on a plane: R* = r, E* of the particle's material on both sides
    r, force, k_p, k_w = 1e-3, 4.0, 10.0, 30.0
    w = WallContactInput(radius_m=np.array([r]), overlap_m=np.array([1e-6]),
                         normal_force_n=np.array([force]), conductivity_particle=np.array([k_p]),
                         conductivity_wall=np.array([k_w]), young_pa=E, poisson=NU)
    a = (3 * force * r / (4 * E_STAR)) ** (1 / 3)
    k_h = 2 * k_p * k_w / (k_p + k_w)
    assert _g("bob", w)[0] == pytest.approx(2 * a * k_h, rel=1e-12)
    assert _g("chaudhuri", w)[0] == pytest.approx(4 * k_p * k_w / (k_p + k_w) * a, rel=1e-12)
    assert _g("argento", w)[0] == pytest.approx(math.pi / (2 * 0.899) * a * k_h, rel=1e-12)
    assert _g("pipe", w)[0] == pytest.approx(
        1 / (0.6846 / (2 * k_p * math.sqrt(2) * a) + 0.6846 / (2 * k_w * math.sqrt(2) * a)),
        rel=1e-12)


def test_bad_parameters_are_refused():
    c = _contacts(m=2)
    with pytest.raises(ValueError, match="beta"):
        _h("argento", c, beta=0.0)
    with pytest.raises(ValueError, match="ct"):
        _h("haddad", c, ct=-1.0)
    with pytest.raises(ValueError, match="young_pa"):
        _h("pipe", dataclasses.replace(c, young_pa=float("nan")))
    with pytest.raises(ValueError, match="solid_fraction"):
        _c("haddad", dataclasses.replace(_particles(), solid_fraction=0.0))
