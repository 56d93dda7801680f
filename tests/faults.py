"""Faults the tests inject (shared by test modules; plain Python, no pytest)."""
import errno
import os


class FullDiskFile:
    """Stands for ``open`` in thermal_kernel.atomic on a full disk: the first write puts 100
    bytes in the file, then raises ENOSPC as a full file system does."""

    def __init__(self, path, mode):
        self.f = open(path, mode)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.f.close()

    def write(self, data):
        self.f.write(bytes(data)[:100])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
