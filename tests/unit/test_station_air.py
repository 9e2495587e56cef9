"""Moist air density at the gun (CIPM-2007, Picard et al. 2008, Metrologia 45, 149) from a weather
meter's station pressure, temperature and relative humidity; the virtual temperature that carries it
into the package's dry-air model; the readings' checks and their unit hints."""
import dataclasses

import numpy as np
import pytest

from bayesdrag.air.atmosphere import R_AIR
from bayesdrag.air.station import (StationAir, compressibility, enhancement_factor, humidity_density_ratio,
                                   moist_air_density, saturation_vapour_pressure, vapour_mole_fraction,
                                   virtual_temperature)

#: the CIPM-2007 saturation vapour pressure is a fit to the IAPWS values within 1e-4 relative
PSV_RTOL = 1e-4
#: CIPM-2007 against an independent humid-air formulation near its stated range [-]: the two
#: differ by their dry-air molar mass and virial data (4e-5 at 20 degC)
INDEPENDENT_RTOL = 1e-4
#: p / (R_AIR Tv) reproduces the moist density to rounding [-]
VIRTUAL_T_RTOL = 1e-9
#: one mmHg [Pa]
MMHG = 133.322387415

#: saturation vapour pressure of water [Pa] at T [K], IAPWS-95 (Wagner and Pruss 2002, J. Phys.
#: Chem. Ref. Data 31, 387): the triple point, 20 degC, 40 degC
IAPWS_PSV = [(273.16, 611.657), (293.15, 2339.3), (313.15, 7384.9)]

#: (p [Pa], T [K], h [-], density [kg/m^3]) from the ASHRAE RP-1485 humid-air formulation
#: (Herrmann, Kretzschmar and Gatley 2009, HVAC&R Research 15, 961), as CoolProp 8.0 HAPropsSI
#: computes it: an independent check of the whole chain to 6 digits
INDEPENDENT_DENSITY = [
    (101325.0, 293.15, 0.5, 1.19936),
    (101325.0, 288.15, 0.0, 1.22557),
    (730 * MMHG, 283.15, 0.4, 1.19574),
    (80000.0, 313.15, 0.8, 0.865411),
]


@pytest.mark.parametrize("T, psv", IAPWS_PSV)
def test_saturation_vapour_pressure_matches_iapws(T, psv):
    assert saturation_vapour_pressure(T) == pytest.approx(psv, rel=PSV_RTOL)


def test_enhancement_factor_and_compressibility_near_the_ground():
    # f = 1.00062 + 3.14e-8 * 101325 + 5.6e-7 * 20^2 (Picard 2008, A1.2)
    assert enhancement_factor(101325.0, 20.0) == pytest.approx(1.0040256, abs=1e-7)
    assert enhancement_factor(101325.0, 20.0) > enhancement_factor(60000.0, 20.0)
    z_dry = compressibility(101325.0, 293.15, 0.0)
    assert z_dry == pytest.approx(0.99964, abs=1e-5)
    assert compressibility(101325.0, 293.15, 0.0116) < z_dry        # vapour adds non-ideality
    assert compressibility(0.0, 293.15, 0.0) == 1.0                  # the ideal-gas limit


def test_density_at_20c_50_percent():
    """The CIPM-2007 value at 101 325 Pa, 20 degC, 50 % RH, xCO2 = 0.0004 is 1.1993 kg/m^3
    (psv = 2339.16 Pa, f = 1.004026, xv = 0.011589, Z = 0.999615)."""
    xv = vapour_mole_fraction(101325.0, 293.15, 0.5)
    assert xv == pytest.approx(0.011589, abs=1e-6)
    assert compressibility(101325.0, 293.15, xv) == pytest.approx(0.999615, abs=1e-6)
    assert moist_air_density(101325.0, 293.15, 0.5) == pytest.approx(1.19931, abs=1e-5)


@pytest.mark.parametrize("p, T, h, rho", INDEPENDENT_DENSITY)
def test_density_agrees_with_an_independent_formulation(p, T, h, rho):
    assert moist_air_density(p, T, h) == pytest.approx(rho, rel=INDEPENDENT_RTOL)


def test_dry_air_at_icao_sea_level():
    # the package's dry-air model: 101 325 Pa / (R_AIR 288.15 K) is the ICAO 1.2250 kg/m^3
    assert 101325.0 / (R_AIR * 288.15) == pytest.approx(1.2250, abs=5e-5)
    # CIPM-2007 dry air is a real gas of molar mass 28.96546 g/mol: 0.04 % denser
    cipm = moist_air_density(101325.0, 288.15, 0.0)
    assert cipm == pytest.approx(1.2250, rel=5e-4) and cipm > 1.2250
    assert humidity_density_ratio(101325.0, 288.15, 0.0) == 1.0


@pytest.mark.parametrize("p, T", [(101325.0, 293.15), (85000.0, 268.15), (60000.0, 318.15)])
def test_density_decreases_with_humidity(p, T):
    h = np.linspace(0.0, 1.0, 11)
    rho = moist_air_density(p, T, h)
    assert rho.shape == h.shape
    assert np.all(np.diff(rho) < 0)
    assert np.all(np.diff(humidity_density_ratio(p, T, h)) < 0)
    assert np.all(np.diff(virtual_temperature(p, T, h)) > 0)


def test_saturated_air_at_20c_is_lighter_by_under_one_percent():
    drop = 1.0 - humidity_density_ratio(101325.0, 293.15, 1.0)
    assert 0.008 < drop < 0.0095


@pytest.mark.parametrize("p, T, h", [(101325.0, 293.15, 0.5), (101325.0, 288.15, 0.0), (52000.0, 223.0, 1.0),
                                     (109000.0, 328.0, 0.95), (70000.0, 300.0, 0.3)])
