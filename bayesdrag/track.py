"""Radar tracks and round descriptions: reading, validation, writing.

Two file kinds are defined in DESIGN.md ("Files"):

track (CSV)
    ``#`` comment lines, a header row naming ``t`` plus at least one of ``x, y, z, v``, then one
    row of numbers per radar sample. SI units: t [s], x, y, z [m], v [m/s]. Extra columns (SNR,
    range rate, ...) are kept in :attr:`RadarTrack.extra`, ignored by the fit, and reported by a
    one-line entry in :attr:`RadarTrack.notes` (the CLI prints the notes; nothing is sent through
    :mod:`warnings`).
round (TOML)
    ``[projectile]``, ``[launch]``, ``[atmosphere]`` and ``[radar]`` sections; see
    :func:`read_round`.

Every validation failure raises :class:`bayesdrag.errors.InputError` with a one-line message that
names the file, the line (file line numbers are 1-based and count comments and the header) or the
TOML key, what was found and what is allowed.

Examples
--------
>>> track = read_track("r1.csv")                     # doctest: +SKIP
>>> track.names, track.n                             # doctest: +SKIP
(('x', 'y', 'z', 'v'), 1200)
>>> rnd = read_round("r1.toml")                      # doctest: +SKIP
>>> rnd.projectile.diameter, rnd.launch.velocity_sd  # doctest: +SKIP
(0.155, 5.0)
"""
from __future__ import annotations

import difflib
import io
import math
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import tomli_w

from .atmosphere import Atmosphere, MetProfile, write_met_profile
from .errors import InputError

if TYPE_CHECKING:  # pragma: no cover
    from .drag import ReferenceTable

__all__ = [
    "CHANNELS", "read_csv_columns", "RadarTrack", "read_track", "write_track",
    "Projectile", "Launch", "Radar", "Round", "read_round", "write_round",
    "DEFAULT_VELOCITY_SD", "DEFAULT_ELEVATION_SD_DEG", "DEFAULT_POSITION_SD",
]

#: measured channels of a track, in canonical order; SI units m, m, m, m/s
CHANNELS = ("x", "y", "z", "v")
_UNITS = {"t": "s", "x": "m", "y": "m", "z": "m", "v": "m/s"}

#: default a-priori sd of the launch velocity [m/s]: round-to-round muzzle-velocity dispersion of
#: a lot is ~0.3-0.5 % (2.5-4 m/s at 800 m/s); 5 m/s also absorbs a nominal value taken from the
#: firing table rather than measured, while staying far looser than what a track determines.
DEFAULT_VELOCITY_SD = 5.0
#: default a-priori sd of the launch elevation [deg]: laying error (~1 mil = 0.056 deg) plus
#: vertical jump (typically 0.5-2 mil) gives ~0.1 deg; 0.2 deg (3.5 mil) is deliberately loose.
DEFAULT_ELEVATION_SD_DEG = 0.2
#: default a-priori sd of the muzzle position at t = 0 per axis [m]: survey of radar vs muzzle and
#: the offset of the muzzle from the trunnion are decimetres; 1 m is loose.
DEFAULT_POSITION_SD = 1.0

#: plausible ranges checked when a round is built (SI / degrees as noted)
MASS_MAX = 10000.0              # kg
DIAMETER_RANGE = (0.004, 1.0)   # m
ELEVATION_RANGE_DEG = (-10.0, 90.0)  # open interval
VELOCITY_MAX = 3000.0           # m/s
ALTITUDE_RANGE = (-1000.0, 10000.0)  # m above sea level of the gun


# ------------------------------------------------------------------------------------------
# CSV
# ------------------------------------------------------------------------------------------
def _read_text(path: Path, what: str) -> str:
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"{path}: {what} not found") from None
    except IsADirectoryError:
        raise InputError(f"{path}: {what} expected, found a directory") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read {what}: {exc.strerror or exc}") from None
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise InputError(f"{path}: {what} is UTF-16 encoded; save it as UTF-8 (or ASCII) text")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise InputError(f"{path}: {what} is not UTF-8 text: undecodable byte 0x{raw[exc.start]:02x} "
                         f"at line {line} (binary file?); expected a CSV text file") from None
    if "\x00" in text:
        line = text[:text.index("\x00")].count("\n") + 1
        raise InputError(f"{path}: {what} contains NUL bytes at line {line} (binary file?); "
                         f"expected a CSV text file")
    return text


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def _clean_name(s: str) -> str:
    s = s.strip()
    if len(s) >= 2 and s[0] == s[-1] and s[0] in "\"'":
        s = s[1:-1].strip()
    return s


