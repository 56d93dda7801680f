"""Shared machinery of cases 8-10 of docs/validation.md (002 sec. 4-5): spherical inclusions put
into a dense packing that models a continuum, and the steady flux test of the composite.

Phases are assigned as 002 and the YADE generator do: a particle whose centre lies inside an
inclusion is phase 1 (conductivity c x the matrix's). A contact between the two phases gets the
conductivity of 002 eq. 24, the harmonic mean (the haddad law's ``interface_mean``): this is the
paper's model, ``interface="harmonic"``. The variant ``interface="cut"`` (tdem's, not the
paper's) uses where the inclusion's surface cuts the branch: a fraction s of the centre-to-centre
segment lies inside, and the contact's conductivity is the series value
1 / (s / l_i + (1 - s) / l_m) - the harmonic mean is its value at s = 1/2 only. It changes
nothing but the interface contacts' conductance and shows how much of the error is the interface.

The flux test is 002 sec. 2.2 and 4.2: the faces ymin / ymax held at 25 / 35 C, adiabatic sides,
one sparse steady solve; k_eff / k_m is the composite's heat flow over the single-phase one on the
same packing, so that C_t and the domain length cancel.
"""
from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from thermal_kernel.effective import steady_effective_conductivity
from thermal_kernel.packing import Packing, read_packing
from thermal_kernel.run import run_in_memory
from thermal_kernel.scene import Material

from validation import framework
from validation.framework import ROOT

K_MATRIX = 33.0
SINGLE_FRACTION = 4.0 * math.pi / 81.0       # a = L/3 in a cube of side L: 15.51 % (002 sec. 4)
T_COLD, T_HOT = 298.15, 308.15          # 25 C at y = 0, 35 C at y = L (002 sec. 2.2, 4.2)
SCENE_PATH = ROOT / "validation" / "inclusions_scene.toml"      # named in messages only


# The matrix of 002 sec. 4 (lambda 33 W/m/K; rho and c do not matter at steady state), law
# haddad with the paper's C_t (it cancels in k_eff / k_m), harmonic interfaces (002 eq. 24).
def scene_text(packing, *, contrast: float = 1.0, axis: int = 1,
               target_z: float | None = None) -> str:
    """The flux test's scene: phase 1 (the inclusions) at ``contrast`` x the matrix's
    conductivity, the face at the ``axis``' maximum held at 35 C and the other at 25 C (hot
    listed first: it holds the shared edges), steady; the neighbours cut to the bulk
    coordination ``target_z`` ([neighbours] target_z_with_gaps; None: every dumped pair)."""
    name = "xyz"[axis]
    return framework.scene_toml(
        packing, "haddad", law_params=dict(ct=0.806),
        material={"conductivity": K_MATRIX, "density": 7800.0, "heat_capacity": 0.9,
                  "1": dict(conductivity=contrast * K_MATRIX)},        # [material.1]
        initial=dict(temperature=303.15),
        boundary=[dict(kind="temperature", name="hot", on=f"{name}max", value=T_HOT),
                  dict(kind="temperature", name="cold", on=f"{name}min", value=T_COLD)],
        solver=dict(method="steady"),
        neighbours=None if target_z is None else dict(target_z_with_gaps=float(target_z)))


# Haddad's bulk coordination with gaps (002 sec. 2.1, Z ~ 7.5), as the dense scenes state it
TARGET_Z = 7.5


def load(path, target_z: float | None = None):
    """(scene, packing) of the flux test on the packing file ``path``, its neighbours cut to the
    bulk coordination ``target_z`` ([neighbours] target_z_with_gaps; None: every dumped pair)."""
    path = str(Path(path).resolve())
    scene = framework.case_scene(scene_text(path, target_z=target_z), SCENE_PATH)
    return scene, read_packing(path)


def _target_z(scene) -> float | None:
    """The bulk coordination ``scene``'s [neighbours] asks for (a scene of :func:`load`)."""
    crit = scene.neighbours
    if crit is None:
        return None
    if not (math.isnan(crit.gap) and crit.bulk_margin_diameters == 2.0):
        raise ValueError(f"{scene.path}: the flux test's scenes cut the neighbours to a "
                         f"target_z_with_gaps only (got {crit})")
    return crit.target_z_with_gaps


