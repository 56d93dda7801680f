"""The affine (fabric-tensor) estimate k_ij = (1/V) sum_c H_c l_i l_j and the contact fabric
(tdem_post/fabric.py, issue 15).

Asserted:
- Thomson's principle: on every committed bed and dense packing with two opposite held faces
  (tests/data: the two 300-sphere beds between zmin and the plate; the dense box along x, y and
  z; the dense cylinder along z; laws pipe and haddad - force-based and geometric), the affine
  k_zz is >= the network's steady conductivity Q L/(A dT) (an exact inequality: the affine field
  with the held spheres on their walls' planes is admissible). Not used: dense_periodic (no
  walls) and dense_sphere (one spherical wall, no opposite pair);
- k_zz is the dissipation of that trial field, sum_c H_c dT_c^2 L/(A dT^2), computed here
  independently from the temperatures it assigns;
- equality on a simple-cubic lattice (the steady field is affine): gamma_affine = gamma_steady =
  2 sqrt(R* delta)/a to 1e-9, and the transverse components equal it too (isotropic lattice);
- <n_z^2> is the share of z-contacts on a lattice and 1/3 for isotropic normals, whose
  contact-angle PDF is sin(phi); weights move <n_z^2> as they should.
"""
import math
from pathlib import Path

import numpy as np
import pytest

from tdem.committed_beds import BED_THERMAL
from tdem.cli import main
from tdem_post.fabric import affine_conductivity, contact_angle_pdf, mean_nz2
from tdem_post.post_run import post_run

DATA = Path(__file__).resolve().parent / "data"


def _steady(tmp_path, packing, law, low, high, name):
    thermal = BED_THERMAL.replace('on = "zmin"', f'on = "{low}"').replace(
        'on = "plate"', f'on = "{high}"')
    extra = "[law_params]\nct = 0.8\n" if law == "haddad" else ""
    scene = tmp_path / f"{name}.toml"
    scene.write_text(f'packing = "{packing}"\nlaw = "{law}"\n{extra}{thermal}'
                     '[solver]\nmethod = "steady"\n')
    out = tmp_path / name
    assert main(["run", str(scene), "--out", str(out), "--quiet"]) == 0
    return post_run(out / "thermal.h5", n_bins=5, plots=False), out


CASES = [("bed_small_1.6e+06Pa.h5", "pipe", "zmin", "plate"),
         ("bed_small_4.05e+07Pa.h5", "pipe", "zmin", "plate"),
         ("bed_small_4.05e+07Pa.h5", "haddad", "zmin", "plate"),
         ("dense_box.h5", "pipe", "xmin", "xmax"),
         ("dense_box.h5", "pipe", "ymin", "ymax"),
         ("dense_box.h5", "pipe", "zmin", "zmax"),
         ("dense_box.h5", "haddad", "zmin", "zmax"),
         ("dense_cylinder.h5", "pipe", "zmin", "zmax"),
         ("dense_cylinder.h5", "haddad", "zmin", "zmax")]


@pytest.mark.parametrize("dump, law, low, high", CASES)
def test_affine_estimate_bounds_the_network_from_above(tmp_path, dump, law, low, high):
    s, out = _steady(tmp_path, DATA / dump, law, low, high, "case")
    assert s["steady_balance"] < 1e-9
    assert s["gamma_affine"] >= s["gamma_steady"] * (1 - 1e-12)
    # a bound, not a tautology: strictly above on a disordered packing
    assert s["gamma_affine"] > s["gamma_steady"] * 1.001
    assert 0 < s["fabric_nz2"] < 1 and 0 < s["fabric_nz2_conductance"] < 1
    edges = np.asarray(s["contact_angle_edges"])
    assert np.sum(np.asarray(s["contact_angle_pdf"]) * np.diff(edges)) == pytest.approx(1.0)


