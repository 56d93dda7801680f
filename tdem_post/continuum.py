"""A small finite-volume solver of the heat equation on a structured 3-D grid: the continuum
reference of the validation cases that no paper tabulates (docs/validation.md, cases 3 and 9).

    rho_c dT/dt = div(k grad T) + q(x, t)

Cell-centred finite volumes on a box [lo, hi] cut into nx x ny x nz equal cells. Each cell has
its own conductivity k and volumetric heat capacity rho_c; the conductance of the face between
two cells is the series (harmonic) one, G = A / (h/(2 k_i) + h/(2 k_j)), so a conductivity jump
(a spherical inclusion) is a resistance in series and not an average. A Dirichlet face holds
T_D on the face itself: the boundary cell exchanges G_b (T_D - T) with G_b = A k / (h/2). Every
face not listed is adiabatic. One conductance matrix L (symmetric, positive semi-definite)
serves the steady solve L T = g_b T_D + Q and the theta-scheme

    (C/dt + theta L) T^{n+1} = (C/dt - (1 - theta) L) T^n + g_b T_D + Q^{n}

with C = rho_c V, Q^{n} the source integrated over the step by Gauss-Legendre points (a moving
source is sampled inside the step, not only at its ends), the matrix factorised once. theta = 1
is backward Euler (first order in dt); theta = 1/2 Crank-Nicolson (second order) started by
``startup_steps`` backward-Euler half steps (Rannacher), which damps the ringing that a held
step change of temperature excites. Second order in space: the tests measure the order under
refinement against tdem_post.analytic.

The energy ledger is exact to round-off: stored(t) - stored(0) = boundary heat + source heat,
with the boundary heat of each step taken at the theta-weighted temperature.

Functions take arrays and return arrays or small frozen results; nothing is global.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

FACES = {"xmin": (0, 0), "xmax": (0, 1), "ymin": (1, 0), "ymax": (1, 1),
         "zmin": (2, 0), "zmax": (2, 1)}


@dataclass(frozen=True)
class Grid:
    """The box [lo, hi] cut into shape = (nx, ny, nz) equal cells (index order x, y, z)."""
    lo: tuple
    hi: tuple
    shape: tuple

    @property
    def spacing(self) -> np.ndarray:
        return (np.asarray(self.hi, float) - np.asarray(self.lo, float)) / np.asarray(self.shape)

    @property
    def cell_volume(self) -> float:
        return float(np.prod(self.spacing))

    @property
    def n_cells(self) -> int:
        return int(np.prod(self.shape))

    def centres(self, axis: int) -> np.ndarray:
        h = self.spacing[axis]
        return self.lo[axis] + h * (np.arange(self.shape[axis]) + 0.5)

    def mesh(self):
        """X, Y, Z arrays of the cell centres, each of the grid's shape."""
        return np.meshgrid(self.centres(0), self.centres(1), self.centres(2), indexing="ij")


def make_grid(lo, hi, shape) -> Grid:
    lo = tuple(float(v) for v in lo)
    hi = tuple(float(v) for v in hi)
    shape = tuple(int(n) for n in shape)
    if len(lo) != 3 or len(hi) != 3 or len(shape) != 3:
        raise ValueError("make_grid: lo, hi and shape need three entries each")
    if any(b <= a for a, b in zip(lo, hi)) or any(n < 1 for n in shape):
        raise ValueError(f"make_grid: expected hi > lo and at least one cell per axis, got "
                         f"lo {lo}, hi {hi}, shape {shape}")
    return Grid(lo, hi, shape)


def cell_average(grid: Grid, fn: Callable, sub: int = 4) -> np.ndarray:
    """Mean of fn(X, Y, Z) over each cell, from sub^3 midpoint samples per cell (sub^2 or sub
    along an axis with one cell only). For sharp-edged fields - an inclusion's indicator, a
    cylinder source - this is the volume fraction the cell holds, which is what makes the grid
    converge smoothly under refinement."""
    h = grid.spacing
    offs = [(np.arange(sub) + 0.5) / sub - 0.5 if n > 1 else np.array([0.0])
            for n in grid.shape]
    X, Y, Z = grid.mesh()
    acc = np.zeros(grid.shape)
    count = 0
    for ox in offs[0]:
        for oy in offs[1]:
            for oz in offs[2]:
                acc += np.asarray(fn(X + ox * h[0], Y + oy * h[1], Z + oz * h[2]), float)
                count += 1
    return acc / count


