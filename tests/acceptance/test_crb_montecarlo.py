"""Cramér-Rao bounds against Monte Carlo (issue 4).

The same point-mass track (155 mm shell, 818 m/s, QE 15 deg, the supersonic first 15 s, x, y, z
and v) is re-noised many times and refitted; the spread of the estimates is compared with the
Cramér-Rao sd of one fit. The drag model is a plain cubic spline on fixed knots (an unpenalised
model: a penalised fit's bounds include its smoothing prior and are not a sampling sd), and the
truth is that same spline fitted to M101, so representation error does not mix in.

* White noise: CRB sd / MC sd within 0.8-1.25 for every coefficient (>= 200 replicates, slow).
  The default run holds 30 replicates with the band widened to the 99.9 % chi-square interval
  of a 30-sample sd ([0.69, 1.42]), so it tests the same property without flaking.
* AR(1) noise with rho = 0.9 (same marginal sd): the white-noise CRB is too small by a large
  factor, and the Morelli-Klein colored-residual bound is within 1.5x of the MC sd.

Run the long versions with ``python3 -m pytest -m slow tests/test_crb_montecarlo.py``.
"""
import numpy as np
import pytest

from bayesdrag.estimate.model.problem import OutputErrorProblem
from bayesdrag.synthetic import add_noise
from bayesdrag.track import RadarTrack
from fixtures.shell155 import spline_truth_flight

SIGMA = {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}
KNOTS = (1.45, 1.7, 2.0, 2.45)
#: issue 4 acceptance band for CRB sd / Monte-Carlo sd (>= 200 replicates)
RATIO_BAND = (0.8, 1.25)
#: 99.9 % interval of sd_true / sd_sample for 30 samples (chi-square, 29 dof)
RATIO_BAND_30 = (0.69, 1.42)
#: colored noise: corrected bound within this factor of the Monte-Carlo sd
COLORED_FACTOR = 1.5
AR_RHO = 0.9


@pytest.fixture(scope="module")
def setup(m101):
    _, theta_true, model, s0, tr = spline_truth_flight(m101, KNOTS)
    clean = RadarTrack(tr.t, {c: tr.channel(c) for c in "xyzv"}, {})
    return model, theta_true, s0, clean


def _replicates(setup, n, rho, seed):
    model, theta_true, s0, clean = setup
    rng = np.random.default_rng(seed)
    est, crb, crbc = [], [], []
    th0 = np.concatenate([theta_true, s0])
    for _ in range(n):
        noisy = add_noise(clean, SIGMA, rng, rho=rho)
        res = OutputErrorProblem(model, noisy, th0, sigma=SIGMA).fit()
        assert res.converged, res.message
        est.append(res.theta[:len(theta_true)])
        crb.append(res.crb[:len(theta_true)])
        crbc.append(res.crb_colored[:len(theta_true)])
    est = np.array(est)
    return est, np.mean(crb, axis=0), np.mean(crbc, axis=0), theta_true


def _check_white(setup, n, band, seed):
    est, crb, _, truth = _replicates(setup, n, 0.0, seed)
    mc_sd = est.std(axis=0, ddof=1)
    ratio = crb / mc_sd
    assert np.all((ratio > band[0]) & (ratio < band[1])), np.round(ratio, 3)
    # unbiased: the mean estimate is within 4 standard errors of the truth
    assert np.all(np.abs(est.mean(axis=0) - truth) < 4 * mc_sd / np.sqrt(n))
    return ratio


def test_crb_matches_monte_carlo_white(setup):
    _check_white(setup, 30, RATIO_BAND_30, seed=101)


@pytest.mark.slow
def test_crb_matches_monte_carlo_white_200(setup):
    ratio = _check_white(setup, 200, RATIO_BAND, seed=202)
    print("CRB / MC sd per coefficient:", np.round(ratio, 3))


def _check_colored(setup, n, seed, sampling=(1.0, 1.0)):
    est, crb, crbc, _ = _replicates(setup, n, AR_RHO, seed)
    mc_sd = est.std(axis=0, ddof=1)
    # the white-noise bound is far too small under rho = 0.9 ...
    assert np.all(crb / mc_sd < 0.5), np.round(crb / mc_sd, 3)
    # ... and the colored-residual bound is within 1.5x of the Monte-Carlo spread (the band
    # widened by the sampling interval of the MC sd itself when n is small)
    r = crbc / mc_sd
    lo, hi = sampling[0] / COLORED_FACTOR, sampling[1] * COLORED_FACTOR
    assert np.all((r > lo) & (r < hi)), np.round(r, 3)
    return crb / mc_sd, r


def test_colored_noise_bounds(setup):
    _check_colored(setup, 30, seed=303, sampling=RATIO_BAND_30)


@pytest.mark.slow
def test_colored_noise_bounds_200(setup):
    # measured (seed 404): white CRB / MC 0.24-0.30, colored 0.73-0.82: the truncated residual
    # autocorrelation (first lag below 2/sqrt(N)) misses the AR(1) tail, so the corrected
    # bound is still ~20-25 % small at rho = 0.9, though within the 1.5x asked
    white, colored = _check_colored(setup, 200, seed=404)
    print("white CRB / MC:", np.round(white, 3), "colored CRB / MC:", np.round(colored, 3))
