"""The packing format (``packing.h5``): the validating reader, the project-side writer, statistics.

Specification: ``docs/packing-format.md``. Every file is validated on load; a problem raises
:class:`PackingError` whose one-line message names the file, the field and what was expected.
The writer is :mod:`thermal_kernel.packing_h5` (shared with the YADE generators), so a packing
written here and one written under YADE are the same bytes for the same arrays.
"""
from __future__ import annotations

import io
import math
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from . import packing_h5

FORMAT = packing_h5.FORMAT
FORMAT_VERSION = packing_h5.FORMAT_VERSION
REQUIRED_ATTRS = ("generator", "seed", "solid_fraction", "mean_coordination", "pressure_pa",
                  "young_pa", "poisson", "density")
# Root attributes that may be NaN ("not applicable"); every other number must be finite.
NAN_ALLOWED_ATTRS = ("pressure_pa",)


class PackingError(ValueError):
    """A packing file that does not follow the format. ``str(e)`` is one line."""


@dataclass
class Packing:
    """A packing in memory: plain numpy arrays in SI units, particle indices 0..N-1."""
    position: np.ndarray            # (N, 3) m
    radius: np.ndarray              # (N,) m
    phase: np.ndarray               # (N,) int32
    pair: np.ndarray                # (M, 2) int64, i < j, sorted
    overlap: np.ndarray             # (M,) m, negative = gap
    normal_force: np.ndarray        # (M,) N
    branch: np.ndarray              # (M, 3) m, centre i -> centre j (periodic image applied)
    wall_name: list = field(default_factory=list)     # (W,) str
    wall_kind: list = field(default_factory=list)     # (W,) 'plane' | 'cylinder' | 'sphere'
    wall_point: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    wall_normal: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    wall_radius: np.ndarray = field(default_factory=lambda: np.zeros(0))
    wall_particle: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    wall_index: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    wall_overlap: np.ndarray = field(default_factory=lambda: np.zeros(0))
    wall_normal_force: np.ndarray = field(default_factory=lambda: np.zeros(0))
    domain_lo: np.ndarray = field(default_factory=lambda: np.zeros(3))
    domain_hi: np.ndarray = field(default_factory=lambda: np.zeros(3))
    periodic: np.ndarray = field(default_factory=lambda: np.zeros(3, bool))
    attrs: dict = field(default_factory=dict)
    contact_radius: np.ndarray | None = None        # (M,) m, optional
    wall_contact_radius: np.ndarray | None = None   # (K,) m, optional
    yade_id: np.ndarray | None = None               # (N,) optional
    path: str = ""
    # A part of the file's contacts (the PETSc backend's ranks, thermal_kernel/rank_build.py):
    # the file's row of each contact held, and how many rows the file has. None: all of them.
    contact_row: np.ndarray | None = None           # (M,) int64
    file_contacts: int | None = None

    @property
    def n_particles(self) -> int:
        return int(self.radius.shape[0])

    @property
    def n_contacts(self) -> int:
        return int(self.pair.shape[0])

    def wall_id(self, name: str) -> int:
        """Index of the wall called ``name``; PackingError if there is none."""
        try:
            return self.wall_name.index(name)
        except ValueError:
            raise PackingError(f"{self.path}: walls/name: no wall named {name!r} "
                               f"(walls: {', '.join(self.wall_name) or 'none'})") from None


# ----------------------------------------------------------------------------- reading

def _fail(path, fieldname, what):
    raise PackingError(f"{path}: {fieldname}: {what}")


def _dataset(f, path, name, dtype_kind, shape, optional=False, rows=None):
    """Read dataset ``name``; check its kind ('f', 'i', 'S') and shape (None = any length).
    ``rows`` (a slice of the first axis, numeric datasets): read those rows only (the shape
    checked is the whole dataset's; an empty slice reads nothing)."""
    if name not in f:
        if optional:
            return None
        _fail(path, name, "missing dataset")
    obj = f[name]
    if not isinstance(obj, h5py.Dataset):
        _fail(path, name, "expected a dataset, found a group")
    if dtype_kind == "S":
        if h5py.check_string_dtype(obj.dtype) is None:
            _fail(path, name, f"expected strings, got dtype {obj.dtype}")
        data = [x.decode() if isinstance(x, bytes) else str(x) for x in obj[()].reshape(-1)]
        got_shape = obj.shape
    else:
        if obj.dtype.kind not in (dtype_kind + ("u" if dtype_kind == "i" else "")):
            expected = {"f": "floating point", "i": "integer"}[dtype_kind]
            _fail(path, name, f"expected {expected} values, got dtype {obj.dtype}")
        data = obj[()] if rows is None else obj[rows]
        got_shape = obj.shape
    if len(got_shape) != len(shape) or any(s is not None and s != g
                                           for s, g in zip(shape, got_shape)):
        want = "(" + ", ".join("n" if s is None else str(s) for s in shape) + \
               ("," if len(shape) == 1 else "") + ")"
        _fail(path, name, f"expected shape {want}, got {got_shape}")
    if dtype_kind == "f" and not np.all(np.isfinite(data)) and name != "walls/radius":
        bad = int(np.flatnonzero(~np.isfinite(np.asarray(data).reshape(-1)))[0])
        if rows is not None:            # the flat index in the whole dataset
            bad += int(rows.start or 0) * int(np.prod(got_shape[1:], dtype=np.int64))
        _fail(path, name, f"non-finite value (NaN or inf) at flat index {bad}")
    return data


def _lengths_agree(path, names_arrays, length):
    for name, arr in names_arrays:
        if arr is not None and arr.shape[0] != length:
            _fail(path, name, f"expected {length} rows (as many as its group's first dataset), "
                              f"got {arr.shape[0]}")


