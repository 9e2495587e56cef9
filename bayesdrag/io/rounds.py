"""Round files (TOML): ``[projectile]``, ``[launch]``, ``[atmosphere]`` and
``[radar]`` sections; paths inside are relative to the round file. See :func:`read_round`.

Every failure raises :class:`bayesdrag.errors.InputError` with one line naming the file, the
key, what was found and what is allowed.
"""
from __future__ import annotations

import difflib
import math
import os
from pathlib import Path

import tomli_w

from ..air.atmosphere import Atmosphere, MetProfile
from ..air.station import STATION_SOURCE, StationAir
from ..errors import InputError
from ..track import ALL_CHANNELS, ANGLE_CHANNELS, FILE_UNITS
from ..round import (ANGLE_BIAS_SD_MAX, DEFAULT_ELEVATION_SD_DEG, DEFAULT_POSITION_SD, DEFAULT_VELOCITY_SD,
                     SIGMA_BOUNDS, SYSTEMATIC_SOURCES, Launch, Projectile, Radar, Round, Systematics, sigma_bounds)
from ..validate import number, positive, type_name
from .csv import read_toml
from .drag_tables import (STANDARD_DRAG_FUNCTIONS, is_standard_drag, read_drag_table, read_standard_drag,
                          standard_drag_name)
from .met import met_file_kind, read_met_profile, write_met_profile, write_wind_profile

__all__ = ["read_round", "write_round", "round_files"]


#: the air at the gun as a weather meter reads it: ``[atmosphere]`` keys and their units
STATION_KEYS = ("pressure", "temperature", "humidity")
STATION_UNITS = ("Pa", "K", "-")
_SCHEMA = {
    "projectile": {"name": "text", "mass": "kg", "diameter": "m",
                   "reference_drag": "CSV path, or G1, G2, G5, G6, G7, G8, GI, GS",
                   "reference_extrapolate": "boolean", "mass_sd": "kg", "diameter_sd": "m"},
    "launch": {"elevation": "deg", "velocity": "m/s", "azimuth": "deg", "latitude": "deg",
               "altitude": "m", "velocity_sd": "m/s", "elevation_sd": "deg", "position_sd": "m"},
    "atmosphere": {"model": "text", "profile": "CSV or METCM path", "metcm_zones": "CSV path",
                   "temperature_offset": "K", "pressure_ratio": "-", "density_ratio": "-",
                   "density_sd": "relative", "temperature_sd": "K", "wind_sd": "m/s",
                   **dict(zip(STATION_KEYS, STATION_UNITS))},
    "radar": {"sigma": "table", "position_scale_sd": "relative", "velocity_scale_sd": "relative",
              "time_offset_sd": "s", "position": "table {x, y, z} in m", "range_bias_sd": "m",
              "azimuth_bias_sd": "deg", "elevation_bias_sd": "deg", "position_sd": "m", "device_offset": "m",
              "device_offset_sd": "m"},
}
ATMOSPHERE_MODELS = ("icao", "profile")
#: smallest radar noise sd a round file may state [m, m/s] (:data:`bayesdrag.round.SIGMA_BOUNDS`)
MIN_SIGMA = SIGMA_BOUNDS["m"][0]
#: smallest angle noise sd a round file may state [deg] (0.2 arc seconds)
MIN_SIGMA_DEG = math.degrees(SIGMA_BOUNDS["rad"][0])
#: plausible range of ``pressure_ratio`` and ``density_ratio`` (the Warner site's 0.78 is inside)
PLAUSIBLE_AIR_RATIO = (0.5, 2.0)
#: how far [Mach] the launch Mach may exceed the reference table's last row before the round is
#: rejected (unless ``reference_extrapolate = true``): beyond its end the table is held constant,
#: and a supersonic Cd changes ~2-4 % per 0.1 Mach, so a 0.05 overshoot costs at most ~2 %
REFERENCE_MACH_SLACK = 0.05


def _unknown(path, what, key, allowed):
    near = difflib.get_close_matches(key, allowed, n=1, cutoff=0.6)
    hint = f" (did you mean {near[0]!r}?)" if near else ""
    return InputError(f"{path}: unknown {what} {key!r}{hint}; allowed: {', '.join(allowed)}")


