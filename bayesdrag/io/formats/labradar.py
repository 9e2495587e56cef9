"""LabRadar per-shot track exports (``SR####/TRK/Shot#### Track.csv``) read into a RadarTrack.

The most common Doppler-radar export among ranges that are not military test centres. The
layout (an example in ``examples/radar_export/``; 729 real ones described in
``docs/radar.md``)::

    sep=;
    Device ID;LBR-0013797;;
    Series No;0001;;
    Shot No;0001;;
    Units velocity;fps;;          <- optional; the column names' units win
    Units distances;yd;;
    Time (s);Vel (fps);Dist (yd);SNR
    0.000000;2800.13;0.00;-       <- the device's muzzle-velocity extrapolation, not a measurement
    0.007021;2784.61;6.64;33.07
    ...

Semicolon separated, optionally padded with NUL characters; a decimal comma is accepted. Units
are taken from the column headers ``Time (s|ms)``, ``Vel (fps|m/s|km/h|mph)``, ``Dist (ft|yd|m)``
(or, for a header without one, from the ``Units velocity`` / ``Units distances`` lines).

Mapping to bayesdrag (docs/radar.md, "A chronograph radar beside the muzzle"):

* ``Time (s)`` -> ``t``; ``Vel`` -> ``range_rate`` [m/s]: the radial speed seen from the
  device's site beside the muzzle, after the device's own cosine correction for the offset typed
  into it (the round's ``[radar] position`` and ``device_offset`` model both).
* ``Dist`` is kept as the **extra** column ``range_m`` [m], unused: the device integrates it from
  its own velocity, it is not a measurement.
* ``SNR`` becomes the column ``snr`` [dB]: each sample's noise sd is taken proportional to
  ``1 / sqrt(SNR)`` (:mod:`bayesdrag.measure.sample_noise`).
* The first row (``SNR`` "-", t = 0) is the device's extrapolation to the muzzle; it is
  **dropped** by default (``keep_extrapolated=True`` keeps it, flagged in the extra column
  ``extrapolated`` with an SNR of 0 dB, i.e. almost no weight): it is not an independent
  measurement and would pin the launch speed twice. A note says so.
* A row whose velocity is ``nan`` (the device's mark for "no value", e.g. a failed
  extrapolation) holds no measurement: it is dropped, with a note naming its line.

Guards (each an :class:`~bayesdrag.errors.InputError` of one line naming the file, the line, what
was found and what is allowed): the file is read through :func:`bayesdrag.io.csv.read_bytes`
(a device, pipe or socket refused before anything is read, a file over :data:`MAX_BYTES` refused
by its size), a header with an empty or repeated column name, a value that is not a finite
number, a velocity outside (0, :data:`VELOCITY_MAX`] m/s, an SNR beyond +-:data:`SNR_MAX_DB`,
time not increasing, and a time column that is not in seconds (a track reaching farther than
:data:`MAX_REACH` from the device: milliseconds are named as the likely mistake).
"""
from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from ...errors import InputError
from ...track import RadarTrack
from ..csv import parse_number, read_bytes

__all__ = ["NAME", "DESCRIPTION", "sniff", "read_labradar", "write_labradar", "VELOCITY_UNITS", "DISTANCE_UNITS", "TIME_UNITS"]

#: the format's name in the registry (``read_track(path, format="labradar")``)
NAME = "labradar"
#: one line for listings
DESCRIPTION = "LabRadar per-shot track export (SR####/TRK/Shot#### Track.csv: Time (s);Vel;Dist;SNR)"

#: velocity units in LabRadar headers -> factor to m/s
VELOCITY_UNITS = {"fps": 0.3048, "ft/s": 0.3048, "m/s": 1.0, "mps": 1.0, "km/h": 1 / 3.6, "mph": 0.44704}
#: distance units -> factor to m
DISTANCE_UNITS = {"ft": 0.3048, "feet": 0.3048, "yd": 0.9144, "yards": 0.9144, "m": 1.0, "meters": 1.0,
                  "metres": 1.0}
