"""ICAO standard atmosphere against published table values.

Sources: U.S. Standard Atmosphere 1976 (NOAA-S/T 76-1562), Table I (geometric altitude),
identical to the ICAO Standard Atmosphere (Doc 7488/3) below 32 km; the tropopause row is the
ICAO value at geopotential 11 000 m (geometric 11 019 m).
"""
import numpy as np
import pytest

from bayesdrag.air.atmosphere import (Atmosphere, geopotential_altitude, standard_atmosphere,
                                  R_EARTH)

# relative tolerance against the published 5-significant-digit table values (half a unit in
# the 5th digit is up to 5e-5; US76 uses R = 8.31432/28.9644 = 287.0531 J/(kg K) where ICAO
# uses 287.05287, worth a further ~3e-5 in pressure aloft)
TABLE_RTOL = 1e-4


@pytest.mark.parametrize("h, rho, a, T, p", [
    (0.0, 1.2250, 340.29, 288.15, 101325.0),
    (1000.0, 1.1117, 336.43, 281.65, 89876.0),
    (5000.0, 0.73643, 320.55, 255.68, 54048.0),
    (11000.0, 0.36480, 295.15, 216.77, 22700.0),
    (15000.0, 0.19476, 295.07, 216.65, 12111.0),
    (20000.0, 0.088910, 295.07, 216.65, 5529.3),
])
def test_us76_table(h, rho, a, T, p):
    s = standard_atmosphere(h)
    assert s.density == pytest.approx(rho, rel=TABLE_RTOL)
    assert s.speed_of_sound == pytest.approx(a, rel=TABLE_RTOL)
    assert s.temperature == pytest.approx(T, abs=0.01)
    assert s.pressure == pytest.approx(p, rel=TABLE_RTOL)


def test_icao_tropopause_geopotential_11km():
    # ICAO Doc 7488: H = 11 000 m geopotential -> 0.36392 kg/m^3, 216.65 K, 22 632 Pa
    h = R_EARTH * 11000.0 / (R_EARTH - 11000.0)
    assert geopotential_altitude(h) == pytest.approx(11000.0, abs=1e-6)
    s = standard_atmosphere(h)
    assert s.density == pytest.approx(0.36392, rel=TABLE_RTOL)
    assert s.temperature == pytest.approx(216.65, abs=1e-9)
    assert s.pressure == pytest.approx(22632.0, rel=TABLE_RTOL)


def test_vectorised_shapes():
    h = np.linspace(0, 20000, 12).reshape(3, 4)
    s = standard_atmosphere(h)
    assert s.density.shape == (3, 4) and s.speed_of_sound.shape == (3, 4)
    assert np.all(np.diff(s.density.ravel()) < 0)


def test_temperature_offset_keeps_gun_pressure():
    gun = 300.0
    hot = Atmosphere(temperature_offset=20.0, gun_altitude=gun)
    std = Atmosphere(gun_altitude=gun)
    s_hot, s_std = hot.at_height(0.0), std.at_height(0.0)
    assert s_hot.pressure == pytest.approx(s_std.pressure, rel=1e-12)
    assert s_hot.temperature == pytest.approx(s_std.temperature + 20.0, abs=1e-9)
    # ideal gas at the gun: density scales as 1/T
    assert s_hot.density / s_std.density == pytest.approx(s_std.temperature / s_hot.temperature, rel=1e-12)
    # aloft a hot column is less dense in pressure drop: pressure higher than standard
    assert hot.at_height(8000.0).pressure > std.at_height(8000.0).pressure
    # speed of sound follows sqrt(T)
    assert s_hot.speed_of_sound / s_std.speed_of_sound == pytest.approx(
        np.sqrt(s_hot.temperature / s_std.temperature), rel=1e-12)


def test_hydrostatic_balance_with_offset():
    """dp/dz = -rho g holds for the shifted profile (finite difference, 1e-6 relative)."""
    atm = Atmosphere(temperature_offset=-15.0, gun_altitude=500.0)
    for z in (100.0, 7000.0, 13000.0):
        dz = 1.0
        dp = (atm.at_height(z + dz).pressure - atm.at_height(z - dz).pressure) / (2 * dz)
        rho = atm.at_height(z).density
        # geometric dz vs geopotential: g(h) = g0 (r0/(r0+h))^2
        g = 9.80665 * (R_EARTH / (R_EARTH + z + 500.0)) ** 2
        assert dp == pytest.approx(-rho * g, rel=1e-6)


def test_pressure_and_density_ratio():
    s = Atmosphere(pressure_ratio=0.95, density_ratio=1.02).at_height(2000.0)
    s0 = Atmosphere().at_height(2000.0)
    assert s.density == pytest.approx(s0.density * 0.95 * 1.02, rel=1e-12)
    assert s.speed_of_sound == pytest.approx(s0.speed_of_sound, rel=1e-12)


def test_scalar_fast_path_matches():
    atm = Atmosphere(temperature_offset=12.0, pressure_ratio=0.98, gun_altitude=800.0)
    for z in (-600.0, 0.0, 4321.0, 10500.0, 12000.0, 19000.0):
        rho, a = atm.density_and_sound_speed(z)
        s = atm.at_height(z)
        assert rho == pytest.approx(float(s.density), rel=1e-13)
        assert a == pytest.approx(float(s.speed_of_sound), rel=1e-13)


def test_table_interpolation_error():
    z0, dz, tab = Atmosphere().table()
    zm = z0 + dz * (np.arange(len(tab) - 1) + 0.5)
    exact = Atmosphere().at_height(zm).density
    interp = 0.5 * (tab[:-1, 0] + tab[1:, 0])
    err = np.abs(interp / exact - 1)
    # smooth layers: curvature error dz^2/(8 H^2) ~ 4e-8; the tropopause kink (11 km
    # geopotential) costs one cell ~1.4e-5 and the 20 km one ~4e-6, harmless for a trajectory
    assert err.max() < 2e-5
    kinks = [R_EARTH * H / (R_EARTH - H) for H in (11000.0, 20000.0)]
    kink = np.min([np.abs(zm - k) for k in kinks], axis=0) < 2 * dz
    assert err[~kink].max() < 1e-7


@pytest.mark.parametrize("kw, match", [
    (dict(temperature_offset=float("nan")), "temperature_offset"),
    (dict(pressure_ratio=0.0), "pressure_ratio"),
    (dict(density_ratio=-1.0), "density_ratio"),
])
def test_bad_parameters(kw, match):
    with pytest.raises(ValueError, match=match):
        Atmosphere(**kw)


def test_altitude_out_of_range():
    with pytest.raises(ValueError, match="outside the standard atmosphere"):
        standard_atmosphere(40000.0)
    with pytest.raises(ValueError, match="finite"):
        standard_atmosphere(np.nan)