def centred_inclusion(packing: Packing, fraction: float = SINGLE_FRACTION):
    """(centres (1, 3), radius) of the sphere at the box's centre holding ``fraction`` of its
    volume (a = L/3 for the paper's 15.51 % in a cube)."""
    lo, hi = packing.domain_lo, packing.domain_hi
    radius = (3.0 * fraction * float(np.prod(hi - lo)) / (4.0 * math.pi)) ** (1.0 / 3.0)
    return (0.5 * (lo + hi))[None, :], float(radius)


def phase_of(packing: Packing, centres, radius) -> np.ndarray:
    """Phase 1 for the particles whose centre is inside one of the spheres."""
    phase = np.zeros(packing.n_particles, np.int32)
    tree = cKDTree(packing.position)
    for c in np.atleast_2d(centres):
        phase[tree.query_ball_point(c, radius)] = 1
    return phase


def owner_of(packing: Packing, centres, radius) -> np.ndarray:
    """Index of the inclusion holding each particle's centre, -1 in the matrix."""
    owner = np.full(packing.n_particles, -1, np.int64)
    tree = cKDTree(packing.position)
    for k, c in enumerate(np.atleast_2d(centres)):
        owner[tree.query_ball_point(c, radius)] = k
    return owner


def cut_fraction(inside_pos, outside_pos, centre, radius):
    """Fraction s of the segment inside -> outside that lies in the sphere (centre, radius):
    the root in (0, 1] of |inside + s (outside - inside) - centre| = radius."""
    d = outside_pos - inside_pos
    m = inside_pos - centre
    a = np.einsum("ij,ij->i", d, d)
    b = 2.0 * np.einsum("ij,ij->i", m, d)
    c = np.einsum("ij,ij->i", m, m) - radius ** 2          # < 0: the start is inside
    return np.clip((-b + np.sqrt(b * b - 4 * a * c)) / (2 * a), 0.0, 1.0)


def interface_factor(packing: Packing, owner: np.ndarray, centres, radius, contrast: float):
    """Per-contact factor turning the harmonic interface conductance into the cut one (1 for
    contacts that do not cross an inclusion's surface)."""
    i, j = packing.pair[:, 0], packing.pair[:, 1]
    cross = (owner[i] >= 0) != (owner[j] >= 0)
    factor = np.ones(len(i))
    if not cross.any():
        return factor
    rows = np.flatnonzero(cross)
    ii, jj = i[rows], j[rows]
    i_in = owner[ii] >= 0
    pos_i = packing.position[ii]
    pos_j = pos_i + packing.branch[rows]
    inside = np.where(i_in[:, None], pos_i, pos_j)
    outside = np.where(i_in[:, None], pos_j, pos_i)
    k_in = np.where(i_in, owner[ii], owner[jj])
    s = cut_fraction(inside, outside, np.atleast_2d(centres)[k_in], radius)
    harmonic = 2.0 * contrast / (1.0 + contrast)
    cut = 1.0 / (s / contrast + (1.0 - s))
    factor[rows] = cut / harmonic
    return factor


@dataclass
class FluxResult:
    k_eff: float              # W/m/K, Q L / (A dT) with the domain length
    heat_flow_w: float
    balance: float
    seconds: float
    temperature: np.ndarray   # steady temperatures (hot face 1, cold face 0)
    net: object               # the assembled network (conductances for the flux)


def flux_test(scene, packing: Packing, phase, contrast: float, *, factor=None,
              keep=False, axis: int = 1) -> FluxResult:
    """The steady flux test of the composite (phase 1 at ``contrast`` x the matrix) along
    ``axis`` (y by default, as 002 sec. 4.2): the face at the axis' minimum held at 25 C, the
    other at 35 C, adiabatic sides. ``factor`` multiplies the contacts' conductances (the cut
    interface). k_eff = Q L / (A dT) with the domain's length and face
    (:func:`thermal_kernel.effective.effective_conductivity`, heat in = heat out checked)."""
    t0 = time.perf_counter()
    sc = framework.case_scene(scene_text(scene.packing, contrast=contrast, axis=axis,
                                         target_z=_target_z(scene)), SCENE_PATH)
    pk = dataclasses.replace(packing, phase=np.asarray(phase, np.int32))
    run = run_in_memory(sc, pk, initial_temperature_k=0.5 * (T_HOT + T_COLD),
                        conductance_factor=factor)
    ext = packing.domain_hi - packing.domain_lo
    result = steady_effective_conductivity(
        run.result, run.network, "hot", "cold", t_in=T_HOT, t_out=T_COLD,
        length_m=float(ext[axis]), area_m2=float(np.prod(np.delete(ext, axis))),
        length_convention="domain", where=scene.path)
    return FluxResult(k_eff=result.k_eff_w_mk, heat_flow_w=result.q_in_w,
                      balance=result.balance, seconds=time.perf_counter() - t0,
                      temperature=np.asarray(result.temperature_k) if keep else None,
                      net=run.network if keep else None)


