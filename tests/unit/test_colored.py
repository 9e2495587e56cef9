"""White + AR(1) model-error noise (bayesdrag.estimate.model.colored): the Kalman whitening is the exact
Gaussian likelihood, and the noise fit tells white from model-error residuals."""
import math

import numpy as np
import pytest
from scipy.linalg import cholesky, solve_triangular

from bayesdrag.estimate.model import colored

#: relative agreement of the Kalman filter with the dense Cholesky factor [-]
EXACT_TOL = 1e-9


def _ar_white(rng, n, rho, q, sigma=1.0):
    d = np.empty(n)
    d[0] = np.sqrt(q) * rng.standard_normal()
    for i in range(1, n):
        d[i] = rho * d[i - 1] + np.sqrt(q * (1 - rho * rho)) * rng.standard_normal()
    return sigma * (rng.standard_normal(n) + d)


@pytest.mark.parametrize("rho,q,irregular", [(0.98, 3.0, False), (0.5, 0.2, False), (0.99, 10.0, True)])
def test_kalman_whitening_is_the_exact_gaussian_likelihood(rho, q, irregular):
    rng = np.random.default_rng(1)
    n = 300
    t = np.cumsum(rng.uniform(0.5, 1.5, n)) if irregular else np.arange(n, dtype=float)
    dt_ratio = np.diff(t) / np.median(np.diff(t))
    lag = np.abs(t[:, None] - t[None, :]) / np.median(np.diff(t))
    C = np.eye(n) + q * rho ** lag
    L = cholesky(C, lower=True)
    e = rng.standard_normal(n)
    ss_exact = float(np.sum(solve_triangular(L, e, lower=True) ** 2))
    ld_exact = 2.0 * float(np.sum(np.log(np.diag(L))))
    u, ld = colored.standardize(e, rho, q, dt_ratio)
    assert u @ u == pytest.approx(ss_exact, rel=EXACT_TOL)
    assert ld == pytest.approx(ld_exact, rel=EXACT_TOL)
    ss_b, ld_b = colored.whitened_ss(np.stack([e, 2 * e]), np.array([rho, rho]), np.array([q, q]), dt_ratio)
    assert ss_b == pytest.approx([ss_exact, 4 * ss_exact], rel=EXACT_TOL)
    assert ld_b == pytest.approx([ld_exact, ld_exact], rel=EXACT_TOL)
    ss_s, ld_s = colored.whitened_ss(np.stack([e, 2 * e]), rho, q, dt_ratio)   # shared noise parameters
    assert ss_s == pytest.approx([ss_exact, 4 * ss_exact], rel=EXACT_TOL)
    assert ld_s == pytest.approx([ld_exact, ld_exact], rel=EXACT_TOL)


def test_white_residuals_stay_white():
    """A white channel is switched to ar1 only when the likelihood ratio passes the chi2(2)
    0.999 quantile: of 20 white series at most one may."""
    rng = np.random.default_rng(2)
    lrs = [colored.fit_noise(rng.standard_normal(800), np.ones(799))[3] for _ in range(20)]
    assert sum(lr > colored.LR_THRESHOLD for lr in lrs) <= 1


def test_model_error_is_found_and_its_size_estimated():
    rng = np.random.default_rng(3)
    e = _ar_white(rng, 2000, 0.99, 4.0, sigma=2.0)
    sigma, rho, q, lr = colored.fit_noise(e, np.ones(1999))
    assert lr > colored.LR_THRESHOLD
    assert sigma == pytest.approx(2.0, rel=0.1)          # the white part [m]
    assert 0.95 < rho < 0.999                             # correlation time 20-1000 samples
    assert 4.0 / 3 < q < 4.0 * 3                          # variance ratio within a factor 3


