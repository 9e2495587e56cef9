"""Radar-native tracks on the way in and out: ``simulate --radar native`` writes range,
azimuth, elevation and range rate with noise in the radar's own coordinates; the track and
round readers take the native columns and keys (docs/radar.md)."""
import math
from importlib.resources import files

import numpy as np
import pytest

from bayesdrag.cli import main
from bayesdrag.commands.simulate import simulate
from bayesdrag.errors import InputError
from bayesdrag.io.rounds import read_round, write_round
from bayesdrag.io.tracks import read_track, write_track
from bayesdrag.measure import wrap_angle
from bayesdrag.synthetic import simulate_round

ROUND = """
[projectile]
name = "155 mm M101"
mass = 42.6
diameter = 0.155
reference_drag = "{ref}"

[launch]
elevation = {qe}
velocity = 818.0
{azimuth}

[radar]
position = {{x = {px}, y = {py}, z = 2.0}}
sigma = {{range = 2.0, azimuth = 0.03, elevation = 0.03, range_rate = 0.1}}
range_bias_sd = 1.0
azimuth_bias_sd = 0.05
elevation_bias_sd = 0.05
position_sd = 0.2
"""
#: the noise sd measured on a whole flight (~1000-2800 samples) must be within this fraction
#: of the round's sigma (the sd of an sd estimate from 1000 samples is 2.2 %)
NOISE_SD_REL = 0.08
#: range rate of a radar at the muzzle against the speed, early in a flat shot [-]
FLAT_RANGE_RATE_REL = 1e-3


def _round(tmp_path, qe=45.0, azimuth="azimuth = 90.0", px=-40.0, py=25.0):
    f = tmp_path / "r.toml"
    f.write_text(ROUND.format(ref=str(files("bayesdrag") / "data" / "cd_m101.csv"), qe=qe, azimuth=azimuth,
                              px=px, py=py))
    return f


def test_round_reads_the_radar_site_and_native_sigma(tmp_path):
    rnd = read_round(_round(tmp_path))
    ra = rnd.radar
    assert ra.position == (-40.0, 25.0, 2.0)
    assert ra.sigma["azimuth"] == pytest.approx(math.radians(0.03))      # deg in the file, rad inside
    assert ra.sigma["range"] == 2.0 and ra.sigma["range_rate"] == 0.1
    assert ra.elevation_bias_sd == pytest.approx(math.radians(0.05))
    assert ra.range_bias_sd == 1.0 and ra.position_sd == 0.2
    out = tmp_path / "again.toml"
    write_round(out, rnd)
    back = read_round(out)
    assert back.radar.position == ra.position
    assert back.radar.sigma == pytest.approx(ra.sigma)
    assert back.radar.azimuth_bias_sd == pytest.approx(ra.azimuth_bias_sd)
    assert back.launch.azimuth_given


def test_round_refuses_a_bad_radar_position(tmp_path):
    f = _round(tmp_path)
    f.write_text(f.read_text().replace("position = {x = -40.0, y = 25.0, z = 2.0}", "position = {x = -40.0, w = 1}"))
    with pytest.raises(InputError, match=r"r.toml: \[radar\] position has unknown key\(s\) w; allowed: x, y, z"):
        read_round(f)


def test_simulate_native_writes_the_radar_columns(tmp_path):
    out = tmp_path / "n.csv"
    assert main(["simulate", str(_round(tmp_path)), "-o", str(out), "--radar", "native", "--noise",
                 "--seed", "3", "--quiet"]) == 0
    header = [ln for ln in out.read_text().splitlines() if not ln.startswith("#")][0]
    assert header == "t,range,azimuth,elevation,range_rate"
    tr = read_track(out)
    assert tr.names == ("range", "azimuth", "elevation", "range_rate")
    # the file holds degrees; the track radians: firing east, the shell is seen east-ish
    assert 60.0 < math.degrees(float(np.median(tr.channels["azimuth"]))) < 120.0
    write_track(tmp_path / "again.csv", tr)
    back = read_track(tmp_path / "again.csv")
    assert np.allclose(back.channels["azimuth"], tr.channels["azimuth"], atol=1e-8)


def test_native_noise_has_the_rounds_sd(tmp_path):
    rnd = read_round(_round(tmp_path))
    clean = simulate(rnd, radar="native")
    noisy = simulate(rnd, radar="native", noise=True, seed=11)
    for c, sd in rnd.radar.sigma.items():
        d = noisy.channels[c] - clean.channels[c]
        if c == "azimuth":
            d = wrap_angle(d)
        assert abs(np.std(d) / sd - 1.0) < NOISE_SD_REL, c


def test_angle_channels_need_the_firing_azimuth(tmp_path):
    f = _round(tmp_path, azimuth="")
    with pytest.raises(InputError, match=r"\[launch\] azimuth is missing.*azimuth and elevation"):
        simulate(read_round(f), radar="native")
    # range and range rate alone do not
    tr = simulate_round(read_round(f), channels=("range", "range_rate"))
    assert tr.names == ("range", "range_rate")


def test_radar_at_the_muzzle_sees_the_speed_early_in_a_flat_shot(tmp_path):
    rnd = read_round(_write_muzzle(tmp_path))
    tr = simulate_round(rnd, channels=("range_rate", "v"))
    early = tr.t < 1.0
    ratio = tr.channels["range_rate"][early] / tr.channels["v"][early]
    assert np.all(np.abs(ratio - 1.0) < FLAT_RANGE_RATE_REL)
    # later the flight turns away from the line of sight: range rate falls below the speed
    assert tr.channels["range_rate"][-1] < (1.0 - FLAT_RANGE_RATE_REL / 10) * tr.channels["v"][-1]


def _write_muzzle(tmp_path):
    f = _round(tmp_path, qe=2.0, px=0.0, py=0.0)
    f.write_text(f.read_text().replace("z = 2.0", "z = 0.0"))
    return f


def test_simulate_native_noise_needs_native_sigma(tmp_path):
    f = _round(tmp_path)
    f.write_text(f.read_text().replace("sigma = {range = 2.0, azimuth = 0.03, elevation = 0.03, range_rate = 0.1}",
                                       "sigma = {range = 2.0}"))
    with pytest.raises(InputError, match="missing: azimuth, elevation, range_rate"):
        simulate(read_round(f), radar="native", noise=True, seed=1)


@pytest.mark.parametrize("line, message", [
    ("azimuth_bias_sd = 0.05", r"\[radar\] azimuth_bias_sd = -1 must be > 0 \(deg\)"),
    ("range_bias_sd = 1.0", r"\[radar\] range_bias_sd = -1 must be > 0"),
])
def test_round_refuses_bad_bias_sds(tmp_path, line, message):
    f = _round(tmp_path)
    f.write_text(f.read_text().replace(line, line.split("=")[0] + "= -1"))
    with pytest.raises(InputError, match=message):
        read_round(f)


def test_round_refuses_an_implausible_angle_bias_and_a_far_site(tmp_path):
    f = _round(tmp_path)
    f.write_text(f.read_text().replace("elevation_bias_sd = 0.05", "elevation_bias_sd = 5.0"))
    with pytest.raises(InputError, match=r"\[radar\] elevation_bias_sd = 5 deg is larger than the plausible 1 deg"):
        read_round(f)
    f = _round(tmp_path, px=-40000.0)
    with pytest.raises(InputError, match=r"\[radar\] position = .* m from the muzzle, more than the plausible 20000 m"):
        read_round(f)
