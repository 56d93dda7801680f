"""Writing an output file all or nothing (issue 16, sec. 2: filesystem errors).

Every output (thermal.h5, checkpoints, figures, tables, VTK) is written to a temporary name
beside it and renamed; whatever goes wrong in between -- a full or read-only disk, a missing
folder, Ctrl-C -- the temporary file is removed and the error propagates (the command line turns
an ``OSError`` into one line, exit status 2). HDF5 files are built in memory and written with
plain file I/O: HDF5's own writer, on a full disk, prints a cascade of tracebacks and can crash
the interpreter (segfault seen on a 40 KB tmpfs), while ``write`` just raises ``ENOSPC``.

This is the one home of writing a file all or nothing (issue 17): text
(:func:`write_text_atomic`), bytes (:func:`write_bytes_atomic`), a stream (:func:`open_atomic`,
e.g. for ``csv``), an HDF5 file built in memory (:func:`write_h5_atomic`), a figure
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


def write_h5_atomic(path, fill) -> Path:
    """An HDF5 file made by ``fill(h5py.File)`` in memory, then written to ``path`` at once."""
    import h5py
    buf = io.BytesIO()
    with h5py.File(buf, "w") as f:
        fill(f)
    return write_bytes_atomic(path, buf.getbuffer())


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
