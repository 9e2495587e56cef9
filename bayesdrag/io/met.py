"""Met profile files: the air a round flew through, level by level, read into
:class:`bayesdrag.air.atmosphere.MetProfile` (or, for a file of winds by downrange distance, an
:class:`bayesdrag.air.atmosphere.Atmosphere` carrying that wind).

Three forms, told apart by the file's first line that is not a comment:

* a met CSV ``altitude,temperature,pressure[,wind_x,wind_y]`` (SI; winds in the track frame,
  linear in altitude between levels; an altitude repeated with its temperature and pressure is a
  step in the wind);
* a wind CSV ``downrange,wind_x,wind_y``: winds that change with downrange distance from the
  gun (layers as repeated rows), for the standard atmosphere of the round's offsets -- what
  ``bayesdrag diagnose`` writes when the data prefer a wind by downrange distance;
* a computer met message (METCM text, :mod:`bayesdrag.io.metcm`).
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from ..air.atmosphere import MET_WIND_SD_DEFAULT, Atmosphere, MetError, MetProfile, rounding_sd
from ..air.wind import WindProfile
from ..errors import InputError
from .csv import read_bytes, read_table
from .metcm import is_metcm, read_metcm

__all__ = ["read_met_profile", "write_met_profile", "write_wind_profile", "met_file_kind", "PROFILE_COLUMNS",
           "PROFILE_OPTIONAL_COLUMNS", "WIND_COLUMNS"]


#: columns of a met profile CSV: required, then optional
PROFILE_COLUMNS = ("altitude", "temperature", "pressure")
PROFILE_OPTIONAL_COLUMNS = ("wind_x", "wind_y")
#: most levels of a met CSV a fit flies: a denser sounding is thinned (:func:`_thinned`) [-]
MAX_MET_LEVELS = 100
#: closest spacing of the levels kept from a dense sounding [m]: a shell crosses it in a few
#: hundredths of a second, and no fitted wind layer is finer
MIN_LEVEL_SPACING = 25.0
#: finest resolution a met CSV's numbers are taken to have, whatever digits they show: what a
#: radiosonde's sensors resolve [K], [Pa] (a file written at full float precision claims 1e-14 K)
TEMPERATURE_RESOLUTION_MIN = 0.01
PRESSURE_RESOLUTION_MIN = 1.0
#: bytes read first to tell the forms apart
_SNIFF_BYTES = 64 << 10
#: columns of a wind CSV by downrange distance
WIND_COLUMNS = ("downrange", "wind_x", "wind_y")


def met_file_kind(path):
    """``"metcm"``, ``"downrange"`` (a wind CSV by downrange distance) or ``"csv"`` (a met CSV by
    altitude), from the file's first line that is neither blank nor a comment."""
    # the first window holds the first content line of nearly every file; only one that is all
    # comments there is read further, up to the met profile's size bound (a fixed window took a
    # METCM after 64 kB of comments for a met CSV)
    for window in (_SNIFF_BYTES, None):
        head = read_bytes(path, "met profile", window, head=True).decode("utf-8", "replace")
        lines = head.splitlines()[:-1] if window is not None and len(head) >= window else head.splitlines()
        for ln in lines:
            s = ln.strip()
            if s and not s.startswith("#"):
                if is_metcm(s):
                    return "metcm"
                names = [c.strip().lower() for c in s.split(",")]
                return "downrange" if "downrange" in names else "csv"
    return "csv"


