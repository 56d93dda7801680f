"""Effective conductivity of a periodic two-phase voxel microstructure by an FFT solver: the
converged continuum reference of the random dispersions of validation case 10 (issue 23,
docs/fft_reference.md).

Method. The Lippmann-Schwinger equation of periodic scalar conduction, in the Galerkin form of
Zeman et al. (2010, J. Comput. Phys. 229, 8065) and Vondrejc, Zeman & Marek (2014, Comput. Math.
Appl. 68, 156): with a prescribed mean gradient E, find the temperature gradient e = E + e~, e~ a
compatible (curl-free, zero-mean) periodic field, such that G K e = 0, where K is the voxels'
conductivity and G the projection onto compatible zero-mean fields (the Green operator Gamma0 of a
unit reference medium: G^ = g g^T / |g|^2 per wave vector). G K G is symmetric positive on the
compatible fields, so conjugate gradients solve it, at a rate set by the contrast alone
((sqrt(c) - 1) / (sqrt(c) + 1) per iteration; about 20 iterations at c = 7.7). Each application
of G costs three forward and three inverse real FFTs (scipy.fft, ``workers`` threads, 1 unless
told). The effective conductivity along the axis is the mean flux <K e> / E.

Green operator (``scheme``): ``"willot"`` (default), the rotated finite-difference scheme of Willot
(2015, C. R. Mecanique 343, 232): the temperature lives on the voxels' corners and its gradient
at the centres is the average of the four edge differences, i.e. g_a = (2/h_a) sin(theta_a)
prod_{b != a} cos(theta_b), theta = xi h / 2; free of the Gibbs ringing of the spectral scheme,
exact for laminates. ``"spectral"``, Moulinec & Suquet's (1998, CMAME 157, 69) continuous
frequencies g = xi (Nyquist frequencies set to zero).

Composite voxels (:func:`spheres`). A voxel cut by an inclusion's surface gets the laminate
conductivity of Kabel, Merkert & Schneider (2015, CMAME 294, 168): with phi the inclusion's
volume fraction in the voxel (sampled on sub^3 points) and n the surface normal (centre of the
sphere to the voxel's centre), K = k_R n n^T + k_V (I - n n^T), k_V = phi k_i + (1 - phi) k_m
(arithmetic, along the interface) and k_R = 1 / (phi / k_i + (1 - phi) / k_m) (harmonic, across
it) - the exact conductivity of a flat interface through the voxel. Plain ``"arithmetic"`` or
``"harmonic"`` mixing of phi, and ``"binary"`` voxels (phase of the centre), are there to compare.

Cube with held faces. ``spheres(..., mirror=True)`` reflects the cube [0, L]^3 across its faces
into a periodic cell of side 2L (2n voxels a side). By symmetry the periodic solution with a mean
gradient along an axis is then constant on the two faces normal to it and carries no flux
through the other four: the cube with two opposite faces held and adiabatic sides - the flux test
of 002 sec. 2.2 that tdem runs on the same inclusions - solved exactly, at 8x the voxels.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

# scipy.fft and scipy.optimize are imported where they are used: `tdem` builds its parser from
# this module's add_arguments, and importing them here cost every `tdem` start-up ~95 ms

SCHEMES = ("willot", "spectral")
RULES = ("laminate", "arithmetic", "harmonic", "binary")


@dataclass(frozen=True, eq=False)
class VoxelConductivity:
    """Conductivity of an n1 x n2 x n3 voxel grid of a periodic cell of side ``cell`` (3 lengths):
    ``k`` the isotropic part per voxel; composite voxels (flat indices ``index``) add
    ``jump`` n n^T with their unit ``normal`` (a laminate: k across the interface = k + jump)."""
    k: np.ndarray
    cell: tuple = (1.0, 1.0, 1.0)
    index: np.ndarray | None = None
    jump: np.ndarray | None = None
    normal: np.ndarray | None = None

    def __post_init__(self):
        k = np.asarray(self.k)
        if k.ndim != 3 or min(k.shape) < 1:
            raise ValueError(f"VoxelConductivity: k must be a 3-D array of voxels, got shape "
                             f"{k.shape}")
        if not np.all(np.isfinite(k)) or np.any(k <= 0):
            raise ValueError("VoxelConductivity: k must be finite and > 0 in every voxel")
        if len(self.cell) != 3 or not all(np.isfinite(c) and c > 0 for c in self.cell):
            raise ValueError(f"VoxelConductivity: cell must be 3 lengths > 0, got {self.cell}")
        if self.index is not None:
            m = len(self.index)
            if np.shape(self.jump) != (m,) or np.shape(self.normal) != (m, 3):
                raise ValueError("VoxelConductivity: index, jump (m,) and normal (m, 3) must "
                                 "describe the same m composite voxels")
            if m and np.any(k.ravel()[self.index] + self.jump <= 0):
                raise ValueError("VoxelConductivity: k + jump must be > 0 (the conductivity "
                                 "across a composite voxel's interface)")

    @property
    def shape(self) -> tuple:
        return tuple(np.shape(self.k))

    def flux(self, e: np.ndarray) -> np.ndarray:
        """q = K e for a gradient field e of shape (3, n1, n2, n3)."""
        q = self.k[None] * e
        if self.index is not None and len(self.index):
            ef = e.reshape(3, -1)[:, self.index]
            proj = self.jump * np.einsum("am,ma->m", ef, self.normal)
            qf = q.reshape(3, -1)
            qf[:, self.index] += proj[None] * self.normal.T
        return q


@dataclass(frozen=True)
class FFTResult:
    """One FFT solve under a unit mean gradient along ``axis``."""
    k: float                 # effective conductivity along the axis, <q_axis> / E
    flux: tuple              # <q> (3 components): the column ``axis`` of the effective tensor
    axis: int
    iterations: int          # conjugate-gradient iterations
    residual: float          # final relative residual |r| / |b|
    converged: bool          # residual <= tol
    grid: tuple              # (n1, n2, n3)
    scheme: str
    boundary: str            # "periodic" or "faces"
    seconds: float


def _theta_g(freqs, h, scheme):
    """The wave-vector factors g_a (a broadcastable list of 3 arrays) and 1/|g|^2 (0 where g = 0:
    the mean and the modes the scheme cannot represent) for the angles theta = pi x (cycles
    per voxel) per axis."""
    g = []
    shape = tuple(len(t) for t in freqs)
    for a in range(3):
        sl = [None, None, None]
        sl[a] = slice(None)
        theta = np.pi * freqs[a]
        if scheme == "willot":
            ga = (2.0 / h[a]) * np.sin(theta)[tuple(sl)]
            for b in range(3):
                if b != a:
                    sb = [None, None, None]
                    sb[b] = slice(None)
                    ga = ga * np.cos(np.pi * freqs[b])[tuple(sb)]
        else:
            xi = 2.0 * theta / h[a]
            ga = np.where(np.isclose(np.abs(freqs[a]), 0.5), 0.0, xi)[tuple(sl)]
        g.append(np.broadcast_to(ga, shape).copy())
    norm2 = g[0] ** 2 + g[1] ** 2 + g[2] ** 2
    scale = norm2.max() if norm2.size else 1.0
    inv = np.zeros_like(norm2)
    ok = norm2 > 1e-12 * scale
    inv[ok] = 1.0 / norm2[ok]
    return g, inv


class _Projection:
    """G: the compatible zero-mean part of a vector field (3, n1, n2, n3).

    ``periodic``: real FFTs of the periodic cell. ``faces``: the cube reflected across its faces
    (module docstring) without building the reflection: each component has a parity per axis
    (the fluctuation of the temperature is odd along the loaded axis and even along the others;
    a derivative along an axis flips the parity there), so the FFT of the reflected field is,
    up to a phase common to all components and a factor (-i) per odd axis, the cosine (DCT-II,
    even) / sine (DST-II, odd) transform of the cube's values: frequencies 0 ... n per axis
    (DCT: 0 ... n - 1, DST: 1 ... n). The factors combine into a sign per component, +1 on the
    loaded axis' component (no odd axis) and -1 on the others (two)."""

    def __init__(self, shape, cell, scheme, boundary, axis, workers):
        self.shape, self.workers, self.boundary = shape, workers, boundary
        h = [cell[a] / shape[a] for a in range(3)]
        if boundary == "periodic":
            freqs = [np.fft.fftfreq(shape[0]), np.fft.fftfreq(shape[1]),
                     np.fft.rfftfreq(shape[2])]
        else:
            # the reflected cell has 2 n voxels a side: frequency k / (2 n), k = 0 ... n
            freqs = [np.arange(n + 1) / (2.0 * n) for n in shape]
            self.odd = [[c for c in range(3) if (c == axis) != (c == a)] for a in range(3)]
            self.sign = [1.0 if a == axis else -1.0 for a in range(3)]
        self.g, self.inv = _theta_g(freqs, h, scheme)

    def _forward(self, x, a):
        import scipy.fft as sfft
        odd = self.odd[a]
        even = [c for c in range(3) if c not in odd]
        y = x
        if even:
            y = sfft.dctn(y, type=2, axes=even, workers=self.workers)
        if odd:
            y = sfft.dstn(y, type=2, axes=odd, workers=self.workers)
        out = np.zeros(tuple(n + 1 for n in self.shape))
        out[tuple(slice(1, None) if c in odd else slice(0, -1) for c in range(3))] = y
        return out

    def _inverse(self, coef, a):
        import scipy.fft as sfft
        odd = self.odd[a]
        even = [c for c in range(3) if c not in odd]
        y = coef[tuple(slice(1, None) if c in odd else slice(0, -1) for c in range(3))]
        if odd:
            y = sfft.idstn(y, type=2, axes=odd, workers=self.workers)
        if even:
            y = sfft.idctn(y, type=2, axes=even, workers=self.workers)
        return y

    def __call__(self, tau):
        import scipy.fft as sfft
        g, inv, w = self.g, self.inv, self.workers
        out = np.empty_like(tau)
        s = None
        if self.boundary == "periodic":
            for a in range(3):
                t = sfft.rfftn(tau[a], workers=w)
                t *= g[a]
                s = t if s is None else s + t
            s *= inv
            for a in range(3):
                out[a] = sfft.irfftn(s * g[a], s=self.shape, workers=w)
            return out
        for a in range(3):
            t = self._forward(tau[a], a)
            t *= self.sign[a] * g[a]
            s = t if s is None else s + t
        s *= inv
        for a in range(3):
            out[a] = self._inverse(s * (self.sign[a] * g[a]), a)
        return out


