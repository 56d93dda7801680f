"""Does a packing's normal force follow its stated contact law? (numpy only)

Used through ``thermal_kernel/packing_stats.py`` by the YADE-side dump
(``yade_scripts/tdem_yade.py``, which imports both as the package on Debian's Python) and by
``tdem import liggghts``. The result is written
into the packing's root attributes (``force_law*``) and printed by ``tdem info``.

Hertz (elastic part; YADE's ``Law2_ScGeom_MindlinPhys_Mindlin`` and LIGGGHTS' ``model hertz``
both use it): F = 4/3 E* sqrt(R*) delta^(3/2), E* = 1 / ((1 - nu_i^2)/E_i + (1 - nu_j^2)/E_j),
R* = r_i r_j / (r_i + r_j), delta the overlap (m), F in N.

Linear (Cundall): F = k_n delta with the contact's own k_n (N/m).

The ratio F / F_law is computed for every touching contact (delta > 0); its median says which
stiffness the forces were made with (a packing made at a softened modulus E_s and labelled with
the real E has median (E_s/E)), its spread how far single contacts stray (the viscous part of the
damping, forces one step older than the positions).
"""
import numpy as np

# Above this relative mismatch (|median ratio - 1| or the 95th percentile of |ratio - 1|) a
# packing is reported as not following its stated law.
MISMATCH_WARN = 0.05


def effective_modulus(young, poisson, young2=None, poisson2=None):
    """E* (Pa) of two elastic bodies; the second defaults to the first."""
    young2 = young if young2 is None else young2
    poisson2 = poisson if poisson2 is None else poisson2
    return 1.0 / ((1.0 - poisson ** 2) / young + (1.0 - poisson2 ** 2) / young2)


def hertz_force(r_star, overlap, e_star):
    """Elastic Hertz normal force (N): 4/3 E* sqrt(R*) delta^(3/2), 0 for delta <= 0."""
    delta = np.clip(np.asarray(overlap, float), 0.0, None)
    return 4.0 / 3.0 * e_star * np.sqrt(np.asarray(r_star, float)) * delta ** 1.5


def check(force, expected, law):
    """Compare forces with the law's forces over touching contacts; return the attributes
    ``force_law`` (str), ``force_law_contacts``, ``force_law_ratio_median`` (F / F_law),
    ``force_law_mismatch_p95`` and ``force_law_mismatch_max`` (of |F / F_law - 1|)."""
    force = np.asarray(force, float)
    expected = np.asarray(expected, float)
    ok = expected > 0
    out = {"force_law": law, "force_law_contacts": int(ok.sum())}
    if not ok.any():
        out.update(force_law_ratio_median=float("nan"), force_law_mismatch_p95=float("nan"),
                   force_law_mismatch_max=float("nan"))
        return out
    ratio = force[ok] / expected[ok]
    dev = np.abs(ratio - 1.0)
    out.update(force_law_ratio_median=float(np.median(ratio)),
               force_law_mismatch_p95=float(np.percentile(dev, 95)),
               force_law_mismatch_max=float(dev.max()))
    return out


def describe(attrs):
    """One line on the check held in ``attrs`` (None when the file has none)."""
    law = attrs.get("force_law")
    if law is None:
        return None
    n = attrs.get("force_law_contacts", 0)
    if not n:
        return f"{law}: not checked (no touching contact with a law force)"
    med = attrs["force_law_ratio_median"]
    p95 = attrs["force_law_mismatch_p95"]
    worst = attrs["force_law_mismatch_max"]
    text = (f"{law}: F / F_law median {med:.4f}, |F / F_law - 1| 95 % {p95:.2g}, max "
            f"{worst:.2g} over {n} contacts")
    if abs(med - 1.0) > MISMATCH_WARN or p95 > MISMATCH_WARN:
        text += (f" -- MISMATCH: the forces do not follow the stated law (median off by "
                 f"{100 * (med - 1):+.1f} %"
                 + (f"; a Hertz ratio {med:.3g} is a modulus {med:.3g} x young_pa: softened?"
                    if law.startswith("hertz") else "") + ")")
    return text


def is_mismatch(attrs):
    n = attrs.get("force_law_contacts", 0)
    return bool(n) and (abs(attrs["force_law_ratio_median"] - 1.0) > MISMATCH_WARN
                        or attrs["force_law_mismatch_p95"] > MISMATCH_WARN)