#: time units -> factor to s
TIME_UNITS = {"s": 1.0, "ms": 1e-3}

#: largest export read [bytes]: the 729 real tracks are 2-6 kB; 4 MB leaves room for NUL padding
#: and a denser device while bounding the memory a file can take
MAX_BYTES = 4 << 20
#: fastest speed a chronograph radar reports [m/s]: small-arms bullets fly below ~1700 m/s; beyond
#: this a value is a unit or typing mistake (1e308 fps is finite after conversion)
VELOCITY_MAX = 2000.0
#: farthest a chronograph radar follows a projectile [m] (a LabRadar ~100 m; margin for others): a
#: time column in milliseconds makes a track 1000 times longer (~5 km at least for any bullet)
MAX_REACH = 2000.0
#: longest a chronograph track can last [s] (the real ones last 0.06-0.5 s)
MAX_DURATION = 100.0
#: largest |SNR| [dB] (as :data:`bayesdrag.io.tracks.SNR_MAX_DB`: the converted file is read back
#: through that bound)
SNR_MAX_DB = 200.0
#: the device's mark for a missing value
_NO_VALUE = "nan"

_HEAD_RE = re.compile(r"^\s*time\s*\(\s*(m?s)\s*\)\s*$", re.I)
_UNIT_RE = re.compile(r"\(([^)]*)\)")
#: a line only a LabRadar export begins with: its ``sep=;`` line, its device line, its table header
_SNIFF_RE = re.compile(r"^\s*(?:sep=;|device id\s*;|time\s*\(\s*m?s\s*\)\s*;\s*vel\b)", re.I)


def sniff(head_text: str) -> bool:
    """Whether the start of a file is a LabRadar track export.

    Parameters
    ----------
    head_text : str
        The first few kB of the file, decoded, NUL characters removed.

    Returns
    -------
    bool
        True when a line begins with ``sep=;``, ``Device ID;`` or ``Time (s);Vel``.
    """
    return any(_SNIFF_RE.match(line.lstrip("\ufeff")) for line in head_text.splitlines())


def _shown(what, cell, quote):
    """``what 'cell'``, or ``what`` alone when the file's content is not to be repeated."""
    return f"{what} {cell.strip()!r}" if quote else what


def _number(cell, path, line_no, what, quote):
    """The finite float of a cell (``"..."`` quotes and a decimal comma allowed)."""
    s = cell.strip().strip('"')
    if "," in s and "." not in s:     # a decimal comma (a European locale's export)
        s = s.replace(",", ".")
    v = parse_number(s)
    if v is None:
        raise InputError(f"{path}: line {line_no}: {_shown(what, cell, quote)} is not a number")
    if not np.isfinite(v):
        raise InputError(f"{path}: line {line_no}: {_shown(what, cell, quote)} is not finite")
    return v


def _unit(path, line_no, header, meta_unit, table, what, quote):
    """(factor to SI, unit) of a column: the header's ``(unit)``, else the ``Units <what>`` line's."""
    m = _UNIT_RE.search(header)
    unit = (m.group(1) if m else "").strip().lower()
    meta_unit = (meta_unit or "").strip().lower()
    column = f"{what} column {header.strip()!r}" if quote else f"{what} column"
    if unit and meta_unit and table.get(unit, unit) != table.get(meta_unit, meta_unit):
        raise InputError(f"{path}: line {line_no}: {column} says {unit!r} but the 'Units {what}' line says "
                         f"{meta_unit!r}; correct one of them")
    unit = unit or meta_unit
    if unit not in table:
        shown = repr(unit) if quote and unit else "missing" if not unit else "not known"
        raise InputError(f"{path}: line {line_no}: {column}: unit {shown} is not one of {', '.join(sorted(table))}")
    return table[unit], unit


