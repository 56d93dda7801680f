"""Effective thermal conductivity of two-phase media: the classical estimates and bounds that the
DEM's ETC is compared with (Haddad 2021, 002 sec. 1, 4-5), and the Zehner-Schluender model of a
packed bed. k_m matrix (or fluid), k_i inclusions (or solid), f the inclusions' volume fraction.
"""
from __future__ import annotations

import numpy as np

# The estimates live with the other analytical solutions (one home, tdem_post/analytic.py);
# re-exported here for tdem etc and its callers.
from .analytic import bruggeman, hashin_shtrikman, maxwell, rayleigh_cubic_array  # noqa: F401


def zehner_schluender(k_f, k_s, solid_fraction):
    """Zehner-Schluender (1970) conductivity of a packed bed of spheres (solid k_s, fluid k_f),
    without radiation or contact flattening: shape factor B = 1.25 ((1 - phi)/phi)^(10/9)."""
    phi = np.asarray(solid_fraction, float)
    kappa = np.asarray(k_s, float) / np.asarray(k_f, float)
    b = 1.25 * ((1 - phi) / phi) ** (10 / 9)
    n = 1 - b / kappa
    core = (2 / n) * (((kappa - 1) * b / (kappa * n * n)) * np.log(kappa / b) - (b + 1) / 2
                      - (b - 1) / n)
    return k_f * (1 - np.sqrt(1 - phi) + np.sqrt(1 - phi) * core)