def _open(path):
    path = str(path)
    if not Path(path).is_file():
        raise PackingError(f"{path}: file not found")
    try:
        return h5py.File(path, "r"), path
    except OSError as e:
        raise PackingError(f"{path}: not an HDF5 file ({str(e).splitlines()[0]})") from None


def read_packing(path, contacts: bool = True) -> Packing:
    """Read and validate ``packing.h5``. Raises PackingError with a one-line message.
    ``contacts=False``: everything but the particle-particle contacts (their datasets' kinds
    and shapes are checked, their rows neither read nor checked; ``file_contacts`` says how
    many there are): the PETSc backend's ranks read their rows with :func:`read_contact_rows`."""
    f, path = _open(path)
    return _read_open(f, path, contacts)


CONTACT_BLOCK_ROWS = 1 << 18     # read_contact_rows reads and checks this many rows at a time


def read_contact_rows(path, n: int, m: int, start: int, stop: int) -> dict:
    """Rows ``start:stop`` of the contacts of the packing file ``path`` (``n`` particles, ``m``
    contact rows: ``read_packing(path, contacts=False)``'s ``n_particles`` and
    ``file_contacts``): a dict of the contacts' arrays (pair as int64; ``contact_radius`` None
    when the file has none) and ``contact_row``, the file's rows. Their kinds and shapes, the
    indices (in range, i < j) and duplicates within a block of rows are checked here; the
    checks against the spheres, by :func:`check_contact_rows` given the rows' spheres (a
    duplicate elsewhere is found by whoever holds both: the rows of a particle,
    thermal_kernel/rank_build.py). Read ``CONTACT_BLOCK_ROWS`` rows at a time; messages name
    the file's rows."""
    f, path = _open(path)
    start, stop = int(start), int(stop)
    names = (("pair", "contacts/pair", "i", (None, 2)),
             ("overlap", "contacts/overlap", "f", (m,)),
             ("normal_force", "contacts/normal_force", "f", (m,)),
             ("branch", "contacts/branch", "f", (m, 3)),
             ("contact_radius", "contacts/contact_radius", "f", (m,)))
    out = {}
    with f:
        for b0 in range(start, max(stop, start + 1), CONTACT_BLOCK_ROWS):
            rows = slice(b0, min(stop, b0 + CONTACT_BLOCK_ROWS))
            got = {key: _dataset(f, path, name, kind, shape, optional=key == "contact_radius",
                                 rows=rows) for key, name, kind, shape in names}
            _check_pairs(path, got["pair"], n, row0=b0)
            if not out:
                out = {key: None if a is None else np.empty(
                    (stop - start,) + a.shape[1:], np.int64 if key == "pair" else a.dtype)
                    for key, a in got.items()}
            for key, a in got.items():
                if a is not None:
                    out[key][rows.start - start:rows.stop - start] = a
    out["contact_row"] = np.arange(start, stop, dtype=np.int64)
    return out


def read_particle_rows(path, start: int, stop: int) -> dict:
    """Rows ``start:stop`` of the particles of the packing file ``path`` (centres, radii,
    phases), for a file :func:`read_packing` has checked (``contacts=False`` will do): the PETSc
    backend's ranks, each reading a block of the file's particles (rank_build.py)."""
    f, path = _open(path)
    rows = slice(int(start), int(stop))
    with f:
        n = int(f["particles/position"].shape[0])
        return dict(position=_dataset(f, path, "particles/position", "f", (None, 3), rows=rows),
                    radius=_dataset(f, path, "particles/radius", "f", (n,), rows=rows),
                    phase=_dataset(f, path, "particles/phase", "i", (n,),
                                   rows=rows).astype(np.int32))


def _check_tensile(path, normal_force, row0=0):
    if np.any(normal_force < 0):
        i = int(np.flatnonzero(normal_force < 0)[0])
        _fail(path, "contacts/normal_force", f"contact {i + row0} has a tensile (negative) "
                                             f"force {float(normal_force[i])!r}; expected >= 0")


def read_packing_image(image, name) -> Packing:
    """Validate the bytes of a packing file built in memory (:func:`packing_image`) before
    anything is written; messages name the file ``name`` it is meant for."""
    try:
        f = h5py.File(io.BytesIO(image), "r")
    except OSError as e:
        raise PackingError(f"{name}: not an HDF5 image ({str(e).splitlines()[0]})") from None
    return _read_open(f, str(name))


def _read_open(f, path, contacts=True) -> Packing:
    """The packing in the open file ``f``, read and checked group by group (the root's
    attributes, particles, contacts, walls, wall contacts, domain: the first fault found is
    the one reported), then the checks across groups."""
    with f:
        attrs = _read_attrs(f, path)
        position, radius, phase, yade_id = _read_particles(f, path)
        n = position.shape[0]
        pair, overlap, normal_force, branch, contact_radius, m = _read_contacts(
            f, path, n, contacts)
        wall_name, wall_kind, wall_point, wall_normal, wall_radius = _read_walls(f, path)
        (wall_particle, wall_index, wall_overlap, wall_normal_force,
         wall_contact_radius) = _read_wall_contacts(f, path, n, len(wall_name))
        dom = _read_domain(f, path)
    _check_geometry(path, position, radius, phase, pair, overlap, branch, wall_particle,
                    wall_overlap, dom["lo"], dom["hi"], dom["periodic"])
    _check_forces_and_walls(path, position, radius, pair, overlap, normal_force, branch,
                            wall_kind, wall_point, wall_normal, wall_radius, wall_particle,
                            wall_index, wall_overlap, wall_normal_force)
    _check_solid_fraction(path, attrs["solid_fraction"], position, radius, wall_kind,
                          wall_normal, wall_radius, wall_particle, wall_overlap, dom["lo"],
                          dom["hi"])

    return Packing(position=position, radius=radius, phase=phase.astype(np.int32),
                   pair=pair.astype(np.int64), overlap=overlap, normal_force=normal_force,
                   branch=branch, wall_name=wall_name, wall_kind=wall_kind,
                   wall_point=wall_point, wall_normal=wall_normal, wall_radius=wall_radius,
                   wall_particle=wall_particle.astype(np.int64),
                   wall_index=wall_index.astype(np.int32), wall_overlap=wall_overlap,
                   wall_normal_force=wall_normal_force, domain_lo=dom["lo"],
                   domain_hi=dom["hi"], periodic=dom["periodic"], attrs=attrs,
                   contact_radius=contact_radius, wall_contact_radius=wall_contact_radius,
                   yade_id=yade_id, path=path, file_contacts=None if contacts else m)


