"""Track formats: one reader module per device format, told apart by sniffing (pvlib iotools style).

:func:`bayesdrag.io.tracks.read_track` (``read_track(path, format="auto")``) reads the plain track
CSV, the format named :data:`PLAIN` (``t`` plus channels, :mod:`bayesdrag.io.tracks`), and every
format registered here. ``"auto"`` reads the first :data:`SNIFF_BYTES` of the file (through the
guarded reader: a device or pipe is refused before anything is read) and asks each registered
format's ``sniff`` in turn; a file no format claims is a plain track CSV.

Built in (:data:`BUILTIN`): :mod:`~bayesdrag.io.formats.labradar` (LabRadar per-shot track exports).

Adding a format is one module holding

``NAME``
    the format's name, lower case (what ``read_track(path, format=NAME)`` and the command line's
    ``--format`` take);
``DESCRIPTION``
    one line, for listings;
``sniff(head_text) -> bool``
    whether the start of a file (its first :data:`SNIFF_BYTES`, decoded as UTF-8, NUL characters
    removed) is in this format; cheap, and strict enough not to claim a plain track CSV;
``read_<NAME>(path, *, quote=True, **options) -> RadarTrack``
    the reader, in SI units, refusing bad input with one-line
    :class:`~bayesdrag.errors.InputError` (``quote=False``: never repeat the file's content in a
    message); reading through :func:`bayesdrag.io.csv.read_bytes` gives it the size bound and the
    refusal of devices and pipes;

and passed to :func:`register` (the extension point: a module of this package is listed in
:data:`BUILTIN` below; any other module registers itself, ``register(sys.modules[__name__])``,
or its user does).

Examples
--------
>>> from bayesdrag.io import formats                        # doctest: +SKIP
>>> formats.names()                                         # doctest: +SKIP
('auto', 'csv', 'labradar')
>>> formats.detect("SR0047/TRK/Shot0001 Track.csv")         # doctest: +SKIP
'labradar'
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, Callable

from ...errors import InputError
from ..csv import read_bytes
from . import labradar

__all__ = ["AUTO", "PLAIN", "SNIFF_BYTES", "BUILTIN", "TrackFormat", "register", "unregister", "available",
           "names", "get", "detect", "detect_text", "resolve"]

#: the format name that sniffs the file
AUTO = "auto"
#: the plain track CSV's name (read by :func:`bayesdrag.io.tracks.read_track` itself)
PLAIN = "csv"
#: bytes of a file's start a format is told by: every device header fits in a few hundred bytes,
#: NUL padding included
SNIFF_BYTES = 4096
#: the formats of this package, registered at import, sniffed in this order
BUILTIN = (labradar,)

_NAME_RE = re.compile(r"^[a-z][a-z0-9_]*$")


@dataclass(frozen=True)
class TrackFormat:
    """A registered track format.

    Attributes
    ----------
    name : str
        Lower-case name (``format=`` of :func:`bayesdrag.io.tracks.read_track`).
    description : str
        One line.
    sniff : callable
        ``sniff(head_text) -> bool``.
    read : callable
        ``read(path, *, quote=True, **options) -> RadarTrack``.
    module : str
        The module that defines the format.
    """

    name: str
    description: str
    sniff: Callable[[str], bool]
    read: Callable[..., Any]
    module: str


_REGISTRY: dict[str, TrackFormat] = {}
#: the registered formats by name (read-only view; :func:`register` adds to it)
FORMATS = MappingProxyType(_REGISTRY)


def register(module: Any, *, replace: bool = False) -> TrackFormat:
    """Register a track format module (see the package docstring for what it holds).

    Parameters
    ----------
    module : module or object
        With attributes ``NAME``, ``sniff``, ``read_<NAME>`` and optionally ``DESCRIPTION``.
    replace : bool
        Replace a format already registered under the same name (else that is an error).

    Returns
    -------
    TrackFormat

    Raises
    ------
    ValueError
        A missing or invalid attribute, a name that is reserved (``auto``, ``csv``) or taken.
    """
    where = getattr(module, "__name__", repr(module))
    name = getattr(module, "NAME", None)
    if not isinstance(name, str) or not _NAME_RE.match(name):
        raise ValueError(f"track format {where}: NAME must be a lower-case identifier such as 'labradar', "
                         f"got {name!r}")
    if name in (AUTO, PLAIN):
        raise ValueError(f"track format {where}: the name {name!r} is reserved (auto, {PLAIN})")
    if name in _REGISTRY and not replace:
        raise ValueError(f"track format {where}: {name!r} is already registered by {_REGISTRY[name].module}; "
                         f"pass replace=True to replace it")
    read = getattr(module, f"read_{name}", None)
    sniff = getattr(module, "sniff", None)
    for attr, fn in ((f"read_{name}", read), ("sniff", sniff)):
        if not callable(fn):
            raise ValueError(f"track format {where}: needs a function {attr}() (bayesdrag.io.formats)")
    desc = getattr(module, "DESCRIPTION", None) or (getattr(module, "__doc__", None) or name).strip().split("\n")[0]
    fmt = TrackFormat(name, str(desc), sniff, read, where)
    _REGISTRY[name] = fmt
    return fmt


def unregister(name: str) -> None:
    """Remove a registered format (a test's toy format); unknown names are ignored."""
    _REGISTRY.pop(name, None)


def available() -> tuple[TrackFormat, ...]:
    """The registered formats, in sniffing order."""
    return tuple(_REGISTRY.values())


def names() -> tuple[str, ...]:
    """Every name ``format=`` takes: ``"auto"``, ``"csv"`` (the plain track CSV), then the
    registered formats (the choices of a ``--format`` option)."""
    return (AUTO, PLAIN, *_REGISTRY)


def get(name: str, path: str | os.PathLike[str] | None = None) -> TrackFormat:
    """The registered format ``name``.

    Raises
    ------
    InputError
        No such format (``path`` names the file in the message); the message lists the valid names.
    """
    fmt = _REGISTRY.get(name) if isinstance(name, str) else None
    if fmt is None:
        raise InputError(_unknown(name, path))
    return fmt


def _unknown(name, path):
    where = f"{path}: " if path is not None else ""
    return f"{where}unknown track format {name!r}; allowed: {', '.join(names())}"


def detect_text(head_text: str) -> str:
    """The name of the first registered format whose ``sniff`` claims ``head_text``, else :data:`PLAIN`."""
    for fmt in _REGISTRY.values():
        if fmt.sniff(head_text):
            return fmt.name
    return PLAIN


def detect(path: str | os.PathLike[str]) -> str:
    """The format of a file from its first :data:`SNIFF_BYTES` (:func:`detect_text`).

    The bytes are read by :func:`bayesdrag.io.csv.read_bytes`: a device, pipe or socket is
    refused before anything is read and a large file is not read beyond its start.

    Raises
    ------
    InputError
        Not found, a directory, not a regular file, unreadable.
    """
    raw = read_bytes(path, "track", SNIFF_BYTES, head=True)
    return detect_text(raw.replace(b"\x00", b"").decode("utf-8", "replace"))


def resolve(path: str | os.PathLike[str], format: str = AUTO) -> str:
    """The format to read ``path`` with: ``format`` checked (case ignored), ``"auto"`` sniffed.

    Returns
    -------
    str
        :data:`PLAIN` or a registered name.

    Raises
    ------
    InputError
        An unknown format name (before the file is touched), or what :func:`detect` raises.
    """
    if not isinstance(format, str):        # a list or a dict is no name (and cannot be looked up)
        raise InputError(_unknown(format, path))
    name = format.strip().lower()
    if name == AUTO:
        return detect(path)
    if name == PLAIN or name in _REGISTRY:
        return name
    raise InputError(_unknown(format, path))


for _module in BUILTIN:
    register(_module)
del _module
