"""Drag table files (CSV with columns ``mach,cd``), the M101 table and the standard drag functions
(G1, G2, G5, G6, G7, G8, GI, GS) shipped with the package."""
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

__all__ = ["read_drag_table", "load_m101", "STANDARD_DRAG_FUNCTIONS", "is_standard_drag", "read_standard_drag",
           "standard_drag_name"]

#: the standard drag functions shipped as package data (``data/drag_functions/<name>.csv``, the
#: public BRL tables of Cd against Mach, reference area pi d^2/4; each file names its source)
STANDARD_DRAG_FUNCTIONS = ("G1", "G2", "G5", "G6", "G7", "G8", "GI", "GS")


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


def is_standard_drag(name: object) -> bool:
    """Whether ``name`` names a standard drag function (:data:`STANDARD_DRAG_FUNCTIONS`).

    Case-insensitive, the bare name only: ``"G7"`` and ``"g7"`` are the standard, while ``"G7.csv"``,
    ``"tables/G7"`` or ``" G7"`` are not (they are file paths, read with :func:`read_drag_table`).

    Parameters
    ----------
    name : object
        Typically the ``[projectile] reference_drag`` string of a round file; anything that is not
        a ``str`` is not a standard name.

    Returns
    -------
    bool
    """
    return isinstance(name, str) and name.isascii() and name.upper() in STANDARD_DRAG_FUNCTIONS


def read_standard_drag(name: str) -> ReferenceTable:
    """The standard drag function ``name`` (G1, G2, G5, G6, G7, G8, GI or GS), read from the
    package data.

    Parameters
    ----------
    name : str
        One of :data:`STANDARD_DRAG_FUNCTIONS`, case-insensitive (``"g7"`` is ``"G7"``).

    Returns
    -------
    ReferenceTable
        Cd [-] (reference area pi d^2/4) against Mach [-], as :func:`read_drag_table` returns a
        table file; its ``source`` names the function, e.g. ``"G7 (standard drag function, BRL)"``.

    Raises
    ------
    bayesdrag.errors.InputError
        ``name`` is not a standard drag function; the message lists the valid names.
    """
    if not is_standard_drag(name):
        raise InputError(f"{name!r} is not a standard drag function; use one of "
                         f"{', '.join(STANDARD_DRAG_FUNCTIONS)} (case-insensitive), or give a CSV file "
                         f"path with columns mach,cd")
    std = name.upper()
    return read_drag_table(files("bayesdrag") / "data" / "drag_functions" / f"{std.lower()}.csv",
                           source=_standard_source(std))


def _standard_source(std: str) -> str:
    return f"{std} (standard drag function, BRL)"


def standard_drag_name(table: ReferenceTable) -> str | None:
    """The standard name of a table :func:`read_standard_drag` made, or None.

    For writing a round back as its name (``reference_drag = "G7"``) rather than as a copy of
    the table: a table is the standard only when its ``source`` names it and its rows are the
    shipped ones.

    Parameters
    ----------
    table : ReferenceTable

    Returns
    -------
    str or None
        One of :data:`STANDARD_DRAG_FUNCTIONS`, or None for any other table.
    """
    for std in STANDARD_DRAG_FUNCTIONS:
        if getattr(table, "source", None) == _standard_source(std):
            ref = read_standard_drag(std)
            same = ref.mach == table.mach and ref.cd_values == table.cd_values
            return std if same else None
    return None
