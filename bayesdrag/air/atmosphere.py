"""ICAO standard atmosphere with offsets, and the tabulated form the fast kernel uses.

The model is the ICAO Standard Atmosphere (ICAO Doc 7488/3, identical to the U.S. Standard
Atmosphere 1976 below 32 km): three layers in geopotential altitude,

====================  ===============  =================
layer (geopotential)  base temperature  lapse rate
====================  ===============  =================
0 - 11 km             288.15 K          -6.5 K/km
11 - 20 km            216.65 K          0 (isothermal)
20 - 32 km            216.65 K          +1.0 K/km
====================  ===============  =================

with sea-level pressure 101 325 Pa, R = 287.05287 J/(kg K), gamma = 1.4, g0 = 9.80665 m/s^2.
Altitudes passed to the public functions are **geometric** heights above mean sea level [m];
they are converted to geopotential altitude with the Earth radius r0 = 6 356 766 m.

Non-standard days are described by three numbers (the round's ``[atmosphere]`` and the effects):

``temperature_offset`` dT [K]
    the whole temperature profile is shifted by dT, *at unchanged pressure at the gun*; the
    pressure elsewhere follows from hydrostatic balance with the shifted temperatures. This
    changes both density and speed of sound.
``pressure_ratio`` [-]
    pressure (and hence density) everywhere multiplied by this factor; temperature unchanged.
``density_ratio`` [-]
    density multiplied by this factor, speed of sound unchanged (the ``density`` effect).
    Physically identical to ``pressure_ratio`` for a point-mass model; both are kept because
    they come from different sources (met message vs diagnosis).

Wind. Both atmospheres may carry a :class:`WindProfile`: horizontal wind that changes with height
above sea level (met practice: a met file's levels, a METCM message's zones) or with downrange
distance from the gun (how small-arms tools and py-ballisticcalc give winds by zone), linear
between its levels, with steps where a level repeats, constant beyond its ends. The point-mass
kernel and its scipy reference fly it (:mod:`bayesdrag.dynamics.pointmass`); a constant wind of
the model or of the ``wind`` effect adds to it.

All functions here are pure and vectorised over altitude.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import math

import numpy as np

from ..validate import float_tuple as _float_tuple
from .wind import PROFILE_WIND_MAX, WindProfile

#: standard gravity [m/s^2]
G0 = 9.80665
#: specific gas constant of dry air [J/(kg K)] (ICAO)
R_AIR = 287.05287
#: ratio of specific heats [-]
GAMMA = 1.4
#: sea-level standard temperature [K] and pressure [Pa]
T0 = 288.15
P0 = 101325.0
#: Earth radius used for geopotential altitude [m] (ICAO)
R_EARTH = 6356766.0

# layer bases (geopotential m), base temperatures (K) and lapse rates dT/dH (K/m)
_H_BASE = np.array([0.0, 11000.0, 20000.0, 32000.0])
_T_BASE = np.array([288.15, 216.65, 216.65, 228.65])
_LAPSE = np.array([-0.0065, 0.0, 0.001])
#: highest geometric altitude [m] the model accepts (top of the 20-32 km layer)
MAX_ALTITUDE = 32000.0 * R_EARTH / (R_EARTH - 32000.0)
#: lowest geometric altitude [m] the model accepts (below sea level, e.g. the Dead Sea)
MIN_ALTITUDE = -5000.0


class AtmosphereState(NamedTuple):
    """Air properties at given altitudes (arrays broadcast like the altitude input).

    Attributes
    ----------
    temperature : ndarray, K
    pressure : ndarray, Pa
    density : ndarray, kg/m^3
    speed_of_sound : ndarray, m/s
    """

    temperature: np.ndarray
    pressure: np.ndarray
    density: np.ndarray
    speed_of_sound: np.ndarray


def geopotential_altitude(h):
    """Geopotential altitude H = r0 h / (r0 + h) [m] of geometric altitude ``h`` [m]."""
    h = np.asarray(h, dtype=float)
    return R_EARTH * h / (R_EARTH + h)


def _layer_index(H):
    return np.clip(np.searchsorted(_H_BASE, H, side="right") - 1, 0, len(_LAPSE) - 1)


def _temperature_geo(H, dT):
    i = _layer_index(H)
    return _T_BASE[i] + _LAPSE[i] * (H - _H_BASE[i]) + dT


def _inv_temperature_integral(H, dT):
    """I(H) = integral_0^H dH'/T(H') [m/K] for the profile shifted by dT (analytic per layer)."""
    H = np.asarray(H, dtype=float)
    a, b = np.minimum(H, 0.0), np.maximum(H, 0.0)
    total = np.zeros_like(H)
    for k in range(len(_LAPSE)):
        lo = -np.inf if k == 0 else _H_BASE[k]
        hi = _H_BASE[k + 1]
        s, e = np.clip(a, lo, hi), np.clip(b, lo, hi)
        L = _LAPSE[k]
        tb = _T_BASE[k] + dT
        if L == 0.0:
            total = total + (e - s) / tb
        else:
            total = total + np.log((tb + L * (e - _H_BASE[k])) / (tb + L * (s - _H_BASE[k]))) / L
    return np.where(H < 0.0, -total, total)


_LN_P0 = math.log(P0)
_HB = tuple(_H_BASE.tolist())
_TB = tuple(_T_BASE.tolist())
_LB = tuple(_LAPSE.tolist())


def _temperature_geo_scalar(H, dT):
    k = 0 if H < _HB[1] else (1 if H < _HB[2] else 2)
    return _TB[k] + _LB[k] * (H - _HB[k]) + dT


def _inv_t_integral_scalar(H, dT):
    """Scalar twin of :func:`_inv_temperature_integral`."""
    a, b = min(H, 0.0), max(H, 0.0)
    total = 0.0
    for k in range(3):
        lo = -math.inf if k == 0 else _HB[k]
        hi = _HB[k + 1]
        s, e = min(max(a, lo), hi), min(max(b, lo), hi)
        if e <= s:
            continue
        tb = _TB[k] + dT
        L = _LB[k]
        if L == 0.0:
            total += (e - s) / tb
        else:
            total += math.log((tb + L * (e - _HB[k])) / (tb + L * (s - _HB[k]))) / L
    return -total if H < 0.0 else total


def _check_altitude(h):
    h = np.asarray(h, dtype=float)
    if np.any(~np.isfinite(h)):
        raise ValueError("altitude must be finite, got non-finite values")
    if np.any(h > MAX_ALTITUDE) or np.any(h < MIN_ALTITUDE):
        raise ValueError(
            f"altitude outside the standard atmosphere's range [{MIN_ALTITUDE:.0f}, "
            f"{MAX_ALTITUDE:.0f}] m: got min {h.min():.1f} m, max {h.max():.1f} m"
        )
    return h


def standard_atmosphere(h, temperature_offset=0.0, pressure_ratio=1.0, density_ratio=1.0,
                        gun_altitude=0.0):
    """ICAO standard atmosphere, optionally shifted, at geometric altitudes ``h``.

    Parameters
    ----------
    h : array_like, m
        Geometric altitude above mean sea level, any shape, within
        [``MIN_ALTITUDE``, ``MAX_ALTITUDE``].
    temperature_offset : float, K
        Shift dT of the whole temperature profile. The pressure at ``gun_altitude`` is kept at its
        standard value (times ``pressure_ratio``); elsewhere it follows hydrostatic balance.
    pressure_ratio : float, -
        Pressure multiplier (density follows, temperature does not).
    density_ratio : float, -
        Density multiplier leaving temperature and speed of sound unchanged.
    gun_altitude : float, m
        Geometric altitude of the gun, where ``temperature_offset`` leaves the pressure unchanged.

    Returns
    -------
    AtmosphereState
        temperature [K], pressure [Pa], density [kg/m^3], speed of sound [m/s], each shaped like
        ``h``.

    Examples
    --------
    >>> s = standard_atmosphere(0.0)
    >>> round(float(s.density), 4), round(float(s.speed_of_sound), 2)
    (1.225, 340.29)
    """
    h = _check_altitude(h)
    _check_params(temperature_offset, pressure_ratio, density_ratio)
    H = geopotential_altitude(h)
    Hg = geopotential_altitude(_check_altitude(gun_altitude))
    T = _temperature_geo(H, temperature_offset)
    # standard pressure at the gun, then hydrostatic with the shifted profile
    ln_pg = np.log(P0) - G0 / R_AIR * _inv_temperature_integral(Hg, 0.0)
    ln_p = ln_pg - G0 / R_AIR * (_inv_temperature_integral(H, temperature_offset)
                                 - _inv_temperature_integral(Hg, temperature_offset))
    p = np.exp(ln_p) * pressure_ratio
    rho = p / (R_AIR * T) * density_ratio
    a = np.sqrt(GAMMA * R_AIR * T)
    return AtmosphereState(T, p, rho, a)


def _check_params(temperature_offset, pressure_ratio, density_ratio):
    if not np.isfinite(temperature_offset) or not (-100.0 < temperature_offset < 100.0):
        raise ValueError(f"temperature_offset must be a finite number of kelvin in (-100, 100),"
                         f" got {temperature_offset!r}")
    for name, val in (("pressure_ratio", pressure_ratio), ("density_ratio", density_ratio)):
        if not np.isfinite(val) or not (0.0 < val < 3.0):
            raise ValueError(f"{name} must be a finite positive factor in (0, 3), got {val!r}")


@dataclass(frozen=True)
class Atmosphere:
    """Parameters of the air a round flew through.

    Attributes
    ----------
    temperature_offset : float, K
    pressure_ratio : float, -
    density_ratio : float, -
    gun_altitude : float, m
        Geometric altitude of the gun above sea level; trajectory heights ``z`` are relative to it.
    wind : WindProfile or None
        Wind that changes along the flight (by height or downrange distance), or None.
    source : str
        File the wind was read from ("" if built in code); not part of equality.
    """

    temperature_offset: float = 0.0
    pressure_ratio: float = 1.0
    density_ratio: float = 1.0
    gun_altitude: float = 0.0
    wind: "WindProfile | None" = None
    source: str = field(default="", compare=False)

    def __post_init__(self):
        _check_params(self.temperature_offset, self.pressure_ratio, self.density_ratio)
        _check_altitude(self.gun_altitude)
        if self.wind is not None and not isinstance(self.wind, WindProfile):
            raise ValueError(f"wind must be a WindProfile or None, got {type(self.wind).__name__}")

    def at_height(self, z):
        """Air at heights ``z`` [m] above the gun. Returns :class:`AtmosphereState`."""
        return standard_atmosphere(np.asarray(z, dtype=float) + self.gun_altitude,
                                   self.temperature_offset, self.pressure_ratio,
                                   self.density_ratio, self.gun_altitude)

    def density_and_sound_speed(self, z):
        """Density [kg/m^3] and speed of sound [m/s] at one height ``z`` [m] above the gun.

        A scalar fast path (``math`` instead of numpy) of :meth:`at_height`, used by the
        scipy reference integrator, which calls it thousands of times per trajectory. It
        agrees with :meth:`at_height` to rounding (tested).
        """
        h = z + self.gun_altitude
        if not (MIN_ALTITUDE <= h <= MAX_ALTITUDE):
            raise ValueError(f"altitude {h:.1f} m outside the standard atmosphere's range")
        H = R_EARTH * h / (R_EARTH + h)
        T = _temperature_geo_scalar(H, self.temperature_offset)
        Hg = R_EARTH * self.gun_altitude / (R_EARTH + self.gun_altitude)
        ln_p = (_LN_P0 - G0 / R_AIR * _inv_t_integral_scalar(Hg, 0.0)
                - G0 / R_AIR * (_inv_t_integral_scalar(H, self.temperature_offset)
                                - _inv_t_integral_scalar(Hg, self.temperature_offset)))
        rho = math.exp(ln_p) * self.pressure_ratio / (R_AIR * T) * self.density_ratio
        return rho, math.sqrt(GAMMA * R_AIR * T)


    def table(self, z_min=-500.0, z_max=MAX_ALTITUDE, dz=5.0):
        """Tabulate density and speed of sound on a uniform grid of heights above the gun.

        The fast kernel interpolates this table linearly: with ``dz`` = 5 m the relative
        interpolation error is below 4e-8 (density scale height ~8.5 km); 25 m gave a 1e-6
        bias, which moved a 155 mm trajectory by 2 mm. The table reaches the model's top
        (:data:`MAX_ALTITUDE` above sea level, less one step): a fit refuses a track above it
        (:func:`bayesdrag.estimate.build.start.check_heights`) rather than fly it in air held at the top.

        Returns
        -------
        z0 : float, m
            First grid height above the gun.
        dz : float, m
        values : ndarray, shape (n, 2)
            Columns density [kg/m^3] and speed of sound [m/s].
        """
        z_max = min(z_max, MAX_ALTITUDE - self.gun_altitude - dz)
        n = int(np.ceil((z_max - z_min) / dz)) + 1
        z = z_min + dz * np.arange(n)
        s = self.at_height(z)
        return float(z_min), float(dz), np.column_stack([s.density, s.speed_of_sound])


# ------------------------------------------------------------------------------------------
# tabulated meteorological profiles
# ------------------------------------------------------------------------------------------
#: plausible air temperature range of a met profile [K]: the coldest tropopause ever recorded is
#: ~175 K, the hottest surface air ~330 K. All values below :data:`CELSIUS_SUSPECT` K mean the
#: column is almost surely in degrees Celsius.
PROFILE_TEMPERATURE_RANGE = (150.0, 350.0)
CELSIUS_SUSPECT = 150.0
#: plausible pressure range [Pa]; a profile whose largest pressure is below
#: :data:`HPA_SUSPECT` Pa is almost surely in hPa (mbar)
PROFILE_PRESSURE_RANGE = (100.0, 120000.0)
HPA_SUSPECT = 2000.0
#: hydrostatic consistency of each layer, as |ln(p_upper/p_lower) measured - hydrostatic| [-]
#: (the relative pressure error the layer's temperatures cannot explain). Humidity (virtual
#: temperature up to ~1.7 % above T on a hot humid day) explains up to ~0.2 % per km; above
#: HYDROSTATIC_NOTE a note is recorded, above HYDROSTATIC_ERROR the profile is rejected
#: (a wrong altitude, a pressure typed in the wrong row, mixed units).
HYDROSTATIC_NOTE = 0.005
HYDROSTATIC_ERROR = 0.03
#: range of a level's pressure over the ICAO standard pressure at its altitude [-], checked on
#: the levels below :data:`DATUM_CHECK_CEILING`. Real weather near the ground spans 0.86 (a
#: typhoon's centre, 870 hPa) to 1.07 (the highest sea-level pressure recorded, 1085 hPa); a
#: profile whose altitudes sit on another datum moves every level by exp(dz / 8 km): 1 km too
#: high reads 1.13, 1 km too low 0.88 (a datum 600 m too low, 0.93, is inside real weather: the
#: fit finds such air unlike the track's, and says so).
DATUM_PRESSURE_RATIO = (0.85, 1.10)
#: levels above this geometric altitude [m] are not checked against the standard pressure (the
#: polar winter's stratosphere reads 0.75 of it at 20 km), but for the lowest level, the gun's
DATUM_CHECK_CEILING = 5000.0
#: farthest the gun may lie below the lowest or above the highest level of a met profile [m]:
#: the air there is the profile's end level carried on at the ICAO lapse rate, which a few
#: hundred metres keep within real weather; beyond it the profile is another place's (or on
#: another datum) and is refused
GUN_OUTSIDE_LEVELS_MAX = 500.0


#: default sd [m/s] of a met file's wind at any height, per component, where the round declares no
#: ``[atmosphere] wind_sd``: a message's wind is a zone's mean in whole knots (0.15 m/s of
#: rounding) of a sounding that the flight meets within its zone's spread and some minutes later;
#: 1 m/s holds the flight's wind in 90 % bands (docs/fitting.md, "A met file's own error"). A
#: message of another hour or place is known worse: declare wind_sd.
MET_WIND_SD_DEFAULT = 1.0


@dataclass(frozen=True)
class MetError:
    """What a met file states of its own error: the sds the round's air carries into the band
    when the round declares none of its own (``[atmosphere] wind_sd``, ``temperature_sd``,
    ``density_sd``).

    Attributes
    ----------
    wind_sd : float or None, m/s
        Per component, at any height (None: the file has no winds).
    temperature_sd : float, K
        Of the whole profile: the temperatures' resolution (a uniform rounding, resolution / sqrt 12).
    density_sd : float, relative
        Of the air density: the pressures' resolution over the pressure at the lowest level.
    why : str
        Where the numbers come from, in words (the report and ``uncertainty_budget`` say it).
    """

    wind_sd: float | None
    temperature_sd: float
    density_sd: float
    why: str = ""


def rounding_sd(resolution):
    """sd of a value rounded to ``resolution`` (uniform over one step) [same unit]."""
    return float(resolution) / math.sqrt(12.0)


def _check_datum(za, pa, z):
    """Refuse (ValueError) a level whose pressure is unlike any real weather's at its altitude
    (:data:`DATUM_PRESSURE_RATIO`): the profile's altitudes are on another datum, or in other
    units. ``za``, ``pa``: the levels' altitudes [m] and pressures [Pa]; ``z``: as given."""
    low = za <= DATUM_CHECK_CEILING
    low[0] = True       # the lowest level always: the gun is within GUN_OUTSIDE_LEVELS_MAX of it
    ratio = pa[low] / standard_atmosphere(za[low]).pressure
    lo, hi = DATUM_PRESSURE_RATIO
    bad = np.flatnonzero((ratio < lo) | (ratio > hi))
    if bad.size:
        i = int(bad[0])          # the lowest: nearest the gun, where the scale height is best known
        dz = 8000.0 * math.log(ratio[i])      # the shift of datum that explains it, at an 8 km scale height
        raise ValueError(
            f"pressure {pa[low][i]:g} Pa at altitude {z[int(np.flatnonzero(low)[i])]:g} m is {ratio[i]:.4g} times the "
            f"standard pressure there, beyond real weather ({lo:g}-{hi:g}); the altitudes look about "
            f"{abs(dz):.0f} m too {'high' if dz > 0 else 'low'}: give them above mean sea level (a METCM's datum "
            f"height is in tens of metres)")