def _check_sigma(path, tab):
    """Refuse a ``[radar] sigma`` value outside the plausible range of its channel
    (:func:`bayesdrag.round.sigma_bounds`), in the file's unit (degrees for the angles). Values
    that are not positive finite numbers, or of unknown channels, are left to :class:`Radar`,
    which names what is wrong with them."""
    sigma = tab.get("sigma")
    if not isinstance(sigma, dict):
        return
    for c, v in sigma.items():
        if c not in ALL_CHANNELS or isinstance(v, bool) or not isinstance(v, (int, float)) \
                or not math.isfinite(v) or v <= 0:
            continue
        lo, hi = sigma_bounds(c)
        if c in ANGLE_CHANNELS:
            lo, hi = math.degrees(lo), math.degrees(hi)
        unit = FILE_UNITS[c]
        if v < lo:
            raise InputError(f"{path}: [radar] sigma.{c} = {v:g} {unit} is below "
                             f"{lo:g} {unit}: no radar measures that precisely (a unit mistake?); give the "
                             f"noise sd of one sample, or leave sigma out to estimate it from the track")
        if v > hi:
            raise InputError(f"{path}: [radar] sigma.{c} = {v:g} {unit} is above the plausible {hi:g} {unit}: a "
                             f"radar that noisy tracks nothing (a unit mistake?); give the noise sd of one sample "
                             f"(allowed {lo:g} .. {hi:g} {unit}), or leave sigma out to estimate it from the track")


def _radar(tab):
    """The ``[radar]`` table as a :class:`Radar`: angles (sigma of azimuth and elevation, the
    angle bias sds) given in degrees, held in radians."""
    sigma = tab.get("sigma", {})
    if isinstance(sigma, dict):
        sigma = {k: (math.radians(positive(f"sigma.{k}", v, "deg")) if k in ANGLE_CHANNELS and isinstance(v, (int, float))
                     and not isinstance(v, bool) else v) for k, v in sigma.items()}
    ang = {}
    for k in ("azimuth_bias_sd", "elevation_bias_sd"):     # checked in the file's unit, held in rad
        v = number(k, tab.get(k), "deg", optional=True)
        if v is not None:
            v = positive(k, v, "deg")
            if v > math.degrees(ANGLE_BIAS_SD_MAX):
                raise ValueError(f"{k} = {v:g} deg is larger than the plausible {math.degrees(ANGLE_BIAS_SD_MAX):g} deg")
            v = math.radians(v)
        ang[k] = v
    pos = tab.get("position", (0.0, 0.0, 0.0))
    off = tab.get("device_offset")
    if "position" not in tab and isinstance(off, (int, float)) and not isinstance(off, bool) and math.isfinite(off):
        # a chronograph radar beside the muzzle, to the right, at its offset (a non-finite offset is
        # left at the muzzle, so that Radar names device_offset, not the position it would give)
        pos = (0.0, float(off), 0.0)
    return Radar(sigma, pos, tab.get("range_bias_sd"), ang["azimuth_bias_sd"],
                 ang["elevation_bias_sd"], tab.get("position_sd"), tab.get("device_offset"),
                 tab.get("device_offset_sd"))


def _check_air_ratios(vals):
    lo, hi = PLAUSIBLE_AIR_RATIO
    for k in ("pressure_ratio", "density_ratio"):
        # a value that is not a finite positive factor is refused by Atmosphere, saying so
        if isinstance(vals[k], (int, float)) and math.isfinite(vals[k]) and vals[k] > 0 and not lo <= vals[k] <= hi:
            raise ValueError(f"{k} = {vals[k]:g} is outside {lo:g} .. {hi:g}: real air differs from the "
                             f"model's by tens of percent at most (a factor, not a percentage?)")


def _check_reference_reach(path, pt, ref, launch, atmosphere):
    """The reference table must reach the launch Mach unless ``reference_extrapolate = true``."""
    extrapolate = pt.get("reference_extrapolate", False)
    if not isinstance(extrapolate, bool):
        raise InputError(f"{path}: [projectile] reference_extrapolate must be true or false, got "
                         f"{type_name(extrapolate)}")
    if ref is None or launch.velocity is None or extrapolate:
        return
    a_gun = float(atmosphere.at_height(0.0).speed_of_sound)
    m_launch = launch.velocity / a_gun
    if m_launch > ref.mach[-1] + REFERENCE_MACH_SLACK:
        raise InputError(
            f"{path}: [projectile] reference_drag = {pt['reference_drag']!r} covers Mach "
            f"{ref.mach[0]:g}-{ref.mach[-1]:g} but the launch (velocity = {launch.velocity:g} m/s, "
            f"speed of sound {a_gun:.1f} m/s) is Mach {m_launch:.2f}; the table must reach the "
            f"launch Mach (to within {REFERENCE_MACH_SLACK:g}): extend it, or set "
            f"reference_extrapolate = true to hold Cd at its last value beyond the table")


