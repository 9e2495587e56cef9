"""A tracking radar's encoder bias (issue 28, docs/radar.md): a declared ``elevation_bias_sd``
with a true bias inside it. The fit estimates the bias with Cd, every row's band still holds the
truth and the uncertainty budget carries ``elevation_bias``; the radar's undeclared sources are
named in ``conditional_on``. Two shells, drag curves and radar sites, none tuned on."""
import math
from pathlib import Path

import numpy as np
import pytest

import bayesdrag
from bayesdrag.io.drag_tables import read_drag_table
from bayesdrag.round import Launch, Projectile, Radar, Round
from bayesdrag.synthetic import add_noise, simulate_round
from bayesdrag.track import RadarTrack

CASES = Path(__file__).resolve().parents[1] / "golden" / "cases"
#: a row holds the truth (anywhere within TRUTH_MACH) within this many of its band sd
BAND_SDS = 3.0
TRUTH_MACH = 0.01
#: margin of the flown Mach span left out at each end [fraction of the span]
SPAN_MARGIN = 0.05
#: the fitted bias lies within this many of its bound of the truth
BIAS_SDS = 3.0
#: the radar's noise: 2 m, 0.03 deg, 0.1 m/s
SIGMA = {"range": 2.0, "azimuth": math.radians(0.03), "elevation": math.radians(0.03), "range_rate": 0.1}
#: declared sd of the elevation bias [rad]
BIAS_SD = math.radians(0.05)
#: sample interval of the simulated tracks [s]
DT = 0.1

#: (name, drag table or None for M101, mass, diameter, QE [deg], v0, azimuth [deg], site [m], true bias [deg])
SHOTS = [("155 mm M101 QE 45, radar behind and right", None, 42.6, 0.155, 45.0, 818.0, 90.0, (-40.0, 25.0, 2.0), 0.04),
         ("130 mm G1 QE 30, radar far to the side", "s130-g1-part/ref.csv", 33.4, 0.13, 30.0, 810.0, 200.0,
          (1500.0, -2500.0, 30.0), -0.03)]


@pytest.mark.parametrize("shot", SHOTS, ids=[s[0] for s in SHOTS])
def test_a_declared_elevation_bias_is_fitted_and_the_band_covers(shot, m101):
    name, table, mass, diam, qe, v0, az, site, bias_deg = shot
    ref = m101 if table is None else read_drag_table(CASES / table)
    rnd = Round(Projectile("shell", mass, diam, ref, None), Launch(qe, v0, azimuth_deg=az),
                radar=Radar(dict(SIGMA), position=site, elevation_bias_sd=BIAS_SD), path="biased.toml")
    clean = simulate_round(rnd, channels=tuple(SIGMA), dt=DT)
    noisy = add_noise(clean, SIGMA, np.random.default_rng(28))
    ch = dict(noisy.channels)
    ch["elevation"] = ch["elevation"] + math.radians(bias_deg)
    assert abs(math.radians(bias_deg)) < BIAS_SD               # a bias inside the declared sd
    res = bayesdrag.fit(RadarTrack(noisy.t, ch, {}, "biased.csv"), rnd, mcmc=False)
    d = res.to_dict()
    b = d["uncertainty_budget"]
    assert "elevation_bias" in b["by_source"] and max(b["by_source"]["elevation_bias"]) > 0
    assert "elevation_bias" not in b["conditional_on"]
    assert {"range_bias", "azimuth_bias", "radar_position"} <= set(b["conditional_on"])
    est, sd = d["ml"]["params"]["elevation_bias"], d["ml"]["crb"]["elevation_bias"]
    assert abs(est - math.radians(bias_deg)) < BIAS_SDS * sd, name
    tab = res.cd
    lo, hi = float(tab.mach[0]), float(tab.mach[-1])
    margin = SPAN_MARGIN * (hi - lo)
    assert tab.determined.any()
    for m, cd, row in zip(tab.mach, tab.ml, d["cd"]):
        if lo + margin <= m <= hi - margin:
            truth = ref.cd((), np.linspace(m - TRUTH_MACH, m + TRUTH_MACH, 21))
            assert np.min(np.abs(cd - truth)) <= BAND_SDS * row["band_sd"], (name, m)


def test_scheme2_windows_say_they_hold_the_radar_sources(m101):
    """Scheme 2's windows fit no radar source: a declared one is not fitted there, and the
    result names every one the native channels depend on in ``conditional_on``."""
    rnd = Round(Projectile("155 mm", 42.6, 0.155, m101, None), Launch(45.0, 818.0, azimuth_deg=90.0),
                radar=Radar(dict(SIGMA), position=(-40.0, 25.0, 2.0), elevation_bias_sd=BIAS_SD), path="s2.toml")
    track = add_noise(simulate_round(rnd, channels=tuple(SIGMA), dt=DT), SIGMA, np.random.default_rng(2))
    b = bayesdrag.fit(track, rnd, mcmc=False, scheme=2).to_dict()["uncertainty_budget"]
    assert {"range_bias", "azimuth_bias", "elevation_bias", "radar_position"} <= set(b["conditional_on"])
