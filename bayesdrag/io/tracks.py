"""Track files (CSV): ``#`` comment lines, a header row naming ``t`` plus at
least one of ``x, y, z, v`` or of the radar-native ``range, azimuth, elevation, range_rate`` (or an
alias: ``time``, ``t_s``, ``speed``, ``slant_range``, ...; :data:`ALIASES`; or any names mapped with
``columns``), then one row of numbers per radar sample; SI units (t [s], x, y, z, range [m], v,
range_rate [m/s]) except the angles, in degrees in the file (radians in the ``RadarTrack``).
Optional per-sample noise columns, kept in ``RadarTrack.extra``: ``sigma_<channel>`` (each sample's
noise sd in the channel's file unit) and ``snr`` (the echo's signal-to-noise ratio [dB]); the fit
weights each sample by them (:mod:`bayesdrag.measure.sample_noise`). Other extra columns are kept,
ignored by the fit, and reported by one line in ``RadarTrack.notes``.

A device's own export is read too: :func:`read_track` sniffs the file's start and hands a
LabRadar track (or any format of :mod:`bayesdrag.io.formats`) to that format's reader
(``format="auto"``, the default; ``format="csv"`` or a format's name says which).

Reading also checks that the channels agree with each other: the speed from the positions must
match ``v`` (a track in yards beside m/s, in km, in ft/s is refused with the likely unit).

Examples
--------
>>> from bayesdrag import read_track            # doctest: +SKIP
>>> track = read_track("r1.csv")                # doctest: +SKIP
>>> track.names, track.n                        # doctest: +SKIP
(('x', 'y', 'z', 'v'), 1200)
"""
from __future__ import annotations

import io
import math
import os
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..track import (ALL_CHANNELS as CHANNELS, ANGLE_CHANNELS, FILE_UNITS, GUN_CHANNELS, NATIVE_CHANNELS,
                     RadarTrack)
from . import formats
from .csv import read_table

__all__ = ["read_track", "write_track", "channel_names", "ALIASES"]


# (median speed-from-positions / v, explanation) for the unit check
_UNIT_GUESSES = (
    (1.0 / 0.9144, "x, y, z look like yards (expected metres)"),
    (0.9144, "v looks like yd/s (expected m/s)"),
    (1e-3, "x, y, z look like kilometres (expected metres)"),
    (1.0 / 3.6, "v looks like km/h (expected m/s)"),
    (0.3048, "v looks like ft/s (expected m/s)"),
    (1.0 / 0.3048, "x, y, z look like feet (expected metres)"),
    (1e3, "x, y, z look like millimetres (expected metres), or v like km/s (expected m/s)"),
)
#: the unit check fires when the median ratio is off from 1 by more than this factor, or, with x
#: and z present (the speed from the positions is then the whole speed: the drift y is tiny), by
#: more than :data:`UNIT_REL_LIMIT` and :data:`UNIT_SIGNIFICANCE` of its standard errors. A
#: consistent track's ratio is 1 to ~0.1 %: chords of 0.5 s are shorter than the arc by
#: (curvature x length)^2 / 24 ~ 1e-6, a missing y channel hides < 0.1 % of the speed, and the
#: noise averages out in the median. Yards beside m/s give 0.914.
UNIT_RATIO_LIMIT = 3.0
UNIT_REL_LIMIT = 0.05
UNIT_SIGNIFICANCE = 5.0
#: fewest independent chords whose median's standard error the 5 % test trusts
MIN_INDEPENDENT_CHORDS = 3

#: header names read as a channel (matched ignoring case): unambiguous spellings of the time,
#: the positions and the ground speed. A bare ``velocity`` is read as ``v`` too, with a note:
#: a Doppler radar's velocity is its radial speed, the ground speed only along the line of
#: sight. ``range`` and ``range_m`` never are: a chronograph's distance is integrated from its
#: own velocity, not measured (``--columns x=range_m`` maps it when it is). An alias is not used
#: when its channel is already in the header (the column is then kept as an extra).
ALIASES = {"time": "t", "t_s": "t", "time_s": "t", "x_m": "x", "y_m": "y", "z_m": "z",
           "speed": "v", "v_mps": "v", "speed_mps": "v", "velocity": "v",
           "slant_range": "range", "slant_range_m": "range", "azimuth_deg": "azimuth", "az_deg": "azimuth",
           "elevation_deg": "elevation", "el_deg": "elevation", "range_rate_mps": "range_rate",
           "radial_velocity": "range_rate", "radial_speed": "range_rate"}
