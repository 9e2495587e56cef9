"""Tabulated meteorological profiles (``[atmosphere] profile = "met.csv"``).

Reference: the ICAO standard atmosphere of :mod:`bayesdrag.air.atmosphere` (itself checked against
US76 tables in test_atmosphere.py): a profile sampled from it must reproduce it.
"""

import numpy as np
import pytest

from bayesdrag.air.atmosphere import Atmosphere, geopotential_altitude, MetProfile, R_AIR, R_EARTH, standard_atmosphere
from bayesdrag.io.met import read_met_profile, write_met_profile
from bayesdrag.dynamics.pointmass import PointMassModel
from bayesdrag.dynamics.trajectory import initial_state
from bayesdrag.io.drag_tables import load_m101
from bayesdrag.errors import InputError
from bayesdrag.io.rounds import read_round, write_round

#: relative agreement of a profile sampled from ICAO with Atmosphere() (the brief's 1e-4; the
#: construction is exact up to the level altitudes' rounding, measured ~1e-6)
ICAO_RTOL = 1e-4
#: the tropopause in geometric metres (geopotential 11 000 m), so a profile has a level on the kink
TROPO = R_EARTH * 11000.0 / (R_EARTH - 11000.0)
LEVELS = np.array([-300.0, 0.0, 250.0, 1000.0, 3000.0, 6000.0, TROPO, 14000.0])


def icao_profile(levels=LEVELS, **kw):
    s = standard_atmosphere(levels)
    return MetProfile(tuple(levels), tuple(s.temperature), tuple(s.pressure), **kw)


def write_csv(path, header, rows):
    path.write_text("# test profile\n" + header + "\n" + "".join(",".join(map(str, r)) + "\n" for r in rows))
    return path


@pytest.mark.parametrize("kw", [dict(), dict(gun_altitude=400.0), dict(temperature_offset=-12.0, gun_altitude=150.0),
                                dict(pressure_ratio=0.97, density_ratio=1.03)])
def test_icao_profile_reproduces_atmosphere(kw):
    prof, ref = icao_profile(**kw), Atmosphere(**kw)
    z = np.linspace(-800.0, 22000.0, 2001)  # inside and on both sides of the profile
    a, b = prof.at_height(z), ref.at_height(z)
    for name in ("density", "speed_of_sound", "pressure", "temperature"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=ICAO_RTOL, err_msg=name)


def test_coarse_icao_profile_is_still_exact():
    # within a layer the hydrostatic integral is exact for linear T, so 2 levels 6 km apart suffice
    prof = icao_profile(np.array([0.0, 6000.0]))
    z = np.linspace(0.0, 6000.0, 61)
    np.testing.assert_allclose(prof.at_height(z).density, Atmosphere().at_height(z).density, rtol=1e-9)


def test_measured_levels_are_honoured_and_ideal_gas():
    # a warm, slightly non-hydrostatic (humid) profile: measured pressures are kept exactly
    z = np.array([100.0, 600.0, 1500.0, 3000.0])
    T = np.array([300.0, 297.5, 291.0, 282.0])
    s = Atmosphere(temperature_offset=12.0).at_height(z)
    p = s.pressure * np.array([1.0, 1.002, 1.003, 1.001])
    prof = MetProfile(tuple(z), tuple(T), tuple(p), gun_altitude=100.0)
    got = prof.at_height(z - 100.0)
    np.testing.assert_allclose(got.pressure, p, rtol=1e-12)
    np.testing.assert_allclose(got.temperature, T, rtol=1e-12)
    np.testing.assert_allclose(got.density, p / (R_AIR * T), rtol=1e-12)
    np.testing.assert_allclose(got.speed_of_sound, np.sqrt(1.4 * R_AIR * T), rtol=1e-12)
    # pressure and density fall monotonically through and beyond the profile
    zz = np.linspace(-500, 15000, 400)
    assert np.all(np.diff(prof.at_height(zz).pressure) < 0)