def cell_fraction(packing: Packing, phase: np.ndarray, grid: int = 96, k: int = 8) -> float:
    """The inclusions' share of the box by the particles' Laguerre (power) cells: the fraction
    of the points of a grid x grid x grid lattice of the box whose nearest particle in the
    power distance |x - c|^2 - r^2 is of phase 1 - the volume the network's inclusion stands
    for (the particles' own volume share is biased wherever the packing is looser, e.g. at
    walls)."""
    lo, hi = packing.domain_lo, packing.domain_hi
    tree = cKDTree(packing.position)
    hits, total = 0, 0
    axes = [lo[a] + (np.arange(grid) + 0.5) * (hi[a] - lo[a]) / grid for a in range(3)]
    for x in axes[0]:                      # one plane at a time: bounded memory
        yy, zz = np.meshgrid(axes[1], axes[2], indexing="ij")
        pts = np.column_stack([np.full(yy.size, x), yy.ravel(), zz.ravel()])
        dist, idx = tree.query(pts, k=k)
        power = dist ** 2 - packing.radius[idx] ** 2
        own = idx[np.arange(len(pts)), np.argmin(power, axis=1)]
        hits += int(phase[own].sum())
        total += len(pts)
    return hits / total


def particle_fraction(packing: Packing, phase: np.ndarray) -> float:
    v = packing.radius ** 3
    return float(v[phase == 1].sum() / v.sum())


# ---------------------------------------------------------------- periodic homogenisation
# A cube of side L with one centred sphere, two opposite faces held and the others adiabatic is,
# for the continuum, exactly the unit cell of the simple-cubic array of spheres (the faces are
# symmetry planes of the array): Rayleigh's formula (tdem_post.analytic.rayleigh_cubic_array) is
# its exact ETC and Maxwell is within 0.1 % of it at f = 15.5 %. The same unit cell can be given
# to the network WITHOUT faces: the relaxed periodic cell of runs/dense_box_1e5.toml tiled
# m x m x m times with its contacts wrapped around the block is a periodic packing of side
# m x cell, and a mean temperature gradient G imposed on it (T = theta + G.x, theta periodic)
# leaves no held layer and no cut face. Then k_eff comes from the volume average of the
# contact flows: q = (1/V) sum_c H_c (T_i - T_j) l_c, k_eff = -q.G / |G|^2.

def periodic_block(cell: Packing, m: int) -> Packing:
    """The periodic cell ``cell`` (a packing.h5 of shape "periodic") copied m x m x m times,
    its contacts wrapped around the block: a periodic packing of side m x cell."""
    size = cell.domain_hi - cell.domain_lo
    pos = cell.position - cell.domain_lo
    n = cell.n_particles
    grid = np.indices((m, m, m)).reshape(3, -1).T
    position = (pos[None, :, :] + (grid * size)[:, None, :]).reshape(-1, 3)
    i, j = cell.pair[:, 0], cell.pair[:, 1]
    shift = np.rint((pos[i] + cell.branch - pos[j]) / size).astype(np.int64)
    stride = np.array([m * m, m, 1], np.int64)
    pairs = []
    for k, g in enumerate(grid):
        tj = np.mod(g + shift, m) @ stride
        pairs.append(np.stack([k * n + i, tj * n + j], axis=1))
    pair = np.concatenate(pairs)
    reps = len(grid)
    return dataclasses.replace(
        cell, position=position, radius=np.tile(cell.radius, reps),
        phase=np.zeros(n * reps, np.int32), pair=pair,
        overlap=np.tile(cell.overlap, reps), normal_force=np.tile(cell.normal_force, reps),
        branch=np.tile(cell.branch, (reps, 1)),
        contact_radius=None if cell.contact_radius is None else np.tile(cell.contact_radius,
                                                                        reps),
        domain_lo=np.zeros(3), domain_hi=m * size, periodic=np.ones(3, bool), yade_id=None,
        path=f"{cell.path} x {m}^3")