def _gun_outside(gun, za):
    """A note when the gun at ``gun`` [m] lies outside the profile's levels ``za`` [m] by up to
    :data:`GUN_OUTSIDE_LEVELS_MAX` (the air there extrapolated); ValueError beyond it; ``""``
    inside."""
    below, above = za[0] - gun, gun - za[-1]
    off = max(below, above)
    if off <= 0.0:
        return ""
    where = (f"below the profile's lowest level {za[0]:g} m" if below > 0
             else f"above the profile's highest level {za[-1]:g} m")
    if off > GUN_OUTSIDE_LEVELS_MAX:
        raise ValueError(f"the gun at {gun:g} m above sea level ([launch] altitude) lies {off:.6g} m {where}; at "
                         f"most {GUN_OUTSIDE_LEVELS_MAX:g} m is extrapolated: give levels down to the gun, or check "
                         f"the profile's altitudes and the gun's (both above mean sea level)")
    return (f"the gun at {gun:g} m lies {off:.0f} m {where}: the air there is the end level's carried on at the "
            f"ICAO lapse rate")


def _layer_integral(Ti, L, dH):
    """Integral of dH'/T over [0, dH] for T = Ti + L H' [m/K], stable for L -> 0."""
    x = L * dH / Ti
    small = np.abs(x) < 1e-8
    xs = np.where(small, 1.0, x)
    ratio = np.where(small, 1.0 - 0.5 * x, np.log1p(xs) / xs)
    return dH / Ti * ratio


