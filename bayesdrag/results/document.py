"""A result's JSON document (``result.json``, ``diagnosis.json``, ``plan.json``): plain JSON types
on the way out, a checked read on the way back."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..io.outputs import read_json

__all__ = ["jsonable", "read_document"]


def jsonable(o: Any) -> Any:
    """Plain JSON types (numpy scalars and arrays converted, non-finite floats to None)."""
    if isinstance(o, dict):
        return {str(k): jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [jsonable(v) for v in o]
    if isinstance(o, np.ndarray):
        return [jsonable(v) for v in o.tolist()]
    if isinstance(o, (bool, np.bool_)):
        return bool(o)
    if isinstance(o, (int, np.integer)):
        return int(o)
    if isinstance(o, (float, np.floating)):
        return float(o) if np.isfinite(o) else None
    return o


def read_document(folder: Path, name: str, what: str, *, required: tuple[str, ...]) -> dict[str, Any]:
    """The JSON document ``folder/name`` a command wrote, checked to be one.

    Parameters
    ----------
    folder : Path
    name : str
        ``result.json``, ``diagnosis.json`` or ``plan.json``.
    what : str
        What the folder should hold, for messages (``fit result``).
    required : tuple of str
        Top-level keys the document must have.

    Raises
    ------
    InputError
        No such folder or file, not JSON, not an object, or a required key missing.
    """
    if not folder.is_dir():
        raise InputError(f"{folder}: no such folder (give the folder a bayesdrag command wrote)")
    path = folder / name
    if not path.exists():
        raise InputError(f"{folder}: no {name} in the folder: not a {what} folder (give the folder a bayesdrag "
                         f"command wrote, e.g. the -o DIR of the command)")
    doc = read_json(path, what=name)
    if not isinstance(doc, dict):
        raise InputError(f"{path}: not a {name} (a JSON object was expected, found {type(doc).__name__})")
    missing = [k for k in required if k not in doc]
    if missing:
        raise InputError(f"{path}: not a {name}: key(s) {', '.join(missing)} missing (the file needs "
                         f"{', '.join(required)})")
    return doc