def _read_table(path, what, required=(), allowed=None, header_check=None):
    """Parse a strict numeric CSV. Returns (path, names, data (N, K), line numbers (N,))."""
    path = Path(path)
    text = _read_text(path, what)
    if not text.strip():
        raise InputError(f"{path}: {what} is empty; expected a header row and rows of numbers")
    lines = text.splitlines()
    rows = [(i, ln) for i, ln in enumerate(lines, 1) if ln.strip() and not ln.lstrip().startswith("#")]
    if not rows:
        raise InputError(f"{path}: {what} has only comments; expected a header row and rows of numbers")

    hline, header = rows[0]
    names = [_clean_name(s) for s in header.split(",")]
    if all(_is_number(s) for s in names):
        raise InputError(f"{path}: line {hline}: {what} has no header row; found numbers "
                         f"{header.strip()[:40]!r}, expected column names"
                         + (f" ({','.join(required)})" if required else ""))
    if len(names) == 1 and (";" in header or "\t" in header):
        sep = "';'" if ";" in header else "tab"
        raise InputError(f"{path}: line {hline}: columns are separated by {sep}; "
                         f"the {what} must be comma-separated")
    for k, n in enumerate(names):
        if not n:
            raise InputError(f"{path}: line {hline}: empty column name in header (column {k + 1} "
                             f"of {len(names)}); found {header.strip()!r}")
    seen = set()
    for n in names:
        if n in seen:
            raise InputError(f"{path}: line {hline}: duplicate column name {n!r} in header "
                             f"{header.strip()!r}; each column may appear once")
        seen.add(n)
    missing = [r for r in required if r not in seen]
    if missing:
        hint = ""
        lower = {n.lower(): n for n in names}
        near = [f"{lower[m.lower()]!r}" for m in missing if m.lower() in lower]
        if near:
            hint = f" (column names are case-sensitive: found {', '.join(near)})"
        raise InputError(f"{path}: line {hline}: {what} needs column(s) {', '.join(required)}; "
                         f"missing {', '.join(missing)}; header has {', '.join(names)}{hint}")
    if allowed is not None:
        bad = [n for n in names if n not in allowed]
        if bad:
            raise InputError(f"{path}: line {hline}: unknown column(s) {', '.join(bad)} in {what}; "
                             f"allowed: {', '.join(allowed)}")
    if header_check is not None:
        header_check(path, hline, names)

    body = rows[1:]
    if not body:
        raise InputError(f"{path}: {what} has a header (line {hline}) but no data rows")
    ncol = len(names)
    data_lines = [ln for _, ln in body]
    try:  # fast path (C parser); any problem is located precisely by the slow path below
        data = np.loadtxt(data_lines, delimiter=",", ndmin=2, comments=None, dtype=float)
        if data.shape[1] != ncol:
            raise ValueError
    except ValueError:
        data = _slow_parse(path, body, names)
    line_no = np.fromiter((i for i, _ in body), dtype=np.int64, count=len(body))
    finite = np.isfinite(data)
    if not finite.all():
        r, c = np.argwhere(~finite)[0]
        field_text = body[r][1].split(",")[c].strip()
        raise InputError(f"{path}: line {line_no[r]}, column {names[c]!r}: {field_text!r} is not a "
                         f"finite number; NaN and infinity are not allowed (drop the row instead)")
    return path, names, data, line_no


def _slow_parse(path, body, names):
    ncol = len(names)
    out = np.empty((len(body), ncol))
    for r, (i, ln) in enumerate(body):
        fields = ln.split(",")
        if len(fields) != ncol:
            raise InputError(f"{path}: line {i}: {len(fields)} fields, but the header has {ncol} "
                             f"({','.join(names)})")
        for c, f in enumerate(fields):
            try:
                out[r, c] = float(f)
            except ValueError:
                what = "empty field" if not f.strip() else f"{f.strip()!r} is not a number"
                raise InputError(f"{path}: line {i}, column {names[c]!r}: {what}; "
                                 f"expected a decimal number like 12.5 or 1.25e3") from None
    return out


def read_csv_columns(path, required=(), what="CSV file", allowed=None):
    """Read a numeric CSV file into columns.

    Format: lines starting with ``#`` (and blank lines) are skipped anywhere; the first other
    line is a comma-separated header of column names; every following line holds one finite
    decimal number per column.

    Parameters
    ----------
    path : str or os.PathLike
    required : sequence of str
        Column names that must be present (case-sensitive).
    what : str
        Name of the file's role in messages, e.g. ``"drag table"``.
    allowed : sequence of str, optional
        If given, every column must be one of these.

    Returns
    -------
    dict of str -> ndarray, shape (N,)
        Float columns in header order, N >= 1.

    Raises
    ------
    bayesdrag.errors.InputError
        Missing/unreadable/binary file, no header, duplicate or missing columns, ragged rows,
        non-numeric or non-finite values, no data rows. Line numbers in messages are file
        lines, 1-based.
    """
    _, names, data, _ = _read_table(path, what, tuple(required),
                                    None if allowed is None else tuple(allowed))
    return {n: np.ascontiguousarray(data[:, k]) for k, n in enumerate(names)}