def _met_path(path, at, key):
    """The file a ``[atmosphere]`` path key names, relative to the round file (None if absent)."""
    if key not in at:
        return None
    rel = at[key]
    if not isinstance(rel, str) or not rel.strip():
        what = " or METCM message" if key == "profile" else ""
        raise InputError(f"{path}: [atmosphere] {key} must be a CSV file path{what} (string), got {type_name(rel)}")
    return Path(os.path.normpath(path.parent / rel))


def _station_air(path, at, model, launch):
    """The standard atmosphere through the air a weather meter reads at the gun (``[atmosphere]
    pressure`` [Pa], ``temperature`` [K], ``humidity`` [0-1]), or None without them.

    The readings become the standard atmosphere's temperature offset and pressure ratio at the
    gun, through the CIPM-2007 virtual temperature (:class:`bayesdrag.air.station.StationAir`):
    the density at the gun is then the humid air's, and the air aloft follows the standard lapse
    from there."""
    given = [k for k in STATION_KEYS if k in at]
    if not given:
        return None
    if model == "profile":
        raise InputError(f"{path}: [atmosphere] {', '.join(given)} (station readings) with a met profile: the "
                         f"profile gives the air itself; drop one of them")
    p_key, t_key, h_key = STATION_KEYS
    missing = [k for k in (p_key, t_key) if k not in at]
    if missing:
        raise InputError(f"{path}: [atmosphere] {', '.join(given)} without {' and '.join(missing)}: the air at the gun "
                         f"needs station pressure [Pa] and temperature [K] (humidity [0-1] optional)")
    clash = [k for k in ("temperature_offset", "pressure_ratio", "density_ratio") if k in at]
    if clash:
        raise InputError(f"{path}: [atmosphere] {', '.join(clash)} with station readings: give the air one way")
    try:
        st = StationAir(at[p_key], at[t_key], at.get(h_key, 0.0))
    except ValueError as exc:
        raise InputError(f"{path}: [atmosphere] {exc}") from None
    icao = Atmosphere(gun_altitude=launch.altitude).at_height(0.0)
    return Atmosphere(temperature_offset=float(st.virtual_temperature - float(icao.temperature)),
                      pressure_ratio=float(st.pressure / float(icao.pressure)), gun_altitude=launch.altitude,
                      source=f"{STATION_SOURCE}: {st.pressure:g} Pa, {st.temperature:g} K, humidity {st.humidity:g}")


