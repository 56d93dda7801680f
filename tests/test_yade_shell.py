"""method = "shell" (issue 24) makes a walled box whose walls are pressed like the direct path's
(YADE for real).

A periodic cell of 500 spheres is tiled and carved to a box of 2,000, the spheres cut by the
faces are removed and six walls are pressed onto a shell along them; the reference is the direct
relaxation of the same box (method = "direct"). Exact identities and physical rules:

- every wall carries the confining pressure: the dumped wall forces over the wall's area;
- every touching contact, copied from the cell or recomputed by YADE, carries Hertz's force at the
  real modulus of its overlap, and every wall contact Hertz's force with R* = r (a flat wall of
  the particles' material);
- no sphere lies beyond a wall by more than its dumped wall overlap;
- against the direct box of the same N: the solid fraction of the first mean diameter along the
  walls within the seed-to-seed scatter of walled boxes (0.02 at this size).

Softened material (E = 5e9 Pa) and unbalanced-force target 1e-2 as in test_yade_dense_paths.py,
so each packing builds in seconds; the code path is the one of the real modulus.
"""
import shutil

import numpy as np
import pytest

from tdem.yade import yade_environment
from thermal_kernel.contact_check import hertz_force
from tdem_post.wall_layers import plane_walls, wall_layers

from test_yade_dense_paths import FAST, build_all

pytestmark = [pytest.mark.yade,
              pytest.mark.skipif(shutil.which("yade", path=yade_environment()["PATH"]) is None,
                                 reason="Debian's yade is not installed")]

N, CELL, SEED = 2000, 500, 2


@pytest.fixture(scope="module")
def boxes(tmp_path_factory):
    built = build_all({
        "shell": (tmp_path_factory.mktemp("shell"),
                  dict(shape="box", method="shell", n_particles=N, cell_particles=CELL, seed=SEED,
                       **FAST)),
        "direct": (tmp_path_factory.mktemp("direct"),
                   dict(shape="box", method="direct", n_particles=N, seed=SEED, **FAST))})
    return built["shell"], built["direct"]


def _wall_stress(packing):
    extent = packing.domain_hi - packing.domain_lo
    out = []
    for w, axis, _ in plane_walls(packing):
        area = float(np.prod(np.delete(extent, axis)))
        out.append(packing.wall_normal_force[packing.wall_index == w].sum() / area)
    return np.array(out)


def test_every_wall_carries_the_pressure(boxes):
    shell, _ = boxes
    assert shell.attrs["method"] == "shell" and shell.attrs["shell_steps"] > 0
    stress = _wall_stress(shell) / shell.attrs["confining_pressure_pa"]
    assert len(stress) == 6
    tol = 0.02
    assert abs(stress.mean() - 1.0) < 2 * tol, stress
    assert np.all(np.abs(stress - 1.0) < 3 * tol), stress


def test_forces_are_hertz(boxes):
    shell, _ = boxes
    e_star = shell.attrs["young_pa"] / (2.0 * (1.0 - shell.attrs["poisson"] ** 2))
    touch = shell.overlap > 0
    r_i, r_j = shell.radius[shell.pair[touch, 0]], shell.radius[shell.pair[touch, 1]]
    np.testing.assert_allclose(shell.normal_force[touch],
                               hertz_force(r_i * r_j / (r_i + r_j), shell.overlap[touch], e_star),
                               rtol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(shell.branch, axis=1),
                               shell.radius[shell.pair[:, 0]] + shell.radius[shell.pair[:, 1]]
                               - shell.overlap, atol=1e-12)
    pressed = shell.wall_normal_force > 0
    assert pressed.sum() > 100
    r = shell.radius[shell.wall_particle[pressed]]
    np.testing.assert_allclose(shell.wall_normal_force[pressed],
                               hertz_force(r, shell.wall_overlap[pressed], e_star), rtol=1e-6)


def test_no_sphere_beyond_a_wall(boxes):
    shell, _ = boxes
    lo, hi = shell.domain_lo, shell.domain_hi
    depth = np.maximum(lo - (shell.position - shell.radius[:, None]),
                       (shell.position + shell.radius[:, None]) - hi).max(axis=1)
    allowed = np.zeros(shell.n_particles)
    np.maximum.at(allowed, shell.wall_particle, np.clip(shell.wall_overlap, 0, None))
    assert np.all(depth <= allowed + 1e-9 * shell.radius)


def test_wall_layer_as_loose_as_the_direct_box(boxes):
    """The layer the walls impose: the first mean diameter along the walls is as loose as the
    direct box's (0.02, the seed-to-seed scatter at this size). (The seam between the free shell
    and the frozen band is not asserted: it is under-coordinated, docs/packings.md.)"""
    shell, direct = boxes
    la, lb = wall_layers(shell, depth_d=1.0, edge_margin_d=2.0), \
        wall_layers(direct, depth_d=1.0, edge_margin_d=2.0)
    assert abs(la.solid_fraction.mean() - lb.solid_fraction.mean()) < 0.02