# ------------------------------------------------------------------------------------------
# tracks
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class RadarTrack:
    """A radar track: time and measured channels, SI units.

    Attributes
    ----------
    t : ndarray, shape (N,), s
        Sample times since launch, strictly increasing.
    channels : dict of str -> ndarray (N,)
        A non-empty subset of ``x, y, z`` [m] and ``v`` [m/s], stored in :data:`CHANNELS` order.
    extra : dict of str -> ndarray (N,)
        Further columns of the file, kept but ignored by the fit.
    source : str
        File path or description.
    notes : tuple of str
        One-line remarks found while reading (e.g. ignored extra columns), for the CLI to print.

    Construction checks shapes and the time axis and raises ``ValueError``; :func:`read_track`
    performs the same checks first and raises :class:`~bayesdrag.errors.InputError` with line
    numbers.
    """

    t: np.ndarray
    channels: dict
    extra: dict = field(default_factory=dict)
    source: str = ""
    notes: tuple = ()

    def __post_init__(self):
        src = self.source or "track"
        t = np.array(self.t, dtype=float).reshape(-1) if np.ndim(self.t) <= 1 else None
        if t is None:
            raise ValueError(f"{src}: t must be 1-D, got shape {np.shape(self.t)}")
        if not np.all(np.isfinite(t)):
            raise ValueError(f"{src}: t contains non-finite values")
        if t.size > 1 and np.any(np.diff(t) <= 0):
            i = int(np.argmax(np.diff(t) <= 0)) + 1
            raise ValueError(f"{src}: t must increase strictly; sample {i} has t = {t[i]} after {t[i - 1]}")
        unknown = [k for k in self.channels if k not in CHANNELS]
        if unknown:
            raise ValueError(f"{src}: unknown channel(s) {', '.join(map(str, unknown))}; "
                             f"allowed: {', '.join(CHANNELS)}")
        if not self.channels:
            raise ValueError(f"{src}: a track needs at least one of the channels {', '.join(CHANNELS)}")
        ch = {}
        for k in CHANNELS:
            if k in self.channels:
                ch[k] = self._column(k, self.channels[k], t.size, src)
                if not np.all(np.isfinite(ch[k])):
                    raise ValueError(f"{src}: channel {k} contains non-finite values")
        clash = [k for k in self.extra if k in CHANNELS or k == "t"]
        if clash:
            raise ValueError(f"{src}: extra columns may not be named like channels: {', '.join(clash)}")
        ex = {str(k): self._column(k, a, t.size, src) for k, a in self.extra.items()}
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "channels", ch)
        object.__setattr__(self, "extra", ex)
        object.__setattr__(self, "source", str(self.source))
        object.__setattr__(self, "notes", tuple(str(s) for s in self.notes))

    @staticmethod
    def _column(name, a, n, src):
        a = np.array(a, dtype=float)
        if a.shape != (n,):
            raise ValueError(f"{src}: column {name} has shape {a.shape}, expected ({n},) like t")
        return a

    def _get(self, k):
        return self.channels.get(k)

    x = property(lambda self: self._get("x"), doc="Downrange position [m], shape (N,), or None.")
    y = property(lambda self: self._get("y"), doc="Cross-range position [m], shape (N,), or None.")
    z = property(lambda self: self._get("z"), doc="Height above the muzzle [m], shape (N,), or None.")
    v = property(lambda self: self._get("v"), doc="Ground speed [m/s], shape (N,), or None.")

    @property
    def names(self):
        """Present channels, in :data:`CHANNELS` order (tuple of str)."""
        return tuple(k for k in CHANNELS if k in self.channels)

    @property
    def n(self):
        """Number of samples N."""
        return int(self.t.size)

    def __len__(self):
        return self.n

    def __repr__(self):
        span = f", t in [{self.t[0]:.3f}, {self.t[-1]:.3f}] s" if self.n else ""
        return (f"RadarTrack(n={self.n}, channels={self.names}{span}, extra={tuple(self.extra)}, "
                f"source={self.source!r})")

    def subset(self, index):
        """Samples selected by a boolean mask (N,), a slice or an increasing integer index array.

        Returns
        -------
        RadarTrack
            Same channels, extras, source and notes.
        """
        if isinstance(index, slice):
            idx = index
        else:
            idx = np.asarray(index)
            if idx.dtype == bool:
                if idx.shape != self.t.shape:
                    raise ValueError(f"mask has shape {idx.shape}, expected {self.t.shape}")
            elif not np.issubdtype(idx.dtype, np.integer):
                raise TypeError(f"subset takes a boolean mask, a slice or integer indices, got {idx.dtype}")
        return RadarTrack(self.t[idx], {k: a[idx] for k, a in self.channels.items()},
                          {k: a[idx] for k, a in self.extra.items()}, self.source, self.notes)

    def with_channels(self, names):
        """Copy keeping only channels ``names`` (each must be present); extras are kept."""
        names = (names,) if isinstance(names, str) else tuple(names)
        missing = [k for k in names if k not in self.channels]
        if missing:
            raise ValueError(f"{self.source or 'track'}: channel(s) {', '.join(missing)} not in the "
                             f"track; present: {', '.join(self.names)}")
        return RadarTrack(self.t, {k: self.channels[k] for k in names}, self.extra, self.source, self.notes)


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


