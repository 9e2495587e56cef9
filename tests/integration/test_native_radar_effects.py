"""The radar's own errors as diagnosis effects (issue 28, docs/radar.md "The radar's errors as
effects"): a tracking radar whose elevation, range or site is off by an amount the round does not
declare has that error named first and sized by the diagnosis, a clean track gains no radar
finding, ``--with`` fits it, and asking for one on a track without its channel is refused."""
import math
from dataclasses import replace

import numpy as np
import pytest

import bayesdrag
from bayesdrag.diagnosis import diagnose
from bayesdrag.effects import RADAR_EFFECT_CHANNELS
from bayesdrag.errors import InputError
from bayesdrag.measure import site_of
from bayesdrag.round import Launch, Projectile, Radar, Round
from bayesdrag.synthetic import add_noise, simulate_round
from fixtures.judge import wrong_rows

#: a found effect's size is within this many of its reported sd of the truth
SIZE_SDS = 3.0
#: a full tracking radar: 2 m in range, 0.03 deg in each angle, 0.1 m/s in range rate
TRACKING = {"range": 2.0, "azimuth": math.radians(0.03), "elevation": math.radians(0.03), "range_rate": 0.1}
#: the undeclared errors: an elevation bias [rad], a range bias [m], the site 3 m off [m]
ELEVATION_BIAS = math.radians(0.05)
RANGE_BIAS = 5.0
SITE_OFFSET = (2.0, -2.0, 1.0)
#: how well the muzzle's place is known [m] in the site case: a radar's offset shows only against
#: it (a shift of the site is a shift of the whole flight but for where the flight starts)
SURVEYED_MUZZLE_SD = 0.3


def _round(m101, position_sd=1.0):
    """155 mm M101 at QE 45 seen by a tracking radar 30 m to the right of the gun, 5 m behind."""
    return Round(Projectile("155 mm M101", 42.6, 0.155, m101, None),
                 Launch(45.0, 818.0, azimuth_deg=90.0, position_sd=position_sd),
                 radar=Radar(dict(TRACKING), position=(-5.0, 30.0, 1.0)), path="tracking.toml")


def _track(rnd, seed, channels=tuple(TRACKING), **site_change):
    """A noisy track recorded by the round's radar with ``site_change`` (biases, another site)
    that the round does not declare."""
    site = site_of(rnd, channels)
    if "offset" in site_change:
        site_change["position"] = tuple(np.add(site.position, site_change.pop("offset")))
    clean = simulate_round(rnd, channels=channels, site=replace(site, **site_change))
    return add_noise(clean, {c: TRACKING[c] for c in channels}, np.random.default_rng(seed))


CASES = {
    # name: (round's muzzle sd [m], the radar's error, effect, its parameters' truth, seed)
    "elevation": (1.0, {"elevation_bias": ELEVATION_BIAS}, "elevation_bias", {"bias": ELEVATION_BIAS}, 2861),
    "range": (1.0, {"range_bias": RANGE_BIAS}, "range_bias", {"bias": RANGE_BIAS}, 2862),
    "site": (SURVEYED_MUZZLE_SD, {"offset": SITE_OFFSET}, "radar_position", dict(zip("xyz", SITE_OFFSET)), 2863),
}


@pytest.mark.parametrize("name", list(CASES))
def test_the_radar_error_is_named_first_and_sized(name, m101):
    sd_muzzle, change, effect, truth, seed = CASES[name]
    rnd = _round(m101, sd_muzzle)
    s = diagnose(_track(rnd, seed, **change), rnd).record
    assert s["verdict"][:1] == [effect], (s["verdict"], [(r["name"], r["delta_chi2"]) for r in s["effects"][:4]])
    row = next(r for r in s["effects"] if r["name"] == effect)
    for p, t in truth.items():
        assert abs(row["params"][p] - t) <= SIZE_SDS * row["sd"][p], (p, row["params"][p], row["sd"][p], t)


@pytest.mark.parametrize("seed", [2864, 2865])
def test_a_clean_track_gains_no_radar_finding(seed, m101):
    rnd = _round(m101)
    s = diagnose(_track(rnd, seed), rnd).record
    assert not set(s["verdict"] + s["immaterial"]) & set(RADAR_EFFECT_CHANNELS), s["verdict"]
    tested = {r["name"] for r in s["effects"]}
    assert {"range_bias", "elevation_bias"} <= tested      # they were candidates, not left out


def test_a_gun_frame_track_has_no_radar_candidate(m101):
    rnd = _round(m101)
    s = diagnose(simulate_round(rnd, channels=("x", "y", "z", "v")), rnd, sigma={"x": 1, "y": 1, "z": 1, "v": 0.3},
                 cd_shifts=False).record
    assert not {r["name"] for r in s["effects"]} & set(RADAR_EFFECT_CHANNELS)
    assert not set(s["skipped"]) & set(RADAR_EFFECT_CHANNELS)


def test_a_range_rate_alone_skips_the_biases_it_has_no_channel_for(m101):
    rnd = Round(Projectile("120 mm mortar", 13.2, 0.12, m101, None), Launch(60.0, 310.0),
                radar=Radar({"range_rate": 0.1}, position=(-10.0, 0.0, 1.0)), path="mortar.toml")
    s = diagnose(add_noise(simulate_round(rnd, channels=("range_rate",)), {"range_rate": 0.1},
                           np.random.default_rng(2866)), rnd).record
    assert "no range channel" in s["skipped"]["range_bias"]
    assert "no elevation channel" in s["skipped"]["elevation_bias"]
    site = next(r for r in s["effects"] if r["name"] == "radar_position")
    # on the line of fire a range rate has no first-order view of a sideways shift of the site
    assert set(site.get("not_identifiable", {})) == {"y"}


def test_a_bias_asked_of_a_track_without_its_channel_is_an_input_error(m101):
    rnd = _round(m101)
    angles_only = _track(rnd, 2867, channels=("azimuth", "elevation"))
    with pytest.raises(InputError, match="effect 'range_bias' acts on the radar's range, but the track has no "
                                         "range channel"):
        diagnose(angles_only, rnd, candidates=["range_bias"])
    with pytest.raises(InputError, match="effect 'elevation_bias' acts on the radar's elevation, but the track "
                                         "has no elevation channel"):
        bayesdrag.fit(angles_only, rnd, mcmc=False, with_effects=("elevation_bias",), channels=("azimuth",))


@pytest.mark.slow
def test_with_elevation_bias_fits_it_and_the_default_fit_marks_no_wrong_row(m101):
    rnd = _round(m101)
    track = _track(rnd, 2861, elevation_bias=ELEVATION_BIAS)
    asked = bayesdrag.fit(track, rnd, mcmc=False, with_effects=("elevation_bias",)).to_dict()
    assert asked["ml"]["with_effects"]["fitted"] == ["elevation_bias"]
    v, sd = asked["ml"]["params"]["elevation_bias.bias"], asked["ml"]["crb"]["elevation_bias.bias"]
    assert abs(v - ELEVATION_BIAS) <= SIZE_SDS * sd
    assert "elevation_bias" in asked["uncertainty_budget"]["by_source"]
    assert "elevation_bias" not in asked["uncertainty_budget"]["conditional_on"]
    res = bayesdrag.fit(track, rnd, mcmc=False)
    assert "elevation_bias" in res.to_dict()["ml"]["quality"]["model_error"]["verdict"]
    assert wrong_rows(res.cd, m101, res.cd.determined) == []
