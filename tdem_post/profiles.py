"""Binned profiles along an axis, each particle weighted by the exact volume of it inside the bin
(pipe-model paper 003, sec. 4.3: "weighted by the partial volume of particles lying in the bin").

The volume of a sphere (centre c, radius r) below the plane x = h is the cap volume
V(h) = pi s^2 (3 r - s) / 3 with s = clip(h - c + r, 0, 2 r); the part in [h0, h1] is
V(h1) - V(h0). Summed over the bins that cover a sphere this gives its whole volume exactly.
"""
from __future__ import annotations

import numpy as np


def volume_below(plane_m, centre_m, radius_m):
    """Volume of each sphere below x = plane (m^3); broadcasting."""
    s = np.clip(np.asarray(plane_m) - np.asarray(centre_m) + radius_m, 0.0, 2.0 * radius_m)
    return np.pi * s * s * (3.0 * radius_m - s) / 3.0


def partial_volumes(coordinate_m, radius_m, edges_m):
    """(N, B) volume of each particle inside each bin [edges[b], edges[b+1]] (m^3)."""
    c = np.asarray(coordinate_m, dtype=float)[:, None]
    r = np.asarray(radius_m, dtype=float)[:, None]
    below = volume_below(np.asarray(edges_m, dtype=float)[None, :], c, r)
    return np.diff(below, axis=1)


def binned_profile(coordinate_m, radius_m, values, edges_m, weights=None):
    """Partial-volume weighted mean of ``values`` (N,) or (K, N) per bin -> (B,) or (K, B).

    ``weights`` (N,) multiplies the partial volumes (e.g. a mask of the particles to count).
    Bins that hold no particle volume give NaN.
    """
    w = partial_volumes(coordinate_m, radius_m, edges_m)
    if weights is not None:
        w = w * np.asarray(weights, dtype=float)[:, None]
    total = w.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return (np.asarray(values, dtype=float) @ w) / total
