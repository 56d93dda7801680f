"""The contact network the three solvers share: :class:`ThermalProblem` (what they receive) and
:func:`assemble` (built once: adjacency CSR, graph Laplacian, per-particle boundary terms,
clusters, explicit stability bound).

Equations (SI units; p, q particles; H_pq >= 0 the contact conductance in W/K)::

    C_p dT_p/dt = sum_q H_pq (T_q - T_p) + sum_k g_k (Tw_k - T_p) + P_p + S_p(t)
                = -(L T)_p - g_p T_p + b_p + S_p(t)

with L the graph Laplacian (L_pq = -H_pq, L_pp = sum_q H_pq), g_p = sum of the exchange
conductances of the rows k on particle p, b_p = sum_k g_k Tw_k + P_p. Dirichlet particles are
held at their temperature. See docs/solvers.md.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components


class NetworkError(ValueError):
    """A ThermalProblem that cannot be solved as given (bad shapes, values or indices)."""


@dataclass(frozen=True)
class ThermalProblem:
    """Everything a solver needs, as plain arrays (built by :mod:`thermal_kernel.problem`)."""
    capacity_j_k: np.ndarray        # (N,) C_p > 0
    pair: np.ndarray                # (M,2) int64, i<j
    conductance_w_k: np.ndarray     # (M,) H_ij >= 0
    # Dirichlet: particles held at a temperature (rows), each belonging to boundary b
    fixed_particle: np.ndarray      # (F,) int64, unique
    fixed_temperature_k: np.ndarray  # (F,)
    fixed_boundary: np.ndarray      # (F,) int32 in 0..B-1
    # exchange with a reservoir (particle touching a wall of fixed temperature): g (T_w - T_p)
    exchange_particle: np.ndarray   # (K,) int64 (a particle may appear several times)
    exchange_w_k: np.ndarray        # (K,) g >= 0
    exchange_temperature_k: np.ndarray  # (K,)
    exchange_boundary: np.ndarray   # (K,) int32
    # constant power injected into particles (prescribed heat flux on a face)
    power_particle: np.ndarray      # (P,) int64
    power_w: np.ndarray             # (P,)
    power_boundary: np.ndarray      # (P,) int32
    # time-dependent volumetric sources: source(t0, t1) -> (N,) mean power in W over [t0,t1]
    source: Callable | None
    source_boundary: int            # boundary index source heat is reported under (-1 if none)
    boundary_names: tuple[str, ...]  # (B,)

    @property
    def n_particles(self) -> int:
        return int(np.shape(self.capacity_j_k)[0])

    @property
    def n_boundaries(self) -> int:
        return len(self.boundary_names)


def make_problem(capacity_j_k, pair, conductance_w_k, *, fixed=(), exchange=(), power=(),
                 source=None, source_boundary=-1, boundary_names=()) -> ThermalProblem:
    """Convenience constructor (tests, examples): ``fixed`` = (particle, T, boundary),
    ``exchange`` = (particle, g, Tw, boundary), ``power`` = (particle, W, boundary); each a
    tuple of arrays or () for none."""
    def rows(spec, kinds):
        if len(spec) == 0:
            return [np.zeros(0, k) for k in kinds]
        return [np.atleast_1d(np.asarray(a, dtype=k)) for a, k in zip(spec, kinds)]
    fp, ft, fb = rows(fixed, (np.int64, np.float64, np.int32))
    ep, eg, et, eb = rows(exchange, (np.int64, np.float64, np.float64, np.int32))
    pp, pw, pb = rows(power, (np.int64, np.float64, np.int32))
    if not boundary_names:
        nb = max([int(a.max()) + 1 for a in (fb, eb, pb) if a.size] + [source_boundary + 1, 0])
        boundary_names = tuple(f"b{i}" for i in range(nb))
    return ThermalProblem(
        capacity_j_k=np.asarray(capacity_j_k, np.float64),
        pair=np.asarray(pair, np.int64).reshape(-1, 2),
        conductance_w_k=np.asarray(conductance_w_k, np.float64),
        fixed_particle=fp, fixed_temperature_k=ft, fixed_boundary=fb,
        exchange_particle=ep, exchange_w_k=eg, exchange_temperature_k=et, exchange_boundary=eb,
        power_particle=pp, power_w=pw, power_boundary=pb, source=source,
        source_boundary=int(source_boundary), boundary_names=tuple(boundary_names))


@dataclass(frozen=True)
class ClusterReport:
    """Connected components of the H > 0 graph that no Dirichlet particle and no exchange row
    with g > 0 ties to a reservoir. Rattlers are such components of one particle. Made by
    :func:`tied_clusters`, the one home of this logic (assembly, the steady solver and tau in
    ``tdem_post.fits`` all read it)."""
    n_components: int
    label: np.ndarray               # (N,) int: component of each particle
    floating_clusters: np.ndarray   # component ids of untied components with >= 2 particles
    floating_sizes: np.ndarray      # their sizes
    rattlers: np.ndarray            # particles alone in an untied component
    tied: np.ndarray                # (n_components,) bool: the component holds a reservoir

    @property
    def tied_particle(self) -> np.ndarray:
        """(N,) bool: the particle's component is tied to a reservoir (held particles
        included); the others (floating clusters, rattlers) keep their own temperature."""
        return self.tied[self.label]

    @property
    def n_floating(self) -> int:
        return int(self.floating_clusters.size)

    @property
    def n_rattlers(self) -> int:
        return int(self.rattlers.size)

    def summary(self) -> str:
        return _clusters_line(self.n_components, self.floating_sizes, self.n_rattlers)


def _clusters_line(n_components, floating_sizes, n_rattlers) -> str:
    """The clusters' one-line summary (ClusterReport and ClusterCounts)."""
    sizes = ", ".join(str(s) for s in floating_sizes[:10])
    more = " ..." if floating_sizes.size > 10 else ""
    return (f"{n_components} clusters; {floating_sizes.size} floating (not tied to a "
            f"temperature or exchange boundary; sizes {sizes or '-'}{more}); "
            f"{n_rattlers} rattlers (no conducting contact)")


