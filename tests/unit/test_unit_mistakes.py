"""Unit mistakes are named, not blamed on another value (issue 47, item 4): a diameter in inches
or centimetres, a mass in grains, a LabRadar column in another unit than its header says, a
track's speed in ft/s beside a round in m/s, and a radar-native track in feet named by its own
channels. The tracks are made here by an integrator of their own (a flat-fire point mass with a
constant Cd, in closed form), not by bayesdrag's simulator."""
from __future__ import annotations

import math

import numpy as np
import pytest

import bayesdrag
from bayesdrag.errors import InputError
from bayesdrag.estimate.build.start import check_gravity_units, check_launch_speed, smooth_kinematics
from bayesdrag.round import Launch, Projectile, Round
from bayesdrag.track import RadarTrack

FT = 0.3048
#: a .308 175 gr bullet [kg, m] and its muzzle speed [m/s]
BULLET_MASS, BULLET_D, BULLET_V0 = 175 * 6.479891e-5, 0.308 * 0.0254, 790.0
#: a subsonic .22 LR bullet's muzzle speed [m/s] (its fps value, 1080, passes the reader's bound)
SUBSONIC_V0 = 330.0
#: the flat-fire drag constant k = rho S Cd / (2 m) [1/m] of a rifle bullet (Cd ~0.3)
K_DRAG = 0.0009


def _flight(v0, n=60, dt=0.001, t0=0.008):
    """Speed [m/s] and distance [m] of a flat-fire point mass with dv/dt = -k v^2 (closed form)."""
    t = t0 + dt * np.arange(n)
    v = v0 / (1.0 + K_DRAG * v0 * t)
    x = np.log1p(K_DRAG * v0 * t) / K_DRAG
    return t, v, x


def _labradar(tmp_path, v_values, x_values, t, vel_unit, dist_unit):
    rows = "".join(f"{a:.6f};{b:.2f};{c:.3f};{30.0:.2f}\n" for a, b, c in zip(t, v_values, x_values))
    p = tmp_path / "Shot0001 Track.csv"
    p.write_text(f"sep=;\nDevice ID;LBR-1;;\nSeries No;0001\nShot No;0001\n\nTime (s);Vel ({vel_unit});Dist ({dist_unit});SNR\n"
                 + f"0.000000;{v_values[0] + 1:.2f};0.00;-\n" + rows)
    return p


# --- the round: diameter and mass ---------------------------------------------------------------

@pytest.mark.parametrize("mass, d, match", [
    (42.6, 6.1, r"diameter = 6\.1 looks like inches; diameter is in metres \(0\.15494\)"),
    (42.6, 15.5, r"diameter = 15\.5 looks like centimetres; diameter is in metres \(0\.155\)"),
    (42.6, 155.0, r"diameter = 155 looks like millimetres; diameter is in metres \(0\.155\)"),
    # a .308 bullet's diameter typed in inches: the diameter is named, not the mass ("tonnes")
    (BULLET_MASS, 0.308, r"implausible for diameter 0\.308 m .*; the diameter looks like inches \(in m: 0\.0078232\)$"),
    (175.0, BULLET_D, r"implausible .*; the mass looks like grains \(in kg: 0\.0113398\)$"),
    (0.0426, 0.155, r"; it looks like tonnes \(in kg: 42\.6\)$"),
])
def test_the_mistaken_unit_is_named(mass, d, match):
    with pytest.raises(ValueError, match=match):
        Projectile("p", mass, d)


def test_a_plausible_projectile_gets_no_guess():
    assert Projectile("p", BULLET_MASS, BULLET_D).diameter == pytest.approx(0.0078232)
    with pytest.raises(ValueError, match=r"diameter = 1\.5 m is outside the plausible range \[0\.004, 1\] m$"):
        Projectile("p", 42.6, 1.5)                                  # no unit makes this a projectile


# --- a LabRadar export: a column in another unit than its header --------------------------------

def test_labradar_reads_a_consistent_export(tmp_path):
    t, v, x = _flight(BULLET_V0)
    tr = bayesdrag.read_track(_labradar(tmp_path, v / FT, x, t, "fps", "m"))
    assert tr.channels["range_rate"][0] == pytest.approx(v[0], rel=1e-4)


