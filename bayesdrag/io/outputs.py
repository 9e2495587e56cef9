"""Writing outputs safely: every file is written under a temporary name in the target folder
and renamed into place only when complete, so a failed or interrupted run never leaves a
half-written file and never overwrites a file it did not finish."""
from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

from ..errors import InputError


def atomic_write(path, write_fn):
    """Call ``write_fn(tmp_path)`` then rename the finished file to ``path``."""
    path = Path(path)
    if path.exists() and path.is_dir():
        raise InputError(f"{path}: output path is a directory; give a file name such as {path / 'track.csv'}")
    if not path.parent.exists():
        raise InputError(f"{path}: output folder {path.parent} does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    os.close(fd)
    try:
        write_fn(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def write_json(path, obj):
    atomic_write(path, lambda tmp: Path(tmp).write_text(json.dumps(obj, indent=2, allow_nan=False)))




def write_bytes(path, data):
    """Write bytes atomically."""
    atomic_write(path, lambda tmp: Path(tmp).write_bytes(data))


def write_figure(path, fig, dpi=110):
    """Save a matplotlib figure atomically in the format of ``path``'s suffix (PNG by default)."""
    fmt = Path(path).suffix.lstrip(".") or "png"
    atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format=fmt))


def ensure_output_dir(out):
    """Create the output folder (and parents); refuse a path that is an existing file."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: output path exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    return out
