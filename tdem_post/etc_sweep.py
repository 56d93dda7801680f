"""Effective thermal conductivity of a particulate composite against contrast and volume fraction
(Haddad 2021, 002 sec. 4-5, Fig. 14 and 17), from steady flux tests on one dense packing.

The packing models a continuum (a dense YADE box); the phases are assigned here, the same way the
YADE generator does it: a particle belongs to an inclusion when its centre lies inside it.
- single inclusion (002 sec. 4.2, Fig. 13-14): one sphere at the centre of the box whose volume
  is the fraction f of the box (f = 15.51 % is the paper's a = L/3), swept over the contrast
  c = k_i / k_m;
- dispersion (002 sec. 5, Fig. 17): non-overlapping spheres of diameter d (d = L/6 in the paper)
  placed by seeded random sequential addition inside the box until their volume reaches f, at a
  fixed contrast (silica in epoxy: 1.5 / 0.195 = 7.7).
Each case is one steady flux test (thermal_kernel.calibrate.flux_test) with the scene's law; the
result is normalised by the same test with a single phase, k_eff / k_m, so that the law's own
calibration (C_t) cancels, and compared with Maxwell, Hashin-Shtrikman and Bruggeman
(tdem_post.etc) at the inclusions' volume fraction measured on the particles (their share of the
particles' volume), which is what the network sees.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from thermal_kernel.calibrate import flux_test
from thermal_kernel.packing import Packing
from thermal_kernel.scene import Material, Scene, SceneError
from thermal_kernel.placement import random_sequential_addition  # the one placement routine

from .etc import bruggeman, hashin_shtrikman, maxwell
from thermal_kernel.atomic import savefig_atomic


def single_inclusion_phase(packing: Packing, volume_fraction: float) -> np.ndarray:
    """Phase 1 for the particles whose centre lies in the centred sphere holding
    ``volume_fraction`` of the box (nested: a larger fraction is a superset)."""
    lo, hi = packing.domain_lo, packing.domain_hi
    radius = (3.0 * volume_fraction * float(np.prod(hi - lo)) / (4.0 * math.pi)) ** (1.0 / 3.0)
    inside = np.linalg.norm(packing.position - 0.5 * (lo + hi), axis=1) < radius
    return inside.astype(np.int32)


def dispersion_phase(packing: Packing, volume_fraction: float, diameter_m: float, seed: int = 0,
                     max_attempts: int = 200_000) -> np.ndarray:
    """Phase 1 for the particles whose centre lies in one of a random set of non-overlapping
    spheres of ``diameter_m``, wholly inside the box, of total volume ``volume_fraction`` of it
    (seeded random sequential addition, thermal_kernel/placement.py: candidates uniform in the box
    shrunk by r, at most ``max_attempts`` in all; it jams near 0.3 for d = L/6)."""
    lo, hi = packing.domain_lo, packing.domain_hi
    r = 0.5 * diameter_m
    if np.any(hi - lo <= diameter_m):
        raise SceneError(f"{packing.path}: inclusion diameter {diameter_m:g} m does not fit in "
                         "the box")
    count = int(round(volume_fraction * float(np.prod(hi - lo)) / (4.0 / 3.0 * math.pi * r ** 3)))
    rng = np.random.default_rng(seed)
    attempts = 0

    def candidates(k, radius):
        nonlocal attempts
        while attempts < max_attempts:
            attempts += 1
            yield rng.uniform(lo + r, hi - r)

    centres = random_sequential_addition([r] * count, candidates)
    if len(centres) < count:
        raise SceneError(f"{packing.path}: fractions: only {len(centres)} of {count} inclusions of "
                         f"diameter {diameter_m:g} m fit (volume fraction "
                         f"{volume_fraction:g} is beyond random sequential addition)")
    phase = np.zeros(packing.n_particles, np.int32)
    for c in centres:
        phase[np.linalg.norm(packing.position - c, axis=1) < r] = 1
    return phase


def phase_volume_fraction(packing: Packing, phase: np.ndarray) -> float:
    volume = packing.radius ** 3
    return float(volume[phase == 1].sum() / volume.sum())


def composite_conductivity(scene: Scene, packing: Packing, phase: np.ndarray, contrast: float,
                           axis: str = "x") -> float:
    """k_eff (W/m/K) of ``packing`` with ``phase`` (0 matrix, 1 inclusions of conductivity
    contrast x the matrix's) by the steady flux test along ``axis``
    (:func:`thermal_kernel.effective.effective_conductivity`, length convention "domain")."""
    matrix = scene.material(0)
    inclusion = Material(conductivity=contrast * matrix.conductivity, density=matrix.density,
                         heat_capacity=matrix.heat_capacity)
    test_scene = dataclasses.replace(scene, materials={0: matrix, 1: inclusion})
    test_packing = dataclasses.replace(packing, phase=np.asarray(phase, np.int32))
    return flux_test(test_scene, test_packing, axis).effective.k_eff_w_mk


def _estimates(contrast, fraction):
    low, high = hashin_shtrikman(1.0, contrast, fraction)
    return dict(maxwell=float(maxwell(1.0, contrast, fraction)), hs_lower=float(low),
                hs_upper=float(high), bruggeman=float(bruggeman(1.0, contrast, fraction)))


def etc_sweep(scene: Scene, packing: Packing, *, contrasts=(0.01, 0.1, 0.5, 2.0, 10.0, 100.0),
              single_fraction=0.1551, fractions=(0.05, 0.1, 0.15, 0.2, 0.25),
              dispersion_contrast=7.7, diameter_over_length=1 / 6, seed=0, axis="x",
              progress=None):
    """Rows (dicts) of both sweeps: case, contrast, volume fraction (target and on the
    particles), k_eff / k_m of the network and the four estimates at the measured fraction."""
    length = float(np.min(packing.domain_hi - packing.domain_lo))
    # place every dispersion first: an impossible fraction fails before any solve
    dispersions = [dispersion_phase(packing, target, diameter_over_length * length, seed)
                   for target in fractions]
    k_m = composite_conductivity(scene, packing, np.zeros(packing.n_particles, np.int32), 1.0,
                                 axis)
    rows = []
    phase = single_inclusion_phase(packing, single_fraction)
    f = phase_volume_fraction(packing, phase)
    for c in contrasts:
        k = composite_conductivity(scene, packing, phase, c, axis)
        rows.append(dict(case="single", contrast=c, fraction_target=single_fraction,
                         fraction=f, inclusion_particles=int(phase.sum()), k_over_km=k / k_m,
                         **_estimates(c, f)))
        if progress:
            progress(rows[-1])
    for target, phase in zip(fractions, dispersions):
        f = phase_volume_fraction(packing, phase)
        k = composite_conductivity(scene, packing, phase, dispersion_contrast, axis)
        rows.append(dict(case="dispersion", contrast=dispersion_contrast,
                         fraction_target=target, fraction=f,
                         inclusion_particles=int(phase.sum()), k_over_km=k / k_m,
                         **_estimates(dispersion_contrast, f)))
        if progress:
            progress(rows[-1])
    return rows, k_m


def _panel(ax, x_points, y_points, x_line, estimate_args):
    """Measured points over the HS band and the Maxwell / Bruggeman lines of one panel;
    estimate_args(x_line) -> (k_m, k_i, f) for the estimates along the line."""
    low, high = hashin_shtrikman(*estimate_args(x_line))
    ax.fill_between(x_line, low, high, color="0.85", label="Hashin-Shtrikman bounds")
    ax.plot(x_line, maxwell(*estimate_args(x_line)), "k-", label="Maxwell")
    ax.plot(x_line, bruggeman(*estimate_args(x_line)), "k:", label="Bruggeman")
    ax.plot(x_points, y_points, "o", color="C3", label="tdem (steady flux test)")
    ax.set_ylabel("k_eff / k_m")
    ax.legend(fontsize=8)


def plot_etc(rows, path, title=""):
    """Two panels: k_eff/k_m against the contrast (single inclusion, 002 Fig. 14) and against
    the volume fraction (dispersion, 002 Fig. 17), with the estimates as lines."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    single = [r for r in rows if r["case"] == "single"]
    disp = [r for r in rows if r["case"] == "dispersion"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    if single:
        f = single[0]["fraction"]
        contrasts = [r["contrast"] for r in single]
        c_line = np.logspace(np.log10(min(contrasts)), np.log10(max(contrasts)), 200)
        _panel(axes[0], contrasts, [r["k_over_km"] for r in single], c_line,
               lambda c: (1.0, c, f))
        axes[0].set_xscale("log")
        axes[0].set_yscale("log")
        axes[0].set_xlabel("contrast k_i / k_m")
        axes[0].set_title(f"single centred inclusion, f = {f:.3f} "
                          f"({single[0]['inclusion_particles']} particles)", fontsize=9)
    if disp:
        c = disp[0]["contrast"]
        fractions = [r["fraction"] for r in disp]
        f_line = np.linspace(0.0, max(fractions) * 1.05, 200)
        _panel(axes[1], fractions, [r["k_over_km"] for r in disp], f_line,
               lambda f: (1.0, c, f))
        axes[1].set_xlabel("inclusion volume fraction f (on the particles)")
        axes[1].set_title(f"random dispersion, contrast {c:g}", fontsize=9)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    savefig_atomic(fig, path, dpi=110)
    plt.close(fig)
