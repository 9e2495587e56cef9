"""Reading tracks exported by Doppler radars into a :class:`~bayesdrag.track.RadarTrack`.

Supported: **LabRadar per-shot track files** (``SR####/TRK/Shot#### Track.csv``), the most common
Doppler-radar export among ranges that are not military test centres. The layout (documented with
an example in ``examples/radar_export/``)::

    sep=;
    Device ID;LBR-0013797;;
    Series No;0001;;
    Shot No;0001;;
    Units velocity;fps;;          <- optional; otherwise the units in the column names
    Units distances;yd;;
    Time (s);Vel (fps);Dist (yd);SNR
    0.000000;2800.13;0.00;-       <- the device's muzzle-velocity extrapolation, not a measurement
    0.007021;2784.61;6.64;33.07
    ...

Semicolon separated, optionally padded with NUL characters; a decimal comma is accepted. Units
are taken from the column headers ``Vel (fps|m/s|km/h|mph)``, ``Dist (ft|yd|m)``.

Mapping to bayesdrag (decisions written down; docs/radar.md, "Chronograph radars"):

* ``Time (s)`` -> ``t``; ``Vel`` -> ``range_rate`` in m/s: the radial speed seen from the
  device's site beside the muzzle, after the device's own cosine correction for the offset typed
  into it. The round says where the device stood (``[radar] position``, default
  ``{y = device_offset}``) and what offset was typed (``[radar] device_offset``): the fit models
  both, so a wrongly typed offset is not baked into the speeds, and ``[radar] position_sd`` lets
  the fit estimate the true site.
* ``Dist`` is kept as an **extra** column ``range_m``, unused: the device integrates it from its
  own velocity, it is not a measurement.
* ``SNR`` becomes the column ``snr`` [dB]: each sample's noise sd is taken proportional to
  ``1 / sqrt(SNR)`` (:mod:`bayesdrag.measure.sample_noise`).
* The first row (``SNR`` "-", t = 0) is the device's extrapolation to the muzzle; it is
  **dropped** by default (``keep_extrapolated=True`` keeps it, flagged in the extra column
  ``extrapolated`` with an SNR of 0 dB, i.e. almost no weight): it is not an independent
  measurement and would pin the launch speed twice. A note says so.

Errors are :class:`~bayesdrag.errors.InputError` naming the file, the line and what was found.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..errors import InputError

#: velocity units in LabRadar headers -> factor to m/s
VELOCITY_UNITS = {"fps": 0.3048, "ft/s": 0.3048, "m/s": 1.0, "mps": 1.0, "km/h": 1 / 3.6, "mph": 0.44704}
#: distance units -> factor to m
DISTANCE_UNITS = {"ft": 0.3048, "feet": 0.3048, "yd": 0.9144, "yards": 0.9144, "m": 1.0, "meters": 1.0,
                  "metres": 1.0}
FORMATS = ("bayesdrag", "labradar")

_HEAD_RE = re.compile(r"^\s*time\s*\(s\)\s*$", re.I)
_UNIT_RE = re.compile(r"\(([^)]*)\)")


def sniff_format(path):
    """``"labradar"`` if the file looks like a LabRadar track export, else ``"bayesdrag"``."""
    try:
        head = Path(path).read_bytes()[:4096].replace(b"\x00", b"").decode("utf-8", "replace")
    except OSError as exc:
        raise InputError(f"{path}: cannot read the track ({exc})") from None
    low = head.lower()
    if "sep=;" in low or "device id;" in low or re.search(r"time \(s\);\s*vel", low):
        return "labradar"
    return "bayesdrag"


def read_radar_export(path, fmt="auto", **kw):
    """Read a track in a supported format (``fmt`` one of :data:`FORMATS` or ``"auto"``).

    Returns
    -------
    RadarTrack
    """
    if fmt == "auto":
        fmt = sniff_format(path)
    if fmt == "labradar":
        return read_labradar_track(path, **kw)
    if fmt == "bayesdrag":
        from .tracks import read_track

        return read_track(path)
    raise InputError(f"{path}: unknown track format {fmt!r}; allowed: auto, {', '.join(FORMATS)}")


def _number(cell, path, line_no, what):
    s = cell.strip().strip('"')
    if "," in s and "." not in s:
        s = s.replace(",", ".")
    try:
        v = float(s)
    except ValueError:
        raise InputError(f"{path}: line {line_no}: {what} {cell.strip()!r} is not a number") from None
    if not np.isfinite(v):
        raise InputError(f"{path}: line {line_no}: {what} {cell.strip()!r} is not finite")
    return v


def _unit(header, table, path, line_no, what):
    m = _UNIT_RE.search(header)
    unit = (m.group(1) if m else "").strip().lower()
    if unit not in table:
        raise InputError(f"{path}: line {line_no}: {what} column {header.strip()!r}: unit {unit or 'missing'!r} "
                         f"is not one of {', '.join(sorted(table))}")
    return table[unit], unit


def read_labradar_track(path, keep_extrapolated=False):
    """Read a LabRadar per-shot track export (module docstring) into a RadarTrack in SI.

    Parameters
    ----------
    path : str or os.PathLike
    keep_extrapolated : bool
        Keep the first row (the device's extrapolated muzzle velocity, ``SNR`` "-").

    Returns
    -------
    RadarTrack
        Channel ``range_rate`` [m/s]; extra columns ``range_m`` [m] (unused) and ``snr`` [dB]
        when present;
        ``notes`` say what was converted and dropped; ``source`` is the file.
    """
    from ..track import RadarTrack

    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{path}: cannot read the track ({exc})") from None
    text = raw.replace(b"\x00", b"").decode("utf-8-sig", "replace")
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    header_at = None
    meta = {}
    for i, line in enumerate(lines):
        cells = [c.strip() for c in line.split(";")]
        if cells and _HEAD_RE.match(cells[0]):
            header_at = i
            break
        if len(cells) >= 2 and cells[0] and cells[0].lower() != "sep=":
            meta[cells[0].lower()] = cells[1]
    if header_at is None:
        raise InputError(f"{path}: no 'Time (s);Vel (...)' header line; not a LabRadar track export")
    head = [c.strip() for c in lines[header_at].split(";")]
    cols = {h.split("(")[0].strip().lower(): k for k, h in enumerate(head) if h}
    if "vel" not in cols:
        raise InputError(f"{path}: line {header_at + 1}: no 'Vel (...)' column in {lines[header_at].strip()!r}")
    v_fac, v_unit = _unit(head[cols["vel"]], VELOCITY_UNITS, path, header_at + 1, "velocity")
    d_fac = None
    if "dist" in cols:
        d_fac, d_unit = _unit(head[cols["dist"]], DISTANCE_UNITS, path, header_at + 1, "distance")
    t, v, dist, snr = [], [], [], []
    dropped = 0
    for i in range(header_at + 1, len(lines)):
        line = lines[i]
        if not line.strip() or line.strip().startswith("#"):
            continue
        cells = line.split(";")
        if len(cells) <= max(cols.values()) and len([c for c in cells if c.strip()]) < 2:
            continue
        no = i + 1
        if len(cells) < len([h for h in head if h]):
            raise InputError(f"{path}: line {no}: {len(cells)} fields, the header has {len(head)}")
        snr_cell = cells[cols["snr"]].strip() if "snr" in cols else ""
        if snr_cell in ("-", "") and "snr" in cols and not keep_extrapolated:
            dropped += 1
            continue
        t.append(_number(cells[cols["time"]], path, no, "time"))
        v.append(_number(cells[cols["vel"]], path, no, "velocity") * v_fac)
        if d_fac is not None:
            dist.append(_number(cells[cols["dist"]], path, no, "distance") * d_fac)
        if "snr" in cols:
            snr.append(np.nan if snr_cell in ("-", "") else _number(snr_cell, path, no, "SNR"))
    if len(t) < 2:
        raise InputError(f"{path}: {len(t)} measured row(s) after the header; at least 2 are needed")
    t = np.asarray(t)
    if np.any(np.diff(t) <= 0):
        k = int(np.argmax(np.diff(t) <= 0)) + 1
        raise InputError(f"{path}: time must increase strictly; row {k + 1} of the table has t = {t[k]:g} s "
                         f"after {t[k - 1]:g} s")
    if np.any(np.asarray(v) < 0):
        raise InputError(f"{path}: negative velocity in the table; LabRadar velocities are receding speeds >= 0")
    extra = {}
    if dist:
        extra["range_m"] = np.asarray(dist)
    if snr:
        snr = np.asarray(snr)
        extra["snr"] = np.nan_to_num(snr, nan=0.0)
        if np.any(np.isnan(snr)):  # kept extrapolated rows are flagged, their SNR written as 0
            extra["extrapolated"] = np.isnan(snr).astype(float)
    notes = [f"{path}: LabRadar track (device {meta.get('device id', '?')}, series {meta.get('series no', '?')}, "
             f"shot {meta.get('shot no', '?')}): velocity from {v_unit} to m/s as the range rate from the device's "
             f"site (give [radar] device_offset and position in the round)"
             + (f", distance from {d_unit} to m as extra column range_m" if d_fac is not None else "")]
    if dropped:
        notes.append(f"{path}: dropped {dropped} row(s) without SNR (the device's extrapolation to the muzzle)")
    return RadarTrack(t, {"range_rate": np.asarray(v)}, extra, str(path), tuple(notes))


def convert(path, output, fmt="auto", **kw):
    """Convert a radar export to a bayesdrag track CSV (extra columns kept). Returns the track."""
    from .outputs import atomic_write
    from .tracks import write_track

    tr = read_radar_export(path, fmt, **kw)
    atomic_write(output, lambda tmp: write_track(tmp, tr, comment=f"converted from {path} ({'; '.join(tr.notes)})"))
    return tr


def main(argv=None):
    """``python -m bayesdrag.radar_formats EXPORT -o TRACK.csv [--format auto|labradar]``."""
    import argparse
    import sys

    ap = argparse.ArgumentParser(prog="python -m bayesdrag.radar_formats",
                                 description="convert a Doppler-radar export to a bayesdrag track CSV")
    ap.add_argument("export")
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--format", default="auto", choices=("auto",) + FORMATS)
    ap.add_argument("--keep-extrapolated", action="store_true")
    a = ap.parse_args(argv)
    try:
        kw = {"keep_extrapolated": a.keep_extrapolated} if a.format != "bayesdrag" else {}
        tr = convert(a.export, a.output, a.format, **kw)
    except InputError as exc:
        print(f"bayesdrag: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    print(f"wrote {a.output}: {tr.n} samples, channels {', '.join(tr.names)}, extra {', '.join(tr.extra) or 'none'}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
