"""The air the diagnosis found, as a met profile the user can give back to ``fit`` and
``simulate`` (``[atmosphere] profile``): the round's atmosphere with the verdict's temperature
and density folded in and the verdict's wind added to the round's own.

Built from ``diagnosis.json`` and the round alone (:func:`found_atmosphere`); the report writes
it as ``diagnosis_met.csv`` (``altitude,temperature,pressure,wind_x,wind_y``) and, for a wind by
downrange distance, ``diagnosis_wind_downrange.csv`` (``downrange,wind_x,wind_y``).

Decisions (and why):

* The file holds the air itself, offsets included: it is given back with no
  ``temperature_offset``, ``pressure_ratio`` or ``density_ratio`` (the header says so). A
  ``density`` ratio is written as the pressure times the ratio (same density, same temperature:
  what a point mass flies).
* Levels every :data:`LEVEL_STEP` from the gun to :data:`TOP_MARGIN` above the highest point of
  the flight (or the wind's top), plus the wind's own levels (a layer step as two rows).
* A met file holds winds by height. A wind by **downrange distance** does not map onto one: the
  shell crosses each height twice, at two distances, in winds that may differ (a tailwind going
  up, a headwind coming down). So for such a verdict the met file holds the air alone, and the
  wind goes to ``diagnosis_wind_downrange.csv``, which ``[atmosphere] profile`` also reads (it
  flies the round's standard air and offsets: the header gives the temperature offset and
  density ratio to put in the round beside it).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..air.atmosphere import Atmosphere, MetProfile
from ..air.wind import WindProfile
from ..effects import air_effects
from ..effects import DENSITY, TEMPERATURE, WIND, WIND_PROFILE

__all__ = ["found_atmosphere", "LEVEL_STEP", "TOP_MARGIN", "AIR_EFFECTS"]

#: spacing of the met file's levels [m]
LEVEL_STEP = 250.0
#: the met file reaches this far above the flight's highest point [m]
TOP_MARGIN = 1000.0
#: verdict effects that change the air (a met file is written when one of them is found)
AIR_EFFECTS = air_effects()


def _values(row):
    """The figures the verdict rests on (joint fit when there is one)."""
    return row.get("params_joint") or row["params"]


def _layered(axis, edges, params):
    n = len(edges) - 1
    wx = [params.get(f"wx_{k}", 0.0) for k in range(1, n + 1)]
    wy = [params.get(f"wy_{k}", params.get("wy_1", 0.0)) for k in range(1, n + 1)]
    return WindProfile.layered(axis, edges, wx, wy)


def found_atmosphere(record, rnd):
    """The air the diagnosis found.

    Parameters
    ----------
    record : dict
        ``diagnosis.json`` (or the in-memory record it is written from).
    rnd : Round
        The round diagnosed (its atmosphere is the starting air).

    Returns
    -------
    (MetProfile or None, Atmosphere or None, list of str)
        The met profile (None when the verdict changes nothing of the air), the atmosphere with
        the wind by downrange distance (None unless the verdict's wind is one) and the lines of
        the files' header.
    """
    verdict = record.get("verdict") or []
    if not set(verdict) & set(AIR_EFFECTS):
        return None, None, []
    rows = {r["name"]: r for r in record["effects"]}
    atm = rnd.atmosphere
    dT = _values(rows[TEMPERATURE.name])["dT"] if TEMPERATURE.name in verdict else 0.0
    ratio = _values(rows[DENSITY.name])["ratio"] if DENSITY.name in verdict else 1.0
    air = replace(atm, temperature_offset=atm.temperature_offset + dT, density_ratio=atm.density_ratio * ratio)
    head = [f"the air bayesdrag diagnose found (verdict: {', '.join(verdict)})",
            "give it as [atmosphere] profile with no temperature_offset, pressure_ratio or density_ratio: "
            "they are in it"]
    if dT:
        head.append(f"temperature: the round's {'profile' if isinstance(atm, MetProfile) else 'air'} "
                    f"{dT:+.3g} K (verdict's temperature)")
    if ratio != 1.0:
        head.append(f"density: times {ratio:.5g} (verdict's density, written as the pressure)")
    base = getattr(atm, "wind", None)
    wind_alt, wind_x = None, None
    if WIND.name in verdict:
        v = _values(rows[WIND.name])
        const = WindProfile("altitude", (atm.gun_altitude,), (v["wx"],), (v.get("wy", 0.0),))
        wind_alt = const
        head.append(f"wind: constant wx = {v['wx']:.4g}, wy = {v.get('wy', 0.0):.4g} m/s (verdict's wind) added "
                    f"to the round's own")
        if base is not None and base.axis == "downrange":
            wind_x = WindProfile("downrange", (0.0,), (v["wx"],), (v.get("wy", 0.0),))
    if WIND_PROFILE.name in verdict:
        r = rows[WIND_PROFILE.name]
        lay = r["layers"]
        if lay["axis"] == "altitude":
            wind_alt = _layered("altitude", lay["edges"], _values(r))
            head.append(f"wind: the verdict's wind_profile by height, layers at {_edges(lay['edges'])} m above sea "
                        f"level, added to the round's own")
        else:
            wind_x = _layered("downrange", lay["edges"], _values(r))
            t_off = atm.temperature_offset + dT
            d_rat = atm.density_ratio * ratio
            head.append(f"wind: the verdict's wind_profile is by downrange distance (layers at {_edges(lay['edges'])} m "
                        f"downrange), which no wind by height can hold (the shell crosses each height twice, at two "
                        f"distances): it is in diagnosis_wind_downrange.csv; diagnosis_met.csv holds the air alone")
            head.append(f"to fly both: [atmosphere] profile = \"diagnosis_wind_downrange.csv\" with "
                        f"temperature_offset = {t_off:.4g} and density_ratio = {d_rat:.5g} (and no met file)")
    if base is not None:
        if wind_alt is not None and base.axis == "altitude":
            wind_alt = wind_alt.plus(base)
        elif wind_alt is None and base.axis == "altitude":
            wind_alt = base
        if wind_x is not None and base.axis == "downrange":
            wind_x = wind_x.plus(base)
    top = record["baseline"].get("z_max") or 0.0
    if wind_alt is not None:
        top = max(top, wind_alt.levels[-1] - atm.gun_altitude)
    levels = atm.gun_altitude + np.arange(0.0, top + TOP_MARGIN + LEVEL_STEP, LEVEL_STEP)
    met = _met(air, levels, wind_alt)
    down = Atmosphere(gun_altitude=atm.gun_altitude, temperature_offset=atm.temperature_offset,
                      pressure_ratio=atm.pressure_ratio, density_ratio=atm.density_ratio, wind=wind_x) \
        if wind_x is not None else None
    return met, down, head


def _edges(edges):
    return ", ".join(f"{e:.0f}" for e in edges)


def _met(air, levels, wind):
    """The met profile of ``air`` (offsets folded in) at ``levels`` [m above sea level] with
    ``wind`` (by altitude, or None)."""
    lv = sorted(set(float(v) for v in levels) | (set(wind.levels) if wind is not None else set()))
    st = air.at_height(np.array(lv) - air.gun_altitude)
    # the density ratio is carried by the pressure (same density at the same temperature)
    p = st.pressure * air.density_ratio
    return MetProfile(tuple(lv), tuple(float(t) for t in st.temperature), tuple(float(v) for v in p),
                      gun_altitude=air.gun_altitude, wind=wind)