def _read_atmosphere(path, at, lt, launch):
    """The round's atmosphere from its ``[atmosphere]`` table ``at`` (``lt``: the ``[launch]``
    table, to know whether ``azimuth`` was given): the standard atmosphere with its offsets, or
    the met profile, wind file or METCM message of ``profile``."""
    model = at.get("model", "profile" if "profile" in at else "icao")
    if not isinstance(model, str) or model.lower() not in ATMOSPHERE_MODELS:
        raise InputError(f"{path}: [atmosphere] model = {model!r} is not supported; allowed: "
                         f"{', '.join(repr(m) for m in ATMOSPHERE_MODELS)}")
    model = model.lower()
    if model == "profile" and "profile" not in at:
        raise InputError(f"{path}: [atmosphere] model = 'profile' needs profile = \"met.csv\" "
                         f"(CSV altitude,temperature,pressure[,wind_x,wind_y], or a METCM message)")
    if model == "icao" and "profile" in at:
        raise InputError(f"{path}: [atmosphere] model = 'icao' contradicts profile = {at['profile']!r}; "
                         f"use model = 'profile' (or leave model out) to fly through the profile, "
                         f"or drop profile for the standard atmosphere")
    station = _station_air(path, at, model, launch)
    if station is not None:
        return station
    vals = {k: number(k, at.get(k, d), _SCHEMA["atmosphere"][k])
            for k, d in (("temperature_offset", 0.0), ("pressure_ratio", 1.0), ("density_ratio", 1.0))}
    _check_air_ratios(vals)
    zones = _met_path(path, at, "metcm_zones")
    if model != "profile":
        if zones is not None:
            raise InputError(f"{path}: [atmosphere] metcm_zones needs profile = a METCM message")
        return Atmosphere(**vals, gun_altitude=launch.altitude)
    rel = at["profile"]
    prof_path = _met_path(path, at, "profile")
    try:
        kind = met_file_kind(prof_path)
        if kind == "metcm" and "azimuth" not in lt:
            raise InputError(f"{path}: [launch] azimuth is missing: [atmosphere] profile = {rel!r} is a METCM "
                             f"message, whose winds are given by direction from true north; give the firing "
                             f"azimuth (deg clockwise from true north) to turn them into the firing frame")
        if zones is not None and kind != "metcm":
            raise InputError(f"{path}: [atmosphere] metcm_zones is given but profile = {rel!r} is not a METCM "
                             f"message; drop metcm_zones or give the METCM file")
        return read_met_profile(prof_path, gun_altitude=launch.altitude, azimuth_deg=launch.azimuth_deg,
                                zones=zones, **vals)
    except InputError as exc:
        if str(exc).startswith(f"{path}:"):
            raise
        raise InputError(f"{path}: [atmosphere] profile = {rel!r}: {exc}") from None