def _as_conductivity(conductivity) -> VoxelConductivity:
    if isinstance(conductivity, VoxelConductivity):
        return conductivity
    k = np.asarray(conductivity, dtype=float)
    if k.ndim != 3:
        raise ValueError(f"solve: conductivity must be a 3-D voxel array or a VoxelConductivity, "
                         f"got shape {k.shape}")
    return VoxelConductivity(k=k)


BOUNDARIES = ("periodic", "faces")


def solve(conductivity, axis: int = 0, *, boundary: str = "periodic", scheme: str = "willot",
          tol: float = 1e-8, maxiter: int = 1000, workers: int = 1) -> FFTResult:
    """Effective conductivity of the voxel cell ``conductivity`` (a 3-D array of isotropic voxel
    conductivities of the unit cell, or a :class:`VoxelConductivity`) along ``axis``:
    conjugate gradients on the Lippmann-Schwinger equation (module docstring) to a relative
    residual ``tol``. ``boundary``: "periodic" (the cell repeats) or "faces" (the cell is a
    cube whose two faces normal to ``axis`` are held at two temperatures and whose other faces
    are adiabatic: solved as its reflection, with cosine / sine transforms, at the cost of the
    cube alone)."""
    t0 = time.perf_counter()
    if axis not in (0, 1, 2):
        raise ValueError(f"solve: axis must be 0, 1 or 2, got {axis!r}")
    if scheme not in SCHEMES:
        raise ValueError(f"solve: scheme must be one of {', '.join(SCHEMES)}, got {scheme!r}")
    if boundary not in BOUNDARIES:
        raise ValueError(f"solve: boundary must be one of {', '.join(BOUNDARIES)}, got "
                         f"{boundary!r}")
    if not (isinstance(tol, (int, float)) and 0 < tol < 1):
        raise ValueError(f"solve: tol must be a number in (0, 1), got {tol!r}")
    if not (isinstance(maxiter, int) and maxiter >= 1):
        raise ValueError(f"solve: maxiter must be an integer >= 1, got {maxiter!r}")
    if not (isinstance(workers, int) and workers >= 1):
        raise ValueError(f"solve: workers must be an integer >= 1, got {workers!r}")
    vc = _as_conductivity(conductivity)
    shape = vc.shape
    project = _Projection(shape, vc.cell, scheme, boundary, axis, workers)
    mean_e = np.zeros((3, 1, 1, 1))
    mean_e[axis] = 1.0
    e_mean = np.broadcast_to(mean_e, (3, *shape))
    q_mean = vc.flux(e_mean)
    b = -project(q_mean)
    bb = float(np.vdot(b, b))
    if bb <= 1e-28 * float(np.vdot(q_mean, q_mean)):    # round-off of a homogeneous cell
        bb = 0.0
    x = np.zeros_like(b)
    it, res = 0, 0.0
    if bb > 0:
        r = b
        p = r.copy()
        rr = bb
        res = 1.0
        while it < maxiter:
            ap = project(vc.flux(p))
            alpha = rr / float(np.vdot(p, ap))
            x += alpha * p
            r -= alpha * ap
            it += 1
            rr_new = float(np.vdot(r, r))
            res = math.sqrt(rr_new / bb)
            if res <= tol:
                break
            p *= rr_new / rr
            p += r
            rr = rr_new
        del p, r, ap
    x += e_mean
    q = vc.flux(x)
    if boundary == "periodic":
        flux = tuple(float(q[a].mean()) for a in range(3))
    else:       # the other components are odd in the reflected cell: their mean is zero
        flux = tuple(float(q[a].mean()) if a == axis else 0.0 for a in range(3))
    return FFTResult(k=flux[axis], flux=flux, axis=axis, iterations=it, residual=res,
                     converged=res <= tol, grid=shape, scheme=scheme, boundary=boundary,
                     seconds=time.perf_counter() - t0)


