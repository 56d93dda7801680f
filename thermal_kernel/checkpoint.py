"""Checkpoints of a long transient run (``tdem run --checkpoint-every K``, ``--resume``).

A checkpoint holds the solver's state after an output time (temperatures, time, step count,
energy ledger, dt) and every output recorded so far, with the scene's text, the particle count
and a content hash of the packing (:func:`packing_sha256`: its arrays, not its file's bytes) so
that a resume on another scene or packing -- also another packing of the same size -- is
refused. It is written to a temporary name and
renamed (a run killed while writing keeps the previous checkpoint). Resuming continues from the
state through the remaining output times; because every output interval is cut into the same
equal steps either way, the result equals the uninterrupted run bit for bit (tested).
"""
from __future__ import annotations

import hashlib
from pathlib import Path

import h5py
import numpy as np

from .atomic import history_rows, write_h5_atomic
from .scene import SceneError
from .solvers import SolverState

_OUTPUTS = ("times", "temperature_k", "boundary_heat_flow_w", "boundary_energy_j",
            "source_energy_j", "stored_energy_j")


def checkpoint_path(output: Path) -> Path:
    output = Path(output)
    return output.with_name(output.stem + ".checkpoint.h5")


# the packing's content, in this order, for its hash (attrs are provenance: left out)
_PACKING_ARRAYS = ("position", "radius", "phase", "pair", "overlap", "normal_force", "branch",
                   "wall_point", "wall_normal", "wall_radius", "wall_particle", "wall_index",
                   "wall_overlap", "wall_normal_force", "domain_lo", "domain_hi", "periodic",
                   "contact_radius", "wall_contact_radius")


# the contacts' arrays: their dataset in the file and the dtype read_packing gives them
_CONTACT_ARRAYS = {"pair": ("contacts/pair", np.int64), "overlap": ("contacts/overlap", None),
                   "normal_force": ("contacts/normal_force", None),
                   "branch": ("contacts/branch", None),
                   "contact_radius": ("contacts/contact_radius", None)}
# the particles' arrays, hashed from the file when asked (thermal_kernel/packing_ranks.py: no
# rank holds them whole): read_packing casts phase to int32, keeps the others' dtypes
PARTICLE_ARRAYS = {"position": ("particles/position", None),
                   "radius": ("particles/radius", None),
                   "phase": ("particles/phase", np.int32),
                   "yade_id": ("particles/yade_id", None)}
_FILE_ARRAYS = {**_CONTACT_ARRAYS, **PARTICLE_ARRAYS}
_HASH_ROWS = 1 << 16


def _hash_from_file(h, path, name):
    """``h`` updated as packing_sha256 updates it with the array ``name`` of read_packing(path),
    read from the file a block of rows at a time."""
    import h5py
    dataset, dtype = _FILE_ARRAYS[name]
    h.update(name.encode() + b"\0")
    with h5py.File(path, "r") as f:
        if dataset not in f:
            h.update(b"none\0")
            return
        d = f[dataset]
        want = np.dtype(dtype or d.dtype).newbyteorder("<")
        h.update(f"{want.str}{d.shape}".encode() + b"\0")
        for start in range(0, d.shape[0], _HASH_ROWS):
            block = np.ascontiguousarray(d[start:start + _HASH_ROWS]).astype(want, copy=False)
            h.update(block.tobytes())


def packing_sha256(packing, particles_in_file: bool = False) -> str:
    """sha256 (hex) of a packing's content: every array (name, dtype, shape, little-endian
    bytes) and the walls' names and kinds. Equal for the same packing read from a copy. A
    packing read without its contacts (``file_contacts`` set: the PETSc backend's ranks) hashes
    them from its file, a block of rows at a time: the same hash, never all of them in memory;
    ``particles_in_file``: the particles' arrays too (a head without them, packing_ranks.py)."""
    h = hashlib.sha256()
    for name in _PACKING_ARRAYS:
        if (packing.file_contacts is not None and name in _CONTACT_ARRAYS) or \
                (particles_in_file and name in PARTICLE_ARRAYS):
            _hash_from_file(h, packing.path, name)
            continue
        a = getattr(packing, name, None)
        h.update(name.encode() + b"\0")
        if a is None:
            h.update(b"none\0")
            continue
        a = np.ascontiguousarray(a)
        a = a.astype(a.dtype.newbyteorder("<"), copy=False)
        h.update(f"{a.dtype.str}{a.shape}".encode() + b"\0")
        h.update(a.tobytes())
    for name in ("wall_name", "wall_kind"):
        h.update(name.encode() + b"\0" + "\0".join(map(str, getattr(packing, name))).encode())
    return h.hexdigest()


