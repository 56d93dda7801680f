"""Outputs are written to a temporary name and renamed: a killed run never leaves a half-written
figure or table behind (the rename is atomic on one file system)."""
from __future__ import annotations

import os
from pathlib import Path


def write_text_atomic(path, text: str) -> Path:
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)
    return path


def savefig_atomic(fig, path, **kwargs) -> Path:
    path = Path(path)
    tmp = path.with_name(path.stem + ".tmp" + path.suffix)   # the suffix tells the format
    fig.savefig(tmp, **kwargs)
    os.replace(tmp, path)
    return path