def ball_fraction(grid: Grid, centre, radius: float, sub: int = 6) -> np.ndarray:
    """Volume fraction of each cell inside the ball |x - centre| <= radius (sampled)."""
    c = np.asarray(centre, float)
    return cell_average(grid, lambda x, y, z: ((x - c[0]) ** 2 + (y - c[1]) ** 2
                                               + (z - c[2]) ** 2) <= radius ** 2, sub)


# ------------------------------------------------------------------------------ operator
def _field(grid, value, name):
    a = np.broadcast_to(np.asarray(value, float), grid.shape).astype(float)
    if not np.all(np.isfinite(a)) or np.any(a <= 0):
        raise ValueError(f"continuum: {name} must be finite and > 0 in every cell")
    return a


def _face_value(grid, face, value):
    axis, _ = FACES[face]
    shape = tuple(n for a, n in enumerate(grid.shape) if a != axis)
    return np.broadcast_to(np.asarray(value, float), shape)


def conductance_matrix(grid: Grid, k, dirichlet: Mapping[str, object] = ()):
    """(L, g_b, b_d): L the (n, n) CSR conductance matrix (W/K) including the Dirichlet faces'
    conductances on its diagonal, g_b (n,) the Dirichlet conductance of each cell (0 inside),
    b_d (n,) = sum over its Dirichlet faces of G_b T_D (W). Heat into the cells: -L T + b_d."""
    k = _field(grid, k, "k")
    dirichlet = dict(dirichlet)
    unknown = sorted(set(dirichlet) - set(FACES))
    if unknown:
        raise ValueError(f"continuum: unknown face {unknown[0]!r} (faces: {', '.join(FACES)})")
    n = grid.n_cells
    h = grid.spacing
    idx = np.arange(n).reshape(grid.shape)
    rows, cols, vals = [], [], []
    diag = np.zeros(grid.shape)
    for axis in range(3):
        if grid.shape[axis] < 2:
            continue
        area = np.prod(np.delete(h, axis))
        lo = [slice(None)] * 3
        hi = [slice(None)] * 3
        lo[axis] = slice(0, -1)
        hi[axis] = slice(1, None)
        lo, hi = tuple(lo), tuple(hi)
        ka, kb = k[lo], k[hi]
        g = area * 2.0 * ka * kb / (h[axis] * (ka + kb))
        diag[lo] += g
        diag[hi] += g
        rows += [idx[lo].ravel(), idx[hi].ravel()]
        cols += [idx[hi].ravel(), idx[lo].ravel()]
        vals += [-g.ravel(), -g.ravel()]
    g_b = np.zeros(grid.shape)
    b_d = np.zeros(grid.shape)
    for face, value in dirichlet.items():
        axis, side = FACES[face]
        area = np.prod(np.delete(h, axis))
        sl = [slice(None)] * 3
        sl[axis] = -1 if side else 0
        sl = tuple(sl)
        gb = area * k[sl] / (0.5 * h[axis])
        g_b[sl] += gb
        b_d[sl] += gb * _face_value(grid, face, value)
    rows.append(idx.ravel())
    cols.append(idx.ravel())
    vals.append((diag + g_b).ravel())
    L = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n, n))
    return L, g_b.ravel(), b_d.ravel()


def _face_heat(grid, k, dirichlet, T):
    """Heat into the domain through each Dirichlet face (W) for cell temperatures T."""
    out = {}
    h = grid.spacing
    T = T.reshape(grid.shape)
    k = _field(grid, k, "k")
    for face, value in dict(dirichlet).items():
        axis, side = FACES[face]
        area = np.prod(np.delete(h, axis))
        sl = [slice(None)] * 3
        sl[axis] = -1 if side else 0
        sl = tuple(sl)
        gb = area * k[sl] / (0.5 * h[axis])
        out[face] = float(np.sum(gb * (_face_value(grid, face, value) - T[sl])))
    return out


# ------------------------------------------------------------------------------ steady
@dataclass(frozen=True)
class SteadyResult:
    temperature: np.ndarray          # grid.shape, K
    face_heat_w: dict                # heat into the domain through each Dirichlet face, W
    source_w: float                  # total source power, W
    balance: float                   # |sum face heat + source| / (sum |terms|): 0 to round-off


def solve_steady(grid: Grid, k, dirichlet: Mapping[str, object], source=None) -> SteadyResult:
    """Steady field: L T = b_d + q V. ``source``: None, or an array of the grid's shape (W/m^3).
    Needs at least one Dirichlet face (else the steady field is not unique)."""
    if not dict(dirichlet):
        raise ValueError("continuum: a steady solve needs at least one Dirichlet face")
    L, _, b_d = conductance_matrix(grid, k, dirichlet)
    q = np.zeros(grid.n_cells) if source is None else \
        np.broadcast_to(np.asarray(source, float), grid.shape).ravel() * grid.cell_volume
    T = splu(L.tocsc()).solve(b_d + q)
    faces = _face_heat(grid, k, dirichlet, T)
    total = sum(faces.values()) + q.sum()
    scale = sum(abs(v) for v in faces.values()) + abs(q.sum())
    return SteadyResult(T.reshape(grid.shape), faces, float(q.sum()),
                        float(abs(total) / scale) if scale > 0 else 0.0)


