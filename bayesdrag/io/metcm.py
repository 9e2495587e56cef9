"""Computer met messages (METCM text, NATO STANAG 4082), the met a range receives, read into a
:class:`bayesdrag.air.atmosphere.MetProfile` whose winds are layers of constant wind by height.

Format read (one message per file; blank lines and lines starting with ``#`` are skipped)::

    METCM1 345123 151200 0 036985        header: the last group is hhhPPP
    00271008 29151012                    one line per zone: ZZ ddd FFF TTTT PPPP
    01271010 29081004
    02265014 28930975
    ...

- **Header**: the first line, starting with ``METCM``; its last group is six digits ``hhhPPP``:
  the height of the met datum plane (MDP) above mean sea level in tens of metres and its
  pressure in millibars (hPa) with the thousands digit left out (``012`` is 1012 hPa, ``985`` is
  985 hPa). The groups between (octant, location, date, time, duration) are not used.
- **Zone lines**: sixteen digits, optionally split into groups by spaces: ``ZZ`` the zone (line)
  number, ``ddd`` the direction the wind blows **from** in tens of mils clockwise from true
  north (6400 mils to the circle; 000 with no wind), ``FFF`` the wind speed in knots, ``TTTT`` the
  mean virtual temperature of the zone in tenths of kelvin, ``PPPP`` the pressure in millibars
  (hPa). Zones are in increasing order, each at most once, and every zone is in the zone table.

Decisions (and why):

* Zone heights come from a table (:data:`ZONES_FILE`, shipped as data; ``[atmosphere]
  metcm_zones`` replaces it): public descriptions of the message disagree on them, so they are
  data the user can check, not constants.
* Each zone's temperature and pressure are placed at the zone's mid-height (line 00 at the MDP);
  the profile between is :class:`MetProfile`'s (T linear, pressure hydrostatic, every given
  pressure honoured). A message whose pressures belong to other heights fails MetProfile's
  hydrostatic check, naming the level, rather than being flown wrong.
* The wind of a zone is constant over the zone (its mean wind), with steps at the zone edges
  (:meth:`WindProfile.layered`; steps spread over 100 m as every wind step is); line 00's wind
  (at the MDP itself) is reported by no layer: zone 01 starts there. Below the MDP and above
  the last zone the nearest zone's wind holds.
* The wind is turned into the firing frame with ``[launch] azimuth`` A: it blows toward
  ``d + 180 deg``, so ``wind_x = F cos(d + 180 deg - A)`` (tailwind > 0) and
  ``wind_y = F sin(d + 180 deg - A)`` (toward +y, the right, > 0).
* Zones whose mid-height lies above the atmosphere model (32 km) are left out, with a note.
"""
from __future__ import annotations

import math
import re
from importlib.resources import files
from pathlib import Path

from ..air.atmosphere import MAX_ALTITUDE, MET_WIND_SD_DEFAULT, MetError, MetProfile, rounding_sd
from ..air.wind import PROFILE_WIND_MAX, WindProfile
from ..errors import InputError
from .csv import read_table, read_text

__all__ = ["read_metcm", "read_metcm_zones", "is_metcm", "ZONES_FILE", "KNOT", "MILS_PER_CIRCLE"]

#: the shipped zone table (``zone,bottom,top`` [m above the MDP]; its source is named in the file)
ZONES_FILE = "metcm_zones.csv"
#: one knot [m/s]
KNOT = 1852.0 / 3600.0
#: a METCM's resolution: temperature in tenths of a kelvin [K], pressure in whole hPa [Pa]
TEMPERATURE_RESOLUTION = 0.1
PRESSURE_RESOLUTION = 100.0
#: NATO mils in a full circle
MILS_PER_CIRCLE = 6400.0
#: largest difference [Pa] between the header's and line 00's pressure at the met datum plane
MDP_PRESSURE_TOL = 500.0
_ZONE_LINE = re.compile(r"^\d{16}$")


def is_metcm(text):
    """Is this file's text a METCM message (its first line that is neither blank nor a comment
    starts with ``METCM``)?"""
    for ln in text.splitlines():
        s = ln.strip()
        if s and not s.startswith("#"):
            return s.upper().startswith("METCM")
    return False