def _read_attrs(f, path) -> dict:
    """The root attributes: the format and its version, the required ones present and
    numbers (finite but where NaN is allowed), within their ranges."""
    fmt = f.attrs.get("format")
    if isinstance(fmt, bytes):
        fmt = fmt.decode()
    if fmt != FORMAT:
        _fail(path, "format", f"expected attribute format = {FORMAT!r}, got {fmt!r}")
    version = f.attrs.get("format_version")
    if isinstance(version, np.generic):
        version = version.item()
    if version is None or not np.issubdtype(np.asarray(version).dtype, np.integer) \
            or int(version) != FORMAT_VERSION:
        _fail(path, "format_version",
              f"unknown format version {version!r} (this tdem reads {FORMAT_VERSION})")
    attrs = {}
    for key, value in f.attrs.items():
        if isinstance(value, bytes):
            value = value.decode()
        elif isinstance(value, np.generic):
            value = value.item()
        attrs[key] = value
    for key in REQUIRED_ATTRS:
        if key not in attrs:
            _fail(path, key, "missing root attribute")
    for key in REQUIRED_ATTRS[2:]:
        value = attrs[key]
        if isinstance(value, (bool, str)) or not isinstance(value, (int, float)):
            _fail(path, key, f"expected a number, got {value!r}")
        if key not in NAN_ALLOWED_ATTRS and not math.isfinite(value):
            _fail(path, key, f"expected a finite number, got {value!r}")
    _check_attr_ranges(path, attrs)
    return attrs


def _read_particles(f, path) -> tuple:
    """particles/: position, radius (> 0), phase and the optional yade_id; at least one."""
    position = _dataset(f, path, "particles/position", "f", (None, 3))
    n = position.shape[0]
    radius = _dataset(f, path, "particles/radius", "f", (n,))
    phase = _dataset(f, path, "particles/phase", "i", (n,))
    yade_id = _dataset(f, path, "particles/yade_id", "i", (n,), optional=True)
    if n == 0:
        _fail(path, "particles/position", "expected at least one particle")
    _check_radius(path, radius)
    return position, radius, phase, yade_id


def _check_radius(path, radius, row0=0):
    """Every radius > 0 (``row0``: the file's index of the first; messages name the file's)."""
    if np.any(radius <= 0):
        i = int(np.flatnonzero(radius <= 0)[0])
        _fail(path, "particles/radius", f"particle {i + row0} has radius {radius[i]!r}; "
                                        "expected > 0")


def _read_contacts(f, path, n, contacts) -> tuple:
    """contacts/: pair, overlap, normal_force, branch and the optional contact_radius, the
    pairs' indices and the forces checked, and the number of rows; ``contacts`` False: the
    kinds and shapes only, no rows read."""
    rows = None if contacts else slice(0, 0)         # no rows: kinds and shapes only
    pair = _dataset(f, path, "contacts/pair", "i", (None, 2), rows=rows)
    m = pair.shape[0] if contacts else int(f["contacts/pair"].shape[0])
    overlap = _dataset(f, path, "contacts/overlap", "f", (m,), rows=rows)
    normal_force = _dataset(f, path, "contacts/normal_force", "f", (m,), rows=rows)
    branch = _dataset(f, path, "contacts/branch", "f", (m, 3), rows=rows)
    contact_radius = _dataset(f, path, "contacts/contact_radius", "f", (m,), optional=True,
                              rows=rows)
    _check_pairs(path, pair, n)
    _check_tensile(path, normal_force)
    return pair, overlap, normal_force, branch, contact_radius, m


def _read_walls(f, path) -> tuple:
    """walls/: name, kind (known; a cylinder or sphere with a radius > 0), point, unit normal
    and radius; the names distinct."""
    wall_name = _dataset(f, path, "walls/name", "S", (None,))
    w = len(wall_name)
    wall_kind = _dataset(f, path, "walls/kind", "S", (w,))
    wall_point = _dataset(f, path, "walls/point", "f", (w, 3))
    wall_normal = _dataset(f, path, "walls/normal", "f", (w, 3))
    wall_radius = _dataset(f, path, "walls/radius", "f", (w,))
    for i, kind in enumerate(wall_kind):
        if kind not in packing_h5.WALL_KINDS:
            _fail(path, "walls/kind", f"wall {i} has kind {kind!r}; expected one of "
                                      f"{', '.join(packing_h5.WALL_KINDS)}")
        if kind in ("cylinder", "sphere") and not (np.isfinite(wall_radius[i])
                                                   and wall_radius[i] > 0):
            _fail(path, "walls/radius", f"{kind} wall {i} has radius {wall_radius[i]!r}; "
                                        "expected > 0")
    if len(set(wall_name)) != w:
        _fail(path, "walls/name", "duplicate wall name")
    norms = np.linalg.norm(wall_normal, axis=1) if w else np.zeros(0)
    if np.any(np.abs(norms - 1.0) > 1e-6):
        i = int(np.flatnonzero(np.abs(norms - 1.0) > 1e-6)[0])
        _fail(path, "walls/normal", f"wall {i} normal has length {norms[i]:.6g}; "
                                    "expected a unit vector")
    return wall_name, wall_kind, wall_point, wall_normal, wall_radius


