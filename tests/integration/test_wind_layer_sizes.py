"""A fitted wind layer's size is a claim like a Cd row: its sd must hold the truth (issue 30).

The flight: a 155 mm shell at QE 45 through a wind that changes linearly with height (the
round does not state it), flown by bayesdrag's own simulation; the default fit adds the wind
layers (by downrange distance: on the way down a layer spans a wide band of heights). A layer's truth is the mean true wind over the samples flown inside it (the
honesty suite's rule); its constant is the track's sensitivity-weighted mean of that wind, so
where the wind changes inside a layer the Cramér-Rao sd alone (the noise) does not hold it.
"""
from __future__ import annotations

import numpy as np
import pytest

import bayesdrag
from bayesdrag.air.atmosphere import Atmosphere
from bayesdrag.estimate.build.winds import within_layer_sd
from bayesdrag.io.drag_tables import load_m101
from bayesdrag.round import Launch, Projectile, Radar, Round
from bayesdrag.synthetic import add_noise, simulate_round
from bayesdrag.air.wind import WindProfile

#: a layer's fitted wind lies within this many of its reported sd of the truth
TOL_SD = 3.0
#: radar noise of the flight [m, m/s]
SIGMA = {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}
#: the wind by height [m above the gun] and its components [m/s]
LEVELS, WX, WY = (0.0, 1200.0, 3500.0, 7000.0), (-1.0, -7.0, -14.0, -19.0), (2.0, 4.0, 7.0, 3.0)


def test_within_layer_sd_is_the_uniform_sd_of_the_wind_inside_each_layer():
    # a wind rising 1 m/s per layer: each layer spans 1 m/s around its middle -> sd 1/sqrt(12)
    lo, hi = np.arange(4.0), np.arange(1.0, 5.0)
    np.testing.assert_allclose(within_layer_sd(lo, hi, [0.0, 1.0, 2.0, 3.0]), 1.0 / np.sqrt(12.0), rtol=1e-12)
    np.testing.assert_allclose(within_layer_sd(lo, hi, [5.0] * 4), 0.0, atol=1e-12)
    assert within_layer_sd([0.0], [1.0], [3.0]).tolist() == [0.0]


def test_layers_of_a_wind_that_changes_inside_them_are_sized_honestly():
    ref = load_m101()
    shell = Projectile("155 mm", 42.6, 0.155, ref)
    launch = Launch(elevation_deg=45.0, velocity=818.0)
    wind = WindProfile("altitude", LEVELS, WX, WY)
    windy = Round(shell, launch, atmosphere=Atmosphere(wind=wind), radar=Radar(dict(SIGMA)))
    clean = simulate_round(windy, dt=0.1)
    track = add_noise(clean, SIGMA, np.random.default_rng(20261127))
    calm = Round(shell, launch, radar=Radar(dict(SIGMA)))
    res = bayesdrag.fit(track, calm, mcmc=False)                       # the default adds the layers
    we = res.to_dict()["ml"]["with_effects"]
    assert "wind_profile" in we["effects"], we
    lay = we["wind_layers"]
    x, z = (np.asarray(clean.channels[c], float) for c in ("x", "z"))
    pos = x if lay["axis"] == "downrange" else z
    true = wind.at(z)                                                  # (N, 2) [m/s]
    judged = 0
    for row in lay["layers"]:
        sel = (pos >= row["from"]) & (pos < row["to"])
        if sel.sum() < 2:
            continue
        for j, c in enumerate(("wx", "wy")):
            if row[f"{c}_sd"] is None:
                continue
            assert row[f"{c}_crb_sd"] <= row[f"{c}_sd"], row           # the plain bound is kept beside it
            truth = float(np.mean(true[sel, j]))
            assert abs(row[c] - truth) <= TOL_SD * row[f"{c}_sd"], (c, row, truth)
            judged += 1
    assert judged >= 10