def test_virtual_temperature_reproduces_the_moist_density(p, T, h):
    tv = virtual_temperature(p, T, h)
    assert p / (R_AIR * tv) == pytest.approx(moist_air_density(p, T, h), rel=VIRTUAL_T_RTOL)


def test_virtual_temperature_values():
    assert virtual_temperature(101325.0, 293.15, 0.5) == pytest.approx(294.32, abs=0.01)
    # dry: the CIPM real gas against R_AIR's ideal gas, 0.12 K
    assert 288.15 - virtual_temperature(101325.0, 288.15, 0.0) == pytest.approx(0.12, abs=0.01)


def test_arrays_broadcast():
    p = np.array([90000.0, 100000.0])
    T = np.array([[280.0], [300.0]])
    rho = moist_air_density(p, T, 0.5)
    assert rho.shape == (2, 2)
    assert rho[0, 1] == pytest.approx(moist_air_density(100000.0, 280.0, 0.5), rel=1e-15)
    assert np.ndim(moist_air_density(1e5, 290.0, 0.2)) == 0


def test_station_air_values_and_frozen():
    air = StationAir(pressure=101325, temperature=293.15, humidity=0.5)
    assert isinstance(air.pressure, float) and air.pressure == 101325.0
    assert air.density == pytest.approx(moist_air_density(101325.0, 293.15, 0.5), rel=1e-15)
    assert air.virtual_temperature == pytest.approx(virtual_temperature(101325.0, 293.15, 0.5), rel=1e-15)
    assert air.vapour_pressure == pytest.approx(0.5 * 1.0040256 * 2339.16, rel=1e-5)
    with pytest.raises(dataclasses.FrozenInstanceError):
        air.humidity = 0.2
    assert StationAir(50000.0, 220.0, 0.0).density > 0
    assert StationAir(110000.0, 330.0, 1.0).density > 0


@pytest.mark.parametrize("kwargs, match", [
    ({"pressure": 1013.25}, r"pressure = 1013\.25 Pa is outside 50000-110000 Pa.*looks like hPa \(mbar\): give Pa, 101325"),
    ({"pressure": 101.325}, r"looks like kPa: give Pa, 101325"),
    ({"pressure": 1.01325}, r"looks like bar"),
    ({"pressure": 20000.0}, r"pressure = 20000 Pa is outside 50000-110000 Pa \(station pressure at the gun, in pascal\)$"),
    ({"pressure": -5.0}, r"outside 50000-110000 Pa"),
    ({"temperature": 20.0}, r"temperature = 20 K is outside 220-330 K.*looks like degrees Celsius: give kelvin, 293\.15"),
    ({"temperature": -10.0}, r"looks like degrees Celsius: give kelvin, 263\.15"),
    ({"temperature": 68.0}, r"looks like degrees Fahrenheit: give kelvin, 293\.15"),
    ({"temperature": 400.0}, r"temperature = 400 K is outside 220-330 K \(air temperature at the gun, in kelvin\)$"),
    ({"humidity": 50.0}, r"humidity = 50 is outside 0-1.*looks like percent: give a fraction, 0\.5"),
    ({"humidity": 1.5}, r"looks like percent: give a fraction, 0\.015"),
    ({"humidity": -0.1}, r"humidity = -0\.1 is outside 0-1 \(relative humidity as a fraction, 0\.5 for 50 %\)$"),
    ({"humidity": 150.0}, r"humidity = 150 is outside 0-1 \(relative humidity as a fraction, 0\.5 for 50 %\)$"),
    ({"pressure": "101325"}, r"pressure must be a number \(Pa\), got string '101325'"),
    ({"temperature": float("nan")}, r"temperature must be a finite number \(K\)"),
    ({"humidity": True}, r"humidity must be a number \(fraction 0-1\), got boolean true"),
    ({"humidity": None}, r"humidity must be a number"),
])
def test_station_air_refuses_readings_naming_the_likely_unit(kwargs, match):
    readings = {"pressure": 101325.0, "temperature": 293.15, "humidity": 0.5} | kwargs
    with pytest.raises(ValueError, match=match):
        StationAir(**readings)


# ---------------------------------------------------------------- [atmosphere] station readings
def _round(tmp_path, atmosphere):
    p = tmp_path / "r.toml"
    p.write_text("[projectile]\nmass = 0.0092\ndiameter = 0.0067\n[launch]\naltitude = 670.0\n[atmosphere]\n"
                 + atmosphere)
    return p


def test_station_readings_give_the_cipm_density_at_the_gun(tmp_path):
    from bayesdrag.air.station import StationAir, is_station_air
    from bayesdrag.io.rounds import read_round

    rnd = read_round(_round(tmp_path, "pressure = 93500.0\ntemperature = 268.15\nhumidity = 0.6\n"))
    air = rnd.atmosphere.at_height(0.0)
    assert abs(float(air.density) / StationAir(93500.0, 268.15, 0.6).density - 1) < 1e-12
    assert abs(float(air.pressure) - 93500.0) < 1e-6
    assert is_station_air(rnd.atmosphere)


@pytest.mark.parametrize("text, match", [
    ("pressure = 93500.0\n", "without temperature"),
    ("pressure = 935.0\ntemperature = 268.15\n", "hPa"),
    ("pressure = 93500.0\ntemperature = 268.15\ndensity_ratio = 1.01\n", "one way"),
    ("pressure = 93500.0\ntemperature = 268.15\nhumidity = 60\n", "fraction|percent|0-1|0 .. 1"),
])
def test_station_readings_refused_with_the_reason(tmp_path, text, match):
    from bayesdrag.errors import InputError
    from bayesdrag.io.rounds import read_round

    with pytest.raises(InputError, match=match):
        read_round(_round(tmp_path, text))
