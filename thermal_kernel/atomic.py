"""Writing an output file all or nothing (issue 16, sec. 2: filesystem errors).

Every output (thermal.h5, checkpoints, figures, tables, VTK) is written to a temporary name
beside it and renamed; whatever goes wrong in between -- a full or read-only disk, a missing
folder, Ctrl-C -- the temporary file is removed and the error propagates (the command line turns
an ``OSError`` into one line, exit status 2). HDF5 files are built in memory and written with
plain file I/O: HDF5's own writer, on a full disk, prints a cascade of tracebacks and can crash
the interpreter (segfault seen on a 40 KB tmpfs), while ``write`` just raises ``ENOSPC``.

This is the one home of writing a file all or nothing (issue 17): text
(:func:`write_text_atomic`), bytes (:func:`write_bytes_atomic`), a stream (:func:`open_atomic`,
e.g. for ``csv``), an HDF5 file built in memory, or on disk in room reserved first when it is
large (:func:`write_h5_atomic`), a figure
(:func:`savefig_atomic`), or any writer that takes a file name (:func:`replacing`). Only the
YADE side (``yade_scripts/``) keeps its own, since it cannot import this package. At module
level this file imports only the standard library: ``packing_h5.py`` loads it by file path
inside YADE, on Debian's Python.
"""
from __future__ import annotations

import contextlib
import io
import os
from pathlib import Path


@contextlib.contextmanager
def replacing(path, keep_suffix: bool = False):
    """Yield a temporary path beside ``path``; rename it to ``path`` when the block succeeds,
    remove it when anything (also KeyboardInterrupt) is raised. ``keep_suffix``: the temporary
    name ends with ``path``'s suffix (writers that deduce the format from it)."""
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(21, "is a folder; expected a file name", str(path))
    name = (path.stem + ".tmp" + path.suffix) if keep_suffix else (path.name + ".tmp")
    tmp = path.with_name(name)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException as e:
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(e, OSError) and not e.filename:
            e.filename = str(path)      # e.g. ENOSPC from write(): name the file
        raise


def write_bytes_atomic(path, data) -> Path:
    """``data`` (bytes or a buffer) to ``path``, flushed to disk before the rename."""
    path = Path(path)
    with replacing(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
    return path


def write_text_atomic(path, text: str) -> Path:
    """``text`` to ``path`` (``Path.write_text``: the locale's encoding, newlines as given)."""
    path = Path(path)
    with replacing(path) as tmp:
        tmp.write_text(text)
    return path


@contextlib.contextmanager
def open_atomic(path, mode: str = "w", **kwargs):
    """``open(<temporary name>, mode, **kwargs)`` for the block (e.g. ``newline=""`` for
    ``csv``); the file is closed, then renamed to ``path`` when the block succeeds, removed
    when anything is raised."""
    with replacing(path) as tmp:
        with open(tmp, mode, **kwargs) as f:
            yield f


def savefig_atomic(fig, path, **kwargs) -> Path:
    """``fig.savefig(path, **kwargs)`` all or nothing (a matplotlib figure; nothing imported
    here). The temporary name keeps ``path``'s suffix, which tells matplotlib the format."""
    path = Path(path)
    with replacing(path, keep_suffix=True) as tmp:
        fig.savefig(tmp, **kwargs)
    return path


# An HDF5 file whose datasets hold more than this is written on disk into space reserved first
# (below) rather than built in memory: a long run's temperature history would otherwise be held
# twice (the history and the file's image) while it is written.
ON_DISK_FROM_BYTES = 256 * 2 ** 20
# what an HDF5 file adds to its datasets' bytes, at most (the header, attributes such as the
# scene's text, the chunk index: ~40 B per chunk of >= 8 KB, < 1 %)
_RESERVE_MARGIN = (0.02, 16 * 2 ** 20)
_FALLOC_FL_KEEP_SIZE = 1


def _reserve(f, nbytes: int, keep_size: bool = True) -> bool:
    """Reserve ``nbytes`` of disk for the open file ``f`` (Linux fallocate, never glibc's
    emulation that writes zeros): ``keep_size``, without changing its size
    (FALLOC_FL_KEEP_SIZE: HDF5 must still see an empty file), else the file grows to it. True
    when reserved; False where the call or the filesystem does not offer it; OSError (ENOSPC)
    when the disk has not that much room."""
    import ctypes
    import errno
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fallocate = libc.fallocate
    except (OSError, AttributeError):
        return False
    fallocate.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_long, ctypes.c_long]
    if fallocate(f.fileno(), _FALLOC_FL_KEEP_SIZE if keep_size else 0, 0, int(nbytes)) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL):
        return False
    raise OSError(err, os.strerror(err))