def read_met_profile(path, gun_altitude=0.0, *, azimuth_deg=None, zones=None, **offsets):
    """Read a met profile (met CSV, wind CSV by downrange distance, or METCM message).

    Format of the met CSV (the track CSV rules: ``#`` comments, a header row, one row of numbers
    per level): columns ``altitude`` [m above sea level, geometric], ``temperature`` [K],
    ``pressure`` [Pa], optional ``wind_x``, ``wind_y`` [m/s, track frame]; rows in increasing
    altitude (an altitude may repeat once, with its temperature and pressure, where the wind
    steps). A wind CSV has ``downrange`` [m from the gun] with ``wind_x``, ``wind_y`` instead.

    Parameters
    ----------
    path : str or os.PathLike
    gun_altitude : float, m
    azimuth_deg : float, optional
        Firing azimuth [deg from true north]; needed by a METCM message (its winds are by
        direction from north).
    zones : path, optional
        METCM zone table (``[atmosphere] metcm_zones``); None: the shipped one.
    **offsets
        ``temperature_offset``, ``pressure_ratio``, ``density_ratio`` as in :class:`MetProfile`.

    Returns
    -------
    MetProfile, or Atmosphere with ``wind`` for a wind CSV by downrange distance.

    Raises
    ------
    bayesdrag.errors.InputError
        Everything the CSV reader rejects, unknown columns, every :class:`MetProfile` or
        :class:`WindProfile` validation failure (the message names the file and, where it
        concerns one level, its line), a METCM message without ``azimuth_deg``, and every METCM
        format error (:func:`bayesdrag.io.metcm.read_metcm`).
    """
    kind = met_file_kind(path)
    if kind == "metcm":
        if azimuth_deg is None:
            raise InputError(f"{path}: a METCM message gives winds by direction from north; the firing azimuth "
                             f"is needed to turn them into the firing frame")
        return read_metcm(path, azimuth_deg, zones=zones, gun_altitude=gun_altitude, **offsets)
    if kind == "downrange":
        return _read_downrange_winds(path, gun_altitude, **offsets)
    path, names, data, line_no = read_table(
        path, "met profile", required=PROFILE_COLUMNS,
        allowed=PROFILE_COLUMNS + PROFILE_OPTIONAL_COLUMNS, quote=False)
    cols = {n: data[:, k] for k, n in enumerate(names)}
    stated = _stated_error(cols)
    cols, line_no, thin_note = _thinned(cols, line_no)
    try:
        return MetProfile(tuple(cols["altitude"]), tuple(cols["temperature"]), tuple(cols["pressure"]),
                          None if "wind_x" not in cols else tuple(cols["wind_x"]),
                          None if "wind_y" not in cols else tuple(cols["wind_y"]),
                          gun_altitude=gun_altitude, source=str(Path(path)), stated_error=stated,
                          notes=(f"met profile {path}: {thin_note}",) if thin_note else (), **offsets)
    except ValueError as exc:
        raise InputError(f"{path}: {_where(exc, cols['altitude'], line_no)}{exc}") from None


