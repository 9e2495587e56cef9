"""White + AR(1) model-error noise (bayesdrag.estimate.model.colored): the Kalman whitening is the exact
Gaussian likelihood, and the noise fit tells white from model-error residuals."""
import math

import numpy as np
import pytest
from scipy.linalg import cholesky, solve_triangular

from bayesdrag.estimate.model import colored, restricted

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


def _scipy_on_the_noise_likelihood(e, dt, x0):
    """scipy's Nelder-Mead on the noise fit's likelihood (the profile log-likelihood, the
    parameters clamped to their ranges), with the noise fit's tolerances."""
    from scipy.optimize import minimize

    def nll(x):
        r = 1.0 - math.exp(min(max(x[0], colored.LOG_1M_RHO_RANGE[0]), 0.0))
        qq = math.exp(min(max(x[1], colored.LOG_Q_RANGE[0]), colored.LOG_Q_RANGE[1]))
        return -colored.profile_loglik(e, r, qq, dt)

    return minimize(nll, x0, method="Nelder-Mead", options={"xatol": 1e-3, "fatol": 1e-4, "maxiter": 400})


@pytest.mark.parametrize("rho, q, irregular", [(0.99, 4.0, False), (0.5, 0.01, True), (0.0, 0.0, False),
                                               (0.999, 100.0, True)])
def test_the_compiled_nelder_mead_is_scipys_bit_for_bit(rho, q, irregular):
    """The noise fit's compiled Nelder-Mead takes scipy's steps (standard coefficients, its first
    simplex, stopping rules, the order of equal values) and ends on the same vertex and value with
    as many values taken, bit for bit; the starts include one deep in the clamped region, where
    whole regions share one value (ties)."""
    rng = np.random.default_rng(7)
    n = 600
    e = _ar_white(rng, n, rho, q) if q else rng.standard_normal(n)
    dt = rng.uniform(0.5, 2.0, n - 1) if irregular else np.ones(n - 1)
    rows = np.ascontiguousarray(e[None])
    for x0 in ((math.log(0.01), 0.0), (math.log(1e-4), 5.0), (-20.0, -20.0), (0.5, 25.0)):
        o = _scipy_on_the_noise_likelihood(e, dt, x0)
        a, b, fun, nfev = colored._noise_nelder_mead(rows, dt, x0[0], x0[1], 1e-3, 1e-4, 400)
        assert (a, b) == (float(o.x[0]), float(o.x[1])) and fun == float(o.fun) and nfev == o.nfev


def test_a_nan_value_ends_the_compiled_search_on_nan_as_scipys():
    e = np.random.default_rng(8).standard_normal(200)
    e[50] = np.nan
    dt = np.ones(199)
    o = _scipy_on_the_noise_likelihood(e, dt, (math.log(0.01), 0.0))
    a, b, fun, nfev = colored._noise_nelder_mead(np.ascontiguousarray(e[None]), dt, math.log(0.01), 0.0,
                                                1e-3, 1e-4, 400)
    assert math.isnan(fun) and math.isnan(o.fun) and nfev == o.nfev and (a, b) == tuple(map(float, o.x))


#: seeds of the restricted-likelihood test, and the basis size of its flexible fit
REML_SEEDS, REML_BASIS = 16, 8
#: information of "the other channels" in the single-channel tests: negligible [1/(noise scale)^2]
NEGLIGIBLE_INFO = 1e-10


def _dense_reml(e, J, rho, q):
    """Minus the textbook restricted log-likelihood (sigma^2 profiled) of residuals ``e`` of the
    linear model ``J`` under white + AR(1) noise (regular steps), from dense matrices; and its sigma^2."""
    n, k = J.shape
    V = np.eye(n) + q * rho ** np.abs(np.subtract.outer(np.arange(n), np.arange(n)))
    Vi = np.linalg.inv(V)
    XtViX = J.T @ Vi @ J
    beta = np.linalg.solve(XtViX, J.T @ Vi @ e)
    r = e - J @ beta
    s2 = float(r @ Vi @ r) / (n - k)
    val = 0.5 * (np.linalg.slogdet(V)[1] + (n - k) * math.log(s2) + np.linalg.slogdet(XtViX)[1] + (n - k))
    return val, s2