def test_extrapolation_continues_with_standard_lapse_rates():
    prof = MetProfile((0.0, 1000.0), (300.0, 294.0), (101325.0, 89900.0))
    above = prof.at_height(np.array([1000.0, 3000.0])).temperature
    dH = geopotential_altitude(3000.0) - geopotential_altitude(1000.0)  # m, geopotential
    assert above[1] - above[0] == pytest.approx(-0.0065 * dH, rel=1e-9)
    below = prof.at_height(np.array([-500.0, 0.0])).temperature
    assert below[0] - below[1] == pytest.approx(0.0065 * -geopotential_altitude(-500.0), rel=1e-9)
    # continuity at the ends (no jump in density)
    eps = 1e-6
    for zb in (0.0, 1000.0):
        lo, hi = prof.at_height(np.array([zb - eps, zb + eps])).density
        assert hi == pytest.approx(lo, rel=1e-8)


def test_temperature_offset_keeps_gun_pressure():
    base = icao_profile(gun_altitude=250.0)
    hot = icao_profile(gun_altitude=250.0, temperature_offset=15.0)
    assert hot.at_height(0.0).pressure == pytest.approx(base.at_height(0.0).pressure, rel=1e-12)
    assert hot.at_height(0.0).temperature == pytest.approx(base.at_height(0.0).temperature + 15.0, abs=1e-9)


def test_hashable_and_table_and_scalar_path():
    a, b = icao_profile(), icao_profile()
    assert a == b and hash(a) == hash(b) and len({a, b}) == 1
    assert a != icao_profile(temperature_offset=1.0)
    z0, dz, tab = a.table()
    z0r, dzr, tabr = Atmosphere().table()
    assert (z0, dz) == (z0r, dzr) and tab.shape == tabr.shape
    np.testing.assert_allclose(tab, tabr, rtol=ICAO_RTOL)
    rho, c = a.density_and_sound_speed(1234.5)
    s = a.at_height(1234.5)
    assert rho == pytest.approx(float(s.density), rel=1e-14) and c == pytest.approx(float(s.speed_of_sound), rel=1e-14)


def test_trajectory_through_icao_profile_matches_standard():
    m101 = load_m101()
    t = np.arange(0.0, 40.0, 0.5)
    s0 = initial_state(818.0, 30.0)
    ref = PointMassModel(42.6, 0.155, m101).simulate((), s0, t)
    got = PointMassModel(42.6, 0.155, m101, atmosphere=icao_profile()).simulate((), s0, t)
    assert np.abs(got.state[:, :3] - ref.state[:, :3]).max() < 0.05  # m over a 40 s flight


def test_per_level_winds_make_the_profiles_wind_by_altitude():
    prof = MetProfile((0.0, 1000.0, 2000.0), (288.0, 281.5, 275.0), (101325.0, 89875.0, 79495.0),
                      wind_x=(2.0, 6.0, 10.0), wind_y=(-1.0, -1.0, 3.0))
    assert prof.has_wind and not icao_profile().has_wind
    assert prof.wind.axis == "altitude" and prof.wind.levels == prof.altitude
    np.testing.assert_allclose(prof.wind.at([500.0, 1500.0, 5000.0, -100.0]),
                               [[4.0, -1.0], [8.0, 1.0], [10.0, 3.0], [2.0, -1.0]])


def test_a_repeated_altitude_is_a_step_in_the_wind():
    """Layers of constant wind in a met CSV: the altitude of a step repeats with its temperature
    and pressure; the air keeps the distinct levels."""
    T, p = (288.0, 281.5, 275.0), (101325.0, 89875.0, 79495.0)
    prof = MetProfile((0.0, 1000.0, 1000.0, 2000.0), (T[0], T[1], T[1], T[2]), (p[0], p[1], p[1], p[2]),
                      wind_x=(2.0, 2.0, -5.0, -5.0))
    assert prof.altitude == (0.0, 1000.0, 2000.0) and prof.wind_x is None
    np.testing.assert_allclose(prof.wind.at([900.0, 1000.0, 1100.0, 1500.0])[:, 0], [2.0, -1.5, -5.0, -5.0])
    plain = MetProfile((0.0, 1000.0, 2000.0), T, p)
    assert prof.at_height(700.0).density == plain.at_height(700.0).density
    with pytest.raises(ValueError, match="repeats with another temperature or pressure"):
        MetProfile((0.0, 1000.0, 1000.0, 2000.0), (T[0], T[1], T[1] + 1, T[2]), (p[0], p[1], p[1], p[2]),
                   wind_x=(2.0, 2.0, -5.0, -5.0))


