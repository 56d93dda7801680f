"""What every conductance law receives and returns. The integrators never see a law.

A law is a pair of small pure functions with the same signature as its siblings:

    conductance(contacts: ContactInput, params: dict) -> (M,) array, W/K, H_ij >= 0
    capacity(particles: ParticleInput, params: dict) -> (N,) array, J/K, C_i > 0

and optionally ``wall_conductance(walls: WallContactInput, params) -> (K,) W/K`` for heat
exchange between a particle and a wall of fixed temperature. Laws are registered by name in
``thermal_kernel.laws.LAWS`` (explicit dict, no discovery). ``params`` holds the scene's
``[law_params]`` merged over the law's ``defaults``.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class ContactInput:
    """Per particle–particle contact (M rows; i < j). SI units."""
    radius_i_m: np.ndarray
    radius_j_m: np.ndarray
    distance_m: np.ndarray          # |branch|, centre-to-centre (periodic image applied)
    overlap_m: np.ndarray           # delta; negative = a gap kept by the neighbour criterion
    normal_force_n: np.ndarray      # from the dump (0 for gaps)
    conductivity_i: np.ndarray      # W/m/K of the particles' phases
    conductivity_j: np.ndarray
    neighbours_i: np.ndarray        # number of particle–particle neighbours of i in the dump
    neighbours_j: np.ndarray
    young_pa: float                 # REAL modulus (scene [material] or packing attrs)
    poisson: float


@dataclass(frozen=True)
class ParticleInput:
    """Per particle (N rows). SI units."""
    radius_m: np.ndarray
    density: np.ndarray             # kg/m^3 (continuum density of the phase)
    heat_capacity: np.ndarray       # J/kg/K
    conductivity: np.ndarray        # W/m/K
    neighbours: np.ndarray          # number of particle–particle neighbours in the dump
    solid_fraction: float           # of the packing (attrs['solid_fraction'])


@dataclass(frozen=True)
class WallContactInput:
    """Per particle–wall contact (K rows). The wall is rigid with the particle's conductivity
    unless the scene says otherwise."""
    radius_m: np.ndarray
    overlap_m: np.ndarray
    normal_force_n: np.ndarray
    conductivity_particle: np.ndarray
    conductivity_wall: np.ndarray
    young_pa: float
    poisson: float


LAW_KINDS = ("geometric", "force", "overlap")


@dataclass(frozen=True)
class Law:
    name: str
    conductance: Callable[[ContactInput, dict], np.ndarray]
    capacity: Callable[[ParticleInput, dict], np.ndarray]
    formula: str                    # one line, shown by `tdem laws`
    reference: str                  # paper file and equation numbers
    # which dumped rows conduct (LAW_KINDS; the "kind" column of docs/laws.md): "geometric"
    # (every row, gaps and F_n = 0 included, less the farther apart), "force" (only a row with
    # a normal force: F_n = 0 gives H = 0) or "overlap" (only spheres that overlap, no force
    # enters: a gap gives H = 0). The same for the law's wall conductance.
    kind: str
    defaults: dict = field(default_factory=dict)
    wall_conductance: Callable[[WallContactInput, dict], np.ndarray] | None = None
    # True for a hypothesis tool that is not a physical law (listed apart by `tdem laws`)
    diagnostic: bool = False


def sphere_volume(radius_m):
    return 4.0 / 3.0 * np.pi * np.asarray(radius_m) ** 3


def mass_capacity(particles: ParticleInput, params: dict) -> np.ndarray:
    """C_i = rho c_p (4/3) pi R^3: the capacity rule of the granular laws (003, 004)."""
    return particles.density * particles.heat_capacity * sphere_volume(particles.radius_m)
