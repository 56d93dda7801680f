"""What every boundary kind shares: the base class, the build context, the rows collector, and
the particles a boundary ``on`` names.

A kind is a frozen dataclass subclassing :class:`BoundaryKind`. Its fields are the keys of its
``[[boundary]]`` table (besides ``kind``), so the table's keys and the kind's fields are one
list; ``parse`` reads and checks them, ``contribute`` adds the kind's rows to the problem
under construction (:class:`Rows`). The solvers only ever see the rows (plain arrays of
``thermal_kernel.network.ThermalProblem``), never which kind made them.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from ..errors import SceneError
from ..physical import TEMPERATURE_MAX_K

FACES = {"xmin": (0, -1), "xmax": (0, +1), "ymin": (1, -1), "ymax": (1, +1),
         "zmin": (2, -1), "zmax": (2, +1)}


@dataclass(frozen=True, kw_only=True)
class BoundaryKind:
    """One ``[[boundary]]`` entry. ``name`` labels it in the outputs (boundary_heat_flow)."""
    kind: ClassVar[str] = ""
    # Declared by every kind (no default here): the unit of its ``value`` as its docstring's
    # Keys line states it, a minimal ``[[boundary]]`` table of it (TOML, ``kind`` left out)
    # and the ``name`` that table gets by default (tests/test_boundaries.py reads all three).
    unit: ClassVar[str]
    example: ClassVar[str]
    example_name: ClassVar[str]
    name: str

    @classmethod
    def parse(cls, t) -> BoundaryKind:
        """Read this kind's keys out of the scene table ``t`` (``thermal_kernel.scene._Table``:
        ``kind`` already read) and check them; leftover keys are refused by the caller."""
        raise NotImplementedError

    def contribute(self, ctx: BuildContext, index: int, rows: Rows) -> None:
        """Add this boundary's rows (boundary number ``index`` of the scene) to ``rows``;
        refuse (:class:`SceneError`, one line) what the packing or the law cannot give."""
        raise NotImplementedError


class Whole:
    """How a kind sees the whole packing when ``ctx.packing`` holds only part of it: the
    numbers a kind needs of every particle (a count, a sum, the phases present) from its
    part's. This one is the whole packing in one process (each method the identity); the
    PETSc backend's ranks, each building the rows of its own particles, pass one that
    reduces over the ranks (thermal_kernel/rank_build.py: ``RanksWhole``), so a kind is
    written once for both."""

    def count(self, k: int) -> int:
        """How many particles over the whole packing, ``k`` of them here."""
        return int(k)

    def any(self, flag) -> bool:
        return bool(flag)

    def all(self, flag) -> bool:
        return bool(flag)

    def ordered_sum(self, values: np.ndarray, particles: np.ndarray) -> float:
        """sum(values) over the whole packing, summed in the order of the particles' packing
        indices (``particles``: this part's indices of ``values``' particles, ascending): the
        same sum, bit for bit, however the packing is split."""
        return values.sum()

    def union(self, values: np.ndarray) -> np.ndarray:
        """The distinct values (sorted) over the whole packing."""
        return np.unique(values)

    def lowest(self, particles: np.ndarray, values: np.ndarray):
        """``values`` at the particle of lowest packing index among ``particles`` (this part's
        indices, ascending; None if there is none anywhere)."""
        return values[0] if particles.size else None


@dataclass(frozen=True)
class BuildContext:
    """What a boundary may need from the scene, the packing and the law to make its rows."""
    scene: Any                     # thermal_kernel.scene.Scene
    packing: Any                   # thermal_kernel.packing.Packing
    law: Any                       # thermal_kernel.laws.base.Law
    params: dict                   # the law's parameters (defaults + scene's law_params)
    particles: Any                 # thermal_kernel.laws.base.ParticleInput
    capacity_j_k: np.ndarray       # (N,) C_p from the law
    young_pa: float                # real modulus and Poisson ratio (scene's, else packing's)
    poisson: float
    whole: Whole = Whole()         # the packing whole here, or a part (a rank's particles)

    def error(self, where: str, what: str) -> SceneError:
        return SceneError(f"{self.scene.path}: {where}: {what}")


class Rows:
    """The rows the boundaries contribute, gathered in scene order (see ThermalProblem):

    - ``hold``: Dirichlet, particles held at a temperature;
    - ``exchange``: g (Tw - T_p) between a particle and a reservoir at Tw;
    - ``power``: a constant power into particles;
    - ``source``: a time-dependent power ``term(t0, t1) -> (N,) W``, made by ``make()`` once
      every boundary has contributed (at most one per scene); a term whose powers are each
      particle's own offers ``term.restricted(particles)``, the same term over those
      particles, which the PETSc backend's ranks evaluate on their blocks (without it rank 0
      evaluates the whole term and scatters its powers).
    """

    def __init__(self):
        self.fixed_p, self.fixed_t, self.fixed_b = [], [], []
        self.exch_p, self.exch_g, self.exch_t, self.exch_b = [], [], [], []
        self.pow_p, self.pow_w, self.pow_b = [], [], []
        self.sources: list[tuple[int, Callable[[], Callable]]] = []
        self.fixed_i, self.pow_i = [], []     # the boundary of each entry (none may be here)

    def hold(self, index: int, particles, temperature_k: float) -> None:
        self.fixed_i.append(index)
        self.fixed_p.append(particles)
        self.fixed_t.append(np.full(particles.size, temperature_k))
        self.fixed_b.append(np.full(particles.size, index))

    def exchange(self, index: int, particles, g_w_k, temperature_k: float) -> None:
        self.exch_p.append(particles)
        self.exch_g.append(np.asarray(g_w_k, dtype=np.float64))
        self.exch_t.append(np.full(particles.size, temperature_k))
        self.exch_b.append(np.full(particles.size, index))

    def power(self, index: int, particles, power_w) -> None:
        self.pow_i.append(index)
        self.pow_p.append(particles)
        self.pow_w.append(power_w)
        self.pow_b.append(np.full(particles.size, index))

    def source(self, index: int, make: Callable[[], Callable]) -> None:
        self.sources.append((index, make))


def boundary_particles(scene, packing, on: str, where: str) -> np.ndarray:
    """Particles of a boundary named ``on``: those in the wall's ``wall_contacts`` for a wall of
    the packing, or, for a domain face without a wall, the spheres that reach the face
    (x - r <= lo, x + r >= hi, within 1e-9 of the domain size)."""
    if on in packing.wall_name:
        w = packing.wall_name.index(on)
        return np.unique(packing.wall_particle[packing.wall_index == w])
    if on in FACES:
        axis, side = FACES[on]
        if packing.periodic[axis]:
            raise SceneError(f"{scene.path}: {where}.on: {packing.path} is periodic along "
                             f"{'xyz'[axis]}: {on!r} is no face (the spheres beside it touch "
                             "those beside the opposite one across the periodic boundary); "
                             f"expected a wall ({', '.join(packing.wall_name) or 'none'}) or "
                             "a face of a non-periodic axis")
        x = packing.position[:, axis]
        r = packing.radius
        tol = 1e-9 * float(packing.domain_hi[axis] - packing.domain_lo[axis])
        if side < 0:
            sel = x - r <= packing.domain_lo[axis] + tol
        else:
            sel = x + r >= packing.domain_hi[axis] - tol
        return np.flatnonzero(sel)
    raise SceneError(f"{scene.path}: {where}.on: {on!r} is neither a wall of "
                     f"{packing.path} ({', '.join(packing.wall_name) or 'no walls'}) nor a "
                     f"domain face ({', '.join(FACES)})")


def members(ctx: BuildContext, on: str, where: str) -> np.ndarray:
    """:func:`boundary_particles`, refusing a wall or face that holds no particle."""
    p = boundary_particles(ctx.scene, ctx.packing, on, where)
    if ctx.whole.count(p.size) == 0:
        raise ctx.error(f"{where}.on", f"no particle belongs to {on!r} in {ctx.packing.path}")
    return p


def read_temperature(t, key: str = "value") -> float:
    """A required absolute temperature (K) in (0, TEMPERATURE_MAX_K]."""
    value = t.number(key)
    if value <= 0:
        t.fail(key, f"expected a temperature > 0 K, got {value!r}")
    if value > TEMPERATURE_MAX_K:
        t.fail(key, f"expected a temperature in (0, {TEMPERATURE_MAX_K:g}] K (no solid above), "
                    f"got {value!r}")
    return value