def read_round(path: str | os.PathLike[str]) -> Round:
    """Read and validate a round TOML file.

    Sections and keys (units in brackets; all but ``[projectile] mass`` and ``diameter``
    optional):

    - ``[projectile]`` name, mass [kg], diameter [m], reference_drag (CSV ``mach,cd``, path
      relative to the TOML file, read with :func:`bayesdrag.io.drag_tables.read_drag_table`; or
      the bare name of a standard drag function, ``"G1"``, ``"G2"``, ``"G5"``, ``"G6"``, ``"G7"``,
      ``"G8"``, ``"GI"``, ``"GS"``, case-insensitive, read with
      :func:`bayesdrag.io.drag_tables.read_standard_drag`; a file called ``G7`` is ``"./G7"``)
      and reference_extrapolate (boolean, default false: the table must reach the launch Mach,
      ``velocity`` over the speed of sound at the gun, to within :data:`REFERENCE_MACH_SLACK`;
      true holds Cd at the table's last value beyond it, e.g. for a published curve that
      stops short of the muzzle Mach)
    - ``[launch]`` elevation [deg], velocity [m/s], azimuth [deg, default 0], latitude [deg],
      altitude [m, default 0], velocity_sd [m/s, default 5], elevation_sd [deg, default 0.2],
      position_sd [m, default 1]
    - ``[atmosphere]`` model (``"icao"``, default, or ``"profile"``), profile (path relative to
      the TOML file, read with :func:`bayesdrag.io.met.read_met_profile`: a met CSV
      ``altitude,temperature,pressure[,wind_x,wind_y]``, a wind CSV
      ``downrange,wind_x,wind_y``, or a computer met message, METCM text, which needs
      ``[launch] azimuth``; giving it implies ``model = "profile"``, and ``model = "icao"``
      with a profile is a contradiction), metcm_zones (CSV ``zone,bottom,top`` replacing the
      shipped METCM zone table), temperature_offset [K], pressure_ratio, density_ratio
      (applied on top of a profile too), wind_sd [m/s] (how well the winds are known per
      layer, :attr:`bayesdrag.round.Systematics.wind_profile`)
    - ``[radar]`` sigma = {x, y, z [m], v [m/s], range [m], azimuth [deg], elevation [deg],
      range_rate [m/s]} (the angles' sd held in radians inside; each within
      :data:`bayesdrag.round.SIGMA_BOUNDS`: 1e-4 .. 1000 m, 1e-4 .. 100 m/s, 5e-5 .. 10 deg),
      position = {x, y, z} [m] (the
      radar's site in the gun's frame at launch, default the muzzle), range_bias_sd [m],
      azimuth_bias_sd [deg], elevation_bias_sd [deg], position_sd [m] (how well the site is
      known), device_offset [m] (a chronograph radar's offset as typed into the device; its
      cosine correction is modelled, and without ``position`` the site is ``{y = device_offset}``);
      docs/radar.md
    - systematic sources (optional; each declared sd makes that quantity a nuisance parameter
      of the fit, see :class:`bayesdrag.round.Systematics`): ``[projectile]`` mass_sd [kg],
      diameter_sd [m]; ``[atmosphere]`` density_sd [relative], temperature_sd [K]; ``[radar]``
      position_scale_sd [relative], velocity_scale_sd [relative], time_offset_sd [s]

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
    doc = read_toml(path, "round file", "a round file holds sections of plain keys")

    for sec, tab in doc.items():
        if sec not in _SCHEMA:
            what = "section" if isinstance(tab, dict) else "top-level key"
            raise _unknown(path, what, sec, tuple(_SCHEMA))
    tables = {}
    for sec, keys in _SCHEMA.items():
        tab = doc.get(sec, {})
        if not isinstance(tab, dict):
            raise InputError(f"{path}: {sec} must be a section [{sec}], got {type_name(tab)}")
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
            raise InputError(f"{path}: [projectile] reference_drag must be a CSV file path or a standard drag "
                             f"function ({', '.join(STANDARD_DRAG_FUNCTIONS)}), got {type_name(rel)}")
        if is_standard_drag(rel) and os.path.lexists(path.parent / rel):
            # a file of that name beside the round: which one is meant is the user's to say
            raise InputError(f"{path}: [projectile] reference_drag = {rel!r} names the standard drag function "
                             f"{rel.upper()} and a file beside the round; write './{rel}' for the file, or rename it "
                             f"to use the standard function")
        try:
            if is_standard_drag(rel):       # the bare name only: "G7.csv" or "./G7" is a file
                ref = read_standard_drag(rel)
            else:
                ref_path = Path(os.path.normpath(path.parent / rel))
                ref = read_drag_table(ref_path)
        except InputError as exc:
            hint = ""
            if ref_path is not None and not ref_path.exists() and Path(rel).name == rel and not Path(rel).suffix:
                hint = f" (or name a standard drag function: {', '.join(STANDARD_DRAG_FUNCTIONS)})"
            raise InputError(f"{path}: [projectile] reference_drag = {rel!r}: {exc}{hint}") from None
    projectile = build("projectile", lambda: Projectile(
        pt.get("name", path.stem), pt["mass"], pt["diameter"], ref,
        None if ref_path is None else str(ref_path), pt.get("reference_extrapolate", False) is True))

    lt = tables["launch"]
    launch = build("launch", lambda: Launch(
        lt.get("elevation"), lt.get("velocity"), lt.get("azimuth"), lt.get("latitude"),
        lt.get("altitude", 0.0), lt.get("velocity_sd", DEFAULT_VELOCITY_SD),
        lt.get("elevation_sd", DEFAULT_ELEVATION_SD_DEG), lt.get("position_sd", DEFAULT_POSITION_SD)))

    atmosphere = build("atmosphere", lambda: _read_atmosphere(path, tables["atmosphere"], lt, launch))
    _check_reference_reach(path, pt, ref, launch, atmosphere)
    _check_sigma(path, tables["radar"])     # in the file's units, before Radar checks them in SI
    radar = build("radar", lambda: _radar(tables["radar"]))
    sds = {stem: tables[sec].get(f"{stem}_sd") for stem, (sec, _, _) in SYSTEMATIC_SOURCES.items()}
    for stem, (sec, _, _) in SYSTEMATIC_SOURCES.items():     # each error names its own section
        build(sec, lambda: Systematics(**{stem: sds[stem]}))
    wind_sd = tables["atmosphere"].get("wind_sd")
    build("atmosphere", lambda: Systematics(wind_profile=wind_sd))
    # a met file carries its own error into the band where the round declares none (docs/fitting.md)
    systematics = Systematics(**sds, wind_profile=wind_sd).with_met_error(getattr(atmosphere, "stated_error", None))
    return build("projectile", lambda: Round(projectile, launch, atmosphere, radar, str(path), systematics))


def round_files(path, rnd):
    """The files a round file brings into a run: ``{"round": path, "reference_drag": ...,
    "met_profile": ...}`` (the ones it references only when they are files), for manifests and
    fingerprints over the inputs' bytes.

    Parameters
    ----------
    path : path
        The round TOML.
    rnd : Round
        As :func:`read_round` read it.

    Returns
    -------
    dict role -> Path
    """
    files = {"round": Path(path)}
    ref = rnd.projectile.reference_drag_path
    if ref and Path(ref).is_file():
        files["reference_drag"] = Path(ref)
    prof = getattr(rnd.atmosphere, "source", "")
    if prof and Path(prof).is_file():
        files["met_profile"] = Path(prof)
    zones = getattr(rnd.atmosphere, "zones", "")
    if zones and Path(zones).is_file():
        files["metcm_zones"] = Path(zones)
    return files


def write_round(path: str | os.PathLike[str], rnd: Round, comment: str | None = None) -> None:
    """Write a round as TOML that :func:`read_round` reads back to the same values.

    ``reference_drag`` is written relative to the new file's directory; a standard drag function
    is written as its name (``"G7"``). Any other reference table without ``reference_drag_path``
    is first written next to it as ``<stem>_reference_drag.csv``.

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
    std = None if p.reference_drag_path is not None or p.reference_drag is None else \
        standard_drag_name(p.reference_drag)
    if std is not None:
        proj["reference_drag"] = std
        if p.reference_extrapolate:
            proj["reference_extrapolate"] = True
    elif p.reference_drag is not None or p.reference_drag_path is not None:
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
    if la.azimuth_given:
        launch["azimuth"] = la.azimuth_deg
    if la.latitude_deg is not None:
        launch["latitude"] = la.latitude_deg
    launch.update(altitude=la.altitude, velocity_sd=la.velocity_sd, elevation_sd=la.elevation_sd_deg,
                  position_sd=la.position_sd)
    atm = {"model": "icao"}
    if isinstance(at, MetProfile) or getattr(at, "wind", None) is not None:
        prof = Path(at.source) if at.source else None
        if prof is None or not prof.is_file():
            if at.wind is not None and at.wind.axis == "downrange":
                prof = path.with_name(f"{path.stem}_wind.csv")
                write_wind_profile(prof, at.wind, comment=f"winds by downrange distance of {p.name}")
            else:
                prof = path.with_name(f"{path.stem}_met.csv")
                write_met_profile(prof, at, comment=f"met profile of {p.name}")
        atm = {"model": "profile", "profile": _relative(prof, path)}
        if getattr(at, "zones", ""):
            atm["metcm_zones"] = _relative(Path(at.zones), path)
    atm.update(temperature_offset=float(at.temperature_offset), pressure_ratio=float(at.pressure_ratio),
               density_ratio=float(at.density_ratio))
    doc = {"projectile": proj, "launch": launch, "atmosphere": atm}
    ra = rnd.radar
    radar = {}
    if ra.sigma:
        radar["sigma"] = {c: (math.degrees(v) if c in ANGLE_CHANNELS else v) for c, v in ra.sigma.items()}
    if any(ra.position) or ra.device_offset is not None:     # (else the offset would give the site)
        radar["position"] = dict(zip("xyz", ra.position))
    for key in ("range_bias_sd", "azimuth_bias_sd", "elevation_bias_sd", "position_sd", "device_offset",
                "device_offset_sd"):
        val = getattr(ra, key)
        if val is not None:
            radar[key] = math.degrees(val) if key in ("azimuth_bias_sd", "elevation_bias_sd") else val
    if radar:
        doc["radar"] = radar
    from_file = rnd.systematics.from_met_file    # the met file states them again when it is read
    for stem, sd in rnd.systematics.declared().items():
        if stem not in from_file:
            doc.setdefault(SYSTEMATIC_SOURCES[stem][0], {})[f"{stem}_sd"] = float(sd)
    if rnd.systematics.wind_profile is not None and "wind_profile" not in from_file:
        doc["atmosphere"]["wind_sd"] = float(rnd.systematics.wind_profile)
    head = "".join(f"# {ln}".rstrip() + "\n" for ln in str(comment).splitlines()) if comment else ""
    head += "# units: kg, m, deg, m/s, K\n"
    path.write_text(head + tomli_w.dumps(doc), encoding="utf-8")


def _relative(target, round_path):
    """``target`` relative to the round file's folder (absolute on another drive)."""
    try:
        rel = os.path.relpath(Path(target).resolve(), Path(round_path).resolve().parent)
    except ValueError:  # other drive (Windows)
        rel = str(Path(target).resolve())
    return Path(rel).as_posix()