def read_metcm_zones(path=None):
    """The METCM zone table: ``{zone: (bottom, top)}`` [m above the MDP].

    Parameters
    ----------
    path : path, optional
        A CSV with columns ``zone,bottom,top`` (``#`` comments); None: the shipped
        :data:`ZONES_FILE`.

    Raises
    ------
    InputError
        Unreadable table, zones not whole numbers 0-99 or repeated, a zone whose top is below its
        bottom, or zones that overlap.
    """
    if path is None:
        path = files("bayesdrag") / "data" / ZONES_FILE
    path, names, data, line_no = read_table(path, "METCM zone table", required=("zone", "bottom", "top"),
                                            allowed=("zone", "bottom", "top"), quote=False)
    cols = {n: data[:, k] for k, n in enumerate(names)}
    out = {}
    prev_top, prev = None, None
    for z, lo, hi, ln in zip(cols["zone"], cols["bottom"], cols["top"], line_no):
        if z != round(z) or not 0 <= z <= 99 or int(z) in out:
            raise InputError(f"{path}: line {ln}: zone {z:g} must be a whole number 0-99 listed once")
        if hi < lo or lo < 0:
            raise InputError(f"{path}: line {ln}: zone {int(z)} spans {lo:g}-{hi:g} m; bottom must be >= 0 and "
                             f"top >= bottom (m above the met datum plane)")
        if prev_top is not None and int(z) > prev and lo < prev_top - 1e-6:
            raise InputError(f"{path}: line {ln}: zone {int(z)} starts at {lo:g} m, below the top {prev_top:g} m "
                             f"of zone {prev}; zones must not overlap")
        out[int(z)] = (float(lo), float(hi))
        prev_top, prev = float(hi), int(z)
    if not out:
        raise InputError(f"{path}: the METCM zone table lists no zones")
    return out


def _header(path, ln, line):
    groups = line.split()
    last = groups[-1] if groups else ""
    if len(groups) < 2 or not re.fullmatch(r"\d{6}", last):
        raise InputError(f"{path}: line {ln}: METCM header must end with the group hhhPPP (six digits: the met "
                         f"datum plane's height in tens of metres and its pressure in hPa without the thousands "
                         f"digit), e.g. 'METCM1 345123 151200 0 036985'")
    mdp = 10.0 * int(last[:3])
    p = int(last[3:])
    return mdp, (p + 1000 if p < 500 else p) * 100.0


