"""The native channels' sensitivities by the chain rule (state differences through the channels'
analytic Jacobian) agree with differences of the channels themselves."""
import math

import numpy as np
import pytest

import bayesdrag
from bayesdrag.round import Launch, Projectile, Radar, Round
from bayesdrag.synthetic import add_noise, simulate_round

NATIVE = {"range": 2.0, "azimuth": math.radians(0.03), "elevation": math.radians(0.03), "range_rate": 0.1}
#: the chain rule and the channels' central differences differ by the differences' truncation
#: and rounding errors: a part in 1e3 of a sensitivity column moves a Cramer-Rao sd by less
#: than that (the worst column seen, azimuth against the first drag coefficient: 1.3e-4)
REL_TOL = 1e-3


@pytest.fixture(scope="module")
def native_problem(m101):
    proj = Projectile("155 mm M101", 42.6, 0.155, m101, None)
    rnd = Round(proj, Launch(45.0, 818.0, azimuth_deg=90.0),
                radar=Radar(dict(NATIVE), position=(-40.0, 25.0, 2.0)), path="native.toml")
    track = add_noise(simulate_round(rnd, channels=tuple(NATIVE), dt=0.1), NATIVE, np.random.default_rng(3))
    res = bayesdrag.fit(track, rnd, mcmc=False, with_effects="none", model_check=False)
    return res.scheme1.problem, res.scheme1.ml


def test_the_chain_rule_matches_differences_of_the_channels(native_problem):
    prob, ml = native_problem
    y0, mach0, S = prob.sensitivities(ml.theta)
    idx = np.flatnonzero(prob.free)
    h = prob.steps[idx]
    batch = np.repeat(ml.theta[None], 2 * idx.size, axis=0)
    for k, j in enumerate(idx):
        batch[2 * k, j] += h[k]
        batch[2 * k + 1, j] -= h[k]
    y, _ = prob.predict(batch)
    S_fd = np.moveaxis((y[0::2] - y[1::2]) / (2 * h[:, None, None]), 0, -1)     # (N, C, n_free)
    scale = np.sqrt(np.sum(S_fd ** 2, axis=0))                                      # (C, n_free)
    err = np.sqrt(np.sum((S - S_fd) ** 2, axis=0))
    rel = err / np.where(scale > 0, scale, 1.0)
    assert float(np.max(rel)) < REL_TOL
    y1, _ = prob.predict(ml.theta[None])
    np.testing.assert_array_equal(y0, y1[0])