@dataclass(frozen=True, eq=False)
class Network:
    """The assembled network (see :func:`assemble`). Arrays are read-only views, shared by the
    explicit, implicit and steady solvers.

    ``adjacency`` is the symmetric CSR of H_pq > 0 without a diagonal (int32 indices when they
    fit); the explicit kernel gathers along its rows. ``laplacian`` (built on first use, once)
    is diag(degree) - adjacency.
    """
    problem: ThermalProblem
    adjacency: sp.csr_matrix
    degree_w_k: np.ndarray          # (N,) sum_q H_pq
    n_active_contacts: int          # contacts with H > 0 (each counted once)
    n_zero_contacts: int            # contacts with H = 0 (dropped from the graph)
    held: np.ndarray                # (N,) bool, Dirichlet particle
    held_temperature_k: np.ndarray  # (N,) the held temperature (NaN where free)
    capacity_j_k: np.ndarray        # (N,) validated copies of the problem's rows:
    fixed_particle: np.ndarray      # (F,) int64
    fixed_boundary: np.ndarray      # (F,) int32
    exchange_particle: np.ndarray   # (K,) int64
    exchange_row_g_w_k: np.ndarray  # (K,)
    exchange_row_temperature_k: np.ndarray  # (K,)
    exchange_boundary: np.ndarray   # (K,) int32
    power_by_boundary_w: np.ndarray  # (B,) constant power entering through each boundary
    exchange_g_w_k: np.ndarray      # (N,) g_p = sum of exchange conductances on p
    exchange_gt_w: np.ndarray       # (N,) sum g Tw on p
    power_w: np.ndarray             # (N,) sum of constant power on p
    clusters: ClusterReport
    dt_max_s: float                 # exact positivity bound of forward Euler (inf if none)
    dt_max_particle: int            # the particle that sets it (-1 if none)
    dt_paper_s: float               # paper 002 eq. 15-16 in network form, for comparison
    flags: tuple[str, ...] = field(default=())

    @property
    def n(self) -> int:
        return self.problem.n_particles

    @cached_property
    def laplacian(self) -> sp.csr_matrix:
        """Graph Laplacian L = diag(sum_q H_pq) - H (CSR, symmetric, built once on first use)."""
        lap = sp.diags(self.degree_w_k, format="csr") - self.adjacency
        lap.sort_indices()
        return lap

    @cached_property
    def conducting(self) -> np.ndarray:
        """(N,) bool: a conducting contact (H > 0), or held: the particles that profiles
        average (post, validation). The others -- free, no conducting contact -- are the
        rattlers that post counts; unlike ``clusters.rattlers`` this counts a particle tied only
        by an exchange row too."""
        conducting = (self.degree_w_k > 0) | self.held
        conducting.flags.writeable = False
        return conducting

    @cached_property
    def constant_rhs_w(self) -> np.ndarray:
        """b_p = sum g Tw + P_p (constant part of the right-hand side)."""
        return self.exchange_gt_w + self.power_w

    @cached_property
    def held_boundary(self) -> np.ndarray:
        """(N,) int32: the Dirichlet boundary holding each particle, -1 where free."""
        hb = np.full(self.n, -1, np.int32)
        hb[self.fixed_particle] = self.fixed_boundary
        return hb

    @cached_property
    def constant_boundary_flow_w(self) -> np.ndarray:
        """(B,) the constant power of each power boundary, with the power that lands on held
        particles moved (negatively) to the Dirichlet boundary that absorbs it."""
        p = self.problem
        return constant_flows(self.power_by_boundary_w, p.power_particle, p.power_w, self.held,
                              self.held_boundary)

    @cached_property
    def _fixed_rows(self) -> sp.csr_matrix:
        return self.adjacency[self.fixed_particle]

    def boundary_heat_flow(self, temperature_k, source_w=None) -> np.ndarray:
        """(B,) heat entering the network through each boundary (W) at ``temperature_k``:
        held particles give sum_q H_pq (T_p - T_q) minus what exchange, power and source put
        into them; exchange rows give g (Tw - T_p); power rows their power; the source (if
        ``source_w`` (N,) is given and source_boundary >= 0) its total under its column."""
        t = np.asarray(temperature_k, dtype=np.float64)
        nb = self.problem.n_boundaries
        out = self.constant_boundary_flow_w.copy()
        if self.fixed_particle.size:
            fp = self.fixed_particle
            flow = self.degree_w_k[fp] * t[fp] - self._fixed_rows @ t
            out += np.bincount(self.fixed_boundary, weights=flow, minlength=nb)
        if self.exchange_particle.size:
            ep = self.exchange_particle
            q = self.exchange_row_g_w_k * (self.exchange_row_temperature_k - t[ep])
            out += np.bincount(self.exchange_boundary, weights=q, minlength=nb)
            on_held = self.held[ep]
            if on_held.any():
                out -= np.bincount(self.held_boundary[ep[on_held]], weights=q[on_held],
                                   minlength=nb)
        if source_w is not None:
            s = np.asarray(source_w, dtype=np.float64)
            if self.problem.source_boundary >= 0:
                out[self.problem.source_boundary] += s.sum()
            if self.fixed_particle.size:
                out -= np.bincount(self.fixed_boundary, weights=s[self.fixed_particle],
                                   minlength=nb)
        return out

    @cached_property
    def free(self) -> np.ndarray:
        return np.flatnonzero(~self.held)

    @cached_property
    def prescribed_mean_k(self) -> float:
        """The steady solve's reference T_ref (:func:`prescribed_mean`)."""
        return prescribed_mean(self.held_temperature_k[self.fixed_particle],
                               self.exchange_row_temperature_k, self.exchange_row_g_w_k)

    @cached_property
    def has_exchange(self) -> bool:
        return bool(np.any(self.exchange_g_w_k > 0))

    @cached_property
    def has_constant_rhs(self) -> bool:
        return bool(np.any(self.constant_rhs_w != 0))