# ------------------------------------------------------------------------------ transient
@dataclass(frozen=True)
class TransientResult:
    times: np.ndarray                # (K,) output times, s
    temperature: np.ndarray | None   # (K, *grid.shape) when fields=True, else None
    probe_temperature: np.ndarray    # (K, P) at the probes (trilinear), K
    stored_energy_j: np.ndarray      # (K,) sum C (T - T(0))
    boundary_energy_j: np.ndarray    # (K,) heat in through the Dirichlet faces since t = 0
    source_energy_j: np.ndarray      # (K,) source heat since t = 0
    dt: float
    steps: int
    info: dict = field(default_factory=dict)

    def ledger_residual_j(self) -> np.ndarray:
        return self.stored_energy_j - self.boundary_energy_j - self.source_energy_j


def probe_weights(grid: Grid, points):
    """(P, 8) cell indices and weights of trilinear interpolation between cell centres at each
    point (clamped to the outermost centres: constant within half a cell of a face)."""
    pts = np.atleast_2d(np.asarray(points, float))
    idx = np.zeros((len(pts), 8), np.int64)
    w = np.ones((len(pts), 8))
    lows, fracs = [], []
    for a in range(3):
        n = grid.shape[a]
        s = (pts[:, a] - grid.lo[a]) / grid.spacing[a] - 0.5
        s = np.clip(s, 0.0, n - 1)
        i0 = np.minimum(np.floor(s).astype(np.int64), max(n - 2, 0))
        lows.append(i0)
        fracs.append(s - i0 if n > 1 else np.zeros(len(pts)))
    c = 0
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                ii = [np.minimum(lows[a] + d, grid.shape[a] - 1)
                      for a, d in enumerate((dx, dy, dz))]
                idx[:, c] = np.ravel_multi_index(ii, grid.shape)
                for a, d in enumerate((dx, dy, dz)):
                    w[:, c] *= fracs[a] if d else 1.0 - fracs[a]
                c += 1
    return idx, w


def interpolate(grid: Grid, T, points) -> np.ndarray:
    """Trilinear interpolation of the cell field T (grid.shape or (n,)) at points (P, 3)."""
    idx, w = probe_weights(grid, points)
    return np.sum(np.asarray(T).ravel()[idx] * w, axis=1)


def _output_steps(times, dt: float, theta: float):
    """:func:`solve_transient`'s output ``times`` as an array and the step count at each (each
    a multiple of ``dt``, increasing, >= 0; ``theta`` in [0.5, 1]), or a ValueError."""
    times = np.asarray(times, float).ravel()
    if dt <= 0 or not np.all(np.diff(times) > 0) or times[0] < 0:
        raise ValueError("continuum: dt > 0 and increasing output times >= 0 expected")
    steps_at = np.rint(times / dt).astype(np.int64)
    if np.any(np.abs(steps_at * dt - times) > 1e-6 * dt):
        raise ValueError(f"continuum: output times must be multiples of dt = {dt:g}")
    if not 0.5 <= theta <= 1.0:
        raise ValueError("continuum: theta in [0.5, 1] expected")
    return times, steps_at


