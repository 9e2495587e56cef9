"""Moist air at the gun as a weather meter reads it: station pressure, temperature and relative
humidity, turned into air density with the CIPM-2007 equation of state for moist air.

Reference: A. Picard, R. S. Davis, M. Glaeser and K. Fujii, "Revised formula for the density of
moist air (CIPM-2007)", Metrologia 45 (2008) 149-155, doi:10.1088/0026-1394/45/2/004.

The rest of the package models the air as dry air (:data:`bayesdrag.air.atmosphere.R_AIR`);
:func:`virtual_temperature` gives the dry-air temperature with the same density at the same
pressure, so humid air enters that model unchanged (for density; see :func:`virtual_temperature`
on the speed of sound).

All functions are pure and take scalars or NumPy arrays (broadcast together); SI units throughout
(Pa, K, kg/m^3), except where a name says otherwise (``t_celsius``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .atmosphere import R_AIR
from ..validate import number

__all__ = ["is_station_air", "STATION_SOURCE", "saturation_vapour_pressure", "enhancement_factor", "vapour_mole_fraction", "compressibility",
           "moist_air_density", "virtual_temperature", "humidity_density_ratio", "StationAir",
           "PRESSURE_RANGE", "TEMPERATURE_RANGE", "HUMIDITY_RANGE", "X_CO2"]

#: 0 degC in kelvin [K]
ZERO_CELSIUS = 273.15

# saturation vapour pressure over liquid water, psv = exp(A T^2 + B T + C + D/T) [Pa] (Picard 2008, A1.2)
PSV_A = 1.2378847e-5     # [K^-2]
PSV_B = -1.9121316e-2    # [K^-1]
PSV_C = 33.93711047      # [-]
PSV_D = -6.3431645e3     # [K]

# enhancement factor f = alpha + beta p + gamma t^2, t in degC (Picard 2008, A1.2)
F_ALPHA = 1.00062        # [-]
F_BETA = 3.14e-8         # [Pa^-1]
F_GAMMA = 5.6e-7         # [K^-2]

# compressibility factor Z (Picard 2008, A1.3), t in degC
Z_A0 = 1.58123e-6        # [K Pa^-1]
Z_A1 = -2.9331e-8        # [Pa^-1]
Z_A2 = 1.1043e-10        # [K^-1 Pa^-1]
Z_B0 = 5.707e-6          # [K Pa^-1]
Z_B1 = -2.051e-8         # [Pa^-1]
Z_C0 = 1.9898e-4         # [K Pa^-1]
Z_C1 = -2.376e-6         # [Pa^-1]
Z_D = 1.83e-11           # [K^2 Pa^-2]
Z_E = -0.765e-8          # [K^2 Pa^-2]

#: molar gas constant used by CIPM-2007 [J/(mol K)]
R_MOLAR = 8.314472
#: molar mass of water [kg/mol]
M_WATER = 18.01528e-3
#: mole fraction of carbon dioxide assumed [-] (the CIPM-2007 reference value; a range in the
#: open air is close to it, and 100 ppm more changes density by about 4e-5 relative)
X_CO2 = 0.0004
#: molar mass of dry air at :data:`X_CO2` [kg/mol]: (28.96546 + 12.011 (xCO2 - 0.0004)) 1e-3
M_DRY_AIR = (28.96546 + 12.011 * (X_CO2 - 0.0004)) * 1e-3

#: the station readings accepted: pressure [Pa], temperature [K], relative humidity [-]. Wider
#: than any firing range's weather (a gun 5 km up, -53 to +57 degC); outside them a reading is
#: most likely in another unit, and the messages say which
PRESSURE_RANGE = (50_000.0, 110_000.0)
TEMPERATURE_RANGE = (220.0, 330.0)
HUMIDITY_RANGE = (0.0, 1.0)


def saturation_vapour_pressure(T):
    """Saturation vapour pressure of water over a plane liquid surface (CIPM-2007).

    ``psv = exp(A T^2 + B T + C + D / T)`` with the constants of Picard et al. (2008), Metrologia
    45, 149, Eq. A1.2: A = 1.2378847e-5 K^-2, B = -1.9121316e-2 K^-1, C = 33.93711047,
    D = -6.3431645e3 K.

    Parameters
    ----------
    T : float or array_like
        Temperature [K].

    Returns
    -------
    float or ndarray
        Saturation vapour pressure [Pa] (about 2339 Pa at 293.15 K). Below 0 degC it is the
        pressure over supercooled water, the reference weather meters use for relative humidity.
    """
    T = np.asarray(T, dtype=float)
    return np.exp(PSV_A * T * T + PSV_B * T + PSV_C + PSV_D / T)[()]


def enhancement_factor(p, t_celsius):
    """Enhancement factor of water vapour in air (CIPM-2007): ``f = alpha + beta p + gamma t^2``.

    Parameters
    ----------
    p : float or array_like
        Pressure [Pa].
    t_celsius : float or array_like
        Temperature [degC] (Celsius, as in the paper; the other functions take kelvin).

    Returns
    -------
    float or ndarray
        f [-], slightly above 1 (about 1.0040 at 101 325 Pa and 20 degC).
    """
    p = np.asarray(p, dtype=float)
    t = np.asarray(t_celsius, dtype=float)
    return (F_ALPHA + F_BETA * p + F_GAMMA * t * t)[()]


def vapour_mole_fraction(p, T, h):
    """Mole fraction of water vapour ``xv = h f(p, t) psv(T) / p`` (CIPM-2007).

    Parameters
    ----------
    p : float or array_like
        Pressure [Pa].
    T : float or array_like
        Temperature [K].
    h : float or array_like
        Relative humidity [0-1] (a fraction, not percent).

    Returns
    -------
    float or ndarray
        xv [-].
    """
    p = np.asarray(p, dtype=float)
    T = np.asarray(T, dtype=float)
    return (np.asarray(h, dtype=float) * enhancement_factor(p, T - ZERO_CELSIUS)
            * saturation_vapour_pressure(T) / p)[()]


def compressibility(p, T, xv):
    """Compressibility factor Z of moist air (CIPM-2007, Picard et al. 2008, Eq. A1.3).

    ``Z = 1 - p/T [a0 + a1 t + a2 t^2 + (b0 + b1 t) xv + (c0 + c1 t) xv^2] + p^2/T^2 (d + e xv^2)``
    with t = T - 273.15 K in degC.

    Parameters
    ----------
    p : float or array_like
        Pressure [Pa].
    T : float or array_like
        Temperature [K].
    xv : float or array_like
        Mole fraction of water vapour [-] (:func:`vapour_mole_fraction`).

    Returns
    -------
    float or ndarray
        Z [-] (about 0.9996 near the ground).
    """
    p = np.asarray(p, dtype=float)
    T = np.asarray(T, dtype=float)
    xv = np.asarray(xv, dtype=float)
    t = T - ZERO_CELSIUS
    virial = Z_A0 + Z_A1 * t + Z_A2 * t * t + (Z_B0 + Z_B1 * t) * xv + (Z_C0 + Z_C1 * t) * xv * xv
    return (1.0 - p / T * virial + (p * p) / (T * T) * (Z_D + Z_E * xv * xv))[()]


def moist_air_density(p, T, h):
    """Density of moist air from station pressure, temperature and relative humidity (CIPM-2007).

    ``rho = p Ma / (Z R T) [1 - xv (1 - Mw / Ma)]`` with the CO2 mole fraction :data:`X_CO2`
    (Picard et al. 2008, Eq. A1.1). Water vapour is lighter than dry air: at the same pressure and
    temperature the density falls as the humidity rises (by about 0.9 % from dry to saturated at
    20 degC).

    The paper states the equation for 60 000-110 000 Pa and 15-27 degC, where its relative
    standard uncertainty is 2.2e-5; over the wider range :class:`StationAir` accepts it is an
    extrapolation of small real-gas terms. It stays within 5e-4 of an independent humid-air
    formulation (ASHRAE RP-1485) there, far below a field weather meter's error (1 K of
    temperature is 0.35 % of density).

    Parameters
    ----------
    p : float or array_like
        Station pressure [Pa] (the pressure at the gun, not reduced to sea level).
    T : float or array_like
        Temperature [K].
    h : float or array_like
        Relative humidity [0-1] (a fraction, not percent).

    Returns
    -------
    float or ndarray
        Air density [kg/m^3] (about 1.1993 at 101 325 Pa, 293.15 K, h = 0.5).
    """
    p = np.asarray(p, dtype=float)
    T = np.asarray(T, dtype=float)
    xv = vapour_mole_fraction(p, T, h)
    z = compressibility(p, T, xv)
    return (p * M_DRY_AIR / (z * R_MOLAR * T) * (1.0 - xv * (1.0 - M_WATER / M_DRY_AIR)))[()]


def virtual_temperature(p, T, h):
    """The dry-air temperature that gives the moist air's density at the same pressure.

    ``Tv = p / (R_AIR rho)`` with ``rho`` = :func:`moist_air_density` and ``R_AIR`` =
    287.05287 J/(kg K), the constant of :mod:`bayesdrag.air.atmosphere`. With it the rest of the
    package models humid air as a dry atmosphere at ``Tv``: ``p / (R_AIR Tv)`` is the CIPM-2007
    density exactly (to rounding). It is made for density: dry air at ``Tv`` also has nearly the
    humid air's speed of sound (both follow the lower molar mass), but not exactly, since the water
    vapour's lower ratio of specific heats is left out (the sound speed comes out high by well under
    0.1 % for saturated air at 20 degC).

    ``Tv`` also carries the difference between CIPM-2007's dry air (real gas, Z ~ 0.9996, molar mass
    28.96546 g/mol) and the ideal gas of ``R_AIR``: at ``h = 0`` it is about 0.12 K below ``T`` near
    sea level (0.04 % of density). :func:`humidity_density_ratio` gives the humidity effect alone.

    Parameters
    ----------
    p : float or array_like
        Station pressure [Pa].
    T : float or array_like
        Temperature [K].
    h : float or array_like
        Relative humidity [0-1].

    Returns
    -------
    float or ndarray
        Virtual temperature [K] (about 294.32 K at 101 325 Pa, 293.15 K, h = 0.5).
    """
    p = np.asarray(p, dtype=float)
    return (p / (R_AIR * moist_air_density(p, T, h)))[()]


def humidity_density_ratio(p, T, h):
    """Density of the moist air over that of dry air at the same pressure and temperature.

    ``moist_air_density(p, T, h) / moist_air_density(p, T, 0)``: the humidity's effect alone, for a
    model that keeps its own dry-air density (scaling it by this ratio, or dividing its
    temperature by it, adds the water vapour and nothing else).

    Parameters
    ----------
    p : float or array_like
        Station pressure [Pa].
    T : float or array_like
        Temperature [K].
    h : float or array_like
        Relative humidity [0-1].

    Returns
    -------
    float or ndarray
        Ratio [-], 1 for dry air and below 1 for humid air (about 0.9956 at 101 325 Pa, 293.15 K,
        h = 0.5).
    """
    return (moist_air_density(p, T, h) / moist_air_density(p, T, 0.0))[()]


def _check_pressure(value):
    p = number("pressure", value, "Pa")
    lo, hi = PRESSURE_RANGE
    if lo <= p <= hi:
        return p
    hint = ""
    if lo / 100 <= p <= hi / 100:
        hint = f"; {p:g} looks like hPa (mbar): give Pa, {p * 100:g}"
    elif lo / 1000 <= p <= hi / 1000:
        hint = f"; {p:g} looks like kPa: give Pa, {p * 1000:g}"
    elif lo / 1e5 <= p <= hi / 1e5:
        hint = f"; {p:g} looks like bar: give Pa, {p * 1e5:g}"
    raise ValueError(f"pressure = {p:g} Pa is outside {lo:g}-{hi:g} Pa (station pressure at the gun, "
                     f"in pascal){hint}")


def _check_temperature(value):
    T = number("temperature", value, "K")
    lo, hi = TEMPERATURE_RANGE
    if lo <= T <= hi:
        return T
    hint = ""
    if lo - ZERO_CELSIUS <= T <= hi - ZERO_CELSIUS:
        hint = f"; {T:g} looks like degrees Celsius: give kelvin, {T + ZERO_CELSIUS:g}"
    elif (lo - ZERO_CELSIUS) * 1.8 + 32 <= T <= (hi - ZERO_CELSIUS) * 1.8 + 32:
        hint = f"; {T:g} looks like degrees Fahrenheit: give kelvin, {(T - 32) / 1.8 + ZERO_CELSIUS:.2f}"
    raise ValueError(f"temperature = {T:g} K is outside {lo:g}-{hi:g} K (air temperature at the gun, "
                     f"in kelvin){hint}")


def _check_humidity(value):
    h = number("humidity", value, "fraction 0-1")
    lo, hi = HUMIDITY_RANGE
    if lo <= h <= hi:
        return h
    hint = ""
    if hi < h <= 100.0:
        hint = f"; {h:g} looks like percent: give a fraction, {h / 100:g}"
    raise ValueError(f"humidity = {h:g} is outside {lo:g}-{hi:g} (relative humidity as a fraction, "
                     f"0.5 for 50 %){hint}")


@dataclass(frozen=True)
class StationAir:
    """The air at the gun as a weather meter reads it.

    Parameters
    ----------
    pressure : float
        Station pressure [Pa] (not reduced to sea level), within :data:`PRESSURE_RANGE`.
    temperature : float
        Air temperature [K], within :data:`TEMPERATURE_RANGE`.
    humidity : float
        Relative humidity [0-1] (a fraction: 0.5 for 50 %; 0 for dry air).

    Raises
    ------
    ValueError
        A value that is not a finite number or is out of range; the message names the key, what
        was found, what is allowed, and the likely unit mistake (hPa or kPa for Pa, Celsius or
        Fahrenheit for K, percent for a fraction).
    """

    pressure: float
    temperature: float
    humidity: float

    def __post_init__(self):
        object.__setattr__(self, "pressure", _check_pressure(self.pressure))
        object.__setattr__(self, "temperature", _check_temperature(self.temperature))
        object.__setattr__(self, "humidity", _check_humidity(self.humidity))

    @property
    def density(self) -> float:
        """Moist air density [kg/m^3] (:func:`moist_air_density`)."""
        return float(moist_air_density(self.pressure, self.temperature, self.humidity))

    @property
    def virtual_temperature(self) -> float:
        """Dry-air temperature [K] of the same density at :attr:`pressure` with ``R_AIR``
        (:func:`virtual_temperature`)."""
        return float(virtual_temperature(self.pressure, self.temperature, self.humidity))

    @property
    def vapour_pressure(self) -> float:
        """Partial pressure of the water vapour [Pa]: ``xv p``."""
        return float(vapour_mole_fraction(self.pressure, self.temperature, self.humidity) * self.pressure)


#: how an atmosphere built from station readings names its source (:func:`is_station_air`)
STATION_SOURCE = "station air"


def is_station_air(atmosphere) -> bool:
    """Whether an atmosphere was built from readings at the gun (``[atmosphere] pressure``,
    ``temperature``, ``humidity``): air measured on the day, like a met profile."""
    return str(getattr(atmosphere, "source", "")).startswith(STATION_SOURCE)