@dataclass(frozen=True, eq=False)
class UntiedParticles:
    """The particles of the components no reservoir ties (floating clusters and rattlers),
    what a steady solve gives them (:func:`~thermal_kernel.solvers.steady.fill_untied`)
    without the rest of the network: their packing indices (sorted), components, capacities
    and the graph Laplacian's rows and columns of them (a contact of theirs joins only their
    own component). :func:`untied_of`."""
    particle: np.ndarray            # (U,) int64, sorted
    label: np.ndarray               # (U,) their components (ClusterReport.label)
    capacity_j_k: np.ndarray        # (U,)
    laplacian: sp.csr_matrix        # (U, U)
    n_components: int               # of the whole network (the labels' range)


def untied_of(net: Network) -> UntiedParticles:
    """The :class:`UntiedParticles` of ``net`` (the network whole, or the PETSc backend's
    rank 0's, which holds the untied particles' rows)."""
    sel = np.flatnonzero(~net.clusters.tied_particle)
    lap = net.laplacian[sel][:, sel].tocsr() if sel.size else sp.csr_matrix((0, 0))
    return UntiedParticles(particle=sel, label=np.asarray(net.clusters.label)[sel],
                           capacity_j_k=np.asarray(net.capacity_j_k)[sel], laplacian=lap,
                           n_components=net.clusters.n_components)


