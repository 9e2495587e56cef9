"""Converting a Doppler radar's export to a bayesdrag track CSV:
``python3 -m bayesdrag.io.radar_formats EXPORT -o TRACK.csv [--format auto|bayesdrag|labradar]``.

The readers are those of the format registry, :mod:`bayesdrag.io.formats` (one module per device
format; LabRadar: :mod:`bayesdrag.io.formats.labradar`, whose docstring gives the layout and how
its columns map to bayesdrag's). This module keeps the command and its older Python names; a
track is read directly, without converting, by ``bayesdrag.read_track("Shot0001 Track.csv")``.

The format ``"bayesdrag"`` here is the plain track CSV (:data:`bayesdrag.io.formats.PLAIN`).
Errors are :class:`~bayesdrag.errors.InputError` naming the file, the line and what was found;
the command prints them as one line and exits with status 2.
"""
from __future__ import annotations

import os
from pathlib import Path

from ..errors import InputError
from . import formats
from .formats.labradar import DISTANCE_UNITS, VELOCITY_UNITS, read_labradar

__all__ = ["FORMATS", "VELOCITY_UNITS", "DISTANCE_UNITS", "sniff_format", "read_radar_export", "read_labradar_track",
           "convert", "main"]

#: this command's name of the plain track CSV
LEGACY_PLAIN = "bayesdrag"
#: the formats this command names (``"auto"`` besides), as when it was written
FORMATS = (LEGACY_PLAIN, *(f.name for f in formats.available()))


def _registry_name(fmt):
    """The registry's name of a format named here (``"bayesdrag"`` is the registry's ``"csv"``)."""
    return formats.PLAIN if fmt == LEGACY_PLAIN else fmt


def sniff_format(path):
    """``"labradar"`` (or another registered format) if the file looks like a device's export,
    else ``"bayesdrag"`` (a track CSV); :func:`bayesdrag.io.formats.detect`."""
    name = formats.detect(path)
    return LEGACY_PLAIN if name == formats.PLAIN else name


def read_radar_export(path, fmt="auto", **kw):
    """Read a track in a supported format (``fmt``: ``"auto"``, ``"bayesdrag"`` or a registered
    format's name; ``kw`` go to a device format's reader, e.g. ``keep_extrapolated``).

    Returns
    -------
    RadarTrack
    """
    name = formats.resolve(path, _registry_name(fmt))
    if name == formats.PLAIN:
        from .tracks import read_track

        return read_track(path, format=formats.PLAIN)
    return formats.get(name, path).read(path, **kw)


def read_labradar_track(path, keep_extrapolated=False):
    """Read a LabRadar per-shot track export (:func:`bayesdrag.io.formats.labradar.read_labradar`)."""
    return read_labradar(path, keep_extrapolated=keep_extrapolated)


def _same_file(a, b):
    """Whether two paths name one file (a link or another spelling of it included)."""
    try:
        return os.path.samefile(a, b)
    except OSError:               # the output does not exist yet: compare where the names point
        return Path(a).resolve() == Path(b).resolve()


def convert(path, output, fmt="auto", **kw):
    """Convert a radar export to a bayesdrag track CSV (extra columns kept). Returns the track.

    Raises
    ------
    InputError
        ``output`` is the export itself (converting would overwrite it), and what reading refuses.
    """
    from .outputs import atomic_write
    from .tracks import write_track

    if _same_file(path, output):
        raise InputError(f"{output}: -o names the export being converted ({path}); writing would overwrite it: "
                         f"give another output file")
    tr = read_radar_export(path, fmt, **kw)
    atomic_write(output, lambda tmp: write_track(tmp, tr, comment=f"converted from {path} ({'; '.join(tr.notes)})"))
    return tr


def main(argv=None):
    """``python3 -m bayesdrag.io.radar_formats EXPORT -o TRACK.csv [--format ...] [--keep-extrapolated]``.

    Returns
    -------
    int
        0, or 2 after one line on stderr for an input the conversion refuses.
    """
    import argparse
    import sys

    ap = argparse.ArgumentParser(prog="python3 -m bayesdrag.io.radar_formats",
                                 description="convert a Doppler-radar export to a bayesdrag track CSV")
    ap.add_argument("export")
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--format", default="auto",
                    choices=(formats.AUTO, LEGACY_PLAIN, *(f.name for f in formats.available())))
    ap.add_argument("--keep-extrapolated", action="store_true")
    a = ap.parse_args(argv)
    try:
        kw = {"keep_extrapolated": True} if a.keep_extrapolated and a.format != LEGACY_PLAIN else {}
        tr = convert(a.export, a.output, a.format, **kw)
    except InputError as exc:
        print(f"bayesdrag: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    print(f"wrote {a.output}: {tr.n} samples, channels {', '.join(tr.names)}, extra {', '.join(tr.extra) or 'none'}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