def write_checkpoint(path: Path, state: SolverState, outputs: dict, totals: dict,
                     scene_text: str, n_particles: int, packing_hash: str = "") -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)

    def fill(f):
        f.attrs["format"] = "tdem-checkpoint"
        f.attrs["scene"] = scene_text
        f.attrs["n_particles"] = n_particles
        f.attrs["packing_sha256"] = packing_hash
        g = f.create_group("state")
        g.create_dataset("temperature_k", data=state.temperature_k)
        g.create_dataset("boundary_energy_j", data=state.boundary_energy_j)
        g.create_dataset("reference_temperature_k", data=state.reference_temperature_k)
        g.attrs.update(time_s=state.time_s, step=state.step, source_energy_j=state.source_energy_j,
                       dt_s=state.dt_s, method=state.method)
        o = f.create_group("outputs")
        for key in _OUTPUTS:
            o.create_dataset(key, data=np.asarray(outputs[key], dtype=np.float64))
        f.create_group("totals").attrs.update(totals)
    # the temperatures so far dominate (written on disk when large: atomic.write_h5_atomic)
    return write_h5_atomic(path, fill, data_bytes=np.asarray(outputs["temperature_k"]).nbytes)


def read_checkpoint(path: Path, scene_text: str, n_particles: int, packing_hash: str = "",
                    packing_path=None):
    """(state, outputs, totals) of a checkpoint made by the same scene on the same packing
    (same particle count and, when ``packing_hash`` is given, the same content hash; the error
    names ``packing_path``)."""
    path = Path(path)
    if not path.exists():
        raise SceneError(f"{path}: --resume: no checkpoint to resume from (run with "
                         "--checkpoint-every first)")
    try:
        with h5py.File(path, "r") as f:
            if f.attrs.get("format") != "tdem-checkpoint":
                raise SceneError(f"{path}: format: expected a tdem checkpoint")
            if f.attrs["scene"] != scene_text:
                raise SceneError(f"{path}: scene: the checkpoint was made by another version of "
                                 "the scene; resume with the same scene file, or delete it")
            if int(f.attrs["n_particles"]) != n_particles:
                raise SceneError(f"{path}: n_particles: the checkpoint has "
                                 f"{int(f.attrs['n_particles'])} particles, the packing "
                                 f"{n_particles}")
            if packing_hash:
                stored = str(f.attrs.get("packing_sha256", ""))
                where = packing_path if packing_path is not None else path
                if not stored:
                    raise SceneError(f"{path}: packing_sha256: the checkpoint does not identify "
                                     "its packing (made by an older tdem); delete it and run "
                                     "again")
                if stored != packing_hash:
                    raise SceneError(f"{where}: --resume: not the packing the checkpoint {path} "
                                     f"was made on (content sha256 {packing_hash[:12]}, "
                                     f"checkpoint {stored[:12]}); resume with that packing, or "
                                     "delete the checkpoint")
            g = f["state"]
            state = SolverState(
                temperature_k=g["temperature_k"][()], time_s=float(g.attrs["time_s"]),
                step=int(g.attrs["step"]), boundary_energy_j=g["boundary_energy_j"][()],
                source_energy_j=float(g.attrs["source_energy_j"]),
                reference_temperature_k=g["reference_temperature_k"][()],
                dt_s=float(g.attrs["dt_s"]), method=str(g.attrs["method"]))
            outputs = {key: f["outputs"][key][()] for key in _OUTPUTS
                       if key != "temperature_k"}
            # the temperatures so far: a long run's history, paged to disk beside the
            # checkpoint when large (atomic.history_rows), never read whole into memory
            stored_t = f["outputs"]["temperature_k"]
            outputs["temperature_k"] = history_rows(*stored_t.shape, path.parent)
            if stored_t.size:
                stored_t.read_direct(outputs["temperature_k"])
            totals = dict(f["totals"].attrs)
    except (OSError, KeyError) as e:
        raise SceneError(f"{path}: checkpoint: unreadable ({e})") from None
    return state, outputs, totals