def _thinned(cols, line_no):
    """A dense sounding's levels thinned to what a flight resolves: at most :data:`MAX_MET_LEVELS`
    rows, the level nearest each of evenly spaced heights at least :data:`MIN_LEVEL_SPACING`
    apart, the first and last always kept, a wind step's two rows together (and counted as two).
    The kept rows are the file's own (their pressures stay hydrostatically consistent with each
    other). Returns ``(cols, line_no, note)``; the note is "" when nothing was dropped."""
    z = np.asarray(cols["altitude"], float)
    n = z.size
    if n <= MAX_MET_LEVELS:
        return cols, line_no, ""
    steps = np.flatnonzero(np.diff(z) == 0)           # row i and i + 1 are a wind step
    budget = MAX_MET_LEVELS // 2 if steps.size else MAX_MET_LEVELS
    span = float(z[-1] - z[0])
    count = max(2, min(budget, int(span // MIN_LEVEL_SPACING) + 1))
    targets = np.linspace(z[0], z[-1], count)
    first = np.searchsorted(z, targets)               # the first row at or above each target
    lower = np.clip(first - 1, 0, n - 1)
    upper = np.clip(first, 0, n - 1)
    pick = np.where(np.abs(z[lower] - targets) <= np.abs(z[upper] - targets), lower, upper)
    keep = set(pick.tolist()) | {0, n - 1}
    partner = {int(i): int(i) + 1 for i in steps} | {int(i) + 1: int(i) for i in steps}
    keep |= {partner[i] for i in list(keep) if i in partner}
    keep = np.array(sorted(keep))
    out = {k: np.asarray(v)[keep] for k, v in cols.items()}
    spacing = span / max(count - 1, 1)
    return out, [line_no[i] for i in keep], (f"{n} levels thinned to {keep.size}, about {spacing:.0f} m apart "
                                              f"(what a flight resolves; the kept rows are the file's own)")


def _resolution(values):
    """The step a column's numbers were written to [its unit]: the finest last digit they show
    (a float's shortest repr is the decimal it was read from, less its trailing zeros, so one
    level's 296.2 of a column written to 0.01 K does not make it 0.1 K; whole numbers that all end
    in zeros were written to tens or hundreds, as 9.954e+04 Pa is to 10 Pa)."""
    def decimals(v):
        mant = repr(float(v)).lower().split("e")
        exp = int(mant[1]) if len(mant) > 1 else 0
        whole, _, frac = mant[0].partition(".")
        if frac in ("", "0"):       # a whole number: its trailing zeros are steps (9.954e+04 -> 10 Pa)
            digits = whole.lstrip("-")
            return -(len(digits) - len(digits.rstrip("0"))) - exp if digits.strip("0") else 0
        return len(frac) - exp
    return 10.0 ** -max(decimals(v) for v in values)


def _stated_error(cols):
    """A met CSV's own error (:class:`bayesdrag.air.atmosphere.MetError`): the resolution its
    temperatures and pressures were written to, and the default wind sd where it has winds."""
    has_wind = "wind_x" in cols or "wind_y" in cols
    t_res = max(_resolution(cols["temperature"]), TEMPERATURE_RESOLUTION_MIN)
    p_res = max(_resolution(cols["pressure"]), PRESSURE_RESOLUTION_MIN)
    p0 = float(cols["pressure"][0])
    return MetError(wind_sd=MET_WIND_SD_DEFAULT if has_wind else None, temperature_sd=rounding_sd(t_res),
                    # a pressure that is no pressure is refused by MetProfile, naming its line
                    density_sd=rounding_sd(p_res) / p0 if p0 > 0 and math.isfinite(p0) else 0.0,
                    why=(f"a met CSV: temperatures to {t_res:g} K, pressures to {p_res:g} Pa"
                         + (f", winds to {MET_WIND_SD_DEFAULT:g} m/s by default" if has_wind else "")))


def _where(exc, levels, line_no):
    """``"line N: "`` of the level an error message quotes, when it quotes one."""
    msg = str(exc)
    m = re.search(r"(?:altitude|downrange|level) (-?[0-9.e+]+) m", msg)
    if not m:
        return ""
    try:
        hit = np.flatnonzero(np.isclose(levels, float(m.group(1)), rtol=1e-5, atol=0.5))
    except ValueError:
        return ""
    if not len(hit):
        return ""
    later = "repeats" in msg or "below the previous" in msg
    return f"line {line_no[hit[-1] if later else hit[0]]}: "


def _read_downrange_winds(path, gun_altitude, **offsets):
    path, names, data, line_no = read_table(path, "met profile", required=("downrange",), allowed=WIND_COLUMNS,
                                            quote=False)
    cols = {n: data[:, k] for k, n in enumerate(names)}
    if "wind_x" not in cols and "wind_y" not in cols:
        raise InputError(f"{path}: a wind file by downrange distance needs wind_x and/or wind_y (m/s) beside "
                         f"downrange (m)")
    zero = np.zeros(len(cols["downrange"]))
    try:
        wind = WindProfile("downrange", tuple(cols["downrange"]), tuple(cols.get("wind_x", zero)),
                           tuple(cols.get("wind_y", zero)))
        return Atmosphere(gun_altitude=gun_altitude, wind=wind, source=str(path), **offsets)
    except ValueError as exc:
        raise InputError(f"{path}: {_where(exc, cols['downrange'], line_no)}{exc}") from None


def _rows_with_steps(levels, wind):
    """(altitude, wind_x, wind_y) rows: every level of ``levels`` and of ``wind`` (a step as two
    rows at its level)."""
    lv = sorted(set(levels) | set(wind.levels))
    out = []
    steps = {wind.levels[i] for i in range(len(wind.levels) - 1) if wind.levels[i] == wind.levels[i + 1]}
    for v in lv:
        if v in steps:
            i = next(i for i in range(len(wind.levels) - 1) if wind.levels[i] == wind.levels[i + 1] == v)
            out.append((v, wind.wind_x[i], wind.wind_y[i]))
            out.append((v, wind.wind_x[i + 1], wind.wind_y[i + 1]))
        else:  # the level's own value (not the smoothing of a step near it: the file's rows define the steps)
            wx, wy = wind.at_level(v)
            out.append((v, float(wx), float(wy)))
    return out


def write_met_profile(path, profile, comment=None, levels=()):
    """Write a :class:`MetProfile` (or an atmosphere with a wind by altitude) as a met CSV that
    :func:`read_met_profile` reads back to the same air and wind.

    The rows are the profile's levels, its wind's levels (a wind step as two rows at one
    altitude) and ``levels``, each with the temperature and pressure the profile has there
    without its offsets (a met file holds the measured air; the round's offsets apply on
    reading): a MetProfile's own numbers at its own levels, elsewhere its layers' values, so
    reading the file back gives the same air.

    Parameters
    ----------
    path : path
    profile : MetProfile or Atmosphere
    comment : str, optional
        Written first as ``#`` lines.
    levels : sequence of float, m above sea level
        Further altitudes to write (an :class:`Atmosphere` without other levels is written at
        the gun and 1000 m above it).
    """
    wind = getattr(profile, "wind", None)
    if wind is not None and wind.axis != "altitude":
        raise ValueError("a met CSV holds winds by altitude; write a wind by downrange distance with "
                         "write_wind_profile")
    own = {}
    if isinstance(profile, MetProfile):
        own = {z: (T, p) for z, T, p in zip(profile.altitude, profile.temperature, profile.pressure)}
    base = list(own) + [float(v) for v in levels]
    if len(set(base) | set(wind.levels if wind is not None else ())) < 2:
        base += [profile.gun_altitude, profile.gun_altitude + 1000.0]
    if wind is None:
        rows = [(z, None, None) for z in sorted(set(base))]
    else:
        rows = _rows_with_steps(base, wind)
    plain = _unshifted(profile)
    with_wind = wind is not None
    head = "".join(f"# {ln}".rstrip() + "\n" for ln in str(comment).splitlines()) if comment else ""
    head += "# units: m above sea level, K, Pa, m/s\n"
    head += "altitude,temperature,pressure" + (",wind_x,wind_y" if with_wind else "") + "\n"
    body = ""
    for z, wx, wy in rows:
        if z in own:
            T, p = own[z]
        else:
            st = plain.at_height(np.array([z - plain.gun_altitude]))
            T, p = float(st.temperature[0]), float(st.pressure[0])
        vals = [z, T, p] + ([wx, wy] if with_wind else [])
        body += ",".join(repr(float(v)) for v in vals) + "\n"
    Path(path).write_text(head + body, encoding="utf-8")


def _unshifted(profile):
    """The profile without its offsets (a met file holds the measured air; the round's offsets
    are applied on reading)."""
    from dataclasses import replace

    return replace(profile, temperature_offset=0.0, pressure_ratio=1.0, density_ratio=1.0)


def write_wind_profile(path, wind, comment=None):
    """Write a wind by downrange distance as a wind CSV (``downrange,wind_x,wind_y``; a step as
    two rows at one distance) that :func:`read_met_profile` reads back."""
    if wind.axis != "downrange":
        raise ValueError("write_wind_profile writes winds by downrange distance; a wind by altitude goes into a "
                         "met CSV (write_met_profile)")
    head = "".join(f"# {ln}".rstrip() + "\n" for ln in str(comment).splitlines()) if comment else ""
    head += "# units: m downrange from the gun, m/s (track frame)\ndownrange,wind_x,wind_y\n"
    body = "".join(f"{float(s)!r},{float(x)!r},{float(y)!r}\n"
                   for s, x, y in zip(wind.levels, wind.wind_x, wind.wind_y))
    Path(path).write_text(head + body, encoding="utf-8")