def contact_conductance(scene, packing: Packing, phase, contrast: float) -> np.ndarray:
    """H per contact (W/K) of the scene's law with phase 1 at ``contrast`` x the matrix, on
    every dumped row: the registered law evaluated where the kernel evaluates it,
    ``thermal_kernel.problem.evaluate_law`` (its inputs, parameters and output checks), for the
    periodic blocks, which have no faces to hold and so no scene run."""
    from thermal_kernel.problem import evaluate_law
    matrix = scene.material(0)
    inclusion = Material(conductivity=contrast * matrix.conductivity, density=matrix.density,
                         heat_capacity=matrix.heat_capacity)
    sc = dataclasses.replace(scene, materials={0: matrix, 1: inclusion})
    pk = dataclasses.replace(packing, phase=np.asarray(phase, np.int32))
    return evaluate_law(sc, pk)[3]


def periodic_conductivity(packing: Packing, conductance, axis: int = 0, tol: float = 1e-11):
    """k_eff (W/m/K) of a periodic network under a unit mean gradient along ``axis``: solve
    L theta = b, b_i = sum_j H_ij l_ij (the flows the gradient drives through the contacts),
    on the particles of the largest connected cluster (others carry no heat), then
    k = -(1/V) sum_c H_c (theta_i - theta_j - l_c) l_c along the axis. Returns (k, seconds)."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components
    t0 = time.perf_counter()
    n = packing.n_particles
    i, j = packing.pair[:, 0], packing.pair[:, 1]
    h = np.asarray(conductance, float)
    lx = packing.branch[:, axis]
    adj = sp.coo_matrix((h, (i, j)), shape=(n, n)).tocsr()
    adj = adj + adj.T
    _, label = connected_components(adj > 0, directed=False)
    main = np.bincount(label).argmax()
    keep = np.flatnonzero(label == main)
    lap = (sp.diags(np.asarray(adj.sum(axis=1)).ravel()) - adj).tocsr()
    b = np.zeros(n)
    np.add.at(b, i, h * lx)
    np.add.at(b, j, -h * lx)
    k_sub = lap[keep][:, keep]
    free = keep[1:]                         # theta = 0 at one particle (the field's gauge)
    a = lap[free][:, free].tocsr()
    rhs = b[free]
    theta = np.zeros(n)
    if len(free) <= 5_000:
        from scipy.sparse.linalg import spsolve
        theta[free] = spsolve(a.tocsc(), rhs)
    else:
        theta[free] = amg_solve(a, rhs, tol)
    del k_sub
    flow = h * (theta[i] - theta[j] - lx)
    volume = float(np.prod(packing.domain_hi - packing.domain_lo))
    return float(-(flow * lx).sum() / volume), time.perf_counter() - t0


# ---------------------------------------------------------------- random dispersions (case 10)
def rsa(lo, hi, radius: float, count: int, rng, max_attempts: int = 200_000):
    """Random sequential addition of ``count`` non-overlapping spheres of ``radius`` wholly
    inside the box [lo, hi]: (centres placed, attempts). Stops short of ``count`` when
    ``max_attempts`` trial centres in a row fail (jammed)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    centres = np.zeros((0, 3))
    fails = 0
    attempts = 0
    while len(centres) < count and fails < max_attempts:
        trial = rng.uniform(lo + radius, hi - radius, size=(256, 3))
        for c in trial:
            attempts += 1
            if len(centres) == 0 or np.min(np.sum((centres - c) ** 2, axis=1)) >= 4 * radius ** 2:
                centres = np.vstack([centres, c])
                fails = 0
                if len(centres) == count:
                    break
            else:
                fails += 1
    return centres, attempts