def _read_wall_contacts(f, path, n, w) -> tuple:
    """wall_contacts/: particle and wall (in range), overlap, normal force (>= 0) and the
    optional contact_radius."""
    wall_particle = _dataset(f, path, "wall_contacts/particle", "i", (None,))
    k = wall_particle.shape[0]
    wall_index = _dataset(f, path, "wall_contacts/wall", "i", (k,))
    wall_overlap = _dataset(f, path, "wall_contacts/overlap", "f", (k,))
    wall_normal_force = _dataset(f, path, "wall_contacts/normal_force", "f", (k,))
    wall_contact_radius = _dataset(f, path, "wall_contacts/contact_radius", "f", (k,),
                                   optional=True)
    _check_index(path, "wall_contacts/particle", wall_particle, n, "particle")
    _check_index(path, "wall_contacts/wall", wall_index, w, "wall")
    if np.any(wall_normal_force < 0):
        _fail(path, "wall_contacts/normal_force", "tensile (negative) force; expected >= 0")
    return wall_particle, wall_index, wall_overlap, wall_normal_force, wall_contact_radius


def _read_domain(f, path) -> dict:
    """domain/ attributes lo, hi (finite, hi > lo) and periodic, three values each."""
    if "domain" not in f:
        _fail(path, "domain", "missing group")
    dattrs = f["domain"].attrs
    dom = {}
    for key, kind in (("lo", "f"), ("hi", "f"), ("periodic", "b")):
        if key not in dattrs:
            _fail(path, f"domain/{key}", "missing attribute")
        value = np.asarray(dattrs[key])
        if value.shape != (3,):
            _fail(path, f"domain/{key}", f"expected 3 values, got shape {value.shape}")
        if kind == "f" and not np.all(np.isfinite(value.astype(float))):
            _fail(path, f"domain/{key}", "non-finite value")
        dom[key] = value.astype(bool) if kind == "b" else value.astype(np.float64)
    if np.any(dom["hi"] <= dom["lo"]):
        _fail(path, "domain/hi", f"expected hi > lo, got lo={dom['lo']}, hi={dom['hi']}")
    return dom


# Relative round-off allowed in the geometric checks below (positions of ~1e4 radii from the
# origin lose ~1e-12 of a radius; anything beyond 1e-9 is a different geometry, not round-off).
GEOMETRY_RTOL = 1e-9
# Branch vectors: |branch - (x_j - x_i)| (periodic axes: to the nearest period) within this
# fraction of the smaller radius.
BRANCH_RTOL = 1e-6


def _first_too_deep(overlap, radius, scale) -> int | None:
    """The first row whose overlap exceeds ``radius`` beyond round-off (``scale``: the
    packing's centres' magnitude), or None."""
    too_deep = overlap > radius * (1.0 + GEOMETRY_RTOL) + 8 * np.finfo(float).eps * scale
    return int(np.flatnonzero(too_deep)[0]) if too_deep.any() else None


def _check_contact_geometry(path, pair, ri, rj, dx, overlap, branch, extent, periodic, scale,
                            row0=0):
    """The contact rows' part of :func:`_check_geometry`, on per-contact values: the radii of
    the two spheres, ``dx`` = x_j - x_i, ``scale`` the packing's (:func:`contact_check_scales`)."""
    i, j = pair[:, 0], pair[:, 1]
    r_min = np.minimum(ri, rj)
    c = _first_too_deep(overlap, r_min, scale)
    if c is not None:
        _fail(path, "contacts/overlap",
              f"contact {c + row0} ({int(i[c])}, {int(j[c])}) has overlap "
              f"{overlap[c]:.6g} m, larger than the smaller radius {r_min[c]:.6g} m; "
              "expected overlap <= the smaller radius")
    residual = branch - dx
    for axis in np.flatnonzero(periodic):        # the partner's image: any whole period
        residual[:, axis] -= extent[axis] * np.round(residual[:, axis] / extent[axis])
    error = np.linalg.norm(residual, axis=1)
    allowed = BRANCH_RTOL * r_min + 8 * np.finfo(float).eps * scale
    bad = error > allowed
    if bad.any():
        c = int(np.flatnonzero(bad)[0])
        image = " (nearest periodic image)" if periodic.any() else ""
        _fail(path, "contacts/branch",
              f"contact {c + row0} ({int(i[c])}, {int(j[c])}): the branch vector is "
              f"{error[c] / r_min[c]:.3g} radii away from x_j - x_i{image}; expected the "
              f"vector from centre i to centre j (within {BRANCH_RTOL:g} of the radius)")


def abs_max(a) -> float:
    """max |a| (0 for an empty array) from the array's max and min: no temporary the size of
    ``a`` (the reader's checks of 1e9 centres would make a 24 GB one)."""
    a = np.asarray(a)
    if a.size == 0:
        return 0.0
    return max(float(a.max()), -float(a.min()), 0.0)


def contact_check_scales(position, lo, hi) -> tuple[float, float]:
    """The round-off scales of the contact checks (geometry, forces), from the whole
    packing's centres: the same for every part of its contacts (thermal_kernel/rank_build.py)."""
    top = abs_max(position)
    return top + float(np.abs(lo).max()) + float(np.abs(hi).max()), top