@pytest.mark.parametrize("vel, dist, scale_v, scale_x, match", [
    ("fps", "m", 1 / FT, 1e-3, r"grows at 0\.001\d* times the velocity .*Dist looks like km \(the header says m\)"),
    ("m/s", "m", 1 / FT, 1.0, r"grows at 0\.3048 times .*Vel looks like fps \(the header says m/s\)"),
    ("fps", "m", 1 / FT, 1 / FT, r"Dist looks like ft \(the header says m\)"),
])
def test_labradar_column_in_another_unit(tmp_path, vel, dist, scale_v, scale_x, match):
    t, v, x = _flight(SUBSONIC_V0)
    p = _labradar(tmp_path, v * scale_v, x * scale_x, t, vel, dist)
    with pytest.raises(InputError, match=match):
        bayesdrag.read_track(p)


# --- the track's speed against the round's launch velocity --------------------------------------

def _speed_track(v0, scale):
    t, v, _ = _flight(v0)
    return RadarTrack(t, {"range_rate": v * scale}, source="shot.csv")


def _round(v0):
    return Round(Projectile("p", BULLET_MASS, BULLET_D), Launch(elevation_deg=0.0, velocity=v0))


def test_a_track_in_fps_beside_a_round_in_m_per_s():
    with pytest.raises(InputError, match=r"shot\.csv: units look wrong: the track's first speed \(range_rate\) is "
                                         r"10\d\d m/s, 3\.2\d times the round's launch velocity 330 m/s; the "
                                         r"track's speed looks like ft/s"):
        check_launch_speed(_speed_track(SUBSONIC_V0, 1 / FT), _round(SUBSONIC_V0), ("range_rate",))


def test_a_round_velocity_typed_in_fps():
    v_fps = round(BULLET_V0 / FT)
    with pytest.raises(InputError, match=r"the round's \[launch\] velocity looks like ft/s \(in m/s: 7\d\d\)"):
        check_launch_speed(_speed_track(BULLET_V0, 1.0), _round(float(v_fps)), ("range_rate",))


@pytest.mark.parametrize("scale", [1.0, 1.05, 0.9])
def test_a_velocity_a_few_percent_off_is_the_launch_checks(scale):
    # no unit explains a few per cent: the fit's launch check says it, this check stays silent
    check_launch_speed(_speed_track(BULLET_V0, scale), _round(BULLET_V0), ("range_rate",))
    check_launch_speed(_speed_track(BULLET_V0, scale), Round(Projectile("p", BULLET_MASS, BULLET_D)), ("range_rate",))


def test_a_fit_of_a_track_in_fps_is_refused_with_the_unit():
    tr = _speed_track(SUBSONIC_V0, 1 / FT)
    with pytest.raises(InputError, match=r"the track's speed looks like ft/s"):
        bayesdrag.fit(tr, _round(SUBSONIC_V0), mcmc=False, model_check=False)


# --- a radar-native track in feet names its own channels -------------------------------------------

def test_native_track_in_feet_names_range_and_range_rate():
    g, v0, el = 9.80665, 800.0, math.radians(30.0)
    t = np.arange(0.0, 20.0, 0.05)
    # a vacuum flight (no drag: gravity is what the check reads) seen from the muzzle
    x, z = v0 * math.cos(el) * t, v0 * math.sin(el) * t - 0.5 * g * t**2
    vx, vz = v0 * math.cos(el) * np.ones_like(t), v0 * math.sin(el) - g * t
    r = np.hypot(x, z)
    rr = np.where(r > 0, (x * vx + z * vz) / np.where(r > 0, r, 1.0), v0)
    track = RadarTrack(t, {"range": r / FT, "elevation": np.arctan2(z, x), "azimuth": np.full_like(t, math.pi / 2),
                           "range_rate": rr / FT}, source="native.csv")
    kin = smooth_kinematics(RadarTrack(t, {"x": x / FT, "z": z / FT, "v": np.hypot(vx, vz) / FT}))
    with pytest.raises(InputError, match=r"range and range_rate look like feet and ft/s"):
        check_gravity_units(kin, "native.csv", channels=tuple(track.channels))


@pytest.mark.parametrize("dist", ["zeros", "nan"])
def test_labradar_without_a_recorded_distance_is_read(tmp_path, dist):
    """A distance column the device left flat (or 'nan') says nothing about units: read, not refused."""
    t, v, x = _flight(SUBSONIC_V0)
    p = _labradar(tmp_path, v / FT, np.zeros_like(x), t, "fps", "m")
    if dist == "nan":
        p.write_text(p.read_text().replace(";0.000;", ";nan;"))
    try:
        tr = bayesdrag.read_track(p)
    except InputError as exc:          # a 'nan' distance may be refused as not a number, never as a unit
        assert "units look wrong" not in str(exc), exc
        return
    assert tr.channels["range_rate"][0] == pytest.approx(v[0], rel=1e-4)