def _find_header(path, lines):
    """(index of the ``Time (s);Vel (...)`` line, metadata ``{key: value}`` of the lines above it)."""
    meta = {}
    for i, line in enumerate(lines):
        cells = [c.strip() for c in line.split(";")]
        if cells and _HEAD_RE.match(cells[0]):
            return i, meta
        if len(cells) >= 2 and cells[0] and cells[0].lower() != "sep=":
            meta[cells[0].lower()] = cells[1]
    raise InputError(f"{path}: no 'Time (s);Vel (...)' header line; not a LabRadar track export")


def _columns(path, line, line_no, meta, quote):
    """``({column key: index}, {key: (factor to SI, unit)}, number of named columns)`` of the header."""
    cells = [c.strip().strip('"') for c in line.split(";")]
    while cells and not cells[-1]:     # trailing separators, as on the device's own ';;' lines
        cells.pop()
    shown = f"; found {line.strip()!r}" if quote else ""
    for k, c in enumerate(cells):
        if not c:
            raise InputError(f"{path}: line {line_no}: empty column name in the LabRadar header (column {k + 1} "
                             f"of {len(cells)}){shown}; expected Time (s);Vel (unit);Dist (unit);SNR")
    cols = {}
    for k, c in enumerate(cells):
        key = c.split("(")[0].strip().lower()
        if key in cols:
            raise InputError(f"{path}: line {line_no}: column {key!r} appears twice in the LabRadar header{shown}; "
                             f"each column may appear once")
        cols[key] = k
    if "vel" not in cols:
        raise InputError(f"{path}: line {line_no}: no 'Vel (...)' column in the LabRadar header{shown}")
    units = {"time": _unit(path, line_no, cells[cols["time"]], None, TIME_UNITS, "time", quote),
             "vel": _unit(path, line_no, cells[cols["vel"]], meta.get("units velocity"), VELOCITY_UNITS,
                          "velocity", quote)}
    if "dist" in cols:
        units["dist"] = _unit(path, line_no, cells[cols["dist"]],
                              meta.get("units distances", meta.get("units distance")), DISTANCE_UNITS, "distances",
                              quote)
    return cols, units, len(cells)


def _rows(path, lines, header_at, cols, units, n_named, keep_extrapolated, quote):
    """The table's values in SI: dict of lists ``t, v, dist, snr, line``, plus the lines of the
    rows dropped as extrapolated and as without a velocity."""
    out = {"t": [], "v": [], "dist": [], "snr": [], "line": []}
    extrapolated, no_value = [], []
    t_fac, v_fac = units["time"][0], units["vel"][0]
    for i in range(header_at + 1, len(lines)):
        line, no = lines[i], i + 1
        if not line.strip() or line.strip().startswith("#"):
            continue
        cells = line.split(";")
        if not any(c.strip() for c in cells):      # a row of bare separators
            continue
        if len(cells) < n_named:
            raise InputError(f"{path}: line {no}: {len(cells)} fields, the header has {n_named}")
        snr_cell = cells[cols["snr"]].strip() if "snr" in cols else ""
        if snr_cell in ("-", "") and "snr" in cols and not keep_extrapolated:
            extrapolated.append(no)
            continue
        if cells[cols["vel"]].strip().strip('"').lower() == _NO_VALUE:
            no_value.append(no)
            continue
        out["t"].append(_number(cells[cols["time"]], path, no, "time", quote) * t_fac)
        v = _number(cells[cols["vel"]], path, no, "velocity", quote) * v_fac
        if not 0.0 < v <= VELOCITY_MAX:
            raise InputError(f"{path}: line {no}: {_shown('velocity', cells[cols['vel']], quote)} "
                             f"({units['vel'][1]}) is {v:.6g} m/s, outside (0, {VELOCITY_MAX:g}] m/s: not a speed a "
                             f"chronograph radar reports (a unit or typing mistake?)")
        out["v"].append(v)
        if "dist" in cols:
            d = _number(cells[cols["dist"]], path, no, "distance", quote) * units["dist"][0]
            if not 0.0 <= d <= MAX_REACH:
                raise InputError(f"{path}: line {no}: {_shown('distance', cells[cols['dist']], quote)} is "
                                 f"{d:.6g} m, outside 0 .. {MAX_REACH:g} m (a chronograph radar's reach)")
            out["dist"].append(d)
        if "snr" in cols:
            s = np.nan if snr_cell in ("-", "") else _number(snr_cell, path, no, "SNR", quote)
            if abs(s) > SNR_MAX_DB:
                raise InputError(f"{path}: line {no}: SNR = {s:g} dB; the echo's signal-to-noise ratio is within "
                                 f"+-{SNR_MAX_DB:g} dB")
            out["snr"].append(s)
        out["line"].append(no)
    return out, extrapolated, no_value