# ------------------------------------------------------------------ spherical inclusions
def sphere_fraction(centres, radius: float, n: int, cell: float = 1.0, sub: int = 6):
    """(phi, normal): the spheres' volume fraction in each voxel of the periodic n^3 grid of the
    cube of side ``cell`` (cut voxels sampled on sub^3 points, periodic images included) and a
    unit normal per voxel (centre of the sphere to the voxel's centre, weighted by how cut the
    voxel is by each sphere that cuts it)."""
    centres = np.atleast_2d(np.asarray(centres, float))
    h = cell / n
    phi = np.zeros((n, n, n))
    nvec = np.zeros((3, n, n, n))
    half = 0.5 * math.sqrt(3.0) * h
    offs = (np.arange(sub) + 0.5) / sub - 0.5                     # sample points in a voxel
    so = np.stack(np.meshgrid(offs, offs, offs, indexing="ij"), -1).reshape(-1, 3) * h
    for c in centres:
        lo = np.floor((c - radius) / h).astype(int) - 1
        hi = np.floor((c + radius) / h).astype(int) + 2
        ranges = [np.arange(lo[a], hi[a]) for a in range(3)]
        ii, jj, kk = np.meshgrid(*ranges, indexing="ij")
        idx = np.stack([ii.ravel(), jj.ravel(), kk.ravel()], -1)
        rel = (idx + 0.5) * h - c                               # voxel centre - sphere centre
        dist = np.linalg.norm(rel, axis=1)
        inside = dist + half <= radius
        cut = (~inside) & (dist - half < radius)
        f = inside.astype(float)
        if np.any(cut):
            pts = rel[cut][:, None, :] + so[None]                 # (m, sub^3, 3)
            f[cut] = np.mean(np.sum(pts * pts, axis=2) <= radius * radius, axis=1)
        keep = f > 0
        wrap = np.mod(idx[keep], n)
        flat = np.ravel_multi_index(wrap.T, (n, n, n))
        np.add.at(phi.ravel(), flat, f[keep])
        w = f[keep] * (1.0 - f[keep])
        unit = rel[keep] / np.maximum(dist[keep], 1e-300)[:, None]
        # a laminate's normal has no sign: align this sphere's normals with what the voxel holds
        # (in the gap between two near spheres their outward normals are opposite - summed as
        # they are they would cancel - and the laminate there is across the line of centres)
        held = np.stack([nvec[a].ravel()[flat] for a in range(3)], axis=1)
        sign = np.where(np.sum(held * unit, axis=1) < 0, -1.0, 1.0)
        for a in range(3):
            np.add.at(nvec[a].ravel(), flat, sign * w * unit[:, a])
    phi = np.clip(phi, 0.0, 1.0)
    norm = np.sqrt(np.sum(nvec ** 2, axis=0))
    nvec = np.where(norm > 0, nvec / np.maximum(norm, 1e-300), 0.0)
    return phi, nvec


