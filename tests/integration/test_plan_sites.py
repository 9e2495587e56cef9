"""`plan --radar-sites` (issue 28): a radar recording its own channels (range, angles, range rate)
planned from candidate sites, ranked by the Cd sd they would give, the best named; the prediction
agrees with what the fit reports on a track recorded from that site."""
import math

import numpy as np
import pytest

import bayesdrag
from bayesdrag.cli import main
from bayesdrag.errors import InputError
from bayesdrag.planning.case import site_round
from bayesdrag.round import Launch, Projectile, Radar, Round
from bayesdrag.synthetic import add_noise, simulate_round

#: a tracking radar: 2 m, 0.03 deg, 0.1 m/s
TRACKING = {"range": 2.0, "azimuth": math.radians(0.03), "elevation": math.radians(0.03), "range_rate": 0.1}
#: candidate sites [m, gun frame]: behind and right, to the left, far downrange and aside, behind on the line of fire
SITES = ((-40.0, 25.0, 2.0), (0.0, -300.0, 5.0), (2000.0, -3000.0, 10.0), (-500.0, 0.0, 1.0))
#: radar sample interval of the planned and the simulated tracks [s]
DT = 0.05
#: the planned sd over the fit's reported sd, median over the fit's determined Mach span
RATIO_RANGE = (0.8, 1.25)


@pytest.fixture(scope="module")
def tracking_round(m101):
    return Round(Projectile("155 mm M101", 42.6, 0.155, m101, None), Launch(45.0, 818.0, azimuth_deg=90.0),
                 radar=Radar(dict(TRACKING), position=SITES[0]), path="tracking.toml")


@pytest.fixture(scope="module")
def planned(tracking_round):
    return bayesdrag.plan(tracking_round, radar_sites=SITES, dt=DT).to_dict()


def test_every_site_is_planned_ranked_and_the_best_named(planned):
    assert [c["radar"]["position"] for c in planned["cases"]] == [list(s) for s in SITES]
    ranked = planned["radar_sites"]
    assert sorted(tuple(r["position"]) for r in ranked) == sorted(SITES)
    sds = [r["median_relative_sd"] for r in ranked]
    assert sds == sorted(sds)
    assert planned["best_site"] == ranked[0]
    # the site on the line of fire sees a constant azimuth: planned without it, and said so
    on_axis = planned["cases"][3]
    assert "azimuth" not in on_axis["radar"]["channels"]
    assert any("constant azimuth" in n for n in on_axis["notes"])


@pytest.mark.parametrize("k", [0, 1])
def test_the_planned_sd_is_what_the_fit_reports_from_that_site(planned, tracking_round, k):
    r = site_round(tracking_round, SITES[k])
    track = add_noise(simulate_round(r, channels=tuple(TRACKING), dt=DT), TRACKING, np.random.default_rng(5))
    res = bayesdrag.fit(track, r, mcmc=False)
    case = planned["cases"][k]
    pm = np.array([row["mach"] for row in case["cd"]])
    psd = np.array([row["sd"] for row in case["cd"]])
    det = res.cd.determined
    lo, hi = res.cd.mach[det].min(), res.cd.mach[det].max()
    grid = pm[(pm >= lo) & (pm <= hi)]
    ratio = float(np.median(np.interp(grid, pm, psd) / np.interp(grid, res.cd.mach, res.cd.sd)))
    assert RATIO_RANGE[0] <= ratio <= RATIO_RANGE[1], f"site {SITES[k]}: planned / fitted sd {ratio:.3f}"


def test_sites_need_a_radars_own_channels(m101):
    gun = Round(Projectile("155", 42.6, 0.155, m101, None), Launch(45.0, 818.0, azimuth_deg=90.0),
                radar=Radar({"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}), path="gun.toml")
    with pytest.raises(InputError, match="radar sites are planned for a radar's own channels"):
        bayesdrag.plan(gun, radar_sites=SITES[:1], dt=DT)


def test_a_malformed_site_on_the_command_line_exits_2(tmp_path, capsys):
    rnd = tmp_path / "r.toml"
    rnd.write_text("[projectile]\nmass = 42.6\ndiameter = 0.155\n[launch]\nelevation = 45.0\nvelocity = 818.0\n"
                   "azimuth = 90.0\n[radar]\nsigma = {range = 2.0, range_rate = 0.1}\n")
    assert main(["plan", str(rnd), "-o", str(tmp_path / "out"), "--radar-sites=-40,25"]) == 2
    assert "is not a site" in capsys.readouterr().err