def compress_dispersion(lo, hi, radius: float, count: int, rng, start_fraction: float = 0.2,
                        max_sweeps: int = 20_000):
    """``count`` non-overlapping spheres of ``radius`` inside the box by Monte Carlo
    compression (a Lubachevsky-Stillinger-like inflation without dynamics, how volume
    fractions beyond random sequential addition's jamming are reached): place them by RSA at the
    radius giving ``start_fraction``, then alternate a sweep of random hard-sphere moves with
    growing every sphere to the largest radius the configuration allows (half the closest
    distance, the distance to the walls), up to ``radius``. Returns (centres, radius reached,
    sweeps)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    f_target = count * 4 / 3 * math.pi * radius ** 3 / float(np.prod(hi - lo))
    r = radius * min(1.0, (start_fraction / f_target) ** (1 / 3))
    centres, _ = rsa(lo, hi, r, count, rng)
    if len(centres) < count:
        raise ValueError(f"compress_dispersion: RSA could not start at f {start_fraction}")
    step = 0.5 * r
    sweeps = 0
    while r < radius and sweeps < max_sweeps:
        sweeps += 1
        accepted = 0
        for k in rng.permutation(count):
            trial = centres[k] + rng.uniform(-step, step, 3)
            if np.any(trial < lo + r) or np.any(trial > hi - r):
                continue
            d2 = np.sum((centres - trial) ** 2, axis=1)
            d2[k] = np.inf
            if d2.min() >= 4 * r * r:
                centres[k] = trial
                accepted += 1
        rate = accepted / count
        step *= 1.1 if rate > 0.4 else 0.9
        tree = cKDTree(centres)
        dmin = tree.query(centres, k=2)[0][:, 1].min()
        wall = np.min(np.minimum(centres - lo, hi - centres))
        r = min(radius, 0.5 * dmin, wall)
        step = min(step, 0.5 * r)
    return centres, r, sweeps


# ---------------------------------------------------------------- the continuum reference
def continuum_field(centres, radius: float, contrast: float, n: int, size: float = 1.0,
                    mixing: str = "arithmetic", axis: int = 1, sub: int = 4):
    """Steady finite-volume solve (tdem_post.continuum's operator, harmonic face conductances)
    of the unit cube [0, size]^3 holding the spheres (centres, radius) of conductivity
    ``contrast`` in a matrix of 1: faces normal to ``axis`` held at 0 (min) and 1 (max), the
    others adiabatic, n^3 cells. A cell's conductivity mixes the two phases by the fraction of it
    inside the spheres (``mixing`` arithmetic or harmonic). Solved by AMG-preconditioned CG
    (pyamg) to 1e-10, so that grids of 1e6 cells fit. Returns (grid, T, k_eff/k_m)."""
    from tdem_post import continuum as C
    grid = C.make_grid((0, 0, 0), (size,) * 3, (n, n, n))
    X, Y, Z = grid.mesh()
    frac = np.zeros(grid.shape)
    h = size / n
    for c in np.atleast_2d(centres):
        # only the cells near this sphere are sampled
        sl = tuple(slice(max(0, int((c[a] - radius) / h) - 1),
                         min(n, int((c[a] + radius) / h) + 2)) for a in range(3))
        sub_lo = tuple(grid.lo[a] + sl[a].start * h for a in range(3))
        sub_hi = tuple(grid.lo[a] + sl[a].stop * h for a in range(3))
        sub_grid = C.make_grid(sub_lo, sub_hi, tuple(s.stop - s.start for s in sl))
        frac[sl] += C.ball_fraction(sub_grid, c, radius, sub=sub)
    frac = np.clip(frac, 0.0, 1.0)
    if mixing == "arithmetic":
        k = 1.0 + (contrast - 1.0) * frac
    else:
        k = 1.0 / ((1.0 - frac) + frac / contrast)
    faces = ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")[2 * axis: 2 * axis + 2]
    dirichlet = {faces[0]: 0.0, faces[1]: 1.0}
    L, _, b = C.conductance_matrix(grid, k, dirichlet)
    T = amg_solve(L, b, 1e-10)
    heat = C._face_heat(grid, k, dirichlet, T)
    q = heat[faces[1]]
    return grid, T.reshape(grid.shape), q * size / (size * size * 1.0), k


def amg_solve(a, rhs, tol: float):
    """``a x = rhs`` (symmetric positive definite) by smoothed-aggregation AMG-preconditioned
    CG to ``tol``, 500 iterations at most: the kernel's AMG path
    (``thermal_kernel.solvers.implicit.SpdSolver``), whose setup runs with numpy's global
    generator seeded, so the same bits every time (pyamg's spectral-radius estimate starts from
    ``np.random.rand``; an unseeded setup moved case 9's FV reference in the 10th digit)."""
    from thermal_kernel.solvers.implicit import SpdSolver
    return SpdSolver(a.tocsr(), method="amg", tol=tol, maxiter=500).solve(rhs)


def centred_inclusion_unit():
    """(centres (1, 3), radius) of 002 sec. 4's inclusion in the unit cube: a = 1/3."""
    return np.array([[0.5, 0.5, 0.5]]), 1.0 / 3.0
