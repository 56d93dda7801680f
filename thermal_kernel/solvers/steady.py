"""Steady state: one sparse solve of (L + G) T = b with the held particles eliminated.

Unknowns u: free particles of clusters tied to a reservoir (a held particle or an exchange row
with g > 0). For them K_uu = L_uu + diag(g_u) is symmetric positive definite and

    K_uu (T_u - T_ref) = b_u + S_u - L_ud T_d - T_ref K_uu 1

is solved for the deviation from T_ref (the mean prescribed temperature), which keeps the
right-hand side free of the large common part. Direct (SuperLU) up to DIRECT_MAX unknowns,
else CG with a smoothed-aggregation AMG preconditioner (pyamg) to relative residual ``tol``.

Floating clusters (not tied to any reservoir: singular) and rattlers are not solved for: each
keeps the capacity-weighted mean of its initial temperatures (the long-time limit of the
transient, energy-preserving); if power is injected into one, its zero-net part is solved for
on top of that mean, and a net power (no steady state exists) is flagged. Never a NaN.
"""
from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from ..network import UntiedParticles, untied_of
from .common import ThermalResult, as_network, blas_threads
from .implicit import SpdSolver

# Unknowns up to which the steady solve is direct (SuperLU). Measured (docs/solvers.md): direct
# 0.09 / 1.6 / 5.6 / 106 s at 2e4 / 1e5 / 2e5 / 4e5 unknowns, AMG-CG (tol 1e-12) 0.18 / 0.7 /
# 1.5 / 4.1 s: they cross near 5e4.
DIRECT_MAX = 50_000


def solve_steady(problem, T0=None, *, method="auto", tol=1e-12, source_interval=None,
                 maxiter=2000, blas=1) -> ThermalResult:
    """Steady temperatures. ``T0`` (N,) only matters for floating clusters and rattlers (which
    keep their capacity-weighted mean); without it they take the mean prescribed temperature
    (flag ``floating_without_T0``). ``source_interval=(t0, t1)`` includes the source's mean
    power over that interval; by default a source is ignored (flag ``source_ignored``).
    ``info['heat_balance_w']``: sum of the heat entering through all boundaries (and the
    source), which is zero at steady state up to the solver's tolerance."""
    with blas_threads(blas):
        return _solve_steady(problem, T0, method=method, tol=tol,
                             source_interval=source_interval, maxiter=maxiter)


def _solve_steady(problem, T0, *, method, tol, source_interval, maxiter) -> ThermalResult:
    net = as_network(problem)
    wall0 = time.perf_counter()
    held_t = net.held_temperature_k
    t_ref, T0, b, sw, flags = steady_inputs(net, T0, source_interval)

    in_untied = ~net.clusters.tied_particle       # floating clusters and rattlers
    u = np.flatnonzero(~net.held & ~in_untied)

    T = np.where(net.held, held_t, 0.0)
    lap = net.laplacian
    k_uu = (lap[u][:, u] + sp.diags(net.exchange_g_w_k[u])).tocsr()
    t_d = np.where(net.held, held_t - t_ref, 0.0)
    rhs = b[u] - lap[u] @ t_d - t_ref * net.exchange_g_w_k[u]
    # (L 1 = 0, so shifting by t_ref only leaves the exchange term -g T_ref on the right.)
    solver = SpdSolver(k_uu, method, tol, maxiter, direct_max=DIRECT_MAX)
    T[u] = t_ref + solver.solve(rhs)

    no_steady = untied_temperatures(net, T, T0, b, t_ref, flags)
    return steady_result(net, T, T0, sw, flags, time.perf_counter() - wall0, no_steady,
                         linear_solver=solver.method, tol=tol, unknowns=int(u.size),
                         t_ref=t_ref, cg_iterations=solver.iterations)


def steady_result(net, T, T0, sw, flags, wall_seconds, no_steady, *, flow_w=None,
                  stored_j=None, source_total_w=None, **info) -> ThermalResult:
    """The steady solve's ThermalResult (the in-process solve and the PETSc backend's rank 0):
    the boundaries' heat flows of T, the heat balance (zero at steady state up to the solver's
    tolerance), the clusters; ``info`` holds the solver's own entries. The flows, the stored
    energy sum C (T - T0) and the source's total power are computed here from the network and
    the source's powers ``sw``, or given (``flow_w``, ``stored_j``, ``source_total_w``: the
    PETSc backend's ranks sum them over their rows)."""
    prob = net.problem
    flow = net.boundary_heat_flow(T, sw) if flow_w is None else np.asarray(flow_w, float)
    if source_total_w is None and sw is not None:
        source_total_w = float(sw.sum())
    total_in = float(flow.sum()) + (source_total_w if source_total_w is not None and
                                    prob.source_boundary < 0 else 0.0)
    scale = float(np.abs(flow).sum()) or 1.0
    nb = prob.n_boundaries
    if stored_j is None:
        stored_j = np.dot(net.capacity_j_k, T - T0) if T0 is not None else np.nan
    return ThermalResult(
        method="steady", times=np.array([np.inf]), temperature_k=T[None, :],
        boundary_heat_flow_w=flow[None, :], boundary_energy_j=np.full((1, nb), np.nan),
        source_energy_j=np.full(1, np.nan), stored_energy_j=np.array([stored_j]),
        boundary_names=prob.boundary_names, source_boundary=prob.source_boundary,
        dt=np.inf, dt_max=net.dt_max_s, dt_paper=net.dt_paper_s, steps=0,
        wall_seconds=wall_seconds, contact_updates_per_second=float("nan"), flags=tuple(flags),
        info=dict(info, heat_balance_w=total_in, heat_balance_relative=total_in / scale,
                  floating_clusters=net.clusters.n_floating,
                  floating_sizes=net.clusters.floating_sizes.tolist(),
                  rattlers=net.clusters.n_rattlers, no_steady_state=no_steady,
                  clusters=net.clusters.summary()),
        state=None)


