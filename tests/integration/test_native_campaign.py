"""A campaign of radar-native tracks (issue 28): every round fitted in the radar's own channels,
pooled into one Cd(M). Three rounds of the 155 mm M101 shell recorded by one tracking radar 40 m
behind and 25 m right of the gun: the pooled Cd is the table's, the scatter near zero."""
import json
import math

import numpy as np

from bayesdrag.cli import main
from bayesdrag.io.rounds import write_round
from bayesdrag.io.tracks import write_track
from bayesdrag.round import Launch, Projectile, Radar, Round
from bayesdrag.synthetic import add_noise, simulate_round

TRACKING = {"range": 2.0, "azimuth": math.radians(0.03), "elevation": math.radians(0.03), "range_rate": 0.1}
#: pooled Cd within this fraction of the table (the rounds fly the table itself) [-]
CD_REL = 0.01
#: the rounds share one Cd: the scatter's 95 % quantile stays below this [-]
SCATTER_MAX = 0.005


def test_a_campaign_of_native_tracks_is_pooled(tmp_path, m101):
    lines = ["[campaign]", 'name = "native"', ""]
    for i in range(3):
        r = Round(Projectile("155 mm M101", 42.6, 0.155, m101, None), Launch(45.0, 815.0 + 3.0 * i, azimuth_deg=90.0),
                  radar=Radar(dict(TRACKING), position=(-40.0, 25.0, 2.0)), path=f"r{i}.toml")
        track = add_noise(simulate_round(r, channels=tuple(TRACKING), dt=0.05), TRACKING, np.random.default_rng(i))
        write_track(tmp_path / f"t{i}.csv", track)
        write_round(tmp_path / f"r{i}.toml", r)
        lines += ["[[rounds]]", f'name = "r{i}"', f'track = "t{i}.csv"', f'round = "r{i}.toml"', ""]
    (tmp_path / "campaign.toml").write_text("\n".join(lines))
    out = tmp_path / "out"
    assert main(["fit", str(tmp_path / "campaign.toml"), "-o", str(out), "--no-mcmc", "--quiet"]) == 0
    camp = json.loads((out / "campaign.json").read_text())
    assert camp["success"] and camp["rounds"] == ["r0", "r1", "r2"] and not camp["failed"]
    pooled = [row for row in camp["cd"] if row["n_rounds"] == 3]
    assert pooled
    for row in pooled:
        truth = float(m101.value(np.array([row["mach"]]))[0])
        assert abs(row["mean"] - truth) <= CD_REL * truth, row
    assert camp["scatter"]["q95"] < SCATTER_MAX
