"""A result's JSON document (``result.json``, ``diagnosis.json``, ``plan.json``): plain JSON types
on the way out, a checked read on the way back.

A folder may have been written by someone else, so :func:`read_document` checks a document
before any result is built from it: a regular file in the folder (not a symbolic link), at most
:data:`~bayesdrag.io.outputs.MAX_JSON_BYTES`, UTF-8 JSON, an object with the required keys, no
number that is not finite (``NaN``, ``Infinity``, or ``1e999`` beyond the float range: the writer
turns non-finite numbers into ``null``) and, given a ``schema``, every key the loader reads of the
type it reads it as. Each refusal is an :class:`~bayesdrag.errors.InputError` naming the file
and the key by its path (``cd[3].mach``).

A schema is built from the checks below: :data:`NUMBER`, :data:`INTEGER`, :data:`BOOLEAN`,
:data:`STRING`, :func:`optional` (``null`` allowed), :func:`list_of`, :func:`pair`,
:func:`mapping` (an object of any keys) and :func:`record` (an object of named keys, others
ignored).
"""
from __future__ import annotations

import math
import os
import stat
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FitWarning, InputError
from ..io.outputs import read_json

__all__ = ["jsonable", "read_document", "Check", "NUMBER", "INTEGER", "BOOLEAN", "STRING", "optional", "list_of",
           "pair", "mapping", "record", "increasing", "integer_in", "RESULT_SCHEMA", "DIAGNOSIS_SCHEMA", "PLAN_SCHEMA",
           "REWRITE"]

#: what a refused document can be mended by
REWRITE = "the file is not as bayesdrag writes it: write the folder again with the command that made it"
#: characters of a refused value a message quotes
SHOWN_CHARS = 40


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
    if isinstance(o, FitWarning):
        return str(o)               # the sentence: result.json holds a warning's words
    return o


def read_document(folder: Path, name: str, what: str, *, required: tuple[str, ...],
                  schema: Check | None = None) -> dict[str, Any]:
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
    schema : Check, optional
        The types of the keys the loader reads (module docstring), checked last.

    Raises
    ------
    InputError
        No such folder or file, a symbolic link, not JSON, not an object, a required key
        missing, a number that is not finite, or a key of another type than ``schema`` says.
    """
    if not folder.is_dir():
        raise InputError(f"{folder}: no such folder (give the folder a bayesdrag command wrote)")
    path = folder / name
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        raise InputError(f"{folder}: no {name} in the folder: not a {what} folder (give the folder a bayesdrag "
                         f"command wrote, e.g. the -o DIR of the command)") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read the {name} ({exc.strerror or exc})") from None
    if stat.S_ISLNK(mode):
        raise InputError(f"{path}: the {name} is a symbolic link, which is never followed (a folder's files are "
                         f"written in place); replace it with the file itself")
    doc = read_json(path, what=name)       # a regular file, opened without following links, size bounded
    if not isinstance(doc, dict):
        raise InputError(f"{path}: not a {name} (a JSON object was expected, found {type(doc).__name__})")
    missing = [k for k in required if k not in doc]
    if missing:
        raise InputError(f"{path}: not a {name}: key(s) {', '.join(missing)} missing (the file needs "
                         f"{', '.join(required)})")
    where = _not_finite(doc)
    if where is not None:
        raise InputError(f"{path}: {where[0]} is {where[1]}: JSON numbers must be finite (NaN, Infinity and numbers "
                         f"beyond the float range such as 1e999 are refused); {REWRITE}")
    if schema is not None:
        try:
            schema(doc, "")
        except _Bad as bad:
            raise InputError(f"{path}: {bad.where or 'the document'} {bad.what}; {REWRITE}") from None
    return doc


def _not_finite(doc: Any) -> tuple[str, str] | None:
    """``(key path, what it is)`` of the first number of ``doc`` that is not a finite float
    (walked without recursion: a document may nest as deep as the JSON parser allowed)."""
    stack: list[tuple[Any, str]] = [(doc, "")]
    while stack:
        v, where = stack.pop()
        if isinstance(v, dict):
            stack.extend((x, _key(where, k)) for k, x in reversed(list(v.items())))
        elif isinstance(v, list):
            stack.extend((x, f"{where}[{i}]") for i, x in reversed(list(enumerate(v))))
        elif isinstance(v, float) and not math.isfinite(v):
            return where or "the document", "NaN" if math.isnan(v) else f"{'-' if v < 0 else ''}infinite"
        elif isinstance(v, int) and not isinstance(v, bool) and not _fits_float(v):
            return where or "the document", f"an integer of {len(str(abs(v)))} digits, beyond the float range"
    return None


def _fits_float(v: int) -> bool:
    try:
        float(v)
    except OverflowError:
        return False
    return True


def _key(where: str, key: str) -> str:
    return f"{where}.{key}" if where else str(key)


# -- the checks a schema is made of -----------------------------------------------------------------
class _Bad(Exception):
    """A key of another type than the schema's: where it is and what was wrong."""

    def __init__(self, where: str, what: str) -> None:
        super().__init__(where, what)
        self.where, self.what = where, what