def write_h5_atomic(path, fill, data_bytes: int = 0) -> Path:
    """An HDF5 file made by ``fill(h5py.File)``, written to ``path`` all or nothing.

    ``data_bytes``: about how many bytes its datasets hold. Up to :data:`ON_DISK_FROM_BYTES`
    (or where the filesystem cannot reserve space) the file is built in memory and written at
    once (HDF5's own writer crashes on a full disk, see above). Above it, the temporary file's
    room is reserved first (that many bytes and a margin; a disk without it raises ENOSPC
    before HDF5 writes anything) and HDF5 writes into it through a Python file object, so the
    file's image is never in memory."""
    import h5py
    path = Path(path)
    if data_bytes > ON_DISK_FROM_BYTES:
        try:
            return _write_h5_reserved(path, fill, data_bytes)
        except _NotReserved:
            pass                        # the filesystem cannot reserve: in memory, as below
    buf = io.BytesIO()
    with h5py.File(buf, "w") as f:
        fill(f)
    return write_bytes_atomic(path, buf.getbuffer())


def history_rows(n_times: int, n_particles: int, folder=None):
    """(n_times, n_particles) float64 rows (a numpy array) for a run's temperatures at its
    output times: in memory, or, above :data:`ON_DISK_FROM_BYTES` with a ``folder`` given (the
    output's), a memory map of an unnamed temporary file there (unlinked at once:
    nothing is left behind, even by a killed run), so the history is paged to disk instead of
    held: a long run's memory does not grow with its output times."""
    import tempfile

    import numpy as np      # here: at module level this file takes the standard library only
    shape = (int(n_times), int(n_particles))
    nbytes = 8 * shape[0] * shape[1]
    if folder is None or nbytes <= ON_DISK_FROM_BYTES:
        return np.empty(shape)
    Path(folder).mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryFile(dir=folder) as f:     # the map outlives the file object
        # its blocks reserved first: a write through the map to a disk that has filled since
        # would kill the process (SIGBUS), where this raises ENOSPC at once, naming the folder
        try:
            reserved = _reserve(f, nbytes, keep_size=False)
        except OSError as e:
            raise OSError(e.errno, f"{e.strerror} (the temperatures of {shape[0]} output "
                          f"times, {nbytes / 1e9:.3g} GB)", str(folder)) \
                from None
        return np.memmap(f, dtype=np.float64, mode="r+" if reserved else "w+", shape=shape)


class _NotReserved(Exception):
    """The filesystem does not reserve space (fallocate unsupported)."""


def _write_h5_reserved(path: Path, fill, data_bytes: int) -> Path:
    """:func:`write_h5_atomic` on disk: the temporary file's room reserved, then HDF5 writing
    into it through a Python file object; :class:`_NotReserved` (nothing left) where the
    filesystem cannot reserve."""
    import h5py
    rel, extra = _RESERVE_MARGIN
    with replacing(path) as tmp:
        with open(tmp, "wb+") as f:
            if not _reserve(f, int(data_bytes * (1 + rel)) + extra):
                raise _NotReserved
            with h5py.File(f, "w") as h5:
                fill(h5)
            f.flush()
            os.fsync(f.fileno())
    return path


class OutputBusyError(RuntimeError):
    """Another process holds the lock of an output file."""

    def __init__(self, path, lock, holder):
        self.path, self.lock, self.holder = Path(path), Path(lock), holder
        super().__init__(f"{path}: another tdem process{f' (pid {holder})' if holder else ''} "
                         f"is writing this output (lock {lock}); wait for it to end or give "
                         "another --out")


@contextlib.contextmanager
def output_lock(path):
    """Hold an exclusive lock on the output ``path`` (``<path>.lock``, an flock, released even
    when the process is killed) for the block; creates the folder. Refuses at once with
    :class:`OutputBusyError` when another process holds it, and ``path`` being a folder with
    IsADirectoryError. On leaving, the lock file is removed, and so are the folders this call
    created when they are still empty (a refused run leaves nothing behind)."""
    import fcntl
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(21, "is a folder; expected the output file's name", str(path))
    created = []
    d = path.parent
    while not d.exists() and d != d.parent:
        created.append(d)
        d = d.parent
    lock = path.with_name(path.name + ".lock")
    fd = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        while True:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.read(fd, 32).decode(errors="replace").strip()
                os.close(fd)
                fd = None
                raise OutputBusyError(path, lock, holder) from None
            try:       # the holder before us may have removed the file we opened: take the new one
                same = os.path.samestat(os.fstat(fd), os.stat(lock))
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        yield lock
    finally:
        if fd is not None:
            with contextlib.suppress(OSError):
                os.unlink(lock)
            os.close(fd)
        for d in created:           # deepest first
            try:
                d.rmdir()
            except OSError:
                break