def untied_temperatures(net, T, T0, b, t_ref, flags) -> list:
    """:func:`fill_untied` of a whole network: sets the untied particles' entries of T in
    place; returns [(cluster, net power W)] of those without a steady state."""
    u = untied_of(net)
    return fill_untied(u, T, T0, b[u.particle], t_ref, flags)


def fill_untied(u: UntiedParticles, T, T0, b_untied, t_ref, flags) -> list:
    """Floating clusters and rattlers (no path to a held temperature; ``u``, their power
    ``b_untied`` (U,) W): each keeps the capacity-weighted mean of T0 (t_ref without T0,
    flagged floating_without_T0), plus the zero-net part of a power b injected into it
    (singular but compatible: the first member pinned, the cluster's mean restored); a net
    power has no steady state and is flagged. Sets their entries of T (whole) in place (the
    in-process solve and the PETSc backend's rank 0, which holds only ``u`` of the network);
    returns [(cluster, net power W)] of those without a steady state."""
    no_steady = []
    sel = u.particle
    if not sel.size:
        return no_steady
    base = T0[sel] if T0 is not None else np.full(sel.size, t_ref)
    if T0 is None:
        flags.append("floating_without_T0")
    c, lab = u.capacity_j_k, u.label
    csum = np.bincount(lab, weights=c, minlength=u.n_components)
    ctsum = np.bincount(lab, weights=c * base, minlength=u.n_components)
    T[sel] = ctsum[lab] / csum[lab]
    for comp in np.unique(lab[b_untied != 0]):
        at = np.flatnonzero(lab == comp)        # untied: no member is held
        members = sel[at]
        net_power = float(b_untied[at].sum())
        if abs(net_power) > 1e-9 * float(np.abs(b_untied[at]).sum()):
            no_steady.append((int(comp), net_power))
            continue
        if members.size < 2:
            continue
        sub = u.laplacian[at][:, at].tocsr()
        x = np.zeros(members.size)
        x[1:] = spsolve(sub[1:, 1:].tocsc(), b_untied[at][1:])
        x -= np.dot(c[at], x) / c[at].sum()
        T[members] += x
    if no_steady:
        flags.append("no_steady_state_in_floating_cluster")
    return no_steady


def steady_start(net, T0, source_interval, has_source: bool):
    """What a steady solve starts from besides its right-hand side (the in-process solve and
    the PETSc backend's rank 0): the reference temperature t_ref (the mean of the prescribed
    ones, which the solve shifts by), T0 checked ((n,) finite, or a scalar broadcast; None
    stays None) and the flags, starting from the network's (a source without a
    ``source_interval`` is ignored and flagged). Returns (t_ref, T0, flags)."""
    n = net.n
    flags = list(net.flags)
    t_ref = net.prescribed_mean_k
    if T0 is not None:
        T0 = np.array(T0, dtype=np.float64)
        if T0.ndim == 0:
            T0 = np.full(n, float(T0))
        if T0.shape != (n,) or not np.all(np.isfinite(T0)):
            raise ValueError(f"T0: expected ({n},) finite temperatures, got shape {T0.shape}")
    if has_source and source_interval is None:
        flags.append("source_ignored")
    return t_ref, T0, flags


def steady_inputs(net, T0, source_interval):
    """:func:`steady_start`, and the right-hand side b (the boundary kinds' constant part,
    plus the source's mean power over source_interval) and the source's powers sw. Returns
    (t_ref, T0, b, sw, flags)."""
    source = net.problem.source
    t_ref, T0, flags = steady_start(net, T0, source_interval, source is not None)
    b = net.constant_rhs_w.copy()
    sw = None
    if source is not None and source_interval is not None:
        sw = np.asarray(source(*source_interval), dtype=np.float64)
        b += sw
    return t_ref, T0, b, sw, flags