def read_metcm(path, azimuth_deg, zones=None, gun_altitude=0.0, **offsets):
    """Read a METCM message into a :class:`MetProfile` (winds in the firing frame).

    Parameters
    ----------
    path : path
    azimuth_deg : float
        Firing azimuth [deg clockwise from true north] (``[launch] azimuth``): the frame the
        winds are turned into.
    zones : path, optional
        Zone table (``zone,bottom,top``); None: the shipped one (:func:`read_metcm_zones`).
    gun_altitude : float, m
    **offsets
        ``temperature_offset``, ``pressure_ratio``, ``density_ratio`` as in :class:`MetProfile`.

    Returns
    -------
    MetProfile
        Levels at the MDP and the zones' mid-heights (above sea level), ``wind`` layers of
        constant wind by altitude at the zone edges, ``source`` the file.

    Raises
    ------
    InputError
        A malformed header or zone line (naming the line, what was found and the form allowed),
        a zone not in the table, zones out of order, a direction beyond 6400 mils, fewer than two
        zones, and every :class:`MetProfile` validation failure.
    """
    path = Path(path)
    table = read_metcm_zones(zones)
    text = read_text(path, "met profile")
    mdp, p_mdp = None, None
    rows = []
    for ln, raw in enumerate(text.splitlines(), start=1):
        s = raw.strip()
        if not s or s.startswith("#"):
            continue
        if mdp is None:
            if not s.upper().startswith("METCM"):
                raise InputError(f"{path}: line {ln}: a METCM message starts with its header line 'METCM...'")
            mdp, p_mdp = _header(path, ln, s)
            continue
        digits = s.replace(" ", "").replace("\t", "")
        if not _ZONE_LINE.match(digits):
            raise InputError(f"{path}: line {ln}: a METCM zone line is 16 digits ZZdddFFFTTTTPPPP (zone, wind "
                             f"direction from in tens of mils, speed in knots, virtual temperature in 0.1 K, "
                             f"pressure in hPa), optionally in groups of digits; this line is not")
        zone, dmils, speed, temp, pres = (int(digits[:2]), 10 * int(digits[2:5]), int(digits[5:8]),
                                          int(digits[8:12]) / 10.0, float(int(digits[12:16])))
        if zone not in table:
            raise InputError(f"{path}: line {ln}: zone {zone:02d} is not in the METCM zone table "
                             f"({min(table):02d}-{max(table):02d}); replace the table with [atmosphere] metcm_zones")
        if rows and zone <= rows[-1][0]:
            raise InputError(f"{path}: line {ln}: zone {zone:02d} follows zone {rows[-1][0]:02d}; zones must be "
                             f"listed once each, in increasing order")
        if dmils >= MILS_PER_CIRCLE + 1e-9:
            raise InputError(f"{path}: line {ln}: wind direction {dmils} mils is beyond the {MILS_PER_CIRCLE:g} "
                             f"mils of a circle (ddd is in tens of mils, 000-640)")
        if pres <= 0:
            raise InputError(f"{path}: line {ln}: pressure {pres:g} hPa must be > 0")
        if speed * KNOT > PROFILE_WIND_MAX:
            raise InputError(f"{path}: line {ln}: wind speed {speed} knots (FFF, in knots) is beyond the plausible "
                             f"{PROFILE_WIND_MAX / KNOT:.1f} knots; check the zone line's digits")
        rows.append((zone, dmils, speed, temp, pres, ln))
    if mdp is None:
        raise InputError(f"{path}: no METCM header line ('METCM...') found")
    if rows and rows[0][0] == 0 and abs(rows[0][4] * 100.0 - p_mdp) > MDP_PRESSURE_TOL:
        raise InputError(f"{path}: line {rows[0][5]}: line 00 gives {rows[0][4]:g} hPa at the met datum plane but "
                         f"the header {p_mdp / 100.0:g} hPa; one of them is mistyped")
    if len(rows) < 2:
        raise InputError(f"{path}: a METCM message needs at least two zone lines, found {len(rows)}")
    notes = []
    mid = []
    for r in rows:
        lo, hi = table[r[0]]
        mid.append(mdp + 0.5 * (lo + hi))
    keep = [i for i, h in enumerate(mid) if h <= MAX_ALTITUDE]
    if len(keep) < len(rows):
        notes.append(f"METCM {path}: {len(rows) - len(keep)} zone(s) above {MAX_ALTITUDE:.0f} m left out "
                     f"(beyond the atmosphere model)")
    rows = [rows[i] for i in keep]
    mid = [mid[i] for i in keep]
    # the wind in the firing frame: it blows toward d + 180 deg
    az = math.radians(float(azimuth_deg))
    layers = [r for r in rows if table[r[0]][1] > table[r[0]][0]]
    edges, wx, wy = [], [], []
    for r in layers:
        lo, hi = table[r[0]]
        if edges and abs(edges[-1] - (mdp + lo)) > 1e-6:
            raise InputError(f"{path}: line {r[5]}: zone {r[0]:02d} starts at {lo:g} m above the MDP but the zone "
                             f"before it ends at {edges[-1] - mdp:g} m: a METCM message lists adjacent zones")
        if not edges:
            edges.append(mdp + lo)
        edges.append(mdp + hi)
        to = 2.0 * math.pi * r[1] / MILS_PER_CIRCLE + math.pi - az
        wx.append(r[2] * KNOT * math.cos(to))
        wy.append(r[2] * KNOT * math.sin(to))
    try:
        wind = WindProfile.layered("altitude", edges, wx, wy) if layers else None
        stated = MetError(wind_sd=MET_WIND_SD_DEFAULT if layers else None,
                          temperature_sd=rounding_sd(TEMPERATURE_RESOLUTION),
                          density_sd=rounding_sd(PRESSURE_RESOLUTION) / (rows[0][4] * 100.0),
                          why=f"a METCM message: winds to {MET_WIND_SD_DEFAULT:g} m/s (whole knots, zone means), "
                              f"temperatures in tenths of a kelvin, pressures in whole hPa")
        return MetProfile(tuple(mid), tuple(r[3] for r in rows), tuple(r[4] * 100.0 for r in rows),
                          gun_altitude=gun_altitude, wind=wind, source=str(path), notes=tuple(notes),
                          zones="" if zones is None else str(zones), stated_error=stated, **offsets)
    except ValueError as exc:
        msg = str(exc)
        m = re.search(r"altitude (-?[0-9.e+]+) m", msg)
        where = ""
        if m:
            hit = [r[5] for r, h in zip(rows, mid) if abs(h - float(m.group(1))) < 0.5]
            if hit:
                where = f"line {hit[-1]}: "
        raise InputError(f"{path}: {where}{msg}") from None