#: a check of one value at a key path; raises :class:`_Bad`
Check = Callable[[Any, str], None]


def _shown(v: Any) -> str:
    """A short description of a JSON value for a message."""
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return f"the number {v!r}"[:SHOWN_CHARS + 11]
    if isinstance(v, str):
        return f"the string {v[:SHOWN_CHARS]!r}"
    if isinstance(v, list):
        return f"a list of {len(v)} item{'s' if len(v) != 1 else ''}"
    return "an object"


def _fail(v: Any, where: str, expected: str) -> None:
    raise _Bad(where, f"is {_shown(v)}, expected {expected}")


def NUMBER(v: Any, where: str) -> None:  # noqa: N802  (a check, used like a constant)
    """A finite number (not a boolean)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        _fail(v, where, "a number")


def INTEGER(v: Any, where: str) -> None:  # noqa: N802
    """An integer (not a boolean)."""
    if isinstance(v, bool) or not isinstance(v, int):
        _fail(v, where, "an integer")


def BOOLEAN(v: Any, where: str) -> None:  # noqa: N802
    """``true`` or ``false``."""
    if not isinstance(v, bool):
        _fail(v, where, "true or false")


def STRING(v: Any, where: str) -> None:  # noqa: N802
    """A string."""
    if not isinstance(v, str):
        _fail(v, where, "a string")


def integer_in(lo: int, hi: int | None = None) -> Check:
    """An integer in ``lo..hi`` (``hi`` None: at least ``lo``)."""
    def check(v: Any, where: str) -> None:
        if isinstance(v, bool) or not isinstance(v, int) or v < lo or (hi is not None and v > hi):
            _fail(v, where, f"an integer in {lo}..{hi}" if hi is not None else f"an integer >= {lo}")
    return check


def optional(inner: Check) -> Check:
    """``null`` or what ``inner`` accepts."""
    def check(v: Any, where: str) -> None:
        if v is not None:
            inner(v, where)
    return check


def list_of(item: Check, *, min_items: int = 0) -> Check:
    """A list of at least ``min_items`` items, each what ``item`` accepts."""
    def check(v: Any, where: str) -> None:
        if not isinstance(v, list):
            _fail(v, where, "a list")
        if len(v) < min_items:
            _fail(v, where, f"a list of at least {min_items} item{'s' if min_items != 1 else ''}")
        for i, x in enumerate(v):
            item(x, f"{where}[{i}]")
    return check


def pair(item: Check) -> Check:
    """A list of exactly two items (a range), each what ``item`` accepts."""
    def check(v: Any, where: str) -> None:
        if not isinstance(v, list) or len(v) != 2:
            _fail(v, where, "a list of two items")
        for i, x in enumerate(v):
            item(x, f"{where}[{i}]")
    return check


def mapping(value: Check) -> Check:
    """An object of any keys, each value what ``value`` accepts."""
    def check(v: Any, where: str) -> None:
        if not isinstance(v, dict):
            _fail(v, where, "an object")
        for k, x in v.items():
            value(x, _key(where, k))
    return check


def record(fields: dict[str, Check], *, required: tuple[str, ...] = ()) -> Check:
    """An object whose keys ``fields`` (where present) are what their checks accept; the keys
    ``required`` must be present; other keys are not read and not checked."""
    def check(v: Any, where: str) -> None:
        if not isinstance(v, dict):
            _fail(v, where, "an object")
        for k in required:
            if k not in v:
                raise _Bad(where, f"has no key '{k}' (it needs {', '.join(required)})")
        for k, inner in fields.items():
            if k in v:
                inner(v[k], _key(where, k))
    return check


def increasing(rows: Check, key: str) -> Check:
    """What ``rows`` accepts (a list of objects with a number ``key``), with ``key`` never
    decreasing from one row to the next."""
    def check(v: Any, where: str) -> None:
        rows(v, where)
        for i in range(1, len(v)):
            if v[i][key] < v[i - 1][key]:
                raise _Bad(f"{where}[{i}].{key}", f"is {v[i][key]!r}, below {where}[{i - 1}].{key} "
                                                  f"{v[i - 1][key]!r}: the rows must be in increasing {key}")
    return check


def _anything(v: Any, where: str) -> None:
    """Any JSON value (a key whose content is not read, only counted)."""


# -- what each loader reads -------------------------------------------------------------------------
_OPT_NUMBER = optional(NUMBER)
_STRINGS = list_of(STRING)
#: a fit's or a window's quality gate
_CHANNEL = record({"chi2_per_sample": _OPT_NUMBER, "n": integer_in(0)})
_QUALITY = optional(record({"ok": BOOLEAN, "problems": _STRINGS, "channels": optional(mapping(_CHANNEL))}))
_CD_ROW = record({"mach": NUMBER, "determined": BOOLEAN,
                  **{k: _OPT_NUMBER for k in ("ml", "band_sd", "crb_sd", "crb_sd_statistical", "reference", "mean",
                                              "q05", "q95")}}, required=("mach",))
#: ``result.json``: what :class:`~bayesdrag.results.fit.FitResult`, its summary, its bands and
#: ``load_result``'s posterior bounds read
RESULT_SCHEMA = record({
    "scheme": integer_in(1, 2), "drag_model": STRING,
    "ml": record({"converged": BOOLEAN, "message": optional(STRING), "iterations": optional(INTEGER),
                  "windows_converged": INTEGER, "windows": INTEGER, "mach_range_data": optional(pair(NUMBER)),
                  "warnings": optional(_STRINGS), "params": optional(mapping(_OPT_NUMBER)),
                  "fixed": optional(list_of(_anything)), "quality": _QUALITY}),
    "cd": increasing(list_of(_CD_ROW, min_items=1), "mach"),
    "windows": optional(list_of(record({"mach": NUMBER, "converged": BOOLEAN, "crb_sd_statistical": _OPT_NUMBER,
                                        "steps": optional(integer_in(0)), "quality": _QUALITY},
                                       required=("mach",)))),
    "mcmc": optional(record({"converged": BOOLEAN, "message": optional(STRING), "walkers": integer_in(1),
                             "steps": integer_in(0), "draws": INTEGER, "tau_max": _OPT_NUMBER,
                             "r_hat_max": _OPT_NUMBER, "windows_converged": INTEGER})),
    "uncertainty_budget": optional(record({"mach": list_of(NUMBER), "total_sd": list_of(_OPT_NUMBER),
                                           "by_source": mapping(list_of(_OPT_NUMBER)),
                                           "model_error_floor": optional(list_of(_OPT_NUMBER))})),
}, required=("scheme", "drag_model", "ml", "cd"))
#: ``diagnosis.json``: what :class:`~bayesdrag.results.diagnosis.DiagnosisResult`, its summary,
#: data frame and ranking figure read
DIAGNOSIS_SCHEMA = record({
    "baseline": record({"chi2_per_sample": _OPT_NUMBER, "gap": _OPT_NUMBER}, required=("chi2_per_sample", "gap")),
    "effects": list_of(record({
        "name": STRING, "significant": BOOLEAN, "material": optional(BOOLEAN), "shrink": _OPT_NUMBER,
        **{k: _OPT_NUMBER for k in ("delta_loglik", "delta_bic", "test_statistic", "threshold", "cd_shift_max",
                                    "end_shift_sd")},
        "confounded_with": optional(_STRINGS), "params": optional(mapping(_OPT_NUMBER)),
        "sd": optional(mapping(_OPT_NUMBER)), "units": optional(mapping(optional(STRING)))},
        required=("name", "significant", "shrink"))),
    "verdict": _STRINGS, "immaterial": optional(_STRINGS), "summary": STRING, "reference_drag": _anything,
    "tests": optional(record({"candidates": INTEGER})),
}, required=("baseline", "effects", "verdict", "summary"))
#: ``plan.json``: what :class:`~bayesdrag.results.plan.PlanResult`, its summary and data frame read
PLAN_SCHEMA = record({
    "cases": list_of(record({
        "elevation": NUMBER, "velocity": NUMBER, "rounds": INTEGER, "mach_range": pair(NUMBER),
        "best_relative_sd": _OPT_NUMBER, "drag_model": optional(STRING), "target_mach_range": optional(pair(NUMBER)),
        "tracked": optional(record({"samples": optional(INTEGER), "t_start": _OPT_NUMBER, "t_end": _OPT_NUMBER}))},
        required=("elevation", "velocity", "rounds", "mach_range"))),
    "summary": STRING, "rounds": optional(INTEGER),
    "target": optional(record({"paragraph": STRING, "relative_sd": NUMBER}, required=("paragraph", "relative_sd"))),
    "radar": optional(record({"sigma": optional(mapping(NUMBER))})),
    "round": optional(record({"name": optional(STRING)})),
    "assumed_drag": optional(record({"source": optional(STRING)})),
}, required=("cases", "summary"))
