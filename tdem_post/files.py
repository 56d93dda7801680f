"""Outputs are written to a temporary name and renamed: a killed run never leaves a half-written
figure or table behind (the rename is atomic on one file system), and a failed write removes
its temporary file (thermal_kernel.atomic)."""
from __future__ import annotations

from pathlib import Path

from thermal_kernel.atomic import replacing


def write_text_atomic(path, text: str) -> Path:
    path = Path(path)
    with replacing(path) as tmp:
        tmp.write_text(text)
    return path


def savefig_atomic(fig, path, **kwargs) -> Path:
    path = Path(path)
    with replacing(path, keep_suffix=True) as tmp:   # the suffix tells the format
        fig.savefig(tmp, **kwargs)
    return path