def test_restricted_objective_is_the_textbook_restricted_likelihood():
    """With negligible other information the objective is the restricted likelihood of the
    linear model (dense matrices, N = 80): its differences between noise parameters to 1e-6,
    and its white variance the restricted rss / (N - K)."""
    rng = np.random.default_rng(7)
    n, k = 80, 4
    tt = np.arange(n) / n
    J = np.column_stack([np.cos(np.pi * j * tt) for j in range(k)])
    e = _ar_white(rng, n, 0.9, 5.0)
    EJ = np.ascontiguousarray(np.column_stack([e, J]))
    dt_ratio = np.ones(n - 1)
    points = [(0.9, 5.0), (0.7, 0.5), (0.97, 40.0)]
    ours = [restricted.restricted_objective(EJ, dt_ratio, NEGLIGIBLE_INFO * np.eye(k), np.zeros(k),
                                         math.log(1 - r), math.log(q)) for r, q in points]
    dense = [_dense_reml(e, J, r, q) for r, q in points]
    for (v, s2), (dv, ds2) in zip(ours, dense):
        assert s2 == pytest.approx(ds2, rel=1e-6)
        assert v - ours[0][0] == pytest.approx(dv - dense[0][0], abs=1e-6)


def test_quadratic_box_minimum_is_the_grid_s():
    """The trust region's step: the exact minimum of a 2-D quadratic over a box, convex or not,
    against a 401 x 401 grid (to its spacing)."""
    rng = np.random.default_rng(3)
    ga = np.linspace(-1.0, 2.0, 401)
    gb = np.linspace(-0.5, 0.5, 401)
    A, B = np.meshgrid(ga, gb, indexing="ij")
    for _ in range(40):
        c = rng.normal(size=6)
        (a, b), v = restricted._quadratic_box_min(c, (-1.0, -0.5), (2.0, 0.5))
        grid = c[0] + c[1] * A + c[2] * B + c[3] * A * A + c[4] * A * B + c[5] * B * B
        assert -1.0 <= a <= 2.0 and -0.5 <= b <= 0.5
        assert v == pytest.approx(c[0] + c[1] * a + c[2] * b + c[3] * a * a + c[4] * a * b + c[5] * b * b)
        assert v <= grid.min() + 1e-12


def test_restricted_likelihood_removes_the_fit_s_absorption_of_slow_noise():
    """Residuals of a flexible fit (a cosine basis of REML_BASIS slow columns, as a spline in Cd
    absorbs slow noise) of white + AR(1) noise (rho 0.95, q 20): the plain likelihood of the
    residuals finds too short a correlation, the restricted one (the basis given) at most half as
    far off. Judged on the mean of log(1 - rho) over REML_SEEDS seeds, the scale the fit works in."""
    n, rho, q = 400, 0.95, 20.0
    dt_ratio = np.ones(n - 1)
    tt = np.arange(n) / n
    J = np.column_stack([np.cos(np.pi * k * tt) for k in range(REML_BASIS)])
    H = J @ np.linalg.pinv(J)
    ml, reml = [], []
    for s in range(REML_SEEDS):
        e = _ar_white(np.random.default_rng(100 + s), n, rho, q)
        r = e - H @ e
        _, r_ml, q_ml, _ = colored.fit_noise(r, dt_ratio)
        _, r_re, _ = restricted.fit_noise_restricted(r, dt_ratio, (r_ml, q_ml), J, NEGLIGIBLE_INFO * np.eye(REML_BASIS),
                                                  np.zeros(REML_BASIS))
        ml.append(math.log(1 - r_ml))
        reml.append(math.log(1 - r_re))
    truth = math.log(1 - rho)
    ml_bias, reml_bias = np.mean(ml) - truth, np.mean(reml) - truth
    se = np.std(ml, ddof=1) / math.sqrt(REML_SEEDS)
    assert ml_bias > 3 * se, (ml_bias, se)                  # the plain fit's correlation is too short
    assert abs(reml_bias) < 0.5 * ml_bias, (reml_bias, ml_bias)
    # never beyond the track: a longer correlation is a drift the fit takes whole
    assert min(reml) >= -math.log(n) - 1e-9
    # never shorter than the plain fit's
    assert all(b <= a + 1e-12 for a, b in zip(ml, reml))