def _track_header_check(path, line, names):
    if "t" not in names:
        lower = [n for n in names if n.lower() == "t"]
        hint = f" (column names are case-sensitive: found {lower[0]!r})" if lower else ""
        raise InputError(f"{path}: line {line}: track needs a time column 't' plus at least one of "
                         f"{', '.join(CHANNELS)}; header has {', '.join(names)}{hint}")
    if not any(c in names for c in CHANNELS):
        raise InputError(f"{path}: line {line}: track has 't' but none of the channels "
                         f"{', '.join(CHANNELS)}; header has {', '.join(names)}")


def read_track(path):
    """Read and validate a radar track CSV (DESIGN.md "Files").

    Parameters
    ----------
    path : str or os.PathLike
        CSV with header ``t`` plus at least one of ``x, y, z, v``; SI units (s, m, m/s).

    Returns
    -------
    RadarTrack
        ``notes`` lists ignored extra columns, if any.

    Raises
    ------
    bayesdrag.errors.InputError
        Everything :func:`read_csv_columns` rejects, plus: no ``t`` or no channel, fewer than 2
        rows, time not strictly increasing (line that repeats or goes back), negative ``v``, and
        positions clearly inconsistent with ``v`` (median ratio of the speed from finite
        differences of the positions to ``v`` off by more than 3x; the message names the likely
        unit mistake: km, ft, ft/s, km/h, mm, ms). A ``v`` in ft/s alone (no positions) cannot be
        detected and is not checked.
    """
    path, names, data, line_no = _read_table(path, "track", header_check=_track_header_check)
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
    channels = {c: cols[c] for c in CHANNELS if c in cols}
    if "v" in channels and np.any(channels["v"] < 0):
        i = int(np.argmax(channels["v"] < 0))
        raise InputError(f"{path}: line {line_no[i]}: v = {channels['v'][i]:g} m/s is negative; v is the "
                         f"ground speed |dr/dt| >= 0 (a signed range rate belongs in an extra column)")
    _check_units(path, t, channels)
    extra = {n: cols[n] for n in names if n != "t" and n not in CHANNELS}
    notes = ()
    if extra:
        notes = (f"{path}: extra column(s) {', '.join(extra)} kept but ignored by the fit",)
    return RadarTrack(t, channels, extra, str(path), notes)


