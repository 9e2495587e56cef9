"""The numpy signal filters agree with scipy.signal's to round-off."""
import numpy as np
import pytest
from scipy import signal

from bayesdrag.estimate.model.filters import convolve_same, savgol_coeffs, savgol_smooth

#: agreement with scipy [relative to the data's scale]: round-off of a least-squares solve
ROUNDOFF = 1e-11


@pytest.mark.parametrize("window,order,deriv,pos,use", [(15, 3, 0, None, "conv"), (7, 2, 0, 2, "dot"),
                                                         (9, 2, 1, 0, "dot"), (8, 3, 0, None, "conv")])
def test_savgol_coeffs_match_scipy(window, order, deriv, pos, use):
    got = savgol_coeffs(window, order, deriv=deriv, delta=0.027, pos=pos, use=use)
    want = signal.savgol_coeffs(window, order, deriv=deriv, delta=0.027, pos=pos, use=use)
    assert np.allclose(got, want, rtol=0, atol=ROUNDOFF * np.abs(want).max())


@pytest.mark.parametrize("n,window,order", [(200, 15, 3), (15, 15, 3), (40, 7, 2)])
def test_savgol_smooth_matches_scipy_interp_mode(n, window, order):
    rng = np.random.default_rng(4)
    t = np.linspace(0, 3, n)
    z = 800 * t - 30 * t**2 + rng.normal(0, 1.0, n)
    want = signal.savgol_filter(z, window, order, mode="interp")
    assert np.allclose(savgol_smooth(z, window, order), want, rtol=0, atol=ROUNDOFF * np.abs(z).max())


def test_savgol_smooth_refuses_an_even_window():
    with pytest.raises(ValueError, match="must be odd"):
        savgol_smooth(np.zeros(20), 8, 2)


@pytest.mark.parametrize("N,kmax", [(500, 12), (30, 1), (64, 31)])
def test_convolve_same_matches_fftconvolve(N, kmax):
    rng = np.random.default_rng(5)
    s = rng.normal(size=(N, 4))
    ker = rng.normal(size=2 * kmax + 1)
    want = signal.fftconvolve(s, ker[:, None], mode="same", axes=0)
    assert np.allclose(convolve_same(s, ker), want, rtol=0, atol=ROUNDOFF * np.abs(want).max())


def test_fast_length_is_the_least_5_smooth_length_not_below_n():
    from bayesdrag.estimate.model.filters import fast_length

    def smooth(m):
        for p in (2, 3, 5):
            while m % p == 0:
                m //= p
        return m == 1

    for n in (1, 2, 7, 1229, 1811, 4097, 12289):
        m = fast_length(n)
        assert m >= n and smooth(m)
        assert not any(smooth(k) for k in range(n, m))


@pytest.mark.parametrize("n, rho, cap", [(1209, 0.0, 302), (1209, 0.95, 302), (500, 0.999, 125), (3, 0.0, 0),
                                         (300, 0.9, 10)])
def test_autocovariance_window_is_numpys_correlate_to_the_bit(n, rho, cap):
    """The window's lags are numpy's full correlation's, bit for bit, up to the first below the
    white-noise band (or the cap), and no further."""
    from bayesdrag.estimate.model.filters import autocovariance_window

    rng = np.random.default_rng(n)
    e = rng.standard_normal(n)
    for i in range(1, n):
        e[i] += rho * e[i - 1]
    e -= e.mean()
    full = np.correlate(e, e, mode="full")[n - 1:] / n
    below = np.flatnonzero(full < 2.0 / np.sqrt(n) * full[0])
    kmax = min(int(below[0]) if below.size else n // 4, cap)
    got = autocovariance_window(e, n, cap)
    assert got.size == kmax + 1
    np.testing.assert_array_equal(got, full[:kmax + 1])


def test_autocovariance_window_beyond_the_float_range_is_silent_as_numpys():
    """Residuals whose squares overflow give the same inf/NaN lags as numpy's correlate, and no
    warning on the user's console."""
    import warnings

    from bayesdrag.estimate.model.filters import autocovariance_window

    e = np.r_[np.full(3, 1e200), np.full(3, -1e200)]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = autocovariance_window(e, 6, 1)
        want = np.correlate(e, e, mode="full")[5:7] / 6
    np.testing.assert_array_equal(got, want)
