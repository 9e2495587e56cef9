"""The posterior's mode (bayesdrag.estimate.bayes.posterior.mode_fit): a refit with every noise
sd estimated where the ML fit held some, none where the fit held only AR(1) channels' sd, whose
noise it estimates anyway (their refit only walked away and back to the same estimate)."""
import numpy as np
import pytest

import bayesdrag
from bayesdrag.estimate.bayes.posterior import mode_fit
from bayesdrag.synthetic import add_noise

#: the track's AR(1) noise: correlation per sample and sd per channel [m, m/s], beside white noise
AR_RHO, AR_SD = 0.9, {"x": 1.5, "y": 1.5, "z": 1.5, "v": 0.4}
#: a refit of a fit that held only AR(1) channels' sd lands within this of its estimate [CRB sd]
SAME_MODE_SD = 0.05
#: with each channel's total noise sd (white and AR(1) parts) within this [-]
SAME_TOTAL_SD = 0.01


@pytest.fixture(scope="module")
def ar_fit(round_, clean_track):
    """White + AR(1) noise on the clean track, fitted with AR(1) noise on every channel."""
    rng = np.random.default_rng(21)
    track = add_noise(clean_track, {"x": 0.5, "y": 0.5, "z": 0.5, "v": 0.1}, rng)
    track = add_noise(track, AR_SD, rng, rho=AR_RHO)
    res = bayesdrag.fit(track, round_, mcmc=False, with_effects="none", model_check=False, noise_model="ar1")
    prob = res.scheme1.problem
    assert set(prob.ar_channels) == set(prob.channels)
    return prob


def _total_sd(res, c):
    rho, q = res.ar.get(c, (0.0, 0.0))
    return res.sigma[c] * np.sqrt(1.0 + q)


def test_a_fit_holding_only_ar1_sd_is_its_own_mode(ar_fit):
    held = ar_fit.replace(sigma_fixed={c: 2.0 * ar_fit.sigma_fixed.get(c, 1.0) for c in ar_fit.channels})
    ml = held.fit()
    assert ml.converged
    assert mode_fit(held, ml) is None
    # what the refit it skips finds: the same estimate and the same noise
    refit = held.replace(sigma_fixed={}, theta0=ml.theta).fit()
    sd = np.where(refit.crb > 0, refit.crb, np.inf)[refit.free]
    assert np.max(np.abs(refit.theta - ml.theta)[refit.free] / sd) < SAME_MODE_SD
    for c in held.channels:
        assert _total_sd(refit, c) == pytest.approx(_total_sd(ml, c), rel=SAME_TOTAL_SD), c


def test_a_held_white_channel_is_estimated_by_the_refit(ar_fit):
    models = {**dict(ar_fit.noise_model), "v": "white"}
    held = ar_fit.replace(noise_model=models, sigma_fixed={"v": 1.0})
    ml = held.fit()
    assert ml.converged and ml.sigma["v"] == 1.0          # held at 1 m/s, 2.4 times its noise
    m = mode_fit(held, ml)
    assert m is not None
    assert m.sigma["v"] < 0.6                              # the refit estimates it (~0.41 m/s)
