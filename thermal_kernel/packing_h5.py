"""The one writer of the tdem packing format (``packing.h5``), shared by YADE and tdem.

This file must import nothing but the standard library, numpy, h5py and its sibling
``atomic.py`` (standard library only): the YADE generators load it by file path
(``yade_scripts/tdem_dump.py``) and run it on Debian's own Python inside ``yade -n -x``, where
tdem's dependencies (numba, ...) are absent. ``thermal_kernel.packing`` wraps it for the project
side and holds the reader, which validates every file.
The format is specified in ``docs/packing-format.md``.

The file is built in memory (:func:`packing_image`, h5py on an ``io.BytesIO``) and written at
once with plain file I/O to ``<path>.tmp``, then renamed
(:func:`thermal_kernel.atomic.write_bytes_atomic`): a killed run never leaves a half-written
``packing.h5``, and a failed write (a full or read-only disk) raises one ``OSError`` and removes
its temporary file. HDF5's own writer on a full disk printed a cascade of tracebacks and then
crashed the interpreter (issue 28: SIGSEGV under ``tdem import`` and ``tdem_yade.dump``).
"""
import io
import os

import h5py
import numpy as np

if __package__:
    from .atomic import write_bytes_atomic
else:       # loaded by file path inside YADE (yade_scripts/tdem_dump.py): the sibling file, alike
    import importlib.util as _util
    _spec = _util.spec_from_file_location(
        "tdem_atomic", os.path.join(os.path.dirname(os.path.abspath(__file__)), "atomic.py"))
    _atomic = _util.module_from_spec(_spec)
    _spec.loader.exec_module(_atomic)
    write_bytes_atomic = _atomic.write_bytes_atomic

FORMAT = "tdem-packing"
FORMAT_VERSION = 1

WALL_KINDS = ("plane", "cylinder", "sphere")


def write_packing(path, *args, **kwargs):
    """Write one packing to ``path`` (arguments: :func:`packing_image`): built in memory, then
    written at once under a temporary name and renamed. An ``OSError`` (full disk, read-only
    folder) propagates, naming ``path``, with nothing left behind."""
    write_bytes_atomic(path, packing_image(*args, **kwargs))


def packing_image(position, radius, phase, pair, overlap, normal_force, branch,
                  walls, wall_particle, wall_index, wall_overlap, wall_normal_force,
                  domain_lo, domain_hi, periodic, attrs, contact_radius=None,
                  wall_contact_radius=None, yade_id=None):
    """The bytes of one packing file.

    walls: list of dicts with keys name, kind ('plane'|'cylinder'|'sphere'), point (3,) (a point
    of the plane, of the cylinder's axis, or the sphere's centre), normal (3,) (the axis for a
    cylinder; unused for a sphere), radius (NaN for planes).
    attrs: root attributes; must hold at least generator, seed, solid_fraction,
    mean_coordination, pressure_pa, young_pa, poisson, density. Extra keys are kept.
    """
    position = np.ascontiguousarray(position, dtype=np.float64).reshape(-1, 3)
    n = position.shape[0]
    pair = np.asarray(pair, dtype=np.int64).reshape(-1, 2)
    # Canonical contact order: i < j, rows sorted by (i, j); a reader may rely on it.
    swap = pair[:, 0] > pair[:, 1]
    branch = np.asarray(branch, dtype=np.float64).reshape(-1, 3).copy()
    pair = pair.copy()
    pair[swap] = pair[swap][:, ::-1]
    branch[swap] *= -1.0
    order = np.lexsort((pair[:, 1], pair[:, 0]))
    pair = pair[order]
    branch = branch[order]
    overlap = np.asarray(overlap, dtype=np.float64)[order]
    normal_force = np.asarray(normal_force, dtype=np.float64)[order]
    if contact_radius is not None:
        contact_radius = np.asarray(contact_radius, dtype=np.float64)[order]

    buffer = io.BytesIO()
    with h5py.File(buffer, "w") as f:
        f.attrs["format"] = FORMAT
        f.attrs["format_version"] = FORMAT_VERSION
        for key, value in attrs.items():
            f.attrs[key] = value
        g = f.create_group("particles")
        g.create_dataset("position", data=position)
        g.create_dataset("radius", data=np.asarray(radius, dtype=np.float64).reshape(n))
        g.create_dataset("phase", data=np.asarray(phase, dtype=np.int32).reshape(n))
        if yade_id is not None:
            g.create_dataset("yade_id", data=np.asarray(yade_id, dtype=np.int64).reshape(n))
        g.attrs["units"] = "position: m, radius: m, phase: -"
        c = f.create_group("contacts")
        c.create_dataset("pair", data=pair)
        c.create_dataset("overlap", data=overlap)
        c.create_dataset("normal_force", data=normal_force)
        c.create_dataset("branch", data=branch)
        if contact_radius is not None:
            c.create_dataset("contact_radius", data=contact_radius)
        c.attrs["units"] = "overlap: m, normal_force: N, branch: m, contact_radius: m"
        w = f.create_group("walls")
        strings = h5py.string_dtype(encoding="utf-8")
        w.create_dataset("name", data=np.array([x["name"] for x in walls], dtype=object),
                         dtype=strings)
        w.create_dataset("kind", data=np.array([x["kind"] for x in walls], dtype=object),
                         dtype=strings)
        w.create_dataset("point", data=np.array([x["point"] for x in walls],
                                                dtype=np.float64).reshape(-1, 3))
        w.create_dataset("normal", data=np.array([x["normal"] for x in walls],
                                                 dtype=np.float64).reshape(-1, 3))
        w.create_dataset("radius", data=np.array([x.get("radius", np.nan) for x in walls],
                                                 dtype=np.float64).reshape(-1))
        wc = f.create_group("wall_contacts")
        wc.create_dataset("particle", data=np.asarray(wall_particle, dtype=np.int64).reshape(-1))
        wc.create_dataset("wall", data=np.asarray(wall_index, dtype=np.int32).reshape(-1))
        wc.create_dataset("overlap", data=np.asarray(wall_overlap, dtype=np.float64).reshape(-1))
        wc.create_dataset("normal_force",
                          data=np.asarray(wall_normal_force, dtype=np.float64).reshape(-1))
        if wall_contact_radius is not None:
            wc.create_dataset("contact_radius",
                              data=np.asarray(wall_contact_radius, dtype=np.float64).reshape(-1))
        d = f.create_group("domain")
        d.attrs["lo"] = np.asarray(domain_lo, dtype=np.float64).reshape(3)
        d.attrs["hi"] = np.asarray(domain_hi, dtype=np.float64).reshape(3)
        d.attrs["periodic"] = np.asarray(periodic, dtype=bool).reshape(3)
    return buffer.getbuffer()
