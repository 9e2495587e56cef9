"""The radar's biases and site among `plan`'s systematic sources (issue 28, docs/radar.md): a
declared ``range_bias_sd``, ``azimuth_bias_sd``, ``elevation_bias_sd`` or ``position_sd`` of a
radar recording its own channels takes its share of the planned Cd sd, as the fit's budget gives
it on a track from that radar."""
import math
from dataclasses import replace

import numpy as np
import pytest

import bayesdrag
from bayesdrag.round import Launch, Projectile, Radar, Round
from bayesdrag.synthetic import add_noise, simulate_round

#: a tracking radar: 2 m, 0.03 deg, 0.1 m/s, 40 m behind and 25 m right of the gun
TRACKING = {"range": 2.0, "azimuth": math.radians(0.03), "elevation": math.radians(0.03), "range_rate": 0.1}
SITE = (-40.0, 25.0, 2.0)
#: declared: the site to 0.5 m per axis, a 1 m range bias, a 0.05 deg elevation bias
DECLARED = dict(position_sd=0.5, range_bias_sd=1.0, elevation_bias_sd=math.radians(0.05))
#: sample interval of the planned and the simulated track [s]
DT = 0.05
#: the planned sd (total, and the site's share) over the fit's, median over the span
RATIO_RANGE = (0.8, 1.25)
#: relative tolerance of the budget's closure (squares of the shares add up to the total's)
CLOSURE_RTOL = 1e-9


@pytest.fixture(scope="module")
def rnd(m101):
    return Round(Projectile("155 mm M101", 42.6, 0.155, m101, None), Launch(45.0, 818.0, azimuth_deg=90.0),
                 radar=Radar(dict(TRACKING), position=SITE, **DECLARED), path="tracking.toml")


@pytest.fixture(scope="module")
def planned(rnd):
    return bayesdrag.plan(rnd, elevations=(45.0,), velocities=(818.0,), dt=DT)


def test_declared_radar_sources_are_planned_and_the_budget_closes(planned):
    case = planned.cases[0]
    assert set(case.by_source) == {"range_bias", "elevation_bias", "radar_position"}
    assert set(planned.to_dict()["systematics"]["declared"]) == {"range_bias", "elevation_bias", "radar_position"}
    total2 = case.statistical ** 2 + sum(v ** 2 for v in case.by_source.values())
    assert np.allclose(case.systematic ** 2 + case.statistical ** 2, total2, rtol=CLOSURE_RTOL)


def test_a_source_the_channels_do_not_see_is_not_planned(rnd):
    """A range rate alone has no range and no angles: only the site acts on it."""
    doppler = replace(rnd, radar=replace(rnd.radar, sigma={"range_rate": 0.1}))
    case = bayesdrag.plan(doppler, elevations=(45.0,), velocities=(818.0,), dt=DT).cases[0]
    assert set(case.by_source) == {"radar_position"}


def test_the_planned_sd_agrees_with_the_fit(rnd, planned):
    """The planned total sd (statistical and the radar's sources) over the total sd the fit
    reports on a track from that radar; the site's share, which the track hardly informs (its
    posterior is its prior), agrees share for share. The biases the track determines are split
    by another convention in the fit's budget (their posterior, not their prior, sd), so only
    the totals are compared for them."""
    case = planned.cases[0]
    track = add_noise(simulate_round(rnd, channels=tuple(TRACKING), dt=DT), TRACKING, np.random.default_rng(7))
    b = bayesdrag.fit(track, rnd, mcmc=False).to_dict()["uncertainty_budget"]
    m = np.asarray(b["mach"], float)
    inside = (case.mach > m.min() + 0.1) & (case.mach < m.max() - 0.1)
    total = np.interp(case.mach, m, np.asarray(b["total_sd"], float))[inside]
    ratio = np.median(np.hypot(case.statistical, case.systematic)[inside] / total)
    assert RATIO_RANGE[0] <= ratio <= RATIO_RANGE[1], ratio
    site = np.interp(case.mach, m, np.abs(np.asarray(b["by_source"]["radar_position"], float)))[inside]
    ratio = np.median(np.abs(case.by_source["radar_position"][inside]) / site)
    assert RATIO_RANGE[0] <= ratio <= RATIO_RANGE[1], ratio
