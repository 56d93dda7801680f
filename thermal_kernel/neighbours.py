"""Which dumped pairs conduct: the scene's ``[neighbours]`` criterion (issue 23, docs/scenes.md).

A packing dumped by YADE lists every pair within ``(1 + gap_tolerance)(r_i + r_j)`` (touching
contacts and gap neighbours, docs/packing-format.md). A geometric law such as ``haddad`` conducts
through every listed row, so the dump's ``gap_tolerance`` sets the coordination. A scene may state
instead

- ``gap = g``: only the pairs with centre distance ``d < (1 + g)(r_i + r_j)`` conduct; or
- ``target_z_with_gaps = Z``: tdem picks the gap ``g`` whose pairs give the mean coordination
  ``Z`` (gaps included) over the **bulk**: the particles whose centres are at least
  ``bulk_margin_diameters`` mean diameters from every wall and every cut face of the domain
  (periodic axes have no face: a periodic cell is all bulk).

The choice is made on the packing at hand by filtering its dumped rows: no new YADE run. Rows
outside the criterion get H = 0 (they stay in the arrays, aligned with the packing's rows; the
network drops them). The chosen gap is the midpoint between the normalised distances
``d / (r_i + r_j)`` of the last pair kept and the first pair left out, so that giving it back as
``gap`` keeps the same pairs. The bulk Z reached is the target or up to one pair's worth
(2 / n_bulk) above it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .packing import Packing
from .scene import NeighbourCriterion, SceneError


def distance_ratio(packing: Packing) -> np.ndarray:
    """d / (r_i + r_j) of every dumped row (d the centre distance, periodic image applied)."""
    i, j = packing.pair[:, 0], packing.pair[:, 1]
    return np.linalg.norm(packing.branch, axis=1) / (packing.radius[i] + packing.radius[j])


def face_distance(packing: Packing) -> np.ndarray:
    """Each centre's distance to the nearest wall or cut face, m (inf if none: a periodic cell).

    Faces: the domain's faces normal to every non-periodic axis (walls of a box, or the cut
    faces of a carved packing), every plane wall, and the curved walls (a cylinder: radial
    distance to its surface; a sphere: R - distance to its centre)."""
    p = packing.position
    dist = np.full(packing.n_particles, np.inf)
    for k in range(3):
        if not packing.periodic[k]:
            dist = np.minimum(dist, np.minimum(p[:, k] - packing.domain_lo[k],
                                               packing.domain_hi[k] - p[:, k]))
    for kind, point, normal, radius in zip(packing.wall_kind, packing.wall_point,
                                           packing.wall_normal, packing.wall_radius):
        rel = p - point
        if kind == "plane":
            dist = np.minimum(dist, np.abs(rel @ normal))
        elif kind == "cylinder":
            axial = rel @ normal
            radial = np.linalg.norm(rel - np.outer(axial, normal), axis=1)
            dist = np.minimum(dist, float(radius) - radial)
        elif kind == "sphere":
            dist = np.minimum(dist, float(radius) - np.linalg.norm(rel, axis=1))
    return dist


def bulk_particles(packing: Packing, margin_diameters: float) -> np.ndarray:
    """(N,) bool: centres at least ``margin_diameters`` mean diameters from every wall / face."""
    margin = 2.0 * float(packing.radius.mean()) * margin_diameters
    return face_distance(packing) >= margin


def neighbour_counts(packing: Packing, keep: np.ndarray | None = None) -> np.ndarray:
    """Particle–particle neighbours of each particle as listed in the dump (gaps included; wall
    contacts are not neighbours — Terreros 2012, sec. 4.1), or of the rows ``keep`` only."""
    pair = packing.pair if keep is None else packing.pair[keep]
    return np.bincount(pair.reshape(-1), minlength=packing.n_particles)


def bulk_coordination(packing: Packing, bulk: np.ndarray, keep: np.ndarray | None = None) -> float:
    """Mean number of (kept) dumped pairs per bulk particle, gaps included."""
    return float(neighbour_counts(packing, keep)[bulk].mean()) if bulk.any() else math.nan


@dataclass(frozen=True)
class NeighbourChoice:
    """The criterion applied to one packing: what ``tdem run`` / ``tdem calibrate`` report."""
    gap: float                    # pairs with d < (1 + gap)(r_i + r_j) conduct
    mode: str                     # "gap" (given) | "target_z_with_gaps" (chosen)
    target_z_with_gaps: float     # NaN when the gap was given
    bulk_margin_diameters: float
    bulk_z: float                 # reached: kept pairs per bulk particle
    bulk_z_dumped: float          # every dumped row
    z_all: float                  # kept pairs per particle, every particle
    n_bulk: int
    n_kept: int
    n_dumped: int
    dump_gap_tolerance: float     # the packing's gap_tolerance attribute (NaN if absent)
    keep: np.ndarray              # (M,) bool over the packing's rows

    def summary(self) -> dict:
        """JSON-ready numbers (thermal.h5's attribute ``neighbours``, calibrate's output)."""
        def num(x):
            return None if math.isnan(x) else float(x)
        return dict(gap=self.gap, mode=self.mode,
                    target_z_with_gaps=num(self.target_z_with_gaps),
                    bulk_margin_diameters=self.bulk_margin_diameters, bulk_z=self.bulk_z,
                    bulk_z_dumped=self.bulk_z_dumped, z_all=self.z_all, n_bulk=self.n_bulk,
                    n_kept=self.n_kept, n_dumped=self.n_dumped,
                    dump_gap_tolerance=num(self.dump_gap_tolerance))

    def line(self) -> str:
        """One line for the command line."""
        how = (f"chosen for bulk Z {self.target_z_with_gaps:g}" if self.mode != "gap"
               else "given")
        return (f"neighbours: gap {self.gap:.6g} ({how}): pairs with d < {1 + self.gap:.6g} "
                f"(r_i + r_j), {self.n_kept} of {self.n_dumped} dumped rows; bulk Z with gaps "
                f"{self.bulk_z:.4f} (every dumped row: {self.bulk_z_dumped:.4f}) over "
                f"{self.n_bulk} particles >= {self.bulk_margin_diameters:g} mean diameters from "
                f"every wall / cut face; Z over all particles {self.z_all:.4f}")


def dump_gap_tolerance(packing: Packing) -> float:
    return dump_gap_tolerance_of(packing.attrs)


def dump_gap_tolerance_of(attrs: dict) -> float:
    """A packing's ``gap_tolerance`` attribute from its attributes (NaN if absent)."""
    value = attrs.get("gap_tolerance")
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def choose_gap(ratio: np.ndarray, weight: np.ndarray, need: float) -> tuple[float, int] | None:
    """The gap whose rows (ratio < 1 + gap) sum ``weight`` to at least ``need`` first:
    (gap, number of rows kept), or None when every row together stays below ``need``. The gap
    is half way between the last row kept and the next one (or at the last row's ratio plus a
    hair when every row is kept)."""
    order = np.argsort(ratio, kind="stable")
    s = ratio[order]
    cum = np.cumsum(weight[order])
    if cum.size == 0 or cum[-1] < need:
        return None
    k = int(np.searchsorted(cum, need, side="left"))
    while k + 1 < s.size and s[k + 1] == s[k]:      # ties go in together
        k += 1
    if k + 1 < s.size:
        cut = 0.5 * (s[k] + s[k + 1])
    else:
        cut = s[k] * (1 + 1e-12)
    return cut - 1.0, k + 1