@pytest.mark.parametrize("irregular", [False, True])
def test_shared_noise_parameters_give_the_per_walker_numbers(irregular):
    """The filter shared by walkers with the same rho and q (the posterior's plug-in) does each
    walker's arithmetic in the same order as the per-walker filter: identical results."""
    rng = np.random.default_rng(5)
    n, W = 700, 13
    t = np.cumsum(rng.uniform(0.5, 1.5, n)) if irregular else np.arange(n, dtype=float)
    dt_ratio = np.diff(t) / np.median(np.diff(t))
    r = rng.standard_normal((W, n)) * rng.uniform(0.5, 3.0, (W, 1))
    for rho, q in ((0.97, 2.0), (0.5, 1e-3), (1 - 1e-5, 50.0)):
        ss_s, ld_s = colored.whitened_ss(r, rho, q, dt_ratio)
        ss_w, ld_w = colored.whitened_ss(r, np.full(W, rho), np.full(W, q), dt_ratio)
        np.testing.assert_array_equal(ss_s, ss_w)
        np.testing.assert_array_equal(ld_s, ld_w)


def _scipy_and_ours(f, x0, **tol):
    from scipy.optimize import minimize

    calls = {"scipy": [], "ours": []}

    def rec(key):
        def g(x):
            calls[key].append((float(x[0]), float(x[1])))
            return f(x)
        return g

    o = minimize(rec("scipy"), x0, method="Nelder-Mead", options={**tol, "maxiter": 400})
    x, fun = colored.nelder_mead_2d(rec("ours"), x0, maxiter=400, **tol)
    return o, x, fun, calls


def _plateau(x):
    # clamped like the noise likelihood's parameters: equal values on a whole region (ties)
    a, b = min(max(x[0], -3.0), 0.0), min(max(x[1], -2.0), 4.0)
    return (a + 1.3) ** 2 + 3.0 * (b - 0.7) ** 2 + 0.5 * a * b


@pytest.mark.parametrize("f, x0", [
    (lambda x: (x[0] - 1.0) ** 2 + 10.0 * (x[1] + 2.0) ** 2 + x[0] * x[1], (0.0, 0.0)),
    (lambda x: 100.0 * (x[1] - x[0] ** 2) ** 2 + (1.0 - x[0]) ** 2, (-1.2, 1.0)),
    (_plateau, (-5.0, 9.0)),
    (_plateau, (math.log(0.01), 0.0)),
    (lambda x: math.nan if x[0] > 0.3 else (x[0] - 1.0) ** 2 + x[1] ** 2, (0.2, 0.5)),
])
def test_nelder_mead_2d_is_scipys_step_for_step(f, x0):
    """The noise fit's own 2-D Nelder-Mead evaluates the same points in the same order as
    scipy's and ends on the same vertex and value, bit for bit (it only drops the array work)."""
    o, x, fun, calls = _scipy_and_ours(f, x0, xatol=1e-3, fatol=1e-4)
    assert calls["ours"] == calls["scipy"]
    assert x == (float(o.x[0]), float(o.x[1]))
    assert fun == float(o.fun) or (math.isnan(fun) and math.isnan(o.fun))


def test_nelder_mead_2d_follows_scipy_on_the_noise_likelihood():
    rng = np.random.default_rng(7)
    for rho, q in ((0.99, 4.0), (0.5, 0.01), (0.0, 0.0)):
        e = _ar_white(rng, 600, rho, q) if q else rng.standard_normal(600)
        dt = np.ones(599)

        def nll(x):
            r = 1.0 - math.exp(min(max(x[0], colored.LOG_1M_RHO_RANGE[0]), 0.0))
            qq = math.exp(min(max(x[1], colored.LOG_Q_RANGE[0]), colored.LOG_Q_RANGE[1]))
            return -colored.profile_loglik(e, r, qq, dt)

        for x0 in ((math.log(0.01), 0.0), (math.log(1e-4), 5.0), (-20.0, -20.0)):
            o, x, fun, calls = _scipy_and_ours(nll, x0, xatol=1e-3, fatol=1e-4)
            assert calls["ours"] == calls["scipy"] and fun == float(o.fun)