@dataclass(frozen=True)
class ClusterCounts:
    """A :class:`ClusterReport`'s counts without its arrays of particles (NetworkSummary)."""
    n_components: int
    floating_sizes: np.ndarray      # (floating clusters,)
    n_rattlers: int

    @property
    def n_floating(self) -> int:
        return int(self.floating_sizes.size)

    def summary(self) -> str:
        return _clusters_line(self.n_components, self.floating_sizes, self.n_rattlers)

    @classmethod
    def of(cls, report: ClusterReport) -> ClusterCounts:
        return cls(n_components=report.n_components,
                   floating_sizes=np.array(report.floating_sizes), n_rattlers=report.n_rattlers)


@dataclass(frozen=True)
class ProblemSummary:
    """A :class:`ThermalProblem`'s boundaries and source, without its arrays (NetworkSummary).
    ``source`` is None when the PETSc backend's ranks each evaluate it on their own block."""
    boundary_names: tuple[str, ...]
    source_boundary: int
    source: Callable | None

    @property
    def n_boundaries(self) -> int:
        return len(self.boundary_names)

    @classmethod
    def of(cls, problem: ThermalProblem) -> ProblemSummary:
        return cls(boundary_names=problem.boundary_names,
                   source_boundary=problem.source_boundary, source=problem.source)


@dataclass(frozen=True, eq=False)
class NetworkSummary:
    """What a run reads of its network on the PETSc backend's rank 0 once every rank holds its
    rows (thermal_kernel/mpi_run.py): its counts, the explicit bounds, the flags, the clusters'
    counts, the boundaries' names and constant powers, the source, the steady reference and
    untied particles, the maximum principle's inputs. No array of every particle (the ranks'
    rows hold them). :func:`summary_of`; the per-rank build makes the same from its parts."""
    problem: ProblemSummary
    n: int
    n_active_contacts: int
    n_zero_contacts: int
    flags: tuple[str, ...]
    dt_max_s: float
    dt_max_particle: int
    dt_paper_s: float
    clusters: ClusterCounts
    constant_boundary_flow_w: np.ndarray    # (B,) W
    prescribed_mean_k: float                # Network.prescribed_mean_k
    untied: UntiedParticles                 # what a steady solve fills on rank 0
    principle: PrincipleInputs              # what the maximum principle's bounds need


def summary_of(net: Network) -> NetworkSummary:
    """The :class:`NetworkSummary` of a whole network (the PETSc backend's ``--whole-build``;
    the per-rank build makes rank 0's from its parts, thermal_kernel/rank_build.py)."""
    return NetworkSummary(
        problem=ProblemSummary.of(net.problem), n=net.n,
        n_active_contacts=net.n_active_contacts, n_zero_contacts=net.n_zero_contacts,
        flags=net.flags, dt_max_s=net.dt_max_s, dt_max_particle=net.dt_max_particle,
        dt_paper_s=net.dt_paper_s,
        clusters=ClusterCounts.of(net.clusters),
        constant_boundary_flow_w=np.array(net.constant_boundary_flow_w, dtype=np.float64),
        prescribed_mean_k=net.prescribed_mean_k, untied=untied_of(net),
        principle=principle_inputs(net))


def without_source(summary: NetworkSummary) -> NetworkSummary:
    """``summary`` without its source (the PETSc backend's ranks each evaluate theirs)."""
    return dataclasses.replace(summary, problem=dataclasses.replace(summary.problem,
                                                                    source=None))


def constant_flows(power_by_boundary_w, power_particle, power_w, held,
                   held_boundary) -> np.ndarray:
    """(B,) the constant power of each power boundary (``power_by_boundary_w``), with the power
    of the rows (``power_particle``, ``power_w``) that land on held particles (``held``,
    ``held_boundary``: indexed by particle) moved (negatively) to the Dirichlet boundary that
    absorbs it: Network.constant_boundary_flow_w, and the PETSc backend's rank 0."""
    out = np.array(power_by_boundary_w, dtype=np.float64)
    pp = np.asarray(power_particle, np.int64)
    on_held = held[pp]
    if on_held.any():
        out -= np.bincount(held_boundary[pp[on_held]],
                           weights=np.asarray(power_w, np.float64)[on_held],
                           minlength=out.size)
    return out


def prescribed_mean(fixed_temperature_k, exchange_temperature_k, exchange_g_w_k) -> float:
    """The mean of the prescribed temperatures (the held rows', the exchange rows' with
    g > 0; 0 without any): the steady solve's reference T_ref, which it solves the deviation
    from."""
    prescribed = np.concatenate([np.asarray(fixed_temperature_k, dtype=np.float64),
                                 np.asarray(exchange_temperature_k, dtype=np.float64)[
                                     np.asarray(exchange_g_w_k) > 0]])
    return float(prescribed.mean()) if prescribed.size else 0.0


