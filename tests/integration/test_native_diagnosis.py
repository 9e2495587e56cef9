"""The diagnosis of radar-native tracks (issue 28, docs/radar.md "The diagnosis"): its problems
compare the model with what the radar measured, from where it stands, so an undeclared effect on
a tracking radar's range and angles or on a Doppler radar's range rate alone is named and sized,
and the default fit's model check carries it. Effects a range rate alone cannot see are said to be
not identifiable instead of being fitted."""
import json
import math

import numpy as np
import pytest

import bayesdrag
from bayesdrag.cli import main
from bayesdrag.diagnosis import diagnose
from bayesdrag.io.rounds import write_round
from bayesdrag.io.tracks import write_track
from bayesdrag.round import Launch, Projectile, Radar, Round
from bayesdrag.synthetic import add_noise, simulate_round
from fixtures.judge import wrong_rows

#: a found effect's size is within this many of its reported sd of the truth
SIZE_SDS = 3.0
#: the undeclared effects: a constant headwind [m/s] and a late radar clock [s]
HEADWIND = -6.0
CLOCK = 0.04

#: a tracking radar beside the gun: 2 m in range, 0.03 deg in each angle
TRACKING = {"range": 2.0, "azimuth": math.radians(0.03), "elevation": math.radians(0.03)}
#: a Doppler radar's range rate [m/s]
DOPPLER = {"range_rate": 0.1}


def _tracking_round(m101):
    """155 mm M101 at QE 45 seen by a radar 30 m to the right of the gun, 5 m behind, 1 m up."""
    return Round(Projectile("155 mm M101", 42.6, 0.155, m101, None), Launch(45.0, 818.0, azimuth_deg=90.0),
                 radar=Radar(dict(TRACKING), position=(-5.0, 30.0, 1.0)), path="tracking.toml")


def _mortar_round(m101):
    """A 120 mm mortar bomb at QE 60 seen by a Doppler radar 10 m behind it (range rate only)."""
    return Round(Projectile("120 mm mortar", 13.2, 0.12, m101, None), Launch(60.0, 310.0),
                 radar=Radar(dict(DOPPLER), position=(-10.0, 0.0, 1.0)), path="mortar.toml")


def _track(rnd, sigma, effect, seed):
    kw = {"wind": (HEADWIND, 0.0, 0.0)} if effect == "wind" else {"clock_offset": CLOCK} if effect == "clock" else {}
    clean = simulate_round(rnd, channels=tuple(sigma), **kw)
    return add_noise(clean, sigma, np.random.default_rng(seed))


CASES = {
    # name: (round maker, sigma, undeclared effect, the verdict's first effect, its parameter, truth, seed)
    "tracking-headwind": (_tracking_round, TRACKING, "wind", "wind", "wx", HEADWIND, 281),
    "tracking-clock": (_tracking_round, TRACKING, "clock", "radar_time", "dt", CLOCK, 282),
    "doppler-headwind": (_mortar_round, DOPPLER, "wind", "wind", "wx", HEADWIND, 283),
    "doppler-clock": (_mortar_round, DOPPLER, "clock", "radar_time", "dt", CLOCK, 284),
}


@pytest.fixture(scope="module")
def cases(m101):
    out = {}
    for name, (make, sigma, effect, *_rest, seed) in CASES.items():
        rnd = make(m101)
        out[name] = (rnd, _track(rnd, sigma, effect, seed))
    return out


@pytest.mark.parametrize("name", list(CASES))
def test_the_undeclared_effect_is_named_first_and_sized(name, cases):
    rnd, track = cases[name]
    _, _, _, first, param, truth, _ = CASES[name]
    s = diagnose(track, rnd).record
    assert s["verdict"][:1] == [first], (s["verdict"], [(r["name"], r["shrink"]) for r in s["effects"]])
    row = next(r for r in s["effects"] if r["name"] == first)
    value = row["params"][param]
    assert abs(value - truth) <= SIZE_SDS * row["sd"][param], (value, row["sd"][param])


@pytest.mark.parametrize("make, sigma, seed", [(_tracking_round, TRACKING, 285), (_mortar_round, DOPPLER, 286)])
def test_a_track_without_an_effect_has_an_empty_verdict(make, sigma, seed, m101):
    rnd = make(m101)
    s = diagnose(_track(rnd, sigma, None, seed), rnd).record
    assert s["verdict"] == [], [(r["name"], r["test_statistic"], r["threshold"]) for r in s["effects"]]


def test_a_range_rate_alone_reports_what_it_cannot_see(cases):
    """Behind the mortar on its line of fire a range rate sees no sideways drift: the cross wind
    is held and said to be not identifiable, the lift (a sideways drift) is not fitted."""
    rnd, track = cases["doppler-headwind"]
    s = diagnose(track, rnd).record
    assert "not identifiable" in s["skipped"]["lift"]
    wind = next(r for r in s["effects"] if r["name"] == "wind")
    assert set(wind["not_identifiable"]) == {"wy"}
    assert any("see no cross-range position" in n for n in s["notes"])


def test_the_command_diagnoses_a_native_track(tmp_path, cases):
    rnd, track = cases["tracking-clock"]
    write_round(tmp_path / "r.toml", rnd)
    write_track(tmp_path / "n.csv", track)
    assert main(["diagnose", str(tmp_path / "n.csv"), str(tmp_path / "r.toml"), "-o", str(tmp_path / "d"),
                 "--quiet"]) == 0
    s = json.loads((tmp_path / "d" / "diagnosis.json").read_text())
    assert s["verdict"][:1] == ["radar_time"]
    assert s["baseline"]["z_max"] > 0.0         # the apex of the fitted flight, read off its path


def _wrong_determined(res, ref):
    return wrong_rows(res.cd, ref, res.cd.determined)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(CASES))
def test_the_default_fit_marks_no_wrong_row(name, cases, m101):
    """The default fit's model check now runs the diagnosis on native tracks: the undeclared
    effect is found, and no row it marks determined is wrong."""
    rnd, track = cases[name]
    res = bayesdrag.fit(track, rnd, mcmc=False)
    me = res.to_dict()["ml"]["quality"]["model_error"]
    assert "diagnosis_failed" not in me
    assert CASES[name][3] in me["verdict"]
    assert _wrong_determined(res, m101) == []