def check_contact_rows(path, pair, ri, rj, xi, xj, overlap, normal_force, branch, lo, hi,
                       periodic, scales, row0=0):
    """Every check :func:`read_packing` makes of contact rows against the particles, on rows
    given with their spheres' radii and centres (the PETSc backend's ranks, which hold only
    the rows' spheres; ``scales`` from :func:`contact_check_scales` on the whole packing;
    messages name the file's rows, ``row0`` the first's)."""
    _check_tensile(path, normal_force, row0)
    _check_contact_geometry(path, pair, ri, rj, xj - xi, overlap, branch, hi - lo, periodic,
                            scales[0], row0)
    _check_contact_forces(path, pair, ri, rj, overlap, normal_force, branch,
                          8 * np.finfo(float).eps * scales[1], row0)


def _check_geometry(path, position, radius, phase, pair, overlap, branch, wall_particle,
                    wall_overlap, lo, hi, periodic, row0=0):
    """Arrays that are each well formed but describe an impossible packing: a negative phase
    id, a centre outside the domain, an overlap beyond a radius, a branch vector that does not
    join the two centres. Spheres may stick out of the domain (a tiled packing carved to a
    shape keeps the spheres cut by its surface) and a wall overlap may reach the radius (their
    wall contacts have overlap r - distance, 0 ... r): only the centre must be inside, and only
    an overlap beyond the radius is refused."""
    _check_phase(path, phase)
    extent = hi - lo
    scale = abs_max(position) + np.abs(lo).max() + np.abs(hi).max()
    _check_centres(path, position, lo, hi, scale)
    if pair.shape[0]:
        i, j = pair[:, 0], pair[:, 1]
        _check_contact_geometry(path, pair, radius[i], radius[j], position[j] - position[i],
                                overlap, branch, extent, periodic, scale, row0)
    if wall_particle.size:
        _check_wall_depth(path, wall_particle, wall_overlap, radius[wall_particle], scale)


# The parts of _check_geometry and _check_forces_and_walls on a block of particles or of wall
# rows (``row0``: the file's index of the block's first; messages name the file's), the
# packing's scales given: the ranks' reader (thermal_kernel/packing_ranks.py) checks each
# block where it is read.

def _check_phase(path, phase, row0=0):
    if phase.size and phase.min() < 0:
        i = int(np.flatnonzero(phase < 0)[0])
        _fail(path, "particles/phase", f"particle {i + row0} has phase {int(phase[i])}; "
                                       "expected a phase id >= 0")


def _check_centres(path, position, lo, hi, scale, row0=0):
    """Every centre inside the domain (``scale``: :func:`_check_geometry`'s, the whole
    packing's)."""
    tol = GEOMETRY_RTOL * (hi - lo) + 8 * np.finfo(float).eps * scale
    # the columns' extremes first (no (N, 3) temporaries); the first centre outside only then
    if position.shape[0] and (np.any(position.min(axis=0) < lo - tol)
                              or np.any(position.max(axis=0) > hi + tol)):
        outside = (position < lo - tol) | (position > hi + tol)
        i, axis = (int(v) for v in np.argwhere(outside)[0])
        _fail(path, "particles/position",
              f"particle {i + row0} has its centre at {'xyz'[axis]} = {position[i, axis]:.6g} m, "
              f"outside the domain [{lo[axis]:.6g}, {hi[axis]:.6g}] (domain/lo, domain/hi); "
              "expected every centre inside the domain")


def _check_wall_depth(path, wall_particle, wall_overlap, r, scale, row0=0):
    """No wall overlap beyond its particle's radius ``r`` (per row)."""
    c = _first_too_deep(wall_overlap, r, scale)
    if c is not None:
        _fail(path, "wall_contacts/overlap",
              f"row {c + row0} (particle {int(wall_particle[c])}) has overlap "
              f"{wall_overlap[c]:.6g} m, "
              f"larger than its radius {r[c]:.6g} m; expected overlap <= the radius (the "
              "centre on the wall's side)")


# Root attributes with a physical range (the thermal laws use young_pa and poisson when a scene
# gives none, post and the capacity rules use solid_fraction): (low, high, low open, high open).
ATTR_RANGES = {
    "young_pa": (0.0, math.inf, True, True, "Pa"),
    "poisson": (-1.0, 0.5, True, True, ""),
    "density": (0.0, math.inf, True, True, "kg/m^3"),
    "pressure_pa": (0.0, math.inf, False, True, "Pa"),        # NaN: none (checked above)
    "solid_fraction": (0.0, 1.0, True, False, ""),
    "mean_coordination": (0.0, math.inf, False, True, ""),
}
# A contact's overlap must be r_i + r_j - |branch| (docs/packing-format.md) within this fraction of
# the smaller radius (and, in an import, a wall contact's r - distance). Every generator writes
# exactly that (measured: 1.5e-15 of the radius over every committed and validation packing); a
# LIGGGHTS import keeps LIGGGHTS' delta, which with the default 6-digit dump format differs from
# the positions by ~1e-5 of a radius (1 % of an overlap).
OVERLAP_RTOL = 1e-3
# A touching wall contact's overlap against r - (the centre's distance to the wall): within half
# a radius. Cylinder and sphere walls are facet polygons in YADE (a depth measured against a
# facet differs from the analytic surface by the facets' sagitta, which the file does not record:
# measured up to 0.067 r, dense_sphere.h5), and hand-made packings state wall overlaps of their
# own (tests' chains); half a radius leaves both and still refuses a wall contact on a particle
# away from the wall (a wrong wall position, a contact on another atom). An importer checks its
# dumps tighter (tdem/liggghts.py: OVERLAP_RTOL).
WALL_RTOL = 0.5
# solid_fraction against the particles: every generator divides the spheres' volume, whole or
# less the caps beyond the walls (tdem_yade, import liggghts), by the domain's volume (the box
# lo..hi, pi R^2 L in a cylinder wall, 4/3 pi R^3 in a sphere wall); measured equal to 1e-12 on
# every packing made here. 1e-3 of phi accepts a value rounded to 3-4 digits or measured by
# another tool; it is 0.1 % of gamma_paper = gamma / phi, below any interval post reports.
SOLID_FRACTION_RTOL = 1e-3