def write_track(path, track, comment=None, extra=True):
    """Write a track as CSV: ``t`` then the present channels (then extra columns).

    Precision: t with 6 decimals (1 us), x, y, z, v with 4 decimals (0.1 mm, 0.1 mm/s), extra
    columns with 10 significant digits.

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
    cols = [track.t, *(track.channels[k] for k in track.names)]
    fmts = ["%.6f"] + ["%.4f"] * len(track.names)
    if extra:
        for k, a in track.extra.items():
            names.append(k)
            cols.append(a)
            fmts.append("%.10g")
    buf = io.StringIO()
    if comment:
        for ln in str(comment).splitlines() or [""]:
            buf.write(f"# {ln}".rstrip() + "\n")
    buf.write(",".join(names) + "\n")
    if track.n:
        np.savetxt(buf, np.column_stack(cols), fmt=fmts, delimiter=",")
    Path(path).write_text(buf.getvalue(), encoding="utf-8")


# ------------------------------------------------------------------------------------------
# rounds
# ------------------------------------------------------------------------------------------
def _type_name(value):
    if isinstance(value, bool):
        return f"boolean {str(value).lower()}"
    if isinstance(value, str):
        return f"string {value!r}"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return "an array"
    return f"{type(value).__name__} {value!r}"


def _number(key, value, unit="", optional=False):
    """``value`` as a finite float, or ValueError naming ``key`` (bools are not numbers)."""
    if value is None and optional:
        return None
    u = f" ({unit})" if unit else ""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{key} must be a number{u}, got {_type_name(value)}")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{key} must be a finite number{u}, got {value}")
    return value


def _positive(key, value, unit):
    value = _number(key, value, unit)
    if value <= 0:
        raise ValueError(f"{key} = {value:g} must be > 0 ({unit})")
    return value


@dataclass(frozen=True, eq=False)
class Projectile:
    """The shell.

    Attributes
    ----------
    name : str
    mass : float, kg
        In (0, 10000].
    diameter : float, m
        Reference diameter (area pi d^2/4), in [0.004, 1.0].
    reference_drag : ReferenceTable or None
        Firing-table Cd(M), if known.
    reference_drag_path : str or None
        Where ``reference_drag`` was read from (as resolved from the round file).
    reference_extrapolate : bool
        The round allows the flight to go beyond the table's Mach range (Cd held at the end
        values); see :func:`read_round`.
    """

    name: str = ""
    mass: float = None
    diameter: float = None
    reference_drag: "ReferenceTable | None" = field(default=None, repr=False)
    reference_drag_path: str | None = None
    reference_extrapolate: bool = False

    def __post_init__(self):
        if not isinstance(self.name, str):
            raise ValueError(f"name must be a string, got {_type_name(self.name)}")
        mass = _number("mass", self.mass, "kg")
        if not 0.0 < mass <= MASS_MAX:
            raise ValueError(f"mass = {mass:g} kg is outside (0, {MASS_MAX:g}] kg")
        d = _number("diameter", self.diameter, "m")
        lo, hi = DIAMETER_RANGE
        if not lo <= d <= hi:
            if lo * 1000 <= d <= hi * 1000:
                raise ValueError(f"diameter = {d:g} looks like millimetres; diameter is in metres "
                                 f"({d / 1000:g}); allowed [{lo:g}, {hi:g}] m")
            raise ValueError(f"diameter = {d:g} m is outside the plausible range [{lo:g}, {hi:g}] m")
        object.__setattr__(self, "mass", mass)
        object.__setattr__(self, "diameter", d)
        if self.reference_drag_path is not None:
            object.__setattr__(self, "reference_drag_path", str(self.reference_drag_path))

    @property
    def area(self):
        """Reference area pi d^2 / 4 [m^2]."""
        return math.pi * self.diameter ** 2 / 4.0


@dataclass(frozen=True, eq=False)
class Launch:
    """Launch conditions: initial guesses, priors, simulator input, Coriolis geometry.

    Messages name the TOML keys (``elevation`` for ``elevation_deg`` etc.).

    Attributes
    ----------
    elevation_deg : float or None, deg
        Quadrant elevation, in (-10, 90). None: unknown (estimated from the track).
    velocity : float or None, m/s
        Launch (muzzle) velocity, in (0, 3000]. None: unknown.
    azimuth_deg : float, deg
        Firing azimuth clockwise from true north, normalised to [0, 360). Default 0 (north): it
        only matters for Coriolis, which also needs ``latitude_deg``.
    latitude_deg : float or None, deg
        Latitude of the gun, north positive, in [-90, 90]. None: unknown (no Coriolis geometry).
    altitude : float, m
        Gun altitude above mean sea level, in [-1000, 10000]; default 0.
    velocity_sd : float, m/s
        A-priori sd of ``velocity``; default :data:`DEFAULT_VELOCITY_SD` = 5 m/s (lot dispersion
        0.3-0.5 % plus a firing-table nominal value).
    elevation_sd_deg : float, deg
        A-priori sd of ``elevation_deg``; default :data:`DEFAULT_ELEVATION_SD_DEG` = 0.2 deg
        (laying error plus jump).
    position_sd : float, m
        A-priori sd of the muzzle position at t = 0, per axis; default
        :data:`DEFAULT_POSITION_SD` = 1 m (radar/muzzle survey).
    """

    elevation_deg: float | None = None
    velocity: float | None = None
    azimuth_deg: float = 0.0
    latitude_deg: float | None = None
    altitude: float = 0.0
    velocity_sd: float = DEFAULT_VELOCITY_SD
    elevation_sd_deg: float = DEFAULT_ELEVATION_SD_DEG
    position_sd: float = DEFAULT_POSITION_SD

    def __post_init__(self):
        el = _number("elevation", self.elevation_deg, "deg", optional=True)
        lo, hi = ELEVATION_RANGE_DEG
        if el is not None and not lo < el < hi:
            raise ValueError(f"elevation = {el:g} deg is outside ({lo:g}, {hi:g}) deg")
        vel = _number("velocity", self.velocity, "m/s", optional=True)
        if vel is not None and not 0.0 < vel <= VELOCITY_MAX:
            raise ValueError(f"velocity = {vel:g} m/s is outside (0, {VELOCITY_MAX:g}] m/s")
        az = _number("azimuth", self.azimuth_deg, "deg") % 360.0
        lat = _number("latitude", self.latitude_deg, "deg", optional=True)
        if lat is not None and not -90.0 <= lat <= 90.0:
            raise ValueError(f"latitude = {lat:g} deg is outside [-90, 90] deg")
        alt = _number("altitude", self.altitude, "m")
        if not ALTITUDE_RANGE[0] <= alt <= ALTITUDE_RANGE[1]:
            raise ValueError(f"altitude = {alt:g} m is outside [{ALTITUDE_RANGE[0]:g}, "
                             f"{ALTITUDE_RANGE[1]:g}] m above sea level")
        values = dict(elevation_deg=el, velocity=vel, azimuth_deg=az, latitude_deg=lat, altitude=alt,
                      velocity_sd=_positive("velocity_sd", self.velocity_sd, "m/s"),
                      elevation_sd_deg=_positive("elevation_sd", self.elevation_sd_deg, "deg"),
                      position_sd=_positive("position_sd", self.position_sd, "m"))
        for k, v in values.items():
            object.__setattr__(self, k, v)

    @property
    def elevation(self):
        """Elevation [rad], or None."""
        return None if self.elevation_deg is None else math.radians(self.elevation_deg)

    @property
    def elevation_sd(self):
        """Elevation sd [rad]."""
        return math.radians(self.elevation_sd_deg)

    @property
    def azimuth(self):
        """Azimuth [rad] clockwise from true north."""
        return math.radians(self.azimuth_deg)

    @property
    def latitude(self):
        """Latitude [rad], or None."""
        return None if self.latitude_deg is None else math.radians(self.latitude_deg)


@dataclass(frozen=True, eq=False)
class Radar:
    """A-priori radar noise.

    Attributes
    ----------
    sigma : dict of str -> float
        Noise sd per channel (keys among ``x, y, z`` [m] and ``v`` [m/s]), each > 0; may be
        empty (then the fit estimates the noise).
    """

    sigma: dict = field(default_factory=dict)

    def __post_init__(self):
        if not isinstance(self.sigma, dict):
            raise ValueError(f"sigma must be a table like {{x = 1.0, v = 0.3}}, got {_type_name(self.sigma)}")
        bad = [k for k in self.sigma if k not in CHANNELS]
        if bad:
            raise ValueError(f"sigma has unknown channel(s) {', '.join(map(str, bad))}; "
                             f"allowed: {', '.join(CHANNELS)}")
        sig = {k: _positive(f"sigma.{k}", self.sigma[k], _UNITS[k]) for k in CHANNELS if k in self.sigma}
        object.__setattr__(self, "sigma", sig)


@dataclass(frozen=True, eq=False)
class Round:
    """Everything known about one firing besides the track.

    Attributes
    ----------
    projectile : Projectile
    launch : Launch
    atmosphere : Atmosphere or MetProfile
        ``gun_altitude`` equals ``launch.altitude`` (built so by :func:`read_round`, and by
        default when None is passed).
    radar : Radar
    path : str
        The round file, or "".
    """

    projectile: Projectile
    launch: Launch = field(default_factory=Launch)
    atmosphere: Atmosphere = None
    radar: Radar = field(default_factory=Radar)
    path: str = ""

    def __post_init__(self):
        if self.atmosphere is None:
            object.__setattr__(self, "atmosphere", Atmosphere(gun_altitude=self.launch.altitude))
        object.__setattr__(self, "path", str(self.path))

    @property
    def reference_drag(self):
        """The projectile's firing-table drag (``ReferenceTable``) or None."""
        return self.projectile.reference_drag