@dataclass(frozen=True)
class PrincipleInputs:
    """What the maximum principle's bounds (:func:`~thermal_kernel.solvers.common.bounds_at`)
    need of a network, besides the start: the range of its prescribed temperatures (held
    particles, exchange walls; +inf / -inf when it has none), the fastest a prescribed power
    raises / lowers a free particle (max_p P_p^+ / C_p, max_p P_p^- / C_p, K/s), its source's
    fastest rise and fall and when the source is on
    (:meth:`~thermal_kernel.boundaries.source.MovingSource.max_rise_rate`; None without a
    source, ``source_unbounded`` for a source that gives no such rate), and whether it is the
    plain principle (no source, no prescribed power). :func:`principle_of`."""
    prescribed_lo_k: float
    prescribed_hi_k: float
    power_up_k_s: float
    power_down_k_s: float
    plain: bool
    source_rate: tuple | None = None      # (up K/s, down K/s, start s, stop s)
    source_unbounded: bool = False


def principle_of(prescribed_k, power_free_w, capacity_free_j_k, *, has_power: bool,
                 has_source: bool, source_rate=None) -> PrincipleInputs:
    """:class:`PrincipleInputs` from the prescribed temperatures (K), the constant power and
    the capacity of free particles (any subset holding every free particle with a power: the
    others add nothing to a maximum that starts at 0), whether any particle (held ones too)
    has a constant power, and the source's rate (None: no source, or one that gives none): the
    whole network's (solvers.common.principle_inputs) or the PETSc backend's rank 0's (its
    rows)."""
    pw = np.asarray(power_free_w, dtype=np.float64)
    c = np.asarray(capacity_free_j_k, dtype=np.float64)
    prescribed = np.asarray(prescribed_k, dtype=np.float64)
    return PrincipleInputs(
        prescribed_lo_k=float(prescribed.min(initial=math.inf)),
        prescribed_hi_k=float(prescribed.max(initial=-math.inf)),
        power_up_k_s=float(np.max(np.clip(pw, 0, None) / c, initial=0.0)),
        power_down_k_s=float(np.max(np.clip(-pw, 0, None) / c, initial=0.0)),
        plain=not has_source and not has_power,
        source_rate=source_rate, source_unbounded=has_source and source_rate is None)


def principle_inputs(net: Network) -> PrincipleInputs:
    """:class:`PrincipleInputs` of a whole network (:func:`principle_of` on its arrays)."""
    prob = net.problem
    free = net.free
    rate = getattr(prob.source, "max_rise_rate", None)
    return principle_of(
        np.concatenate([net.held_temperature_k[net.fixed_particle],
                        np.asarray(net.exchange_row_temperature_k, dtype=np.float64)]),
        np.asarray(net.power_w, dtype=np.float64)[free], net.capacity_j_k[free],
        has_power=bool(np.any(np.asarray(net.power_w) != 0)),
        has_source=prob.source is not None,
        source_rate=None if rate is None else rate(net.capacity_j_k, free))


def _as(name, a, dtype, shape):
    a = np.asarray(a)
    if a.ndim != len(shape) or any(s is not None and a.shape[k] != s for k, s in enumerate(shape)):
        want = "(" + ", ".join("?" if s is None else str(s) for s in shape) + ")"
        raise NetworkError(f"ThermalProblem.{name}: shape {a.shape}, expected {want}")
    if np.issubdtype(dtype, np.integer) and a.size and not np.issubdtype(a.dtype, np.integer):
        raise NetworkError(f"ThermalProblem.{name}: integer indices expected, got {a.dtype}")
    return np.ascontiguousarray(a, dtype=dtype)


def _check_finite(name, a, nonneg=False, positive=False):
    bad = ~np.isfinite(a)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise NetworkError(f"ThermalProblem.{name}: {int(bad.sum())} non-finite values "
                           f"(first at row {k}: {a[k]})")
    if positive and a.size and (a <= 0).any():
        k = int(np.flatnonzero(a <= 0)[0])
        raise NetworkError(f"ThermalProblem.{name}: must be > 0; {int((a <= 0).sum())} values "
                           f"are not (first at row {k}: {a[k]})")
    if nonneg and a.size and (a < 0).any():
        k = int(np.flatnonzero(a < 0)[0])
        raise NetworkError(f"ThermalProblem.{name}: must be >= 0; {int((a < 0).sum())} values "
                           f"are negative (first at row {k}: {a[k]})")