def _mirror(phi, nvec):
    """phi and normals of the cube reflected across its three upper faces (2n a side)."""
    for a in range(3):
        phi = np.concatenate([phi, np.flip(phi, axis=a)], axis=a)
        flipped = np.flip(nvec, axis=a + 1).copy()
        flipped[a] *= -1.0
        nvec = np.concatenate([nvec, flipped], axis=a + 1)
    return phi, nvec


def composite(phi, nvec, k_matrix: float, k_inclusion: float, rule: str = "laminate",
              cell: float = 1.0) -> VoxelConductivity:
    """Voxel conductivities from the inclusion fraction ``phi`` (and normals ``nvec`` for the
    laminate rule) by ``rule`` (module docstring)."""
    if rule not in RULES:
        raise ValueError(f"composite: rule must be one of {', '.join(RULES)}, got {rule!r}")
    phi = np.asarray(phi, float)
    if rule == "binary":
        phi = (phi >= 0.5).astype(float)
    k_v = phi * k_inclusion + (1.0 - phi) * k_matrix
    k_r = 1.0 / (phi / k_inclusion + (1.0 - phi) / k_matrix)
    size = (cell,) * 3
    if rule in ("arithmetic", "binary"):
        return VoxelConductivity(k=k_v, cell=size)
    if rule == "harmonic":
        return VoxelConductivity(k=k_r, cell=size)
    flat = np.flatnonzero((phi.ravel() > 0) & (phi.ravel() < 1)
                          & (np.sum(nvec.reshape(3, -1) ** 2, axis=0) > 0.5))
    return VoxelConductivity(k=k_v, cell=size, index=flat,
                             jump=(k_r.ravel() - k_v.ravel())[flat],
                             normal=np.ascontiguousarray(nvec.reshape(3, -1)[:, flat].T))