_SCHEMA = {
    "projectile": {"name": "text", "mass": "kg", "diameter": "m", "reference_drag": "CSV path",
                   "reference_extrapolate": "boolean"},
    "launch": {"elevation": "deg", "velocity": "m/s", "azimuth": "deg", "latitude": "deg",
               "altitude": "m", "velocity_sd": "m/s", "elevation_sd": "deg", "position_sd": "m"},
    "atmosphere": {"model": "text", "profile": "CSV path", "temperature_offset": "K",
                   "pressure_ratio": "-", "density_ratio": "-"},
    "radar": {"sigma": "table"},
}
ATMOSPHERE_MODELS = ("icao", "profile")
#: how far [Mach] the launch Mach may exceed the reference table's last row before the round is
#: rejected (unless ``reference_extrapolate = true``): beyond its end the table is held constant,
#: and a supersonic Cd changes ~2-4 % per 0.1 Mach, so a 0.05 overshoot costs at most ~2 %
REFERENCE_MACH_SLACK = 0.05


def _unknown(path, what, key, allowed):
    near = difflib.get_close_matches(key, allowed, n=1, cutoff=0.6)
    hint = f" (did you mean {near[0]!r}?)" if near else ""
    return InputError(f"{path}: unknown {what} {key!r}{hint}; allowed: {', '.join(allowed)}")