def _check_attr_ranges(path, attrs):
    for key, (low, high, low_open, high_open, unit) in ATTR_RANGES.items():
        value = attrs[key]
        if math.isnan(value):
            continue
        below = value <= low if low_open else value < low
        above = value >= high if high_open else value > high
        if below or above:
            interval = ("(" if low_open else "[") + f"{low:g}, {high:g}" + \
                (")" if high_open else "]")
            unit = f" {unit}" if unit else ""
            _fail(path, key, f"root attribute is {value:.6g}{unit}; expected a value in "
                             f"{interval}")


def _wall_distance(kind, point, normal, radius, x):
    """Distance of the centres ``x`` to a wall, positive on the domain's side."""
    d = x - point
    if kind == "plane":
        return d @ normal
    if kind == "cylinder":
        along = d @ normal
        return radius - np.linalg.norm(d - along[:, None] * normal, axis=1)
    return radius - np.linalg.norm(d, axis=1)


def _check_contact_forces(path, pair, ri, rj, overlap, normal_force, branch, eps, row0=0):
    """The contact rows' part of :func:`_check_forces_and_walls`, on per-contact radii."""
    i, j = pair[:, 0], pair[:, 1]
    r_min = np.minimum(ri, rj)
    # the branch (already checked to join the centres) gives the spheres' own overlap
    geo = ri + rj - np.sqrt(np.einsum("ij,ij->i", branch, branch))
    off = np.abs(overlap - geo) > OVERLAP_RTOL * r_min + eps
    if off.any():
        c = int(np.flatnonzero(off)[0])
        _fail(path, "contacts/overlap",
              f"contact {c + row0} ({int(i[c])}, {int(j[c])}) has overlap {overlap[c]:.6g} m, "
              f"but its spheres give r_i + r_j - |branch| = {geo[c]:.6g} m; expected the "
              f"overlap of the two spheres (within {OVERLAP_RTOL:g} of the smaller radius)")
    c = _first_gap_force(overlap, normal_force)
    if c is not None:
        _fail(path, "contacts/normal_force",
              f"contact {c + row0} ({int(i[c])}, {int(j[c])}) is a gap (overlap "
              f"{overlap[c]:.6g} m) with a normal force of {normal_force[c]:.6g} N; "
              "expected 0 on a gap")


def _check_forces_and_walls(path, position, radius, pair, overlap, normal_force, branch,
                            wall_kind, wall_point, wall_normal, wall_radius, wall_particle,
                            wall_index, wall_overlap, wall_normal_force, row0=0):
    """Overlaps that contradict the geometry, forces on gaps: a contact's overlap is
    r_i + r_j - |branch| (the branch is already checked against the centres), a touching wall
    contact's is r - its centre's distance to the wall; a gap (overlap <= 0) carries no force;
    no two centres coincide."""
    scale = abs_max(position)
    eps = 8 * np.finfo(float).eps * scale
    if pair.shape[0]:
        i, j = pair[:, 0], pair[:, 1]
        _check_contact_forces(path, pair, radius[i], radius[j], overlap, normal_force, branch,
                              eps, row0)
    if wall_particle.size:
        r = radius[wall_particle]
        for w, kind in enumerate(wall_kind):
            rows = np.flatnonzero(wall_index == w)
            if not rows.size:
                continue
            _check_wall_overlap(path, w, kind, wall_point[w], wall_normal[w], wall_radius[w],
                                rows, wall_particle[rows], r[rows],
                                position[wall_particle[rows]], wall_overlap[rows], eps)
        _check_wall_gap_force(path, wall_particle, wall_overlap, wall_normal_force)
    # coincident centres: two spheres in one place (any overlap search would be O(N log N) on
    # every load; equal centres are the impossible case that costs one sort). Sorted by x,
    # y, z (ties in index order), a column at a time: a tiled packing ties every x (its tiles
    # are copies shifted along y or z), and (N, 3) temporaries of 1e9 centres are 24 GB each
    if position.shape[0] > 1 and _x_tied(position[:, 0]):
        order = np.lexsort((position[:, 2], position[:, 1], position[:, 0]))
        equal = np.ones(order.size - 1, dtype=bool)
        for k in range(3):
            column = position[:, k]
            equal &= column[order[1:]] == column[order[:-1]]
        same = np.flatnonzero(equal)
        del equal
        if same.size:
            a, b = sorted((int(order[same[0]]), int(order[same[0] + 1])))
            _fail_coincident(path, a, b, position[a])


def _fail_coincident(path, a, b, centre):
    """The error of particles ``a`` < ``b`` at the same ``centre`` (``a``'s)."""
    _fail(path, "particles/position",
          f"particles {a} and {b} have the same centre "
          f"({', '.join(f'{v:.6g}' for v in centre)}) m; expected distinct spheres")


