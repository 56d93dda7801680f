"""Case 11 of docs/validation.md: the two-sphere conductances of the pipe model (003 eq. 34-40)
and of Batchelor-O'Brien, Argento and Chaudhuri (004) against their closed forms.

Exact case: the inputs and formulas are those of tests/test_laws.py (``test_pipe_by_hand_*``,
``test_bob_argento_ott_by_hand``, ``test_pipe_is_1033_times_bob_for_equal_spheres``,
``test_chaudhuri_by_hand``), computed with the helpers the tests use
(``thermal_kernel/hand_inputs.py``: ``one_contact``, ``conductance``,
``hertz_radius_equal_spheres``, ``YOUNG_PA``, ``POISSON``) and reported as relative errors
instead of asserted.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from tdem_post.records import to_dict
from thermal_kernel.hand_inputs import (POISSON, YOUNG_PA, conductance,
                                        hertz_radius_equal_spheres, one_contact)

from .framework import CaseInfo, CaseResult, Context
from .framework import Judgement, md_table, numbers_reader

CASE = CaseInfo(number=11, title="pipe / BOB / Argento / Chaudhuri two-sphere values",
                paper="003 eq. 34–40, 004", paper_n="two spheres",
                paper_error="2.066 / 2 / π/(2β)")
TESTS = ("tests/test_laws.py::test_pipe_by_hand_equal_spheres", "test_pipe_by_hand_unequal_spheres",
         "test_bob_argento_ott_by_hand", "test_pipe_is_1033_times_bob_for_equal_spheres",
         "test_chaudhuri_by_hand")


@dataclass(frozen=True, kw_only=True)
class TwoSphereRow:
    """One two-sphere value: tdem's and its closed form's, in the quantity's unit (a
    conductance H in W/K, or H / (κ ζ) and pipe / BOB dimensionless, as ``quantity`` says)."""
    quantity: str
    tdem: float
    closed_form: float
    source: str                     # where the closed form is (003 eq. 36-39, 004, ...)

    @property
    def rel_error(self) -> float:
        return abs(self.tdem / self.closed_form - 1)


@dataclass(frozen=True, kw_only=True)
class TwoSphereResult:
    """Case 11's saved ``numbers``: every row, and the largest relative error over them."""
    rows: tuple[TwoSphereRow, ...]
    max_rel_error: float


read_numbers = numbers_reader(TwoSphereResult, 11)


def measure() -> TwoSphereResult:
    """tdem's value and the closed form's for each two-sphere value."""
    E, NU = YOUNG_PA, POISSON

    def h(name, contact):
        return float(conductance(name, contact)[0])

    rows = []
    r, kappa, force = 2e-3, 205.0, 10.0                     # 003 Table 1 particle, F_n = 10 N
    c = one_contact(r, r, 2 * r - 1e-6, kappa, kappa, force=force)
    zeta = hertz_radius_equal_spheres(force, r)
    k_n = 4 * E / (6 * (1 - NU ** 2)) * math.sqrt(r / 2)     # eq. 39
    chain = kappa / 0.6846 * math.sqrt(r) * (force / k_n) ** (1 / 3)   # eq. 36-38
    pipe = h("pipe", c)
    bob = h("bob", c)
    rows.append(("pipe, equal spheres: H (eq. 36-39 chain)", pipe, chain, "003 eq. 36-39"))
    rows.append(("pipe, equal spheres: H / (κ ζ) (eq. 40: 2.066)", pipe / (kappa * zeta),
                 math.sqrt(2) / 0.6846, "003 eq. 40 (2.066 printed)"))
    rows.append(("BOB: H / (κ ζ)", bob / (kappa * zeta), 2.0, "003 eq. 34"))
    rows.append(("Argento: H / (κ ζ), β = 0.899", h("argento", c) / (kappa * zeta),
                 math.pi / (2 * 0.899), "003 eq. 35"))
    rows.append(("Ott (Argento, β = 0.952): H / (κ ζ)", h("ott", c) / (kappa * zeta),
                 math.pi / (2 * 0.952), "003 eq. 35"))
    rows.append(("pipe / BOB, equal spheres (1.033)", pipe / bob, math.sqrt(2) / (2 * 0.6846),
                 "003 eq. 40 / eq. 34"))
    # unequal spheres: eq. 18-20, one contact disc of the lens radius
    r_i, r_j, k_i, k_j, f = 1e-3, 2e-3, 10.0, 40.0, 3.0
    e_star = E / (2 * (1 - NU ** 2))
    r_star = r_i * r_j / (r_i + r_j)
    a_l = math.sqrt(2) * (3 * f * r_star / (4 * e_star)) ** (1 / 3)
    rows.append(("pipe, unequal spheres and κ: H (eq. 18-20)",
                 h("pipe", one_contact(r_i, r_j, 3e-3 - 1e-6, k_i, k_j, force=f)),
                 1 / (0.6846 / (2 * k_i * a_l) + 0.6846 / (2 * k_j * a_l)), "003 eq. 18-20"))
    # Chaudhuri (004): 4 k1 k2 / (k1 + k2) (3 F r* / (4 E*))^(1/3)
    e_star2 = 1 / (2 * (1 - NU ** 2) / E)
    rows.append(("Chaudhuri: H",
                 h("chaudhuri", one_contact(1e-3, 2e-3, 3e-3 - 1e-6, 1.0, 3.0, force=5.0)),
                 3.0 * (3 * 5.0 * (2e-3 / 3) / (4 * e_star2)) ** (1 / 3), "004"))
    rows = tuple(TwoSphereRow(quantity=q, tdem=v, closed_form=ref, source=src)
                 for q, v, ref, src in rows)
    return TwoSphereResult(rows=rows, max_rel_error=max(r.rel_error for r in rows))



def judge(numbers: dict) -> Judgement:
    """Issue 23's columns: an exact case (two spheres, no N to choose)."""
    if not numbers:
        return Judgement("not measured", "", None)
    worst = read_numbers(numbers).max_rel_error
    return Judgement(at_paper_n=f"two spheres: max {worst:.1e} against the closed forms",
                     speed_vs_error="seconds", target_met=worst < 1e-12)


def run(ctx: Context) -> CaseResult:
    m = measure()
    worst = m.max_rel_error
    table = md_table(["quantity", "tdem", "closed form", "relative error", "reference"],
                     [(r.quantity, f"{r.tdem:.10g}", f"{r.closed_form:.10g}",
                       f"{r.rel_error:.1e}", r.source) for r in m.rows])
    printed = m.rows[1].tdem
    section = f"""\
Exact case: each law's conductance of two spheres in contact (003 Table 1 particle, R = 2 mm,
κ = 205 W/m/K, F_n = 10 N; E = 50 GPa, ν = 0.2; ζ the Hertz contact radius of eq. 34-35)
against its closed form.

{table}

The pipe law's 2.066 of eq. 40 is √2 / 0.6846 = {printed:.6f} rounded to four digits (the paper's
λ = −0.6846). The tests {', '.join(f'`{t}`' for t in TESTS)} assert the same values (rtol 1e-12);
this case computes them with the tests' own helpers."""
    return CaseResult(
        our_n="two spheres", our_error=f"max {worst:.1e} (round-off); 2.066 to its 4 printed "
                                       f"digits ({printed:.5f})",
        wall_time="— (seconds)",
        verdict="exact: " + ", ".join(f"`{t}`" for t in TESTS), section_md=section,
        numbers=to_dict(m))