# the refusals, in one line naming the scene, the key and the packing (the whole build's and the
# ranks' alike)
def _no_bulk(scene, crit, path) -> SceneError:
    return SceneError(f"{scene.path}: neighbours.bulk_margin_diameters: no particle of {path} is "
                      f"{crit.bulk_margin_diameters:g} mean diameters from every wall / cut "
                      "face (expected a smaller margin or a larger packing)")


def _check_given_gap(scene, crit, path, tol) -> None:
    if math.isfinite(tol) and crit.gap > tol * (1 + 1e-12):
        raise SceneError(f"{scene.path}: neighbours.gap: {crit.gap:g} is beyond the "
                         f"gap_tolerance {tol:g} {path} was dumped with (the pairs in between "
                         f"are not in the file); expected a gap <= {tol:g}")


def _above_dump(scene, crit, path, tol, z_dumped) -> SceneError:
    tol_text = f"gap_tolerance {tol:g}" if math.isfinite(tol) else "its gap_tolerance"
    return SceneError(f"{scene.path}: neighbours.target_z_with_gaps: "
                      f"{crit.target_z_with_gaps:g} is above the bulk Z {z_dumped:.4f} of every "
                      f"pair {path} holds (dumped with {tol_text}); expected at most "
                      f"{z_dumped:.4f} (or a packing dumped with a larger gap_tolerance)")