def spheres(centres, radius: float, k_matrix: float, k_inclusion: float, n: int, *,
            cell: float = 1.0, rule: str = "laminate", sub: int = 6,
            mirror: bool = False) -> VoxelConductivity:
    """Voxel conductivity of spheres (``centres`` (m, 3) in [0, cell)^3, one ``radius``) of
    ``k_inclusion`` in a matrix of ``k_matrix`` on an n^3 grid of the periodic cube of side
    ``cell``. ``mirror``: the cube with faces instead (module docstring): the cube reflected
    into the periodic cell of side 2 cell, (2n)^3 voxels."""
    centres = np.atleast_2d(np.asarray(centres, float))
    if centres.ndim != 2 or centres.shape[1] != 3 or not np.all(np.isfinite(centres)):
        raise ValueError(f"spheres: centres must be finite points of shape (m, 3), got shape "
                         f"{centres.shape}")
    if not (np.isfinite(radius) and radius > 0):
        raise ValueError(f"spheres: radius must be > 0, got {radius!r}")
    if not (isinstance(n, (int, np.integer)) and n >= 2):
        raise ValueError(f"spheres: n must be an integer >= 2 (voxels a side), got {n!r}")
    for name, v in (("k_matrix", k_matrix), ("k_inclusion", k_inclusion), ("cell", cell)):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"spheres: {name} must be > 0, got {v!r}")
    if not (isinstance(sub, (int, np.integer)) and sub >= 1):
        raise ValueError(f"spheres: sub must be an integer >= 1 (samples a voxel edge), got "
                         f"{sub!r}")
    if rule not in RULES:
        raise ValueError(f"spheres: rule must be one of {', '.join(RULES)}, got {rule!r}")
    phi, nvec = sphere_fraction(centres, radius, int(n), cell, sub)
    if mirror:
        phi, nvec = _mirror(phi, nvec)
        cell = 2.0 * cell
    return composite(phi, nvec, k_matrix, k_inclusion, rule, cell)


# ------------------------------------------------------------------ grid convergence
@dataclass(frozen=True)
class Extrapolation:
    """k(h) = k0 + C h^p through the three finest grids (any spacings)."""
    value: float             # k0, the h -> 0 limit (the finest value when order is NaN)
    order: float             # observed p (NaN when the differences change sign)
    error: float             # |k_finest - k0|: the finest grid's estimated error
    finest: float