def _check_index(name, idx, n, what="particle"):
    if idx.size and (idx.min() < 0 or idx.max() >= n):
        k = int(np.flatnonzero((idx < 0) | (idx >= n))[0])
        raise NetworkError(f"ThermalProblem.{name}: {what} index {idx[k]} at row {k} is out of "
                           f"range 0..{n - 1}")


def validate(problem: ThermalProblem) -> dict:
    """Check shapes, indices and values; return the arrays as contiguous, typed copies/views.
    Raises :class:`NetworkError` (a ValueError) with a one-line message naming the field."""
    c = _as("capacity_j_k", problem.capacity_j_k, np.float64, (None,))
    n = c.shape[0]
    _check_finite("capacity_j_k", c, positive=True)
    pair = _as("pair", problem.pair, np.int64, (None, 2))
    m = pair.shape[0]
    h = _as("conductance_w_k", problem.conductance_w_k, np.float64, (m,))
    _check_finite("conductance_w_k", h, nonneg=True)
    _check_index("pair", pair.reshape(-1), n)
    if m and not (pair[:, 0] < pair[:, 1]).all():
        k = int(np.flatnonzero(pair[:, 0] >= pair[:, 1])[0])
        raise NetworkError(f"ThermalProblem.pair: row {k} = {tuple(pair[k])} is not i < j")
    nb = len(problem.boundary_names)
    out = dict(capacity=c, pair=pair, conductance=h, n=n, m=m)
    f = _as("fixed_particle", problem.fixed_particle, np.int64, (None,))
    out["fixed_particle"] = f
    out["fixed_temperature"] = _as("fixed_temperature_k", problem.fixed_temperature_k,
                                   np.float64, (f.size,))
    out["fixed_boundary"] = _as("fixed_boundary", problem.fixed_boundary, np.int32, (f.size,))
    _check_index("fixed_particle", f, n)
    if np.unique(f).size != f.size:
        raise NetworkError(f"ThermalProblem.fixed_particle: {f.size - np.unique(f).size} "
                           "particles are listed twice (each must be held by one boundary)")
    _check_finite("fixed_temperature_k", out["fixed_temperature"])
    k = _as("exchange_particle", problem.exchange_particle, np.int64, (None,))
    out["exchange_particle"] = k
    out["exchange_g"] = _as("exchange_w_k", problem.exchange_w_k, np.float64, (k.size,))
    out["exchange_t"] = _as("exchange_temperature_k", problem.exchange_temperature_k,
                            np.float64, (k.size,))
    out["exchange_boundary"] = _as("exchange_boundary", problem.exchange_boundary, np.int32,
                                   (k.size,))
    _check_index("exchange_particle", k, n)
    _check_finite("exchange_w_k", out["exchange_g"], nonneg=True)
    _check_finite("exchange_temperature_k", out["exchange_t"])
    p = _as("power_particle", problem.power_particle, np.int64, (None,))
    out["power_particle"] = p
    out["power"] = _as("power_w", problem.power_w, np.float64, (p.size,))
    out["power_boundary"] = _as("power_boundary", problem.power_boundary, np.int32, (p.size,))
    _check_index("power_particle", p, n)
    _check_finite("power_w", out["power"])
    for name in ("fixed_boundary", "exchange_boundary", "power_boundary"):
        _check_index(name, out[name], nb, what="boundary")
    sb = int(problem.source_boundary)
    if not -1 <= sb < nb:
        raise NetworkError(f"ThermalProblem.source_boundary: {sb} is not -1 or a boundary "
                           f"index 0..{nb - 1}")
    if problem.source is not None and not callable(problem.source):
        raise NetworkError("ThermalProblem.source: must be callable source(t0, t1) or None")
    return out


def paper_critical_dt(d_min_m: float, diffusivity_m2_s: float, n_p: float, c_t: float) -> float:
    """Critical time step of paper 002 (eq. 16): dt_cr = 2 d_min^2 / (3 alpha n_p C_t).

    Derived there for a uniform packing (all particles of the mean radius, every contact like
    the mean contact); it is an estimate, not a bound (see :func:`assemble`'s exact bound)."""
    return 2.0 * d_min_m ** 2 / (3.0 * diffusivity_m2_s * n_p * c_t)