def test_round_with_profile_roundtrip(tmp_path):
    prof = icao_profile(gun_altitude=0.0)
    write_met_profile(tmp_path / "met.csv", prof)
    (tmp_path / "r.toml").write_text('[projectile]\nmass = 42.6\ndiameter = 0.155\n'
                                     '[launch]\naltitude = 250.0\n'
                                     '[atmosphere]\nprofile = "met.csv"\ntemperature_offset = 2.0\n')
    rnd = read_round(tmp_path / "r.toml")
    assert isinstance(rnd.atmosphere, MetProfile)
    assert rnd.atmosphere.gun_altitude == 250.0 and rnd.atmosphere.temperature_offset == 2.0
    assert rnd.atmosphere == icao_profile(gun_altitude=250.0, temperature_offset=2.0)
    (tmp_path / "sub").mkdir()
    write_round(tmp_path / "sub" / "r2.toml", rnd)
    assert read_round(tmp_path / "sub" / "r2.toml").atmosphere == rnd.atmosphere


ROWS = [(0.0, 288.15, 101325.0), (1000.0, 281.65, 89876.3), (2000.0, 275.15, 79495.2)]


@pytest.mark.parametrize("rows, match", [
    ([ROWS[1], ROWS[0], ROWS[2]], r"line 4: altitude 0 m is below the previous level 1000 m"),
    ([ROWS[0], ROWS[0], ROWS[2]], r"line 4: altitude 0 m repeats"),
    ([ROWS[0], (1000.0, 281.65, -5.0), ROWS[2]], r"line 4: pressure -5 Pa at altitude 1000 m must be > 0"),
    ([(z, T - 273.15, p) for z, T, p in ROWS], r"looks like degrees Celsius.*kelvin"),
    ([(z, T, p / 100) for z, T, p in ROWS], r"looks like hPa"),
    ([ROWS[0], (1000.0, 281.65, 85000.0), ROWS[2]], r"line 4: .*inconsistent with hydrostatic balance"),
    ([ROWS[0], (1000.0, 281.65, 102000.0), ROWS[2]], r"must fall with altitude"),
    ([ROWS[0]], r"at least 2 levels"),
])
def test_bad_profiles(tmp_path, rows, match):
    p = write_csv(tmp_path / "met.csv", "altitude,temperature,pressure", rows)
    with pytest.raises(InputError, match=match):
        read_met_profile(p)


def test_bad_profile_columns_and_round_keys(tmp_path):
    write_csv(tmp_path / "met.csv", "altitude,temp,pressure", ROWS)
    with pytest.raises(InputError, match=r"needs column\(s\) altitude, temperature, pressure; missing temperature"):
        read_met_profile(tmp_path / "met.csv")
    write_csv(tmp_path / "good.csv", "altitude,temperature,pressure", ROWS)
    base = '[projectile]\nmass = 42.6\ndiameter = 0.155\n[atmosphere]\n'
    for body, match in [('profile = "nope.csv"', r"\[atmosphere\] profile = 'nope.csv': .*not found"),
                        ('model = "icao"\nprofile = "good.csv"', r"model = 'icao' contradicts profile"),
                        ('model = "profile"', r"model = 'profile' needs profile"),
                        ('profile = 3', r"profile must be a CSV file path"),
                        ('profile = "met.csv"', r"met.csv: line 2: met profile needs column")]:
        (tmp_path / "r.toml").write_text(base + body + "\n")
        with pytest.raises(InputError, match=match):
            read_round(tmp_path / "r.toml")


def test_wind_in_knots_rejected():
    with pytest.raises(ValueError, match=r"wind_x = 200 m/s .* exceeds"):
        MetProfile((0.0, 1000.0), (288.15, 281.65), (101325.0, 89876.3), wind_x=(10.0, 200.0))