def solve_transient(grid: Grid, k, rho_c, dirichlet: Mapping[str, object], t_initial, times,
                    dt: float, *, source: Callable | None = None, theta: float = 0.5,
                    startup_steps: int = 2, source_points: int = 3, probes=None,
                    fields: bool = True) -> TransientResult:
    """Transient field from T(0) = t_initial (scalar or grid array) to each of ``times`` (each a
    multiple of dt). ``source(t)`` -> array of the grid's shape in W/m^3 (use cell_average for a
    sharp region), integrated over each step with ``source_points`` Gauss-Legendre points.
    theta = 1: backward Euler; 0.5: Crank-Nicolson with ``startup_steps`` Rannacher steps (each
    two backward-Euler half steps). ``probes`` (P, 3): temperatures kept at every output time;
    ``fields=False`` keeps only those (a long run on a large grid)."""
    times, steps_at = _output_steps(times, dt, theta)
    L, g_b, b_d = conductance_matrix(grid, k, dirichlet)
    C = (_field(grid, rho_c, "rho_c") * grid.cell_volume).ravel()
    T = np.broadcast_to(np.asarray(t_initial, float), grid.shape).ravel().copy()
    T0 = T.copy()
    V = grid.cell_volume
    gp, gw = np.polynomial.legendre.leggauss(max(1, int(source_points)))

    def source_heat(t0, t1):      # J per cell over [t0, t1]
        if source is None:
            return None
        acc = np.zeros(grid.n_cells)
        for x, w in zip(gp, gw):
            t = t0 + 0.5 * (x + 1.0) * (t1 - t0)
            acc += 0.5 * w * np.broadcast_to(np.asarray(source(t), float), grid.shape).ravel()
        return acc * V * (t1 - t0)

    factors = {}

    def factor(step, th):
        key = (step, th)
        if key not in factors:
            factors[key] = splu((sp.diags(C / step) + th * L).tocsc())
        return factors[key]

    pidx, pw = (probe_weights(grid, probes) if probes is not None
                else (np.zeros((0, 8), np.int64), np.zeros((0, 8))))
    out_T, out_p, out_s, out_b, out_q = [], [], [], [], []
    e_bound = e_src = 0.0
    n_steps = int(steps_at[-1])
    t = 0.0
    k_out = 0

    def record():
        if fields:
            out_T.append(T.reshape(grid.shape).copy())
        out_p.append(np.sum(T[pidx] * pw, axis=1))
        out_s.append(float(C @ (T - T0)))
        out_b.append(e_bound)
        out_q.append(e_src)

    while k_out < len(times) and steps_at[k_out] == 0:
        record()
        k_out += 1
    for n in range(1, n_steps + 1):
        sub = [(dt / 2, 1.0)] * 2 if (theta < 1.0 and n <= startup_steps) else [(dt, theta)]
        for step, th in sub:
            q = source_heat(t, t + step)
            lu = factor(step, th)
            rhs = C / step * T - (1.0 - th) * (L @ T) + b_d
            if q is not None:
                rhs += q / step
            T_new = lu.solve(rhs)
            # heat in through the Dirichlet faces at the theta-weighted temperature
            T_th = th * T_new + (1.0 - th) * T
            e_bound += step * float(b_d.sum() - g_b @ T_th)
            if q is not None:
                e_src += float(q.sum())
            T = T_new
            t += step
        if k_out < len(times) and n == steps_at[k_out]:
            record()
            k_out += 1
    return TransientResult(times, np.array(out_T) if fields else None,
                           np.array(out_p).reshape(len(times), -1), np.array(out_s),
                           np.array(out_b), np.array(out_q), float(dt), n_steps,
                           {"theta": theta, "startup_steps": startup_steps,
                            "cells": grid.n_cells})


# ------------------------------------------------------------------------------ error estimate
@dataclass(frozen=True)
class RichardsonEstimate:
    extrapolated: np.ndarray   # the limit h -> 0 estimated from the two finest grids
    error: np.ndarray          # |finest - extrapolated|: the finest grid's error estimate
    order: np.ndarray          # observed order (from three grids; the assumed one with two)
    ratio: float               # refinement ratio h_coarse / h_fine


def richardson(values, ratio: float = 2.0, order: float | None = None) -> RichardsonEstimate:
    """Richardson error estimate of the finest of a sequence of solutions (coarse -> fine, each
    refined by ``ratio``; each entry a number or an array of values at the same points/times).

    With three or more solutions the observed order p = log(|f1 - f2| / |f2 - f3|) / log(ratio)
    is measured from the three finest (order=None); ``order`` fixes it (e.g. 2, when the
    differences are too small to measure it). Extrapolated f = f3 + (f3 - f2)/(ratio^p - 1);
    the error estimate of the finest is |f3 - f|. Report a "converged to X %" as
    error / (a scale of the solution)."""
    f = [np.asarray(v, float) for v in values]
    if len(f) < 2:
        raise ValueError("richardson: at least two solutions needed")
    if order is None:
        if len(f) < 3:
            raise ValueError("richardson: the observed order needs three solutions (or give order)")
        d1, d2 = f[-3] - f[-2], f[-2] - f[-1]
        # norm-wise order (pointwise ratios are noisy where a difference changes sign)
        n1, n2 = float(np.max(np.abs(d1))), float(np.max(np.abs(d2)))
        p = np.log(n1 / n2) / np.log(ratio) if n2 > 0 and n1 > 0 else np.nan
    else:
        p = float(order)
    ext = f[-1] + (f[-1] - f[-2]) / (ratio ** p - 1.0)
    return RichardsonEstimate(ext, np.abs(f[-1] - ext), np.asarray(p), float(ratio))