#: the distance column grows at the velocity column's rate to within this factor (the 146 real
#: tracks checked: 0.993-1.002) or the two are in different units from what the header says
DIST_RATE_LIMIT = 1.05
#: a unit hypothesis explains a ratio when it predicts it to within this factor
DIST_RATE_MATCH = 1.03
#: distance units a mistaken column may be in beside the header's (km is no LabRadar unit, but a
#: hand-edited or converted export holds it)
_MISTAKEN_DISTANCE = {**DISTANCE_UNITS, "km": 1000.0}


def _check_distance_rate(path, t, v, dist, units):
    """Refuse a track whose distance column does not grow at its velocity's rate, naming the
    likely mistake: a column in another unit than its header says (``Dist (m)`` holding km,
    ``Vel (m/s)`` holding ft/s). The device's distance is the integral of its velocity, so the two
    agree to 0.2 % on real tracks; the unit mistake is found by trying each unit for each column."""
    if dist is None or t.size < 4 or not np.all(np.isfinite(dist)) or not np.ptp(dist) > 0:
        return            # no distance recorded (a flat or missing column): nothing to check, and it is unused
    k = max(1, t.size // 10)
    dt = t[k:] - t[:-k]
    vm = 0.5 * (v[k:] + v[:-k])
    ok = (dt > 0) & (vm > 0)
    if ok.sum() < 2:
        return
    q = float(np.median((dist[k:] - dist[:-k])[ok] / dt[ok] / vm[ok]))
    if not q > 0 or 1.0 / DIST_RATE_LIMIT < q < DIST_RATE_LIMIT:
        return            # agreeing, or a distance that does not grow (no unit explains that)
    f_v, u_v = units["vel"]
    f_d, u_d = units["dist"]
    guesses = []
    # one name per factor (fps and ft/s are one unit)
    vel_units = {fv: uv for uv, fv in reversed(VELOCITY_UNITS.items())}
    dist_units = {fd: ud for ud, fd in reversed(_MISTAKEN_DISTANCE.items())}
    for fv, uv in vel_units.items():
        for fd, ud in dist_units.items():
            # true units (uv, ud): the read values are off by the declared / true factors
            expect = (f_d / fd) / (f_v / fv)
            changed = (fv != f_v) + (fd != f_d)
            if changed and abs(np.log(max(q, 1e-300) / expect)) < np.log(DIST_RATE_MATCH):
                guesses.append((changed, f"{'Vel' if fv != f_v else 'Dist'} looks like {uv if fv != f_v else ud} "
                                         f"(the header says {u_v if fv != f_v else u_d})" if changed == 1 else
                                f"Vel looks like {uv} and Dist like {ud} (the header says {u_v} and {u_d})"))
    guesses = sorted(set(guesses))
    why = ("; ".join(g for c, g in guesses if c == guesses[0][0]) if guesses
           else "check the units of the Vel and Dist columns against their headers")
    raise InputError(f"{path}: units look wrong: the distance grows at {q:.4g} times the velocity (1 expected: "
                     f"the device's distance is its velocity's integral); {why}")


def _check_time(path, t, v, line, t_unit):
    """Time from the trigger, increasing, and in seconds: a track farther than :data:`MAX_REACH`
    from the device or longer than :data:`MAX_DURATION` is refused, naming milliseconds when
    the track would fit in seconds."""
    if t[0] < 0:
        raise InputError(f"{path}: line {line[0]}: t = {t[0]:g} s; a LabRadar's time counts from the shot, >= 0")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        k = bad[0] + 1
        raise InputError(f"{path}: line {line[k]}: t = {t[k]:g} s after {t[k - 1]:g} s on line {line[k - 1]}; "
                         f"time must increase strictly")
    v_typ = float(np.median(v))
    reach = v_typ * float(t[-1])        # how far from the muzzle the last sample is, about
    if reach <= MAX_REACH and t[-1] <= MAX_DURATION:
        return
    if t_unit == "s" and reach / 1e3 <= MAX_REACH and t[-1] / 1e3 <= MAX_DURATION:
        hint = ("the time column looks like milliseconds (LabRadar's 'Time (s)' is in seconds: divide it by "
                "1000, or name the column 'Time (ms)')")
    else:
        hint = "check the units of the Time and Vel columns"
    raise InputError(f"{path}: line {line[-1]}: t = {t[-1]:g} s at velocities near {v_typ:.4g} m/s puts the "
                     f"projectile ~{reach / 1e3:.4g} km from the device; a chronograph radar follows it for at most "
                     f"{MAX_REACH:g} m and {MAX_DURATION:g} s; {hint}")


def read_labradar(path: str | os.PathLike[str], *, keep_extrapolated: bool = False,
                  quote: bool = True) -> RadarTrack:
    """Read a LabRadar per-shot track export (module docstring) into a RadarTrack in SI.

    Parameters
    ----------
    path : str or os.PathLike
        The export, ``Shot#### Track.csv``.
    keep_extrapolated : bool
        Keep the first row (the device's extrapolated muzzle velocity, ``SNR`` "-").
    quote : bool
        False for an export another file points to (a campaign's): a message never repeats the
        file's content.

    Returns
    -------
    RadarTrack
        Channel ``range_rate`` [m/s]; extra columns ``range_m`` [m] (unused) and ``snr`` [dB]
        when present (and ``extrapolated``, 1 on a kept extrapolated row); ``notes`` say what was
        converted and dropped; ``source`` is the file.

    Raises
    ------
    bayesdrag.errors.InputError
        Not a regular file, larger than :data:`MAX_BYTES`, no ``Time (s);Vel (...)`` header, an
        empty or repeated column name, an unknown unit, a short row, a value that is not a finite
        number, a velocity outside (0, :data:`VELOCITY_MAX`] m/s, fewer than 2 measured rows,
        time not increasing, or not in seconds (module docstring), a distance that does not grow
        at the velocity's rate (a column in another unit than its header says, named).
    """
    path = Path(path)
    raw = read_bytes(path, "LabRadar track", MAX_BYTES)
    text = raw.replace(b"\x00", b"").decode("utf-8-sig", "replace")      # the device pads lines with NULs
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    header_at, meta = _find_header(path, lines)
    cols, units, n_named = _columns(path, lines[header_at], header_at + 1, meta, quote)
    rows, extrapolated, no_value = _rows(path, lines, header_at, cols, units, n_named, keep_extrapolated, quote)
    if len(rows["t"]) < 2:
        raise InputError(f"{path}: {len(rows['t'])} measured row(s) after the header; at least 2 are needed")
    t, v = np.asarray(rows["t"]), np.asarray(rows["v"])
    _check_time(path, t, v, rows["line"], units["time"][1])
    extra = {}
    if rows["dist"]:
        extra["range_m"] = np.asarray(rows["dist"])
        _check_distance_rate(path, t, v, extra["range_m"], units)
    if rows["snr"]:
        snr = np.asarray(rows["snr"])
        extra["snr"] = np.nan_to_num(snr, nan=0.0)
        if np.any(np.isnan(snr)):  # kept extrapolated rows are flagged, their SNR written as 0
            extra["extrapolated"] = np.isnan(snr).astype(float)
    # a file another file names is never quoted, not even its header's device, series and shot
    which = (f" (device {meta.get('device id', '?')}, series {meta.get('series no', '?')}, shot "
             f"{meta.get('shot no', '?')})") if quote else ""
    notes = [f"{path}: LabRadar track{which}: velocity from {units['vel'][1]} to m/s as the range rate from the "
             f"device's site (give [radar] device_offset and position in the round)"
             + (f", distance from {units['dist'][1]} to m as extra column range_m" if "dist" in units else "")
             + (", time from ms to s" if units["time"][1] == "ms" else "")]
    if extrapolated:
        notes.append(f"{path}: dropped {len(extrapolated)} row(s) without SNR (the device's extrapolation to the "
                     f"muzzle; line {', '.join(map(str, extrapolated[:5]))})")
    if no_value:
        notes.append(f"{path}: dropped {len(no_value)} row(s) whose velocity is 'nan' (the device's mark for no "
                     f"value; line {', '.join(map(str, no_value[:5]))})")
    return RadarTrack(t, {"range_rate": v}, extra, str(path), tuple(notes))


def write_labradar(path: str | os.PathLike[str], t, velocity, distance, snr, *, v0_extrapolated=None,
                   series: int = 1, shot: int = 1, velocity_unit: str = "fps", distance_unit: str = "m",
                   device_id: str = "LBR-0000000") -> Path:
    """Write a track as a LabRadar device writes it to its card (the module docstring's layout).

    Parameters
    ----------
    path : path
        The file to write (``Shot0001 Track.csv``).
    t : array_like, s
        Sample times from the device's trigger.
    velocity : array_like, m/s
        The speed the device reports (its range rate after its own offset correction).
    distance : array_like, m
        The distance column (the device integrates it from its speed).
    snr : array_like, dB
    v0_extrapolated : float, m/s, optional
        The device's extrapolation to the muzzle, written as the first row (t = 0, SNR ``-``).
    series, shot : int
    velocity_unit : str
        One of :data:`VELOCITY_UNITS` (the device's setting; ``fps`` by default, as most are).
    distance_unit : str
        One of :data:`DISTANCE_UNITS`.

    Returns
    -------
    Path
        The file written.
    """
    from ..outputs import atomic_write

    if velocity_unit not in VELOCITY_UNITS or distance_unit not in DISTANCE_UNITS:
        raise ValueError(f"velocity unit {velocity_unit!r} or distance unit {distance_unit!r} not known")
    fv, fd = VELOCITY_UNITS[velocity_unit], DISTANCE_UNITS[distance_unit]
    lines = ["sep=;", f"Device ID;{device_id};;", f"Series No;{series:04d};;", f"Shot No;{shot:04d};;",
             f"Units velocity;{velocity_unit};;", f"Units distances;{distance_unit};;", "",
             f"Time (s);Vel ({velocity_unit});Dist ({distance_unit});SNR"]
    if v0_extrapolated is not None:
        lines.append(f"0.000000;{v0_extrapolated / fv:.2f};0.00;-")
    for ti, vi, di, si in zip(np.asarray(t, float), np.asarray(velocity, float), np.asarray(distance, float),
                              np.asarray(snr, float)):
        lines.append(f"{ti:.6f};{vi / fv:.2f};{di / fd:.2f};{si:.2f}")
    text = "\n".join(lines) + "\n"
    path = Path(path)
    atomic_write(path, lambda tmp: Path(tmp).write_bytes(text.encode()))
    return path