def _below_touching(scene, crit, path, z_touch) -> SceneError:
    return SceneError(f"{scene.path}: neighbours.target_z_with_gaps: "
                      f"{crit.target_z_with_gaps:g} is below the bulk Z {z_touch:.4f} of the "
                      f"touching contacts of {path} alone (a negative gap would cut touching "
                      f"contacts); expected at least {z_touch:.4f}")


def choose_neighbours(scene, packing: Packing) -> NeighbourChoice | None:
    """The scene's [neighbours] criterion on ``packing`` (None: the scene has none, every dumped
    row conducts). Refused in one line naming the scene, the key and the packing: a gap beyond
    the dump's gap_tolerance, a target above what the dumped rows give the bulk (or below what
    the touching contacts alone give), no bulk particle."""
    crit: NeighbourCriterion | None = scene.neighbours
    if crit is None:
        return None
    tol = dump_gap_tolerance(packing)
    ratio = distance_ratio(packing)
    bulk = bulk_particles(packing, crit.bulk_margin_diameters)
    n_bulk = int(bulk.sum())
    if n_bulk == 0:
        raise _no_bulk(scene, crit, packing.path)
    z_dumped = bulk_coordination(packing, bulk)
    if not math.isnan(crit.gap):
        _check_given_gap(scene, crit, packing.path, tol)
        gap, mode = crit.gap, "gap"
    else:
        target = crit.target_z_with_gaps
        weight = (bulk[packing.pair[:, 0]].astype(np.int64)
                  + bulk[packing.pair[:, 1]].astype(np.int64))
        need = target * n_bulk * (1 - 1e-12)
        found = choose_gap(ratio, weight, need)
        if found is None:
            raise _above_dump(scene, crit, packing.path, tol, z_dumped)
        gap = found[0]
        if gap < 0:
            raise _below_touching(scene, crit, packing.path,
                                  bulk_coordination(packing, bulk, ratio < 1.0))
        if math.isfinite(tol):
            gap = min(gap, tol)
        mode = "target_z_with_gaps"
    keep = ratio < 1.0 + gap
    n = packing.n_particles
    return NeighbourChoice(
        gap=float(gap), mode=mode, target_z_with_gaps=float(crit.target_z_with_gaps),
        bulk_margin_diameters=float(crit.bulk_margin_diameters),
        bulk_z=bulk_coordination(packing, bulk, keep), bulk_z_dumped=z_dumped,
        z_all=2.0 * int(keep.sum()) / n, n_bulk=n_bulk, n_kept=int(keep.sum()),
        n_dumped=packing.n_contacts, dump_gap_tolerance=tol, keep=keep)


