"""Effective thermal conductivity of two-phase media: the classical estimates and bounds that the
DEM's ETC is compared with (Haddad 2021, 002 sec. 1, 4-5), and the Zehner-Schluender model of a
packed bed. k_m matrix (or fluid), k_i inclusions (or solid), f the inclusions' volume fraction.
"""
from __future__ import annotations

import numpy as np


def maxwell(k_m, k_i, f):
    """Maxwell (Maxwell-Garnett) for dilute spheres in a matrix (002 ref. [10]); equals the
    Hashin-Shtrikman bound on the matrix side."""
    k_m, k_i, f = (np.asarray(x, float) for x in (k_m, k_i, f))
    return k_m * (k_i + 2 * k_m + 2 * f * (k_i - k_m)) / (k_i + 2 * k_m - f * (k_i - k_m))


def hashin_shtrikman(k_m, k_i, f):
    """(lower, upper) Hashin-Shtrikman bounds of an isotropic two-phase medium (3-D)."""
    a = maxwell(k_m, k_i, f)
    b = maxwell(k_i, k_m, 1.0 - np.asarray(f, float))
    return np.minimum(a, b), np.maximum(a, b)


def bruggeman(k_m, k_i, f):
    """Bruggeman's symmetric effective-medium theory (002 ref. [13]):
    f (k_i - k)/(k_i + 2k) + (1 - f)(k_m - k)/(k_m + 2k) = 0, the positive root of
    2 k^2 - b k - k_i k_m = 0 with b = (3f - 1) k_i + (2 - 3f) k_m."""
    k_m, k_i, f = (np.asarray(x, float) for x in (k_m, k_i, f))
    b = (3 * f - 1) * k_i + (2 - 3 * f) * k_m
    return (b + np.sqrt(b * b + 8 * k_i * k_m)) / 4


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