def tied_clusters(adjacency, reservoir) -> ClusterReport:
    """The connected components of the graph ``adjacency`` (N x N, its nonzeros the conducting
    contacts) and which of them are tied to a reservoir: a component is tied when it holds a
    particle with ``reservoir`` True (a Dirichlet particle, or an exchange row with g > 0).
    Untied components of >= 2 particles are floating clusters, of one particle rattlers."""
    n_comp, label = connected_components(adjacency, directed=False)
    return cluster_report(n_comp, label, reservoir)


def untied_components(tied, sizes) -> tuple[np.ndarray, np.ndarray]:
    """The components no reservoir ties (``tied``, ``sizes``: per component), as (floating
    clusters: >= 2 particles, rattlers: 1), component ids ascending: :func:`cluster_report`'s,
    and the PETSc backend's rank 0's counts (thermal_kernel/rank_build.py)."""
    untied = np.flatnonzero(~np.asarray(tied, dtype=bool))
    return untied[sizes[untied] >= 2], untied[sizes[untied] == 1]


def cluster_report(n_comp: int, label: np.ndarray, reservoir) -> ClusterReport:
    """The :class:`ClusterReport` of components ``label`` (numbered 0..n_comp-1, in the order
    of their first particle, as scipy's connected_components numbers them), found whole by
    :func:`tied_clusters`."""
    tied = np.zeros(n_comp, dtype=bool)
    tied[label[np.asarray(reservoir, dtype=bool)]] = True
    sizes = np.bincount(label, minlength=n_comp)
    floating, rattler_comp = untied_components(tied, sizes)
    if rattler_comp.size:       # a flag per component, read through the labels (isin sorts)
        is_rattler = np.zeros(n_comp, dtype=bool)
        is_rattler[rattler_comp] = True
        rattlers = np.flatnonzero(is_rattler[label])
    else:
        rattlers = np.zeros(0, np.int64)
    tied.flags.writeable = False
    return ClusterReport(n_components=int(n_comp), label=label, floating_clusters=floating,
                         floating_sizes=sizes[floating], rattlers=rattlers, tied=tied)


def particle_terms(v: dict) -> dict:
    """The per-particle boundary terms of a validated problem (:func:`validate`'s ``v``): held
    and its temperature, the exchange g_p and sum g Tw, the constant power."""
    n = v["n"]
    held = np.zeros(n, dtype=bool)
    held[v["fixed_particle"]] = True
    held_t = np.full(n, np.nan)
    held_t[v["fixed_particle"]] = v["fixed_temperature"]
    ep, eg = v["exchange_particle"], v["exchange_g"]
    # (bincount with weights gives float64: no copy)
    g_p = np.bincount(ep, weights=eg, minlength=n).astype(np.float64, copy=False)
    gt_p = np.bincount(ep, weights=eg * v["exchange_t"], minlength=n).astype(np.float64,
                                                                            copy=False)
    pw_p = np.bincount(v["power_particle"], weights=v["power"], minlength=n).astype(
        np.float64, copy=False)
    return dict(held=held, held_t=held_t, g_p=g_p, gt_p=gt_p, pw_p=pw_p)


def assemble(problem: ThermalProblem) -> Network:
    """Validate ``problem`` and build, once, everything the solvers need.

    - adjacency CSR of the H > 0 contacts (symmetric, sorted rows; the explicit kernel gathers
      along rows, which is what makes its result independent of the thread count);
    - degree sum_q H_pq, per-particle exchange g_p and sum g Tw, constant power;
    - clusters: connected components of the H > 0 graph; those tied neither to a Dirichlet
      particle nor to an exchange row with g > 0 are reported (floating clusters, rattlers);
    - the exact forward-Euler positivity bound dt_max = min over free p of
      C_p / (sum_q H_pq + g_p), and the paper-002 estimate C_mean / (n_max H_mean).
    """
    v = validate(problem)
    n = v["n"]
    h, pair = v["conductance"], v["pair"]
    active = h > 0
    n_active = int(active.sum())
    i, j, ha = pair[active, 0], pair[active, 1], h[active]
    idx = np.int32 if n < 2 ** 31 - 1 else np.int64   # halves the peak memory of assembly
    rows = np.concatenate([i, j]).astype(idx, copy=False)
    cols = np.concatenate([j, i]).astype(idx, copy=False)
    del i, j
    # Counting sort into CSR (scipy, O(nnz)), then sorted column indices within each row: the
    # order in which the explicit kernel sums a row is fixed by the data, not by the threads.
    adjacency = sp.coo_matrix((np.concatenate([ha, ha]), (rows, cols)), shape=(n, n)).tocsr()
    del rows, cols
    adjacency.sum_duplicates()
    adjacency.sort_indices()
    if adjacency.nnz != 2 * n_active:
        key = pair[active, 0] * n + pair[active, 1]
        uniq, counts = np.unique(key, return_counts=True)
        first = int(uniq[counts > 1][0])
        raise NetworkError(f"ThermalProblem.pair: {int((counts - 1).sum())} contacts are listed "
                           f"more than once (first: {first // n}-{first % n})")
    indptr = adjacency.indptr
    # Row sums, each row added in column order (deterministic).
    degree = np.bincount(np.repeat(np.arange(n), np.diff(indptr)), weights=adjacency.data,
                         minlength=n).astype(np.float64)

    terms = particle_terms(v)
    clusters = tied_clusters(adjacency, terms["held"] | (terms["g_p"] > 0))
    coord_max = int(np.diff(indptr).max()) if n_active else 0
    h_mean = float(np.mean(ha)) if n_active else float("nan")
    return network_of(problem, v, terms, adjacency, degree, n_active, clusters, coord_max,
                      h_mean)