def _check_wall_overlap(path, w, kind, point, normal, wall_radius, rows, particle, r, x,
                        overlap, eps):
    """The touching rows ``rows`` (the file's) of wall ``w``: overlap = r - the centre's
    distance to the wall (``particle``, ``r``, ``x``, ``overlap``: the rows')."""
    dist = _wall_distance(kind, point, normal, wall_radius, x)
    geo = r - dist
    rtol = WALL_RTOL
    # touching rows only: a row with overlap <= 0 is a near-wall neighbour without
    # force (thermal_kernel.lattice writes 0 for its outer layers whatever the radius)
    off = (overlap > 0) & (np.abs(overlap - geo) > rtol * r + eps)
    if off.any():
        k = int(np.flatnonzero(off)[0])
        _fail(path, "wall_contacts/overlap",
              f"row {int(rows[k])} (particle {int(particle[k])}, wall {w}) has overlap "
              f"{overlap[k]:.6g} m, but the particle's centre is "
              f"{dist[k]:.6g} m from the {kind} wall (r - distance = {geo[k]:.6g} m); "
              f"expected r - distance (within {rtol:g} of the radius)")


def _first_gap_force(overlap, normal_force) -> int | None:
    """The first row that is a gap (overlap <= 0) yet carries a normal force, or None."""
    gap_force = (overlap <= 0) & (normal_force > 0)
    return int(np.flatnonzero(gap_force)[0]) if gap_force.any() else None


def _check_wall_gap_force(path, wall_particle, wall_overlap, wall_normal_force):
    c = _first_gap_force(wall_overlap, wall_normal_force)
    if c is not None:
        _fail(path, "wall_contacts/normal_force",
              f"row {c} (particle {int(wall_particle[c])}) is a gap (overlap "
              f"{wall_overlap[c]:.6g} m) with a normal force of "
              f"{wall_normal_force[c]:.6g} N; expected 0 on a gap")


def _x_tied(x) -> bool:
    """Whether two centres share an x (the candidates of coincident centres), from the sorted
    x alone: one copy of the column, not the index sort the search for the pair needs."""
    xs = np.sort(x)
    return bool(np.any(xs[1:] == xs[:-1]))


def domain_volume(wall_kind, wall_normal, wall_radius, lo, hi):
    """The volume the spheres fill, m^3: a sphere wall's ball, a cylinder wall's pi R^2 times the
    domain's length along its (axis-aligned) axis, else the box lo..hi; None when a cylinder's
    axis is oblique (not measurable from the file)."""
    for k, kind in enumerate(wall_kind):
        if kind == "sphere":
            return 4.0 / 3.0 * math.pi * float(wall_radius[k]) ** 3
    for k, kind in enumerate(wall_kind):
        if kind == "cylinder":
            axis = int(np.argmax(np.abs(wall_normal[k])))
            if abs(abs(wall_normal[k][axis]) - 1.0) > 1e-9:
                return None
            return math.pi * float(wall_radius[k]) ** 2 * float(hi[axis] - lo[axis])
    return float(np.prod(hi - lo))


def solid_fraction_bounds(radius, wall_kind, wall_normal, wall_radius, wall_particle,
                          wall_overlap, lo, hi):
    """(phi with the caps beyond the walls cut off, phi with every sphere whole), or None:
    the two ways generators count the spheres' volume over the domain's."""
    volume = domain_volume(wall_kind, wall_normal, wall_radius, lo, hi)
    if volume is None or not volume > 0:
        return None
    whole = float(np.sum(4.0 / 3.0 * math.pi * radius ** 3))
    h = np.clip(wall_overlap, 0.0, None)
    caps = float(np.sum(math.pi * h ** 2 * (3.0 * radius[wall_particle] - h) / 3.0))
    return (whole - caps) / volume, whole / volume


def _check_solid_fraction(path, phi, position, radius, wall_kind, wall_normal, wall_radius,
                          wall_particle, wall_overlap, lo, hi):
    bounds = solid_fraction_bounds(radius, wall_kind, wall_normal, wall_radius, wall_particle,
                                   wall_overlap, lo, hi)
    _check_solid_fraction_bounds(path, phi, bounds, wall_kind)


def _check_solid_fraction_bounds(path, phi, bounds, wall_kind):
    """solid_fraction against :func:`solid_fraction_bounds`' (cut, whole), None: not checked."""
    if bounds is None:
        return
    cut, whole = bounds
    if whole > 1.0 + SOLID_FRACTION_RTOL and cut > 1.0 + SOLID_FRACTION_RTOL:
        _fail(path, "particles/radius",
              f"the spheres' volume is {cut:.4g} times the domain's; expected a solid fraction "
              "<= 1 (overlapping spheres, or a domain smaller than the packing?)")
    if not (cut * (1.0 - SOLID_FRACTION_RTOL) <= phi <= whole * (1.0 + SOLID_FRACTION_RTOL)):
        what = f"{cut:.6g}" if abs(whole - cut) <= 1e-12 * whole else \
            f"{cut:.6g} (caps beyond the walls cut off) ... {whole:.6g} (spheres whole)"
        _fail(path, "solid_fraction",
              f"root attribute is {phi:.6g}, but the particles fill {what} of the domain "
              f"({_domain_words(wall_kind)}); expected the spheres' volume over the domain's "
              f"(within {SOLID_FRACTION_RTOL:g})")


def _domain_words(wall_kind):
    if "sphere" in wall_kind:
        return "the sphere wall's ball"
    if "cylinder" in wall_kind:
        return "the cylinder wall times the domain's length along its axis"
    return "domain/lo .. domain/hi"


def _check_index(path, name, index, n, what):
    if index.size and (index.min() < 0 or index.max() >= n):
        bad = int(np.flatnonzero((index < 0) | (index >= n))[0])
        _fail(path, name, f"row {bad} refers to {what} {int(index[bad])}, "
                          f"out of range 0..{n - 1}")