def read_round(path):
    """Read and validate a round TOML file (DESIGN.md "Files").

    Sections and keys (units in brackets; all but ``[projectile] mass`` and ``diameter``
    optional):

    - ``[projectile]`` name, mass [kg], diameter [m], reference_drag (CSV ``mach,cd``, path
      relative to the TOML file, read with :func:`bayesdrag.drag.read_drag_table`)
      and reference_extrapolate (boolean, default false: the table must reach the launch Mach,
      ``velocity`` over the speed of sound at the gun, to within :data:`REFERENCE_MACH_SLACK`;
      true holds Cd at the table's last value beyond it, e.g. for a published curve that
      stops short of the muzzle Mach)
    - ``[launch]`` elevation [deg], velocity [m/s], azimuth [deg, default 0], latitude [deg],
      altitude [m, default 0], velocity_sd [m/s, default 5], elevation_sd [deg, default 0.2],
      position_sd [m, default 1]
    - ``[atmosphere]`` model (``"icao"``, default, or ``"profile"``), profile (CSV met
      profile ``altitude,temperature,pressure[,wind_x,wind_y]``, path relative to the TOML file,
      read with :func:`bayesdrag.atmosphere.read_met_profile`; giving it implies
      ``model = "profile"``, and ``model = "icao"`` with a profile is a contradiction),
      temperature_offset [K], pressure_ratio, density_ratio (applied on top of a profile too)
    - ``[radar]`` sigma = {x, y, z [m], v [m/s]}

    A missing ``name`` defaults to the file's stem.

    Returns
    -------
    Round

    Raises
    ------
    bayesdrag.errors.InputError
        Missing/unreadable file, invalid TOML (with line and column), unknown section or key
        (allowed ones listed, close matches suggested), wrong types (booleans are not numbers),
        missing ``[projectile]`` mass or diameter, implausible values (mass, diameter -- with a
        millimetre hint --, elevation, velocity, latitude, sd values, sigma, atmosphere), and a
        missing or malformed reference drag table (naming the key and the CSV file).
    """
    path = Path(path)
    text = _read_text(path, "round file")
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML: {exc}") from None

    for sec, tab in doc.items():
        if sec not in _SCHEMA:
            what = "section" if isinstance(tab, dict) else "top-level key"
            raise _unknown(path, what, sec, tuple(_SCHEMA))
    tables = {}
    for sec, keys in _SCHEMA.items():
        tab = doc.get(sec, {})
        if not isinstance(tab, dict):
            raise InputError(f"{path}: {sec} must be a section [{sec}], got {_type_name(tab)}")
        for k in tab:
            if k not in keys:
                raise _unknown(path, f"key in [{sec}]", k, tuple(keys))
        tables[sec] = tab

    def build(sec, fn):
        try:
            return fn()
        except InputError:
            raise
        except ValueError as exc:
            raise InputError(f"{path}: [{sec}] {exc}") from None

    pt = tables["projectile"]
    if "projectile" not in doc:
        raise InputError(f"{path}: missing section [projectile]; it needs mass (kg) and diameter (m)")
    for k, unit in (("mass", "kg"), ("diameter", "m")):
        if k not in pt:
            raise InputError(f"{path}: [projectile] missing key {k} ({unit})")

    ref, ref_path = None, None
    if "reference_drag" in pt:
        rel = pt["reference_drag"]
        if not isinstance(rel, str) or not rel.strip():
            raise InputError(f"{path}: [projectile] reference_drag must be a CSV file path (string), "
                             f"got {_type_name(rel)}")
        ref_path = Path(os.path.normpath(path.parent / rel))
        from .drag import read_drag_table

        try:
            ref = read_drag_table(ref_path)
        except InputError as exc:
            raise InputError(f"{path}: [projectile] reference_drag = {rel!r}: {exc}") from None
    projectile = build("projectile", lambda: Projectile(
        pt.get("name", path.stem), pt["mass"], pt["diameter"], ref,
        None if ref_path is None else str(ref_path), pt.get("reference_extrapolate", False) is True))

    lt = tables["launch"]
    launch = build("launch", lambda: Launch(
        lt.get("elevation"), lt.get("velocity"), lt.get("azimuth", 0.0), lt.get("latitude"),
        lt.get("altitude", 0.0), lt.get("velocity_sd", DEFAULT_VELOCITY_SD),
        lt.get("elevation_sd", DEFAULT_ELEVATION_SD_DEG), lt.get("position_sd", DEFAULT_POSITION_SD)))

    at = tables["atmosphere"]
    model = at.get("model", "profile" if "profile" in at else "icao")
    if not isinstance(model, str) or model.lower() not in ATMOSPHERE_MODELS:
        raise InputError(f"{path}: [atmosphere] model = {model!r} is not supported; allowed: "
                         f"{', '.join(repr(m) for m in ATMOSPHERE_MODELS)}")
    model = model.lower()
    if model == "profile" and "profile" not in at:
        raise InputError(f"{path}: [atmosphere] model = 'profile' needs profile = \"met.csv\" "
                         f"(CSV altitude,temperature,pressure[,wind_x,wind_y])")
    if model == "icao" and "profile" in at:
        raise InputError(f"{path}: [atmosphere] model = 'icao' contradicts profile = {at['profile']!r}; "
                         f"use model = 'profile' (or leave model out) to fly through the profile, "
                         f"or drop profile for the standard atmosphere")

    def make_atmosphere():
        vals = {k: _number(k, at.get(k, d), _SCHEMA["atmosphere"][k])
                for k, d in (("temperature_offset", 0.0), ("pressure_ratio", 1.0), ("density_ratio", 1.0))}
        if model == "profile":
            rel = at["profile"]
            if not isinstance(rel, str) or not rel.strip():
                raise InputError(f"{path}: [atmosphere] profile must be a CSV file path (string), "
                                 f"got {_type_name(rel)}")
            from .atmosphere import read_met_profile

            prof_path = Path(os.path.normpath(path.parent / rel))
            try:
                return read_met_profile(prof_path, gun_altitude=launch.altitude, **vals)
            except InputError as exc:
                raise InputError(f"{path}: [atmosphere] profile = {rel!r}: {exc}") from None
        return Atmosphere(**vals, gun_altitude=launch.altitude)

    atmosphere = build("atmosphere", make_atmosphere)
    extrapolate = pt.get("reference_extrapolate", False)
    if not isinstance(extrapolate, bool):
        raise InputError(f"{path}: [projectile] reference_extrapolate must be true or false, got "
                         f"{_type_name(extrapolate)}")
    if ref is not None and launch.velocity is not None and not extrapolate:
        a_gun = float(atmosphere.at_height(0.0).speed_of_sound)
        m_launch = launch.velocity / a_gun
        if m_launch > ref.mach[-1] + REFERENCE_MACH_SLACK:
            raise InputError(
                f"{path}: [projectile] reference_drag = {pt['reference_drag']!r} covers Mach "
                f"{ref.mach[0]:g}-{ref.mach[-1]:g} but the launch (velocity = {launch.velocity:g} m/s, "
                f"speed of sound {a_gun:.1f} m/s) is Mach {m_launch:.2f}; the table must reach the "
                f"launch Mach (to within {REFERENCE_MACH_SLACK:g}): extend it, or set "
                f"reference_extrapolate = true to hold Cd at its last value beyond the table")
    radar = build("radar", lambda: Radar(tables["radar"].get("sigma", {})))
    return Round(projectile, launch, atmosphere, radar, str(path))


