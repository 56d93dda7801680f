"""The effective conductivity of a packing from one steady solve between two held boundaries.

    k_eff = |Q_in| L / (A |T_in - T_out|)                       (002 eq. 8; 003 sec. 4.4)

with Q_in the heat entering through the boundary held at T_in (W), A the cross-section (m^2)
and L the length between the two held boundaries. The steady heat flow must balance: heat in =
heat out, |Q_in + Q_out| / |Q_in| at most :data:`BALANCE_TOLERANCE` (the direct solve gives
~1e-15, AMG-CG to its 1e-12 residual ~1e-10), else the answer is refused in one line
(:class:`BalanceError`): another boundary or a source taking part, or a solve that did not
converge, would make k_eff wrong without a sign.

Two lengths are in use, and the result says which (:data:`LENGTH_CONVENTIONS`):
- ``"domain"``: the domain's extent along the axis; the flux test of
  :func:`thermal_kernel.calibrate.flux_test` holds the particles touching the two faces
  (002 eq. 8-9, the calibration of C_t and the ETC sweep of tdem_post.etc_sweep);
- ``"held_centres"``: between the mean centre planes of the two held sets of spheres, the slab
  of the analytical solution the transient profiles are fitted to (tdem_post.post_run: the
  steady ETC is compared with the fitted gamma on the same L).

Used by post-processing (the steady ETC), calibrate and the ETC sweep (through flux_test): one
definition of k_eff, its balance check and its result.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .network import NetworkError
from .solvers.steady import solve_steady

BALANCE_TOLERANCE = 1e-6
LENGTH_CONVENTIONS = {
    "domain": "the domain's extent along the axis (the held faces' distance; 002 eq. 8)",
    "held_centres": "between the mean centre planes of the two held sets of spheres (the slab "
                    "of the profile fit, 003 App. A)",
}


class BalanceError(NetworkError):
    """The steady heat flow does not balance (heat in != heat out); ``str(e)`` is one line."""


@dataclass(frozen=True, eq=False)
class EffectiveConductivity:
    k_eff_w_mk: float             # |Q_in| L / (A |T_in - T_out|)
    q_in_w: float                 # heat entering through the boundary held at T_in
    q_out_w: float                # heat entering through the boundary held at T_out (< 0)
    balance: float                # |Q_in + Q_out| / |Q_in|, at most BALANCE_TOLERANCE
    length_m: float
    area_m2: float
    length_convention: str        # a key of LENGTH_CONVENTIONS
    delta_t_k: float              # T_in - T_out
    n_rattlers: int               # particles without a conducting contact (not solved for)
    n_floating_clusters: int      # clusters tied to no boundary (keep their initial mean)
    temperature_k: np.ndarray = field(repr=False)   # the steady field (N,)


def _check_convention(length_convention: str) -> None:
    if length_convention not in LENGTH_CONVENTIONS:
        raise ValueError(f"length_convention: expected one of {', '.join(LENGTH_CONVENTIONS)}, "
                         f"got {length_convention!r}")


def effective_conductivity(net, inlet: str, outlet: str, *, t_in: float, t_out: float,
                           length_m: float, area_m2: float, length_convention: str,
                           initial_k, where="", tolerance: float = BALANCE_TOLERANCE
                           ) -> EffectiveConductivity:
    """k_eff of the assembled network ``net`` whose boundaries named ``inlet`` and ``outlet``
    hold ``t_in`` and ``t_out``: one steady solve (``initial_k``: the temperatures floating
    clusters and rattlers keep), then :func:`steady_effective_conductivity`."""
    _check_convention(length_convention)          # before the solve
    steady = solve_steady(net, np.asarray(initial_k))
    return steady_effective_conductivity(
        steady, net, inlet, outlet, t_in=t_in, t_out=t_out, length_m=length_m,
        area_m2=area_m2, length_convention=length_convention, where=where,
        tolerance=tolerance)


def steady_effective_conductivity(steady, net, inlet: str, outlet: str, *, t_in: float,
                                  t_out: float, length_m: float, area_m2: float,
                                  length_convention: str, where="",
                                  tolerance: float = BALANCE_TOLERANCE) -> EffectiveConductivity:
    """k_eff from a steady solve already made (``steady``, a ThermalResult, e.g. a steady
    scene's ``thermal_kernel.run.run_in_memory(...).result``) on the network ``net``: the
    balance checked against ``tolerance`` (:class:`BalanceError` naming ``where`` otherwise)."""
    _check_convention(length_convention)
    flows = steady.boundary_heat_flow_w[-1]
    names = list(steady.boundary_names)
    q_in = float(flows[names.index(inlet)])
    q_out = float(flows[names.index(outlet)])
    balance = abs(q_in + q_out) / max(abs(q_in), 1e-300)
    if not balance <= tolerance:
        raise BalanceError(f"{where}: steady heat balance: {q_in:.6g} W in through {inlet}, "
                           f"{-q_out:.6g} W out through {outlet}, |Q_in + Q_out| / |Q_in| = "
                           f"{balance:.3g}; expected at most {tolerance:g} (another boundary or "
                           "a source takes part, or the solve did not converge): no k_eff")
    return EffectiveConductivity(
        k_eff_w_mk=abs(q_in) * length_m / (area_m2 * abs(t_in - t_out)), q_in_w=q_in,
        q_out_w=q_out, balance=balance, length_m=float(length_m), area_m2=float(area_m2),
        length_convention=length_convention, delta_t_k=float(t_in - t_out),
        n_rattlers=int(net.clusters.n_rattlers), n_floating_clusters=int(net.clusters.n_floating),
        temperature_k=steady.temperature_k[-1])