def choose_neighbours_on_ranks(scene, comm, path, tol: float, n: int, m: int, n_bulk: int,
                               ratio: np.ndarray, weight: np.ndarray) -> NeighbourChoice | None:
    """:func:`choose_neighbours` on the ranks (issue 25, :mod:`thermal_kernel.rank_build`):
    collective over the mpi4py communicator ``comm``; each rank gives its slice of the file's
    contact rows only -- their ``ratio`` (:func:`distance_ratio`) and ``weight`` (how many of
    the row's two particles are bulk particles, 0-2) -- and ``n_bulk`` (the bulk particles,
    counted over the ranks' blocks of the particles). No rank holds every row: the whole build's
    choice is reproduced from collectives, bit for bit (``tests/mpi_rank_build_check.py``):

    - the bulk Z's are exact integer sums of ``weight`` over ``n_bulk``, as the whole build's
      means of integer counts are;
    - ``target_z_with_gaps``: the whole build keeps, in the order of the ratios, the rows whose
      summed weight first reaches ``need`` (ties together): the last row kept has the smallest
      ratio v with W(v) >= need, W(v) the summed weight of the rows with ratio <= v. Ratios are
      >= 0, so their float64 bits as int64 are in the same order: a bisection over those bits
      (W summed over the ranks a step, <= 64 steps) finds v exactly; the next ratio is the
      smallest one above v; the gap is the whole build's arithmetic on the two.

    The collectives are ``comm.allgather`` of one number a rank (summed, or the min / max
    taken, in Python: exact integers; one call a bisection step). Refused as the whole build
    refuses (the same lines, on every rank: every decision is made on gathered numbers). The
    choice's ``keep`` is over this rank's rows."""
    crit = scene.neighbours
    if crit is None:
        return None
    if n_bulk == 0:
        raise _no_bulk(scene, crit, path)
    ratio = np.asarray(ratio, dtype=np.float64)
    weight = np.asarray(weight, dtype=np.int64)

    def total(x):
        return sum(comm.allgather(int(x)))

    z_dumped = float(total(weight.sum())) / n_bulk
    if not math.isnan(crit.gap):
        _check_given_gap(scene, crit, path, tol)
        gap, mode = crit.gap, "gap"
    else:
        need = crit.target_z_with_gaps * n_bulk * (1 - 1e-12)
        if not total(weight.sum()) >= need:
            raise _above_dump(scene, crit, path, tol, z_dumped)
        order = np.argsort(ratio, kind="stable")
        s = ratio[order]
        cum = np.cumsum(weight[order])
        del order

        def w_at_most(v):           # the summed weight of every rank's rows with ratio <= v
            k = int(np.searchsorted(s, v, side="right"))
            return total(cum[k - 1] if k else 0)

        bits = s.view(np.int64)
        big = np.iinfo(np.int64).max
        lo = min(comm.allgather(int(bits[0]) if bits.size else big)) - 1
        hi = max(comm.allgather(int(bits[-1]) if bits.size else -1))
        while hi - lo > 1:          # W(lo) < need <= W(hi)
            mid = lo + (hi - lo) // 2
            if w_at_most(np.array(mid, dtype=np.int64).view(np.float64)) >= need:
                hi = mid
            else:
                lo = mid
        v = np.array(hi, dtype=np.int64).view(np.float64)[()]
        k = int(np.searchsorted(s, v, side="right"))
        nxt = min(comm.allgather(float(s[k]) if k < s.size else math.inf))
        cut = 0.5 * (v + np.float64(nxt)) if math.isfinite(nxt) else v * (1 + 1e-12)
        gap = cut - 1.0
        if gap < 0:
            raise _below_touching(scene, crit, path,
                                  float(total(weight[ratio < 1.0].sum())) / n_bulk)
        if math.isfinite(tol):
            gap = min(gap, tol)
        mode = "target_z_with_gaps"
    keep = ratio < 1.0 + gap
    n_kept = total(np.count_nonzero(keep))
    return NeighbourChoice(
        gap=float(gap), mode=mode, target_z_with_gaps=float(crit.target_z_with_gaps),
        bulk_margin_diameters=float(crit.bulk_margin_diameters),
        bulk_z=float(total(weight[keep].sum())) / n_bulk, bulk_z_dumped=z_dumped,
        z_all=2.0 * n_kept / n, n_bulk=n_bulk, n_kept=n_kept, n_dumped=m,
        dump_gap_tolerance=tol, keep=keep)