def write_round(path, rnd, comment=None):
    """Write a round as TOML that :func:`read_round` reads back to the same values.

    ``reference_drag`` is written relative to the new file's directory. A reference table
    without ``reference_drag_path`` is first written next to it as ``<stem>_reference_drag.csv``.

    Parameters
    ----------
    path : str or os.PathLike
    rnd : Round
    comment : str, optional
        Written first as ``#`` lines.
    """
    path = Path(path)
    p, la, at = rnd.projectile, rnd.launch, rnd.atmosphere
    proj = {"name": p.name, "mass": p.mass, "diameter": p.diameter}
    if p.reference_drag is not None or p.reference_drag_path is not None:
        ref = p.reference_drag_path
        if ref is None:
            ref = path.with_name(f"{path.stem}_reference_drag.csv")
            body = "".join(f"{m:.6g},{c:.8g}\n" for m, c in zip(p.reference_drag.mach,
                                                                p.reference_drag.cd_values))
            ref.write_text(f"# reference drag of {p.name}\nmach,cd\n{body}", encoding="utf-8")
        try:
            rel = os.path.relpath(Path(ref).resolve(), path.resolve().parent)
        except ValueError:  # other drive (Windows)
            rel = str(Path(ref).resolve())
        proj["reference_drag"] = Path(rel).as_posix()
        if p.reference_extrapolate:
            proj["reference_extrapolate"] = True
    launch = {}
    if la.elevation_deg is not None:
        launch["elevation"] = la.elevation_deg
    if la.velocity is not None:
        launch["velocity"] = la.velocity
    launch["azimuth"] = la.azimuth_deg
    if la.latitude_deg is not None:
        launch["latitude"] = la.latitude_deg
    launch.update(altitude=la.altitude, velocity_sd=la.velocity_sd, elevation_sd=la.elevation_sd_deg,
                  position_sd=la.position_sd)
    atm = {"model": "icao"}
    if isinstance(at, MetProfile):
        prof = Path(at.source) if at.source else None
        if prof is None or not prof.is_file():
            prof = path.with_name(f"{path.stem}_met.csv")
            write_met_profile(prof, at, comment=f"met profile of {p.name}")
        try:
            rel = os.path.relpath(prof.resolve(), path.resolve().parent)
        except ValueError:  # other drive (Windows)
            rel = str(prof.resolve())
        atm = {"model": "profile", "profile": Path(rel).as_posix()}
    atm.update(temperature_offset=float(at.temperature_offset), pressure_ratio=float(at.pressure_ratio),
               density_ratio=float(at.density_ratio))
    doc = {"projectile": proj, "launch": launch, "atmosphere": atm}
    if rnd.radar.sigma:
        doc["radar"] = {"sigma": dict(rnd.radar.sigma)}
    head = "".join(f"# {ln}".rstrip() + "\n" for ln in str(comment).splitlines()) if comment else ""
    head += "# units: kg, m, deg, m/s, K\n"
    path.write_text(head + tomli_w.dumps(doc), encoding="utf-8")