#: aliases read with a note
_NOTED = {"velocity": "a Doppler radar's 'velocity' is often its radial speed (the range rate), "
                      "the ground speed only along the line of sight; map it with --columns, or rename "
                      "it, only if it is the projectile's speed"}


def _speed_ratio(t, channels):
    """Median over the track of |chord velocity from positions| / mean v, or None."""
    pos = [c for c in ("x", "y", "z") if c in channels]
    v = channels.get("v")
    n = t.size
    if not pos or v is None or n < 2:
        return None, pos, None
    dt_med = float(np.median(np.diff(t)))
    # chords of ~0.5 s average the radar noise down (1 m noise -> ~3 m/s) and bend negligibly
    k = int(min(max(round(0.5 / dt_med), 1), max((n - 1) // 2, 1)))
    i0 = np.arange(n - k)
    i1 = i0 + k
    d2 = sum((channels[c][i1] - channels[c][i0]) ** 2 for c in pos)
    speed = np.sqrt(d2) / (t[i1] - t[i0])
    vm = 0.5 * (v[i0] + v[i1])
    ok = vm > 0
    if not ok.any():
        return None, pos, None
    q = speed[ok] / vm[ok]
    med = float(np.median(q))
    # standard error of the median from the MAD; chords overlap by k samples, so count only
    # non-overlapping ones as independent
    n_ind = max(q.size / k, 1.0)
    if n_ind < MIN_INDEPENDENT_CHORDS:
        # a median of one or two chords has no spread to measure its error by: the 5 % test
        # would fire on the noise of two samples 0.027 s apart ("v looks like yd/s")
        return med, pos, math.inf
    se = 1.2533 * 1.4826 * float(np.median(np.abs(q - med))) / math.sqrt(n_ind)
    return med, pos, se


def _check_units(path, t, channels):
    r, pos, se = _speed_ratio(t, channels)
    if r is None:
        return
    full = "x" in pos and "z" in pos  # drift y is small: x and z carry nearly all of |dr/dt|
    too_high = r > UNIT_RATIO_LIMIT
    # with missing components the position speed is legitimately below v; only x alone still bounds it
    low_limit = 1.0 / UNIT_RATIO_LIMIT if full else (0.01 if "x" in pos else 0.0)
    near = full and abs(r - 1.0) > UNIT_REL_LIMIT and abs(r - 1.0) > UNIT_SIGNIFICANCE * se
    if not (too_high or r < low_limit or near):
        return
    guess = min(_UNIT_GUESSES, key=lambda g: abs(math.log(max(r, 1e-300) / g[0])))
    if abs(math.log(max(r, 1e-300) / guess[0])) < math.log(1.3 if abs(math.log(guess[0])) > 0.5 else 1.03):
        why = guess[1]
        if guess[0] == 1e-3 and t[-1] - t[0] > 1000.0:
            why = "t looks like milliseconds (expected seconds), or " + why
        elif guess[0] == 1e-3:
            why += ", or t like milliseconds (expected seconds)"
    else:
        why = "check the units of x, y, z (m), v (m/s) and t (s), and that v is the total ground speed"
    raise InputError(f"{path}: units look wrong: the speed from the positions ({','.join(pos)}) is "
                     f"{r:.4g} times v (median over the track); {why}")


#: plausible values of each column of a track [SI]: beyond them a value is a unit or typing
#: mistake (the longest ranges are a few hundred km, the fastest guns a few km/s)
PLAUSIBLE = {"t": (-1e4, 1e5), "x": (-2e6, 2e6), "y": (-2e6, 2e6), "z": (-2e5, 2e5), "v": (-1e4, 1e4),
             "range": (0.0, 2e6), "azimuth": (-360.0, 720.0), "elevation": (-90.0, 90.0),
             "range_rate": (-1e4, 1e4)}
#: a gap is refused as a stray sample when it is longer than this many median sample intervals
#: and longer than the rest of the track lasts
STRAY_GAP_INTERVALS = 50
#: a track whose x falls by more than this [m] flies toward -x (noted; frames in docs/formats.md)
MIN_DOWNRANGE = 10.0


def _check_gap(path, t, line_no):
    """Refuse a sample far after (or before) the others: the fit would integrate the flight
    through the whole gap (a sample 1000 s after impact kept it busy for minutes and ended in a
    bare "not converged"). A dropout in the middle of a flight is shorter than the rest of it."""
    if t.size < 3:
        return
    dt = np.diff(t)
    i = int(np.argmax(dt))
    med = float(np.median(dt))
    rest = float(t[-1] - t[0] - dt[i])
    if dt[i] > STRAY_GAP_INTERVALS * med and dt[i] > rest:
        raise InputError(f"{path}: line {line_no[i + 1]}: t = {t[i + 1]:g} s comes {dt[i]:.4g} s after the previous "
                         f"sample, longer than the rest of the track lasts ({rest:.4g} s, samples {med:.3g} s apart): "
                         f"a stray sample (after impact?); drop it or split the track")


def channel_names(path, line, names, columns=None):
    """The header's names as the track reads them: ``columns`` (``{channel: header name}``, the
    ``--columns`` mapping) first, then :data:`ALIASES`; other names stay as they are.

    Returns
    -------
    (list of str, tuple of str)
        The names, and notes on what was read how.

    Raises
    ------
    InputError
        A mapping naming a column the header lacks or a channel the header already has, or two
        columns read as the same channel.
    """
    out, notes, src = list(names), [], {}
    for canon, col in (columns or {}).items():
        if col not in names:
            raise InputError(f"{path}: line {line}: --columns {canon}={col}: the track has no column {col!r}; "
                             f"header has {', '.join(names)}")
        if canon in names and canon != col:
            raise InputError(f"{path}: line {line}: --columns {canon}={col}: the header already has a column "
                             f"{canon!r}; drop or rename one of them")
        out[names.index(col)] = canon
        src[canon] = col
    for k, n in enumerate(names):
        if n in src.values() or n in ("t",) + CHANNELS:
            continue
        target = ALIASES.get(n.lower())
        if target is None or target in names or target in (columns or {}):
            continue                  # the channel's own column (or the mapped one) wins
        if target in src:
            raise InputError(f"{path}: line {line}: columns {src[target]!r} and {n!r} both read as {target}; "
                             f"keep one, or say which with --columns {target}=NAME")
        out[k], src[target] = target, n
        notes.append(f"{path}: column {n!r} read as {target} ({FILE_UNITS[target]})"
                     + (f"; {_NOTED[n.lower()]}" if n.lower() in _NOTED else ""))
    return out, tuple(notes)


def _track_header_check(path, line, names, columns=None):
    names = channel_names(path, line, names, columns)[0]
    if "t" not in names:
        lower = [n for n in names if n.lower() == "t"]
        hint = f" (column names are case-sensitive: found {lower[0]!r})" if lower else ""
        raise InputError(f"{path}: line {line}: track needs a time column 't' (or time, t_s) plus at least one "
                         f"of {', '.join(CHANNELS)}; header has {', '.join(names)}{hint}; or map a column with "
                         f"--columns t=NAME")
    if not any(c in names for c in CHANNELS):
        rng = [n for n in names if n.lower() in ("range", "range_m", "dist", "distance")]
        hint = (f"; {rng[0]!r} is not read as x: a chronograph's distance is integrated from its own velocity "
                f"(map it with --columns x={rng[0]} only if it is a measured downrange distance)" if rng else "")
        hint = hint or " (or an alias: speed, x_m, ...; or map a column with --columns v=NAME)"
        raise InputError(f"{path}: line {line}: track has 't' but none of the channels "
                         f"{', '.join(GUN_CHANNELS)}; header has {', '.join(names)}{hint}; a radar's own "
                         f"channels are {', '.join(NATIVE_CHANNELS)}")


def read_track(path: str | os.PathLike[str], *, quote: bool = True,
               columns: dict[str, str] | None = None, format: str = "auto") -> RadarTrack:
    """Read and validate a radar track: a track CSV, or a device's export (a LabRadar track).

    Parameters
    ----------
    path : str or os.PathLike
        CSV with header ``t`` plus at least one of ``x, y, z, v, range, azimuth, elevation,
        range_rate``; SI units (s, m, m/s), the angles in degrees (held in radians). Or a
        device's export in a format of :mod:`bayesdrag.io.formats` (``Shot0001 Track.csv``).
    quote : bool
        False for a track another file points to (a campaign's): a message never repeats the
        file's content (:func:`bayesdrag.io.csv.read_table`).
    columns : dict, optional
        ``{channel: header name}`` (``--columns t=time,v=velocity``): which column holds which
        of t, x, y, z, v; other names are read through :data:`ALIASES` (:func:`channel_names`).
        A track CSV's only: a device's export has its own columns.
    format : str
        ``"auto"`` (the default: the first few kB sniffed, :func:`bayesdrag.io.formats.detect`),
        ``"csv"`` (the track CSV described here), or a registered device format's name
        (``"labradar"``); :func:`bayesdrag.io.formats.names` lists them.

    Returns
    -------
    RadarTrack
        ``notes`` lists ignored extra columns, if any.

    Raises
    ------
    bayesdrag.errors.InputError
        Everything :func:`read_csv_columns` rejects, plus: no ``t`` or no channel, fewer than 2
        rows, time not strictly increasing (line that repeats or goes back), negative ``v``, and
        positions inconsistent with ``v``: the median ratio of the speed from chords of the
        positions to ``v`` off by more than 3x, or, with both ``x`` and ``z`` (the whole speed),
        by more than 5 % and 5 of its standard errors (yards beside m/s give 1.094); the message
        names the likely unit mistake (km, ft, ft/s, yd, yd/s, km/h, mm, ms). A track entirely in
        another unit is consistent here; the fit refuses it from the physics (its path bends as
        if gravity were 32.2 for feet). A ``v`` in ft/s alone (no positions) cannot be detected.
        An unknown ``format`` (the message lists the valid ones), ``columns`` with a device's
        export, and what a device format's reader refuses
        (:func:`bayesdrag.io.formats.labradar.read_labradar`).
    """
    fmt = formats.resolve(path, format)
    if fmt != formats.PLAIN:
        if columns:
            raise InputError(f"{path}: --columns maps the columns of a track CSV; this is a {fmt} export, whose "
                             f"columns its reader knows (drop --columns)")
        return formats.get(fmt, path).read(path, quote=quote)
    hline = []

    def check(p, line, names):
        hline.append(line)
        _track_header_check(p, line, names, columns)

    path, names, data, line_no = read_table(path, "track", header_check=check, quote=quote)
    names, alias_notes = channel_names(path, hline[0], names, columns)
    if data.shape[0] < 2:
        raise InputError(f"{path}: track has {data.shape[0]} data row; at least 2 are needed")
    cols = {n: np.ascontiguousarray(data[:, k]) for k, n in enumerate(names)}
    t = cols["t"]
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = bad[0] + 1
        how = ("repeats the previous row's time" if dt[bad[0]] == 0
               else f"goes back from {t[i - 1]:g} s on line {line_no[i - 1]}")
        raise InputError(f"{path}: line {line_no[i]}: t = {t[i]:g} s {how}; time must increase "
                         f"strictly (sort the rows, drop duplicates)")
    _check_gap(path, t, line_no)
    channels = {c: cols[c] for c in CHANNELS if c in cols}
    if "v" in channels and np.any(channels["v"] < 0):
        i = int(np.argmax(channels["v"] < 0))
        raise InputError(f"{path}: line {line_no[i]}: v = {channels['v'][i]:g} m/s is negative; v is the "
                         f"ground speed |dr/dt| >= 0 (a signed range rate belongs in an extra column)")
    _check_units(path, t, channels)      # names the unit mistake; values are within 1e15 (read_table)
    for c, a in [("t", t)] + list(channels.items()):
        lo, hi = PLAUSIBLE[c]
        bad = np.flatnonzero((a < lo) | (a > hi))
        if bad.size:
            i = bad[0]
            raise InputError(f"{path}: line {line_no[i]}: {c} = {a[i]:.6g} {FILE_UNITS[c]} is not plausible for a "
                             f"projectile's track (allowed {lo:g} .. {hi:g} {FILE_UNITS[c]}); check the units")
    for c in ANGLE_CHANNELS:        # degrees in the file, radians inside
        if c in channels:
            channels[c] = np.radians(channels[c])
    extra = {n: cols[n] for n in names if n != "t" and n not in CHANNELS}
    notes = alias_notes
    weighting = _sample_noise_columns(path, extra, channels, line_no)
    ignored = [n for n in extra if n not in weighting]
    if weighting:
        notes += (f"{path}: column(s) {', '.join(weighting)} give each sample's noise (docs/radar.md)",)
    if ignored:
        notes += (f"{path}: extra column(s) {', '.join(ignored)} kept but ignored by the fit",)
    if "x" in channels and channels["x"][-1] - channels["x"][0] < -MIN_DOWNRANGE:
        x = channels["x"]
        notes += (f"{path}: x goes from {x[0]:.6g} m to {x[-1]:.6g} m: the track flies toward -x, while x is "
                  f"the range downrange along the firing azimuth; the fit follows it (launch direction "
                  f"reversed), but Coriolis and winds use the round's azimuth: negate x if the radar's "
                  f"x axis points back at the gun",)
    return RadarTrack(t, channels, extra, str(path), notes)


def _sample_noise_columns(path, extra, channels, line_no):
    """Check the per-sample noise columns (``sigma_<channel>`` > 0 in the channel's file unit,
    turned into radians for the angles; ``snr`` in dB, finite) and return their names.

    Raises
    ------
    InputError
        A value that cannot be a noise sd or an SNR, naming its line.
    """
    used = []
    for n in list(extra):
        if n.startswith("sigma_") and n[6:] in CHANNELS:
            c = n[6:]
            if c not in channels:
                continue                   # a sd of a channel the track lacks: kept, ignored
            a = extra[n]
            bad = np.flatnonzero(~(np.isfinite(a) & (a > 0)))
            if bad.size:
                i = bad[0]
                raise InputError(f"{path}: line {line_no[i]}: {n} = {a[i]:g} {FILE_UNITS[c]}; a sample's noise sd must "
                                 f"be a positive number (leave the column out where it is not known)")
            extra[n] = np.radians(a) if c in ANGLE_CHANNELS else a
            used.append(n)
        elif n == "snr":
            a = extra[n]
            bad = np.flatnonzero(~np.isfinite(a) | (np.abs(a) > SNR_MAX_DB))
            if bad.size:
                i = bad[0]
                raise InputError(f"{path}: line {line_no[i]}: snr = {a[i]:g} dB; the echo's signal-to-noise ratio is "
                                 f"a finite number of dB within +-{SNR_MAX_DB:g}")
            used.append(n)
    return used


#: largest |SNR| a track may give [dB]: beyond it the column is not a radar's SNR in dB
SNR_MAX_DB = 200.0


def write_track(path: str | os.PathLike[str], track: RadarTrack, comment: str | None = None,
                extra: bool = True) -> None:
    """Write a track as CSV: ``t`` then the present channels (then extra columns).

    Precision: t with 6 decimals (1 us), x, y, z, v, range, range_rate with 4 decimals (0.1 mm,
    0.1 mm/s), azimuth and elevation in degrees with 7 decimals (2 nrad), extra columns with 10
    significant digits.

    Parameters
    ----------
    path : str or os.PathLike
    track : RadarTrack
    comment : str, optional
        Written first, each line prefixed by ``# ``.
    extra : bool
        Also write ``track.extra`` columns (default True; :func:`read_track` notes them).
    """
    names = ["t", *track.names]
    cols = [track.t, *(np.degrees(track.channels[k]) if k in ANGLE_CHANNELS else track.channels[k]
                       for k in track.names)]
    fmts = ["%.6f"] + ["%.7f" if k in ANGLE_CHANNELS else "%.4f" for k in track.names]
    if extra:
        for k, a in track.extra.items():
            names.append(k)
            cols.append(np.degrees(a) if k in [f"sigma_{c}" for c in ANGLE_CHANNELS] else a)   # degrees in files
            fmts.append("%.10g")
    buf = io.StringIO()
    if comment:
        for ln in str(comment).splitlines() or [""]:
            buf.write(f"# {ln}".rstrip() + "\n")
    buf.write(",".join(names) + "\n")
    if track.n:
        np.savetxt(buf, np.column_stack(cols), fmt=fmts, delimiter=",")
    Path(path).write_text(buf.getvalue(), encoding="utf-8")
