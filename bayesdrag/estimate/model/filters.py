"""Savitzky-Golay coefficients and smoothing, an FFT convolution and a residual's autocovariance
to its window's end: the few signal filters
the estimators use, in numpy, so that a fit does not import ``scipy.signal`` (which imports
``scipy.stats``: ~0.6 s of a command's start-up, measured in docs/report.md "Speed"). Each
follows scipy's algorithm (``scipy.signal.savgol_coeffs``, ``savgol_filter(mode="interp")``,
``fftconvolve(mode="same")``) and agrees with it to round-off (tests/unit/test_filters.py).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["savgol_coeffs", "savgol_smooth", "convolve_same", "fast_length", "autocovariance_window"]


def savgol_coeffs(window, order, deriv=0, delta=1.0, pos=None, use="conv"):
    """Savitzky-Golay filter coefficients (as ``scipy.signal.savgol_coeffs``).

    Parameters
    ----------
    window : int
        Samples in the window (> ``order``).
    order : int
        Degree of the local polynomial.
    deriv : int
        Derivative order of the estimate (0: the value).
    delta : float
        Sample spacing [s] (for ``deriv > 0``).
    pos : float, optional
        The estimate's place in the window (default its middle).
    use : {"conv", "dot"}
        Coefficients for a convolution (reversed) or for a dot product with the window.

    Returns
    -------
    (window,) ndarray
    """
    if order >= window:
        raise ValueError(f"Savitzky-Golay order {order} must be less than the window ({window} samples)")
    half, rem = divmod(window, 2)
    if pos is None:
        pos = half if rem else half - 0.5
    x = np.arange(-pos, window - pos, dtype=float)
    if use == "conv":
        x = x[::-1]
    A = x ** np.arange(order + 1).reshape(-1, 1)
    y = np.zeros(order + 1)
    y[deriv] = math.factorial(deriv) / delta ** deriv
    return np.linalg.lstsq(A, y, rcond=None)[0]


def savgol_smooth(z, window, order):
    """The local-polynomial smooth of ``z`` (as ``scipy.signal.savgol_filter(z, window, order,
    mode="interp")``): the filter inside, and at each end the polynomial fitted to the first or
    last ``window`` samples.

    Parameters
    ----------
    z : (N,) ndarray
    window : int, odd, <= N
    order : int, < window

    Returns
    -------
    (N,) ndarray
    """
    z = np.asarray(z, dtype=float)
    if window % 2 == 0 or window > z.size:
        raise ValueError(f"Savitzky-Golay window {window} must be odd and at most the {z.size} samples")
    out = np.convolve(z, savgol_coeffs(window, order), mode="same")
    half = window // 2
    i = np.arange(window)
    for lo, sl in ((0, slice(0, half)), (z.size - window, slice(z.size - half, z.size))):
        poly = np.polyfit(i, z[lo:lo + window], order)
        out[sl] = np.polyval(poly, np.arange(sl.start, sl.stop) - lo)
    return out


def convolve_same(s, kernel):
    """Each column of ``s`` convolved with ``kernel``, the middle ``N`` rows (as
    ``scipy.signal.fftconvolve(s, kernel[:, None], mode="same", axes=0)``).

    Parameters
    ----------
    s : (N, p) ndarray
    kernel : (K,) ndarray

    Returns
    -------
    (N, p) ndarray
    """
    N, K = s.shape[0], kernel.size
    n = fast_length(N + K - 1)           # zero padding beyond the full length changes nothing
    full = np.fft.irfft(np.fft.rfft(s, n, axis=0) * np.fft.rfft(kernel, n)[:, None], n, axis=0)
    start = (K - 1) // 2
    return full[start:start + N]


def fast_length(n):
    """The least length >= ``n`` whose only prime factors are 2, 3 and 5 (as
    ``scipy.fft.next_fast_len`` for real transforms): a transform of a length with a large prime
    factor (a track's sample count plus a lag window often is one) takes several times longer."""
    best = 1 << max(0, (int(n) - 1).bit_length())     # a power of two >= n
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            m = p35
            while m < n:
                m *= 2
            best = min(best, m)
            p35 *= 3
        p5 *= 5
    return best


def autocovariance_window(e, scale, cap):
    """A residual's autocovariances up to the end of its window: ``r_k = sum_n e[n + k] e[n] /
    scale`` for ``k = 0..kmax``, ``kmax`` the first lag whose value is below ``2 r_0 / sqrt(N)``
    (the white-noise band), at most ``cap``.

    The same numbers as ``np.correlate(e, e, "full")[N - 1:][:kmax + 1] / scale`` to the bit
    (each lag one BLAS dot product, as numpy's correlate takes it), without the O(N^2) lags
    beyond the window (tests/unit/test_filters.py).

    Parameters
    ----------
    e : (N,) ndarray
        Residuals, mean removed [any unit].
    scale : float
        Divisor of the sums (the samples counted).
    cap : int
        Largest lag returned.

    Returns
    -------
    (kmax + 1,) ndarray
        ``r_0 .. r_kmax`` [unit^2].
    """
    e = np.asarray(e, float)
    N = e.size
    # residuals beyond the float range give inf and NaN lags silently, as numpy's correlate does
    with np.errstate(over="ignore", invalid="ignore"):
        r0 = float(np.dot(e, e)) / scale
        lim = 2.0 / math.sqrt(N) * r0
        out = [r0]
        if r0 < lim:
            return np.array(out)
        for k in range(1, cap + 1):
            rk = float(np.dot(e[k:], e[:N - k])) / scale
            out.append(rk)
            if rk < lim:
                break
    return np.array(out)
