"""The pointwise log-likelihood of posterior draws (what ``arviz.loo`` needs) against scipy's
densities: white Gaussian, white plus AR(1) (the Kalman prediction errors against the dense
covariance, irregular sampling included) and Student-t; the thinning of the stored draws."""
import math

import numpy as np
import pytest
from scipy import stats

from bayesdrag.estimate.model import colored
from bayesdrag.estimate.bayes.loglik import pointwise_log_likelihood, thinned_draws

#: log densities agree with scipy's to this many nats (float64 rounding)
TOL_LOGPDF = 1e-9


def _ar1_covariance(rho, q, dt_ratio):
    """Covariance of white noise (variance 1) plus a stationary AR(1) of variance q with step
    coefficients rho ** dt_ratio: the dense matrix the Kalman filter factorises."""
    n = len(dt_ratio) + 1
    t = np.concatenate([[0.0], np.cumsum(dt_ratio)])
    return np.eye(n) + q * rho ** np.abs(t[:, None] - t[None, :])


def test_pointwise_gaussian_terms_are_normal_log_densities():
    rng = np.random.default_rng(1)
    r = rng.normal(size=(3, 20, 2)) * [1.0, 0.3]
    ls = np.log(rng.uniform(0.5, 2.0, size=(3, 2)))
    ll = pointwise_log_likelihood(r, ls)
    want = stats.norm.logpdf(r, scale=np.exp(ls)[:, None, :])
    assert np.max(np.abs(ll - want)) < TOL_LOGPDF


def test_pointwise_ar1_terms_sum_to_the_exact_gaussian_likelihood():
    """An ar1 channel's terms (Kalman prediction errors) sum to the log density of the whole
    channel under white noise plus AR(1), irregular sampling included."""
    rng = np.random.default_rng(2)
    n, rho, q, sigma = 40, 0.9, 3.0, 0.7
    dt_ratio = np.where(np.arange(n - 1) % 7 == 3, 2.0, 1.0)
    cov = sigma ** 2 * _ar1_covariance(rho, q, dt_ratio)
    r = rng.multivariate_normal(np.zeros(n), cov, size=2)           # two draws, one channel
    ls = np.full((2, 1), math.log(sigma))
    ll = pointwise_log_likelihood(r[..., None], ls, ar={0: (rho, q)}, dt_ratio=dt_ratio)
    want = stats.multivariate_normal(np.zeros(n), cov).logpdf(r)
    assert ll.sum(axis=(1, 2)) == pytest.approx(want, abs=1e-8)
    # per-draw noise parameters (a sampled AR) give the same terms as the shared ones
    per = pointwise_log_likelihood(r[..., None], ls, ar={0: (np.full(2, rho), np.full(2, q))}, dt_ratio=dt_ratio)
    assert np.max(np.abs(per - ll)) < TOL_LOGPDF


def test_innovation_variances_match_the_filters_log_determinant():
    dt_ratio = np.where(np.arange(99) % 11 == 5, 1.5, 1.0)
    F = colored.innovation_variances(0.97, 12.0, dt_ratio)
    _, ld = colored.whitened_ss(np.zeros((1, 100)), np.array([0.97]), np.array([12.0]), dt_ratio)
    assert F.shape == (100,) and np.all(F >= 1.0)
    assert np.sum(np.log(F)) == pytest.approx(ld[0], rel=1e-10)
    assert np.linalg.slogdet(_ar1_covariance(0.97, 12.0, dt_ratio))[1] == pytest.approx(ld[0], rel=1e-10)


def test_pointwise_student_t_terms_are_t_log_densities():
    rng = np.random.default_rng(3)
    r = rng.standard_t(4, size=(2, 15, 3))
    ls = np.log(rng.uniform(0.5, 2.0, size=(2, 3)))
    nu = np.array([4.0, 9.0])
    ll = pointwise_log_likelihood(r, ls, likelihood="student-t", nu=nu)
    want = stats.t.logpdf(r, df=nu[:, None, None], scale=np.exp(ls)[:, None, :])
    assert np.max(np.abs(ll - want)) < TOL_LOGPDF
    with pytest.raises(ValueError, match="likelihood 'cauchy' is not known"):
        pointwise_log_likelihood(r, ls, likelihood="cauchy")


def test_thinned_draws_spread_over_each_chain():
    assert list(thinned_draws(345, 16, 128)) == list(np.linspace(0, 344, 8).round().astype(int))
    assert list(thinned_draws(10, 4, None)) == list(range(10))
    assert list(thinned_draws(10, 4, 1000)) == list(range(10))
    assert list(thinned_draws(10, 128, 64)) == [0]                    # at least one per chain