def extrapolate(h, values) -> Extrapolation:
    """Richardson extrapolation through the three finest of grids of spacings ``h`` (coarse to
    fine, any ratios): p solves (k1 - k2)/(k2 - k3) = (h1^p - h2^p)/(h2^p - h3^p). When the
    differences change sign (not in the asymptotic range) or p is outside (0.2, 6), the finest
    value is returned with the last difference as its error and order NaN."""
    h = np.asarray(h, float)
    v = np.asarray(values, float)
    if h.shape != v.shape or len(h) < 3:
        raise ValueError("extrapolate: h and values must be equally long, with 3 or more grids")
    (h1, h2, h3), (k1, k2, k3) = h[-3:], v[-3:]
    d1, d2 = k1 - k2, k2 - k3
    fallback = Extrapolation(float(k3), float("nan"), float(abs(d2)), float(k3))
    if d1 * d2 <= 0 or d2 == 0:
        return fallback
    ratio = d1 / d2

    def fn(p):
        return (h1 ** p - h2 ** p) / (h2 ** p - h3 ** p) - ratio
    from scipy.optimize import brentq
    try:
        p = brentq(fn, 0.2, 6.0)
    except ValueError:
        return fallback
    c = d2 / (h2 ** p - h3 ** p)
    k0 = k3 - c * h3 ** p
    return Extrapolation(float(k0), float(p), float(abs(k3 - k0)), float(k3))


# ------------------------------------------------------------------ command line
def add_arguments(ap) -> None:
    """The options of ``tdem fft-reference`` (one home: the subcommand and ``main``)."""
    ap.add_argument("--fraction", type=float, default=0.2,
                    help="volume fraction of the sphere, default 0.2")
    ap.add_argument("--contrast", type=float, default=1.5 / 0.195,
                    help="k_i/k_m, default 1.5/0.195 = 7.69")
    ap.add_argument("--grids", default="8,12,16,24,32,48,64",
                    help="voxels a side, comma-separated (default 8,12,16,24,32,48,64)")
    ap.add_argument("--rules", default="laminate,arithmetic,harmonic",
                    help="composite-voxel rules, comma-separated (default "
                         "laminate,arithmetic,harmonic; binary too)")
    ap.add_argument("--scheme", default="willot", choices=SCHEMES,
                    help="Green operator (default willot)")


def command(a) -> int:
    """``tdem fft-reference``: one sphere in the periodic cube (the simple-cubic array) on a
    refined sequence of grids, against Rayleigh's formula: the convergence table of
    docs/fft_reference.md."""
    from tdem_post.analytic import maxwell, rayleigh_cubic_array
    grids = [int(g) for g in a.grids.split(",")]
    f, c = a.fraction, a.contrast
    radius = (3 * f / (4 * math.pi)) ** (1 / 3)
    exact = float(rayleigh_cubic_array(1.0, c, f))
    print(f"one sphere, f {f}, contrast {c:.4f}: Rayleigh k/k_m {exact:.6f} "
          f"(Maxwell {float(maxwell(1.0, c, f)):.6f}); scheme {a.scheme}, 1 thread")
    for rule in a.rules.split(","):
        errs = []
        for n in grids:
            r = solve(spheres([[0.31, 0.47, 0.58]], radius, 1.0, c, n, rule=rule), 0,
                      scheme=a.scheme)
            errs.append(r.k / exact - 1)
            print(f"  {rule:10s} n {n:4d}: k/k_m {r.k:.6f}  error {100 * errs[-1]:+.4f} %  "
                  f"CG {r.iterations:3d}  {r.seconds:6.2f} s")
        h = 1.0 / np.array(grids, float)
        p = np.polyfit(np.log(h), np.log(np.abs(errs)), 1)[0]
        print(f"  {rule:10s} fitted order of |error| in h: {p:.2f}")
    return 0


def main(argv=None) -> int:
    """``python -m tdem_post.fft_conductivity``: the same as ``tdem fft-reference``."""
    import argparse
    ap = argparse.ArgumentParser(prog="python -m tdem_post.fft_conductivity",
                                 description=command.__doc__.splitlines()[0])
    add_arguments(ap)
    return command(ap.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