def test_restricted_search_finds_the_objective_s_minimum():
    """The trust-region search ends where a dense grid of the objective has its minimum (within
    the bounds it keeps), to the grid's spacing: 0.05 in log(1 - rho), 0.25 in log q."""
    rng = np.random.default_rng(11)
    n = 300
    dt_ratio = np.ones(n - 1)
    tt = np.arange(n) / n
    J = np.column_stack([np.cos(np.pi * k * tt) for k in range(6)])
    e = _ar_white(rng, n, 0.9, 10.0)
    r = e - J @ np.linalg.lstsq(J, e, rcond=None)[0]
    _, r_ml, q_ml, _ = colored.fit_noise(r, dt_ratio)
    A, g = NEGLIGIBLE_INFO * np.eye(6), np.zeros(6)
    _, r_re, q_re = restricted.fit_noise_restricted(r, dt_ratio, (r_ml, q_ml), J, A, g)
    EJ = np.ascontiguousarray(np.column_stack([r, J]))
    hi, lo = math.log(1 - r_ml), max(-math.log(n), colored.LOG_1M_RHO_RANGE[0])
    ga = np.arange(lo, hi + 1e-9, 0.05)
    gb = np.arange(math.log(q_ml) - 4, math.log(q_ml) + 4, 0.25)
    vals = np.array([[restricted.restricted_objective(EJ, dt_ratio, A, g, a, b)[0] for b in gb] for a in ga])
    i, j = np.unravel_index(np.argmin(vals), vals.shape)
    found = restricted.restricted_objective(EJ, dt_ratio, A, g, math.log(1 - r_re), math.log(q_re))[0]
    assert found <= vals[i, j] + 1e-3
    assert abs(math.log(1 - r_re) - ga[i]) <= 0.1 and abs(math.log(q_re) - gb[j]) <= 0.5


def _counted(monkeypatch):
    """Count the restricted objective's values (the search's cost, known before any timing)."""
    calls = []
    inner = restricted.restricted_objective

    def counted(*args):
        calls.append(args[-2:])
        return inner(*args)

    monkeypatch.setattr(restricted, "restricted_objective", counted)
    return calls


def test_a_correlation_held_at_the_track_s_length_searches_log_q_alone(monkeypatch):
    """A plain estimate beyond the track (rho 0.9999 on 300 samples) is kept; the search then
    moves log q only, on three-point models (no value off its line), and ends at the minimum of
    a dense line of the objective (spacing 0.05 in log q) to the search's tolerance."""
    rng = np.random.default_rng(12)
    n = 300
    dt_ratio = np.ones(n - 1)
    tt = np.arange(n) / n
    J = np.column_stack([np.cos(np.pi * k * tt) for k in range(6)])
    e = np.cumsum(rng.normal(size=n)) * 0.1 + rng.normal(size=n)
    r = e - J @ np.linalg.lstsq(J, e, rcond=None)[0]
    A, g = NEGLIGIBLE_INFO * np.eye(6), np.zeros(6)
    start = (0.9999, 0.05)
    calls = _counted(monkeypatch)
    _, r_re, q_re = restricted.fit_noise_restricted(r, dt_ratio, start, J, A, g)
    a0 = math.log(1 - start[0])
    assert r_re == pytest.approx(start[0], rel=0, abs=1e-12)
    assert all(a == pytest.approx(a0, abs=1e-12) for a, _ in calls)        # no value off the line
    monkeypatch.undo()
    EJ = np.ascontiguousarray(np.column_stack([r, J]))
    gb = np.arange(math.log(1e-3), math.log(1e3), 0.05)
    vals = np.array([restricted.restricted_objective(EJ, dt_ratio, A, g, a0, b)[0] for b in gb])
    found = restricted.restricted_objective(EJ, dt_ratio, A, g, a0, math.log(q_re))[0]
    # within the search's own tolerance of the line's minimum (a flat stretch is left where the
    # decrease a model predicts falls below REML_FTOL)
    assert found <= vals.min() + 2 * restricted.REML_FTOL



def test_a_step_beyond_the_float_range_has_no_value_and_no_warning():
    """Residuals of 1e154 (a track far off the model: an attacker's offset) overflow the
    parameters' move: the objective is inf there, with no numpy warning."""
    import warnings

    n = 50
    J = np.column_stack([np.ones(n), np.linspace(0.0, 1.0, n)])
    EJ = np.ascontiguousarray(np.column_stack([np.full(n, 1e154), J]))
    A = np.diag([1e-300, 1e-300])
    g = np.array([1e300, -1e300])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        value, _ = restricted.restricted_objective(EJ, np.ones(n - 1), A, g, math.log(0.5), 0.0)
    assert value == math.inf