def _check_pairs(path, pair, n, row0=0, row=None):
    """Indices in range, i < j, no contact twice. ``row0`` the file's row of the first row
    (or ``row`` the file's row of each): messages name the file's rows."""
    def at(r):
        return int(row[r]) if row is not None else r + row0
    if pair.shape[0] and (pair.min() < 0 or pair.max() >= n):
        bad = int(np.flatnonzero(((pair < 0) | (pair >= n)).any(axis=1))[0])
        _fail(path, "contacts/pair", f"row {at(bad)} refers to particle "
                                     f"{int(pair[bad][(pair[bad] < 0) | (pair[bad] >= n)][0])}, "
                                     f"out of range 0..{n - 1}")
    if pair.shape[0] == 0:
        return
    self_rows = np.flatnonzero(pair[:, 0] == pair[:, 1])
    if self_rows.size:
        r = int(self_rows[0])
        _fail(path, "contacts/pair", f"row {at(r)} is a self contact ({pair[r, 0]}, "
                                     f"{pair[r, 1]})")
    bad_order = np.flatnonzero(pair[:, 0] > pair[:, 1])
    if bad_order.size:
        r = int(bad_order[0])
        _fail(path, "contacts/pair", f"row {at(r)} is ({pair[r, 0]}, {pair[r, 1]}); "
                                     "expected i < j in every row")
    key = pair[:, 0] * np.int64(n) + pair[:, 1]
    order = np.argsort(key, kind="stable")
    dup = np.flatnonzero(np.diff(key[order]) == 0)
    if dup.size:
        r = int(order[dup[0] + 1])
        _fail(path, "contacts/pair", f"row {at(r)} duplicates contact ({pair[r, 0]}, "
                                     f"{pair[r, 1]})")


# ----------------------------------------------------------------------------- writing

def write_packing(path, packing: Packing) -> None:
    """Write ``packing`` to ``path`` (built in memory, written under a temporary name, then
    renamed; an OSError leaves nothing behind)."""
    from .atomic import write_bytes_atomic
    write_bytes_atomic(path, packing_image(packing))


def packing_image(packing: Packing):
    """The bytes of ``packing``'s file (a buffer), built in memory."""
    walls = [dict(name=nm, kind=kd, point=pt, normal=nr, radius=rd)
             for nm, kd, pt, nr, rd in zip(packing.wall_name, packing.wall_kind,
                                           packing.wall_point, packing.wall_normal,
                                           packing.wall_radius)]
    attrs = {k: v for k, v in packing.attrs.items() if k not in ("format", "format_version")}
    return packing_h5.packing_image(
        packing.position, packing.radius, packing.phase, packing.pair, packing.overlap,
        packing.normal_force, packing.branch, walls, packing.wall_particle, packing.wall_index,
        packing.wall_overlap, packing.wall_normal_force, packing.domain_lo, packing.domain_hi,
        packing.periodic, attrs, contact_radius=packing.contact_radius,
        wall_contact_radius=packing.wall_contact_radius, yade_id=packing.yade_id)


# ----------------------------------------------------------------------------- statistics

def packing_statistics(packing: Packing) -> dict:
    """Summary numbers printed by ``tdem pack`` and ``tdem info``.

    Coordination counts particle–particle contacts with overlap > 0 (``mean_z``) and with the
    neighbour gaps the file keeps (``mean_z_with_gaps``). A *rattler* here is a particle with no
    touching contact at all (particle or wall): thermally isolated.
    """
    n = packing.n_particles
    touching = packing.overlap > 0
    pairs = packing.pair[touching]
    count = np.bincount(pairs.reshape(-1), minlength=n)
    wall_count = np.bincount(packing.wall_particle[packing.wall_overlap > 0], minlength=n)
    r = packing.radius
    solid_volume = float(np.sum(4.0 / 3.0 * np.pi * r ** 3))
    return {
        "n_particles": n,
        "n_contacts": int(touching.sum()),
        "n_gap_neighbours": int((~touching).sum()),
        "n_wall_contacts": int((packing.wall_overlap > 0).sum()),
        "solid_fraction": float(packing.attrs.get("solid_fraction", float("nan"))),
        "mean_z": 2.0 * pairs.shape[0] / n,
        "mean_z_with_gaps": 2.0 * packing.n_contacts / n,
        "radius_mean_m": float(r.mean()),
        "radius_std_m": float(r.std()),
        "radius_std_over_mean": float(r.std() / r.mean()),
        "rattler_fraction": float(np.mean((count + wall_count) == 0)),
        "solid_volume_m3": solid_volume,
        "pressure_pa": float(packing.attrs.get("pressure_pa", float("nan"))),
        "mean_normal_force_n": float(packing.normal_force[touching].mean())
        if touching.any() else 0.0,
    }


def format_statistics(stats: dict) -> str:
    """The human-readable block printed by ``tdem pack`` / ``tdem info``."""
    p = stats["pressure_pa"]
    pressure = "none" if not math.isfinite(p) else f"{p:.4g} Pa ({p / 1e5:.4g} bar)"
    return "\n".join([
        f"  particles            {stats['n_particles']}",
        f"  solid fraction       {stats['solid_fraction']:.4f}",
        f"  mean Z (touching)    {stats['mean_z']:.3f}   "
        f"({stats['n_contacts']} contacts, {stats['n_wall_contacts']} wall contacts)",
        f"  mean Z (with gaps)   {stats['mean_z_with_gaps']:.3f}   "
        f"({stats['n_gap_neighbours']} gap neighbours)",
        f"  radius mean / std    {stats['radius_mean_m']:.4g} m / {stats['radius_std_m']:.3g} m"
        f"   (std/mean {stats['radius_std_over_mean']:.3f})",
        f"  rattlers (no contact) {100 * stats['rattler_fraction']:.2f} %",
        f"  mean normal force    {stats['mean_normal_force_n']:.4g} N",
        f"  pressure reached     {pressure}",
    ])
