"""The gross-outlier rule of bayesdrag/estimate/model/noise.py on fast-decelerating projectiles: a
bullet through the transonic drag rise sampled coarsely leaves a large but smooth residual about
the local cubic, which is flight and must not be flagged; a noise-free track has no outliers;
real spikes are still flagged on the same bullet."""
from importlib.resources import files

import numpy as np
import pytest

from bayesdrag.estimate.model.noise import OUTLIER_MIN_SD, noise_and_outliers
from bayesdrag.io.drag_tables import read_drag_table
from bayesdrag.round import Launch, Projectile, Radar, Round
from bayesdrag.synthetic import add_noise, add_outliers, simulate_round

SIG = {"x": 0.5, "y": 0.5, "z": 0.5, "v": 0.1}


def _bullet(dt, mass=0.01, diameter=0.0078, velocity=850.0):
    """A 10 g, 7.8 mm bullet at 850 m/s (about 65 g of deceleration at the muzzle, through Mach 1
    within 3 s) with the M101 drag shape, sampled every ``dt`` s."""
    ref = read_drag_table(files("bayesdrag") / "data" / "cd_m101.csv")
    rnd = Round(Projectile("bullet", mass, diameter, ref, None, True), Launch(1.0, velocity), radar=Radar({}),
                path="bullet.toml")
    return simulate_round(rnd, dt=dt, max_time=3.0)


@pytest.mark.parametrize("dt", [0.1, 0.05])
@pytest.mark.parametrize("given", [None, SIG], ids=["estimated", "stated"])
def test_a_coarse_fast_decelerating_track_has_no_outliers(dt, given):
    track = add_noise(_bullet(dt), SIG, np.random.default_rng(1))
    _, _, out = noise_and_outliers(track, track.names, given)
    assert not out.any(), np.flatnonzero(out.any(axis=1))


@pytest.mark.parametrize("dt", [0.1, 0.01])
def test_a_noise_free_track_has_no_outliers(dt):
    track = _bullet(dt)
    _, _, out = noise_and_outliers(track, track.names)
    assert not out.any(), np.flatnonzero(out.any(axis=1))
    assert OUTLIER_MIN_SD <= 1e-3


def test_spikes_on_a_fast_decelerating_track_are_still_flagged():
    track = add_noise(_bullet(0.01), SIG, np.random.default_rng(2))
    bad, idx = add_outliers(track, 0.02, 15.0, SIG, np.random.default_rng(3))
    _, _, out = noise_and_outliers(bad, bad.names)
    flagged = set(np.flatnonzero(out.any(axis=1)))
    assert set(idx) <= flagged and len(flagged) <= len(idx) + 2