def explicit_ratios(capacity_j_k, degree_w_k, g_w_k, held) -> tuple[np.ndarray, bool]:
    """(C_p / (sum_q H_pq + g_p) for the free particles with a conductance, inf for the others;
    whether there is any such particle): the exact forward-Euler bound is their minimum
    (network_of, whole; the PETSc backend's ranks, each over its rows). Made in place: two
    arrays of N at most, not five."""
    ratio = degree_w_k + g_w_k
    ok = ratio > 0
    ok &= ~held
    with np.errstate(divide="ignore", invalid="ignore"):
        np.divide(capacity_j_k, ratio, out=ratio)
    ratio[~ok] = np.inf
    return ratio, bool(ok.any())


def network_flags(n_zero_contacts: int, clusters) -> tuple[str, ...]:
    """A network's flags: contacts of H = 0 dropped, floating clusters, rattlers (``clusters``:
    a ClusterReport or ClusterCounts)."""
    flags = []
    if n_zero_contacts:
        flags.append("zero_conductance_contacts_dropped")
    if clusters.n_floating:
        flags.append("floating_clusters")
    if clusters.n_rattlers:
        flags.append("rattlers")
    return tuple(flags)


def network_of(problem: ThermalProblem, v: dict, terms: dict, adjacency, degree, n_active,
               clusters, coord_max, h_mean) -> Network:
    """The :class:`Network` from its parts (:func:`assemble`): the explicit bounds and the
    flags computed here (:func:`network_flags`)."""
    m = v["m"]
    held, held_t, g_p = terms["held"], terms["held_t"], terms["g_p"]
    gt_p, pw_p = terms["gt_p"], terms["pw_p"]
    c = v["capacity"]
    ratio, any_free = explicit_ratios(c, degree, g_p, held)
    if any_free:
        p_min = int(np.argmin(ratio))
        dt_max = float(ratio[p_min])
    else:
        p_min, dt_max = -1, float("inf")
    del ratio
    # Paper 002 eq. 15-16 in network form: every particle like the mean particle, every contact
    # like the mean contact, the largest coordination number.
    if n_active:
        dt_paper = float(np.mean(c) / (coord_max * h_mean))
    else:
        dt_paper = float("inf")
    flags = network_flags(m - n_active, clusters)
    for a in (adjacency.data, adjacency.indices, adjacency.indptr, degree, held, held_t, g_p,
              gt_p, pw_p, clusters.label):   # our own arrays only, never the caller's
        a.flags.writeable = False
    return Network(problem=problem, adjacency=adjacency, degree_w_k=degree,
                   n_active_contacts=n_active, n_zero_contacts=m - n_active, held=held,
                   held_temperature_k=held_t, capacity_j_k=c, fixed_particle=v["fixed_particle"],
                   fixed_boundary=v["fixed_boundary"], exchange_particle=v["exchange_particle"],
                   exchange_row_g_w_k=v["exchange_g"],
                   exchange_row_temperature_k=v["exchange_t"],
                   exchange_boundary=v["exchange_boundary"],
                   power_by_boundary_w=np.bincount(v["power_boundary"], weights=v["power"],
                                                   minlength=len(problem.boundary_names)),
                   exchange_g_w_k=g_p, exchange_gt_w=gt_p, power_w=pw_p, clusters=clusters,
                   dt_max_s=dt_max, dt_max_particle=p_min, dt_paper_s=dt_paper,
                   flags=flags)