def test_affine_k_zz_is_the_dissipation_of_the_trial_field(tmp_path):
    """Independently of fabric.py's sum: the trial field (held spheres at their wall's value,
    the others T_b + G (z - z0)) dissipates sum H dT^2 = k_zz A dT^2 / L."""
    import dataclasses
    from thermal_kernel.calibrate import cross_section
    from thermal_kernel.laws import LAWS
    from thermal_kernel.packing import read_packing
    from thermal_kernel.problem import boundary_particles, build_problem
    from thermal_kernel.scene import load_scene
    s, out = _steady(tmp_path, DATA / "bed_small_1.6e+06Pa.h5", "pipe", "zmin", "plate", "bed")
    scene = load_scene(tmp_path / "bed.toml", known_laws=LAWS)
    packing = read_packing(DATA / "bed_small_1.6e+06Pa.h5")
    problem, _ = build_problem(dataclasses.replace(scene), packing)
    low = boundary_particles(scene, packing, "zmin", "b")
    high = boundary_particles(scene, packing, "plate", "b")
    z = packing.position[:, 2]
    z0, z1 = z[low].mean(), z[high].mean()
    t_b, t_t = 500.0, 400.0
    trial = t_b + (t_t - t_b) * (z - z0) / (z1 - z0)
    trial[low], trial[high] = t_b, t_t
    i, j = packing.pair.T
    dissipation = float(np.sum(problem.conductance_w_k * (trial[i] - trial[j]) ** 2))
    area = cross_section(packing, 2)
    k_zz = dissipation * (z1 - z0) / (area * (t_b - t_t) ** 2)
    assert s["gamma_affine"] == pytest.approx(k_zz / 205.0, rel=1e-12)
    est = affine_conductivity(packing.pair, packing.branch, problem.conductance_w_k,
                              packing.position, 2, low, high, z0, z1, area)
    np.testing.assert_allclose(est.k, est.k.T, rtol=1e-14)
    assert est.k[2, 2] == pytest.approx(k_zz, rel=1e-12)


def test_affine_estimate_is_exact_on_a_simple_cubic_lattice(tmp_path):
    from thermal_kernel.lattice import simple_cubic_packing
    from thermal_kernel.packing import write_packing
    pitch, delta = 4e-3, 4e-6
    radius = (pitch + delta) / 2
    write_packing(tmp_path / "lattice.h5", simple_cubic_packing(
        (3, 3, 9), spacing_m=pitch, radius_m=radius, young_pa=5e10, poisson=0.2))
    s, _ = _steady(tmp_path, tmp_path / "lattice.h5", "bob", "zmin", "zmax", "lat")
    gamma_exact = 2 * math.sqrt(radius / 2 * delta) / pitch
    assert s["gamma_steady"] == pytest.approx(gamma_exact, rel=1e-9)
    assert s["gamma_affine"] == pytest.approx(gamma_exact, rel=1e-9)
    # 2 x (2 x 3 x 9) horizontal, 3 x 3 x 8 vertical contacts: <n_z^2> = 72 / 180
    assert s["fabric_nz2"] == pytest.approx(72 / 180, rel=1e-12)
    # transverse: each x-contact carries H a^2; of the 2 x 3 x 9 x-contacts, the 2 x 3 within
    # each held layer are left out (both ends at the wall's temperature): 42 H a^2 over
    # V = 9 a^2 x 8 a
    assert s["gamma_affine_transverse"] == pytest.approx(42 / 72 * gamma_exact, rel=1e-9)


def test_contact_angle_pdf_and_nz2_on_known_fabrics():
    rng = np.random.default_rng(5)
    v = rng.normal(size=(200_000, 3))
    mask = np.ones(len(v), bool)
    assert mean_nz2(v, mask, 2) == pytest.approx(1 / 3, abs=3e-3)
    edges, pdf = contact_angle_pdf(v, mask, 2, bins=9)
    centres = 0.5 * (edges[1:] + edges[:-1])
    np.testing.assert_allclose(pdf, np.sin(centres), atol=0.03)      # isotropic: sin(phi)
    # weights: all the weight on the vertical contacts gives 1
    axial = np.array([[0, 0, 1.0], [1.0, 0, 0], [0, 1.0, 0]])
    assert mean_nz2(axial, np.ones(3, bool), 2, weights=[1.0, 0, 0]) == 1.0
    assert mean_nz2(axial, np.ones(3, bool), 2) == pytest.approx(1 / 3)


def test_love_weber_stress_of_a_loaded_lattice():
    """A simple-cubic lattice of pitch a with force F on every z-contact and none on the others:
    sigma_zz = F/a^2 on the volume the z-contacts span, the other components 0."""
    from tdem_post.fabric import love_weber_stress
    from thermal_kernel.lattice import simple_cubic_packing
    a, force = 2e-3, 7.0
    p = simple_cubic_packing((4, 5, 6), spacing_m=a)
    f = np.where(np.abs(p.branch[:, 2]) > 0, force, 0.0)
    sigma = love_weber_stress(p.branch, f, volume_m3=4 * 5 * 5 * a ** 3)
    assert sigma[2, 2] == pytest.approx(force / a ** 2, rel=1e-12)
    np.testing.assert_allclose(np.delete(sigma.ravel(), 8), 0.0, atol=1e-9)
