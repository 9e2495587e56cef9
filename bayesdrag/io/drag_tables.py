"""Drag table files (CSV with columns ``mach,cd``) and the M101 table shipped with the package."""
from __future__ import annotations

import os
from importlib.resources import files
from pathlib import Path
from typing import TYPE_CHECKING

from ..drag import ReferenceTable
from ..errors import InputError
from .csv import read_csv_columns

if TYPE_CHECKING:
    from importlib.abc import Traversable

__all__ = ["read_drag_table", "load_m101"]


def read_drag_table(path: str | os.PathLike[str] | Traversable, source: str | None = None) -> ReferenceTable:
    """Read a CSV drag table with columns ``mach,cd`` (``#`` comments allowed).

    Raises
    ------
    bayesdrag.errors.InputError
        naming the file and row when the table is missing, malformed or not physical.
    """
    path = Path(path)
    # named inside a round file: its content is never repeated in a message (any readable file
    # could be named there), the message names the file and the header expected instead
    cols = read_csv_columns(path, required=("mach", "cd"), what="drag table", quote=False)
    try:
        return ReferenceTable(tuple(cols["mach"]), tuple(cols["cd"]), source=source or str(path))
    except ValueError as exc:
        raise InputError(str(exc)) from None


def load_m101() -> ReferenceTable:
    """The 155 mm HE M101 zero-yaw drag curve shipped with the package (BRL MR-1167, 1958)."""
    return read_drag_table(files("bayesdrag") / "data" / "cd_m101.csv",
                           source="M101, BRL MR-1167 (Odom 1958)")