@dataclass(frozen=True)
class MetProfile:
    """A measured (tabulated) atmosphere: temperature and pressure by altitude, optional wind.

    Same interface as :class:`Atmosphere` (``at_height``, ``density_and_sound_speed``,
    ``table``, ``gun_altitude``, ``temperature_offset``, ``pressure_ratio``,
    ``density_ratio``), so the point-mass kernel, the scipy reference, the 6-DOF simulator and
    the diagnosis use it unchanged. Frozen and hashable (the kernel memoises its table by value).

    Physics
    -------
    - Altitudes are geometric heights above mean sea level [m], like ``[launch] altitude``;
      internally everything is in geopotential altitude H (as in the ICAO model).
    - Between levels the temperature is linear in H. The pressure honours every measured level
      exactly: within a layer ln p follows hydrostatic balance with the layer's linear
      temperature, plus the layer's residual (measured minus hydrostatic ln-pressure drop)
      spread linearly over the layer. For a hydrostatic profile the residual is zero and the
      pressure is exact at any level spacing.
    - Density rho = p / (R T) (dry air, R = 287.05287 J/(kg K)); speed of sound
      a = sqrt(gamma R T). Humidity is not modelled: give virtual temperature if you have it.
    - **Outside the profile** (below the lowest or above the highest level) the temperature
      continues with the ICAO standard lapse rates, shifted to match the end level's
      temperature, and the pressure follows hydrostatically from that level. A profile equal
      to ICAO therefore reproduces :class:`Atmosphere` everywhere.
    - ``temperature_offset`` dT shifts every temperature by dT at unchanged pressure at the gun
      (hydrostatic elsewhere, keeping the layer residuals); ``pressure_ratio`` and
      ``density_ratio`` multiply as in :class:`Atmosphere`. They let the diagnosis and the
      fit perturb a measured profile exactly as they perturb the standard one.

    Attributes
    ----------
    altitude : tuple of float, m
        Geometric altitude above mean sea level of each level, strictly increasing, >= 2 levels.
        An altitude may repeat once with the same temperature and pressure: a step in the wind
        there (the first row's wind below, the second's above); the air's levels are then the
        distinct altitudes and the winds become :attr:`wind`.
    temperature : tuple of float, K
        In [150, 350] K.
    pressure : tuple of float, Pa
        In [100, 120000] Pa, strictly decreasing with altitude, hydrostatically consistent
        within :data:`HYDROSTATIC_ERROR`.
    wind_x, wind_y : tuple of float or None, m/s
        Wind components at the levels in the track frame (x downrange, y right, z up;
        docs/formats.md) (``wind_x`` > 0 tailwind, ``wind_y`` > 0 toward +y), or None; a missing
        component is zero. Constructor inputs only: they make :attr:`wind` (linear in altitude
        between levels), which the point-mass kernel and its scipy reference fly, and are then
        None on the value, so that the wind is held once.
    gun_altitude : float, m
        Geometric altitude of the gun above sea level; heights ``z`` are relative to it.
    temperature_offset, pressure_ratio, density_ratio : float
        As in :class:`Atmosphere`.
    wind : WindProfile or None
        The wind the profile carries: from ``wind_x, wind_y`` (by altitude), or given directly
        (a METCM message's zones, layers of constant wind; a wind by downrange distance).
        Giving both is an error.
    source : str
        File the profile was read from ("" if built in code); not part of equality.
    zones : str
        The METCM zone table the profile was read with ("": the shipped one, or not a METCM
        message); not part of equality.
    notes : tuple of str
        Remarks found in validation (e.g. a layer slightly off hydrostatic balance); not part
        of equality.
    stated_error : MetError or None
        The file's own error (its resolution, and :data:`MET_WIND_SD_DEFAULT` for its winds), set
        by the readers; the round carries it into the band where it declares no sd of its own.
        Not part of equality.

    Raises
    ------
    ValueError
        On any invalid level (message names the level's altitude);
        :func:`read_met_profile` turns these into :class:`~bayesdrag.errors.InputError` with
        file and line.
    """

    altitude: tuple
    temperature: tuple
    pressure: tuple
    wind_x: tuple | None = None
    wind_y: tuple | None = None
    gun_altitude: float = 0.0
    temperature_offset: float = 0.0
    pressure_ratio: float = 1.0
    density_ratio: float = 1.0
    wind: WindProfile | None = None
    source: str = field(default="", compare=False)
    zones: str = field(default="", compare=False)
    notes: tuple = field(default=(), compare=False)
    stated_error: MetError | None = field(default=None, compare=False)

    def __post_init__(self):
        z = _float_tuple("altitude", self.altitude)
        T = _float_tuple("temperature", self.temperature)
        p = _float_tuple("pressure", self.pressure)
        n = len(z)
        if len(T) != n or len(p) != n:
            raise ValueError(f"altitude, temperature and pressure need one value per level; got "
                             f"{n}, {len(T)}, {len(p)}")
        z, T, p, steps = self._wind_steps(z, T, p, self.wind_x is not None or self.wind_y is not None)
        n = len(z)
        if n < 2:
            raise ValueError(f"a met profile needs at least 2 levels, got {n} (a single surface "
                             f"observation is [atmosphere] temperature_offset / pressure_ratio)")
        za = np.array(z)
        d = np.diff(za)
        if np.any(d <= 0):
            i = int(np.argmax(d <= 0)) + 1
            how = "repeats" if d[i - 1] == 0 else f"is below the previous level {z[i - 1]:g} m"
            raise ValueError(f"altitude {z[i]:g} m {how}; levels must be sorted by strictly "
                             f"increasing altitude")
        if za[0] < MIN_ALTITUDE or za[-1] > MAX_ALTITUDE:
            raise ValueError(f"altitudes must lie in [{MIN_ALTITUDE:.0f}, {MAX_ALTITUDE:.0f}] m above "
                             f"sea level; got {za[0]:g} .. {za[-1]:g} m")
        Ta = np.array(T)
        lo, hi = PROFILE_TEMPERATURE_RANGE
        if np.all(Ta < CELSIUS_SUSPECT) and np.all(Ta > -100.0):
            raise ValueError(f"temperature {Ta.min():g} .. {Ta.max():g} looks like degrees Celsius; "
                             f"temperature is in kelvin (add 273.15); allowed [{lo:g}, {hi:g}] K")
        bad = np.flatnonzero((Ta < lo) | (Ta > hi))
        if bad.size:
            i = bad[0]
            raise ValueError(f"temperature {T[i]:g} K at altitude {z[i]:g} m is outside the plausible "
                             f"range [{lo:g}, {hi:g}] K")
        pa = np.array(p)
        plo, phi = PROFILE_PRESSURE_RANGE
        if np.any(pa <= 0):
            i = int(np.argmax(pa <= 0))
            raise ValueError(f"pressure {p[i]:g} Pa at altitude {z[i]:g} m must be > 0")
        if pa.max() < HPA_SUSPECT and za[0] < 20000.0:
            raise ValueError(f"pressure {pa.min():g} .. {pa.max():g} looks like hPa (mbar); pressure "
                             f"is in Pa (multiply by 100); allowed [{plo:g}, {phi:g}] Pa")
        bad = np.flatnonzero((pa < plo) | (pa > phi))
        if bad.size:
            i = bad[0]
            raise ValueError(f"pressure {p[i]:g} Pa at altitude {z[i]:g} m is outside the plausible "
                             f"range [{plo:g}, {phi:g}] Pa")
        dp = np.diff(pa)
        if np.any(dp >= 0):
            i = int(np.argmax(dp >= 0)) + 1
            raise ValueError(f"pressure {p[i]:g} Pa at altitude {z[i]:g} m is not below the pressure "
                             f"{p[i - 1]:g} Pa of the level beneath; pressure must fall with altitude")
        _check_datum(za, pa, z)
        winds = {}
        z_all = steps if steps is not None else z
        for name in ("wind_x", "wind_y"):
            w = getattr(self, name)
            if w is None:
                winds[name] = None
                continue
            w = _float_tuple(name, w)
            if len(w) != len(z_all):
                raise ValueError(f"{name} needs one value per level ({len(z_all)}), got {len(w)}")
            wa = np.abs(np.array(w))
            if np.any(wa > PROFILE_WIND_MAX):
                i = int(np.argmax(wa > PROFILE_WIND_MAX))
                raise ValueError(f"{name} = {w[i]:g} m/s at altitude {z_all[i]:g} m exceeds the plausible "
                                 f"{PROFILE_WIND_MAX:g} m/s (knots or km/h? the unit is m/s)")
            winds[name] = w
        wind = self.wind
        if any(v is not None for v in winds.values()):
            if wind is not None:
                raise ValueError("give the profile's wind either per level (wind_x, wind_y) or as wind, not both")
            zero = (0.0,) * len(z_all)
            wind = WindProfile("altitude", z_all, winds["wind_x"] or zero, winds["wind_y"] or zero)
            # one wind, held once: per-level winds beside the wind made of them were two states that
            # a shifted copy (``dataclasses.replace``) could not hold both of
            winds = {"wind_x": None, "wind_y": None}
        elif wind is not None and not isinstance(wind, WindProfile):
            raise ValueError(f"wind must be a WindProfile or None, got {type(wind).__name__}")
        _check_params(self.temperature_offset, self.pressure_ratio, self.density_ratio)
        _check_altitude(self.gun_altitude)
        outside = _gun_outside(float(self.gun_altitude), za)
        for k, v in dict(altitude=z, temperature=T, pressure=p, **winds, wind=wind,
                         gun_altitude=float(self.gun_altitude),
                         temperature_offset=float(self.temperature_offset),
                         pressure_ratio=float(self.pressure_ratio),
                         density_ratio=float(self.density_ratio), source=str(self.source)).items():
            object.__setattr__(self, k, v)

        # --- precomputation (geopotential levels, lapse rates, layer residuals) -------------
        H = geopotential_altitude(za)
        L = np.diff(Ta) / np.diff(H)
        J = _layer_integral(Ta[:-1], L, np.diff(H))
        resid = np.diff(np.log(pa)) + G0 / R_AIR * J  # measured minus hydrostatic ln-p drop
        notes = list(self.notes)
        if outside and not any(n.startswith("the gun at ") for n in notes):
            notes.append(outside)
        worst = int(np.argmax(np.abs(resid)))
        if abs(resid[worst]) > HYDROSTATIC_ERROR:
            raise ValueError(
                f"pressure {p[worst + 1]:g} Pa at altitude {z[worst + 1]:g} m is inconsistent with "
                f"hydrostatic balance from {p[worst]:g} Pa at {z[worst]:g} m and the temperatures "
                f"({100 * (math.exp(resid[worst]) - 1):+.1f} %; at most "
                f"{100 * HYDROSTATIC_ERROR:g} % allowed): check altitudes, pressures and units")
        if abs(resid[worst]) > HYDROSTATIC_NOTE:
            notes.append(f"met profile {self.source or ''}: layer {z[worst]:g}-{z[worst + 1]:g} m is "
                         f"{100 * (math.exp(resid[worst]) - 1):+.2f} % off hydrostatic balance "
                         f"(humidity or measurement error); the measured pressures are honoured")
        object.__setattr__(self, "notes", tuple(notes))
        self._set("_H", H)
        self._set("_L", L)
        self._set("_resid", resid)
        # ln-pressure at the levels, unshifted (= measured) and shifted by temperature_offset
        Hg = float(geopotential_altitude(self.gun_altitude))
        dT = self.temperature_offset
        Js = _layer_integral(Ta[:-1] + dT, L, np.diff(H))
        self._set("_lnp_levels", np.log(pa[0]) + np.concatenate([[0.0], np.cumsum(resid - G0 / R_AIR * Js)]))
        self._set("_Tk", Ta + dT)
        anchor = 0.0
        if dT != 0.0:
            unshifted = self._eval(np.array([Hg]), Ta, np.log(pa), 0.0)[1][0]
            anchor = unshifted - self._eval(np.array([Hg]), self._Tk, self._lnp_levels, dT)[1][0]
        self._set("_ln_anchor", anchor + math.log(self.pressure_ratio))

    @staticmethod
    def _wind_steps(z, T, p, has_wind):
        """Levels whose altitude repeats (with the same temperature and pressure) mark a step in
        the wind: the air's levels are the distinct ones. Returns (altitudes, temperatures,
        pressures, all altitudes or None when none repeats)."""
        za = np.array(z)
        rep = np.flatnonzero(np.diff(za) == 0)
        if not rep.size or not has_wind:
            return z, T, p, None  # a repeat without winds: refused as unsorted levels below
        for i in rep:
            if T[i] != T[i + 1] or p[i] != p[i + 1]:
                raise ValueError(f"altitude {z[i + 1]:g} m repeats with another temperature or pressure; a "
                                 f"repeated altitude marks a step in the wind and must repeat the level's "
                                 f"temperature and pressure")
        keep = np.ones(za.size, bool)
        keep[rep + 1] = False
        pick = np.flatnonzero(keep)
        return tuple(z[i] for i in pick), tuple(T[i] for i in pick), tuple(p[i] for i in pick), z

    def _set(self, name, value):
        if isinstance(value, np.ndarray):
            value.setflags(write=False)
        object.__setattr__(self, name, value)

    def _eval(self, H, Tk, lnpk, dT):
        """Temperature [K] and ln p (before the gun anchor) at geopotential altitudes H."""
        Hk, L, r = self._H, self._L, self._resid
        n = Hk.size
        k = np.clip(np.searchsorted(Hk, H, side="right") - 1, 0, n - 2)
        dH = H - Hk[k]
        T = Tk[k] + L[k] * dH
        lnp = lnpk[k] - G0 / R_AIR * _layer_integral(Tk[k], L[k], dH) + r[k] * dH / (Hk[k + 1] - Hk[k])
        for end, mask in ((0, H < Hk[0]), (n - 1, H > Hk[-1])):
            if np.any(mask):
                He = Hk[end]
                off = Tk[end] - float(_temperature_geo(np.array(He), 0.0))
                Hm = H[mask]
                T[mask] = _temperature_geo(Hm, off)
                lnp[mask] = lnpk[end] - G0 / R_AIR * (_inv_temperature_integral(Hm, off)
                                                      - _inv_temperature_integral(np.array(He), off))
        return T, lnp

    def at_height(self, z):
        """Air at heights ``z`` [m] above the gun (any shape). Returns :class:`AtmosphereState`."""
        h = _check_altitude(np.asarray(z, dtype=float) + self.gun_altitude)
        shape = h.shape
        H = geopotential_altitude(h).reshape(-1)
        T, lnp = self._eval(H, self._Tk, self._lnp_levels, self.temperature_offset)
        p = np.exp(lnp + self._ln_anchor)
        rho = p / (R_AIR * T) * self.density_ratio
        a = np.sqrt(GAMMA * R_AIR * T)
        return AtmosphereState(T.reshape(shape), p.reshape(shape), rho.reshape(shape), a.reshape(shape))

    def density_and_sound_speed(self, z):
        """Density [kg/m^3] and speed of sound [m/s] at one height ``z`` [m] above the gun
        (floats; same values as :meth:`at_height`)."""
        s = self.at_height(np.array([float(z)]))
        return float(s.density[0]), float(s.speed_of_sound[0])

    table = Atmosphere.table

    @property
    def has_wind(self):
        """True when the profile carries a wind."""
        return self.wind is not None

