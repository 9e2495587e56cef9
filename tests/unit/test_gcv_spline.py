"""The start curve's GCV smoothing spline (bayesdrag.estimate.build.gcv_spline) is scipy's
``make_smoothing_spline`` to the last bit, on start-curve-like data and on odd inputs."""
import numpy as np
import pytest
from scipy.interpolate import make_smoothing_spline

from bayesdrag.estimate.build.gcv_spline import gcv_lambda, gcv_smoothing_spline


def _cases():
    rng = np.random.default_rng(11)
    for n in (5, 6, 9, 40, 149, 300):
        # a Cd(M)-like curve in Mach bins with a transonic rise, per-bin noise and counts
        x = np.sort(rng.uniform(0.6, 2.6, n))
        x = np.unique(np.round(x, 6))
        cd = 0.15 + 0.25 / (1 + np.exp(-(x - 1.0) / 0.04)) - 0.05 * (x - 1)
        w = rng.integers(1, 30, x.size).astype(float)
        yield x, cd + rng.normal(0, 0.02, x.size) / np.sqrt(w), w / w.mean()
    x = np.linspace(0.0, 1.0, 50)
    yield x, np.sin(7 * x), np.ones(50)                       # equal weights
    yield x, np.zeros(50), np.ones(50)                        # a flat line (criterion 0/denominator)
    yield np.cumsum(rng.uniform(1e-3, 1.0, 80)), rng.normal(size=80), rng.uniform(0.1, 5, 80)


@pytest.mark.parametrize("case", list(_cases()), ids=lambda c: f"n{c[0].size}")
def test_the_spline_is_scipys_bit_for_bit(case):
    x, y, w = case
    ours = gcv_smoothing_spline(x, y, w)
    theirs = make_smoothing_spline(x, y, w=w)
    grid = np.linspace(x[0], x[-1], 997)
    assert np.array_equal(ours.c, theirs.c) and np.array_equal(ours.t, theirs.t)
    assert np.array_equal(ours(grid), theirs(grid))


def test_lambda_is_in_the_searched_interval():
    x, y, w = next(iter(_cases()))
    assert 0.0 <= gcv_lambda(x, y, w) <= x.size


@pytest.mark.parametrize("x, y, w, match", [
    (np.arange(4.0), np.ones(4), np.ones(4), "length >= 5"),
    (np.array([0.0, 1, 1, 2, 3]), np.ones(5), np.ones(5), "ascending"),
    (np.arange(5.0), np.ones(5), np.array([1.0, 1, 0, 1, 1]), "weights"),
    (np.arange(5.0), np.ones(6), np.ones(5), "one length"),
])
def test_bad_input_is_refused_as_scipy_refuses_it(x, y, w, match):
    with pytest.raises(ValueError, match=match):
        gcv_smoothing_spline(x, y, w)
