"""Colored residuals: white radar noise plus a first-order autoregressive model-error process.

Why this model
--------------
When the model is not exactly right (a 6-DOF shell fitted with a point mass, another simulator's
atmosphere, a table of another shell), the residuals of a channel are the radar's white noise
plus a slowly varying *model-error* signal. Counting such residuals as independent overstates the
information of the track many times over: the bands become too narrow.

A pure AR(1) noise of the whole residual does not capture this: its lag-one coefficient is
dominated by the white radar noise (measured on the shipped 6-DOF demo: x 0.05, v 0.04, while the
model-error part there is correlated over hundreds of samples), so the generalised least squares
barely changes the bounds. The noise of an ``ar1`` channel is therefore

    e_i = w_i + d_i,   w_i ~ N(0, sigma^2) independent,
    d_i = phi_i d_{i-1} + eta_i,   d stationary with variance q sigma^2,
    phi_i = rho ** (dt_i / dt_median)   (an irregular step keeps the correlation time),

an ARMA(1, 1) process: ``rho`` is the AR coefficient of the model-error part per median sample
interval, ``q`` its variance in units of the white noise variance. ``q = 0`` is white noise.

Its exact Gaussian likelihood comes from the Kalman filter of the scalar state ``d`` (O(N)):
innovations ``nu_i`` with variances ``F_i sigma^2``; ``u_i = nu_i / sqrt(F_i)`` are independent
with variance ``sigma^2``. The filter is linear in the data and its gains do not depend on them,
so the same transform applied to the sensitivities gives the generalised least squares and its
information matrix (the colored Cramér-Rao bound). With ``sigma`` profiled out,

    log L(rho, q) = -1/2 sum log F_i - N/2 log(sum u_i^2 / N) + const.

Functions here are pure; the Kalman passes are compiled with numba.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

#: largest model-error AR coefficient per median sample interval: a correlation time of 10^5
#: samples, i.e. a model-error signal that is practically a slow drift over a whole track
RHO_MAX = 1.0 - 1e-5
#: range of log q (model-error variance over white noise variance) [-]: from negligible to a
#: model error 10^4 times the radar noise sd
LOG_Q_RANGE = (-14.0, 18.0)
#: range of log(1 - rho) sampled by the posterior (uniform prior on it)
LOG_1M_RHO_RANGE = (math.log(1.0 - RHO_MAX), 0.0)
#: likelihood-ratio statistic 2 (log L_ar - log L_white) above which ``auto`` gives a channel the
#: ``ar1`` noise: 13.8 is the chi-square(2) 0.999 quantile, so a white channel is switched with
#: probability ~0.1 % (and then carries q near 0, i.e. nearly the same bands)
LR_THRESHOLD = 13.8


def step_coefficients(rho, dt_ratio):
    """AR coefficients per step.

    Parameters
    ----------
    rho : float or (W,) array_like
        AR coefficient per median sample interval, in [0, 1).
    dt_ratio : (N - 1,) array_like
        Sample intervals over their median [-].

    Returns
    -------
    (N - 1,) or (W, N - 1) ndarray
        ``rho ** dt_ratio``.
    """
    r = np.asarray(rho, float)
    return np.power(r[..., None], np.asarray(dt_ratio, float))


@njit(cache=True)
def _standardize(a, phi, q):
    """Kalman innovations of the columns of ``a`` (N, K) over their sd: (u (N, K), sum log F)."""
    N, K = a.shape
    u = np.empty_like(a)
    m = np.zeros(K)
    P = q
    logdet = 0.0
    for i in range(N):
        F = P + 1.0
        sF = math.sqrt(F)
        gain = P / F
        logdet += math.log(F)
        for k in range(K):
            nu = a[i, k] - m[k]
            u[i, k] = nu / sF
            m[k] += gain * nu
        if i < N - 1:
            f = phi[i]
            for k in range(K):
                m[k] *= f
            P = f * f * (P / F) + q * (1.0 - f * f)
    return u, logdet


@njit(cache=True)
def _whitened_ss(r, rho, q, dt_ratio):
    """Sum of squared standardised innovations and sum log F for rows of ``r`` (W, N).

    Once the filter's variance has converged (a constant step), ``F`` and its log are reused:
    the loop is then a multiply-add per sample."""
    W, N = r.shape
    ss = np.zeros(W)
    ld = np.zeros(W)
    for w in range(W):
        m = 0.0
        P = q[w]
        F = P + 1.0
        lF = math.log(F)
        iF = 1.0 / F
        acc = 0.0
        lg = 0.0
        for i in range(N):
            nu = r[w, i] - m
            acc += nu * nu * iF
            lg += lF
            m += (P * iF) * nu
            if i < N - 1:
                dr = dt_ratio[i]
                f = rho[w] if dr == 1.0 else rho[w] ** dr
                m *= f
                Pn = f * f * (P * iF) + q[w] * (1.0 - f * f)
                if abs(Pn - P) > 1e-13 * (P + 1.0):
                    P = Pn
                    F = P + 1.0
                    lF = math.log(F)
                    iF = 1.0 / F
        ss[w] = acc
        ld[w] = lg
    return ss, ld


def standardize(a, rho, q, dt_ratio):
    """Whiten residual-like data of one channel.

    Parameters
    ----------
    a : (N,) or (N, K) array_like
        Residuals [m or m/s] or sensitivity columns.
    rho : float
        Model-error AR coefficient per median sample interval.
    q : float
        Model-error variance over the white noise variance [-].
    dt_ratio : (N - 1,) array_like
        Sample intervals over their median.

    Returns
    -------
    u : ndarray of ``a``'s shape
        Standardised innovations: independent with the white noise variance under the model.
    logdet : float
        ``sum log F_i`` (the log determinant of the correlation matrix over sigma^2).
    """
    a = np.asarray(a, float)
    flat = a.reshape(a.shape[0], -1)
    u, logdet = _standardize(np.ascontiguousarray(flat), step_coefficients(rho, dt_ratio), float(q))
    return u.reshape(a.shape), float(logdet)


@njit(cache=True)
def _adjoint_standardize(y, phi, q):
    """The transpose of :func:`_standardize`'s linear map applied to the columns of ``y`` (N, K):
    its recursion run backwards (the filter's variances and gains do not depend on the data)."""
    N, K = y.shape
    s = np.empty(N)
    g = np.empty(N)
    P = q
    for i in range(N):
        F = P + 1.0
        s[i] = math.sqrt(F)
        g[i] = P / F
        if i < N - 1:
            f = phi[i]
            P = f * f * (P / F) + q * (1.0 - f * f)
    x = np.empty_like(y)
    lam = np.zeros(K)              # the adjoint of the filter's state after sample i
    for i in range(N - 1, -1, -1):
        f = phi[i] if i < N - 1 else 0.0
        for k in range(K):
            direct = y[i, k] / s[i]
            x[i, k] = direct + lam[k] * f * g[i]
            lam[k] = -direct + lam[k] * f * (1.0 - g[i])
    return x


def adjoint_standardize(y, rho, q, dt_ratio):
    """``L^-T y``, where ``L^-1`` is :func:`standardize`'s map (the whitening: ``L L'`` is the
    noise's correlation matrix over the white variance, ``I + q R``).

    Parameters
    ----------
    y : (N,) or (N, K) array_like
    rho, q : float
    dt_ratio : (N - 1,) array_like

    Returns
    -------
    ndarray of ``y``'s shape
        With ``u = standardize(a)``, ``(I + q R)^-1 a = adjoint_standardize(u)``.
    """
    y = np.asarray(y, float)
    flat = np.ascontiguousarray(y.reshape(y.shape[0], -1))
    return _adjoint_standardize(flat, step_coefficients(rho, dt_ratio), float(q)).reshape(y.shape)


@njit(cache=True)
def _correlation_apply(z, phi):
    """``R z`` for the AR(1) correlation ``R_ij = prod phi`` between samples i and j: a forward
    and a backward exponentially weighted sum, less the diagonal counted twice."""
    N, K = z.shape
    out = np.empty_like(z)
    acc = np.zeros(K)
    for i in range(N):
        f = phi[i - 1] if i > 0 else 0.0
        for k in range(K):
            acc[k] = z[i, k] + f * acc[k]
            out[i, k] = acc[k]
    acc[:] = 0.0
    for i in range(N - 1, -1, -1):
        f = phi[i] if i < N - 1 else 0.0
        for k in range(K):
            acc[k] = z[i, k] + f * acc[k]
            out[i, k] += acc[k] - z[i, k]
    return out


def correlation_apply(z, rho, dt_ratio):
    """The AR(1) part's correlation matrix times ``z``: ``(R z)_i = sum_j rho^|t_i - t_j|
    z_j``, times in median sample intervals (O(N) per column).

    Parameters
    ----------
    z : (N,) or (N, K) array_like
    rho : float
    dt_ratio : (N - 1,) array_like

    Returns
    -------
    ndarray of ``z``'s shape
    """
    z = np.asarray(z, float)
    flat = np.ascontiguousarray(z.reshape(z.shape[0], -1))
    return _correlation_apply(flat, step_coefficients(rho, dt_ratio)).reshape(z.shape)


def innovation_variances(rho, q, dt_ratio):
    """Variances of the Kalman innovations in units of the white noise variance, ``F_i``.

    The filter's variances do not depend on the data: ``u_i = nu_i / sqrt(F_i)`` of
    :func:`standardize` and these ``F_i`` give each sample's Gaussian log density,
    ``-1/2 (log(2 pi sigma^2 F_i) + u_i^2 / sigma^2)``, whose sum is the channel's exact
    log-likelihood (the pointwise terms of :mod:`bayesdrag.estimate.bayes.loglik`).

    Parameters
    ----------
    rho, q : float or (W,) array_like
        Model-error AR coefficient per median sample interval and variance ratio.
    dt_ratio : (N - 1,) array_like
        Sample intervals over their median.

    Returns
    -------
    (N,) or (W, N) ndarray
        ``F_i >= 1`` [-].
    """
    rho = np.asarray(rho, float)
    q = np.asarray(q, float)
    shape = np.broadcast(rho, q).shape
    phi = step_coefficients(rho, dt_ratio)
    n = np.asarray(dt_ratio).size + 1
    F = np.empty(shape + (n,))
    P = np.array(np.broadcast_to(q, shape), float)
    for i in range(n):
        F[..., i] = P + 1.0
        if i < n - 1:
            f = phi[..., i]
            P = f * f * (P / F[..., i]) + q * (1.0 - f * f)
    return F


@njit(cache=True)
def _whitened_ss_shared(rT, rho, q, dt_ratio):
    """:func:`_whitened_ss` for walkers that share ``rho`` and ``q`` (floats), residuals ``rT``
    (N, W): the filter's variances and gains do not depend on the data, so they are computed
    once, and the walkers' recursions run side by side (independent lanes the compiler
    vectorises instead of one latency-bound chain per walker). The arithmetic of each walker is
    the same, in the same order, as in :func:`_whitened_ss`."""
    N, W = rT.shape
    iFs = np.empty(N)
    gains = np.empty(N)
    fs = np.ones(N)
    P = q
    F = P + 1.0
    lF = math.log(F)
    iF = 1.0 / F
    lg = 0.0
    for i in range(N):
        iFs[i] = iF
        gains[i] = P * iF
        lg += lF
        if i < N - 1:
            dr = dt_ratio[i]
            f = rho if dr == 1.0 else rho ** dr
            fs[i] = f
            Pn = f * f * (P * iF) + q * (1.0 - f * f)
            if abs(Pn - P) > 1e-13 * (P + 1.0):
                P = Pn
                F = P + 1.0
                lF = math.log(F)
                iF = 1.0 / F
    m = np.zeros(W)
    ss = np.zeros(W)
    for i in range(N):
        iF = iFs[i]
        g = gains[i]
        f = fs[i]
        for w in range(W):
            nu = rT[i, w] - m[w]
            ss[w] += nu * nu * iF
            m[w] = (m[w] + g * nu) * f
    return ss, np.full(W, lg)


def whitened_ss(r, rho, q, dt_ratio):
    """Whitened residual sums of squares of many parameter sets (the posterior's hot path).

    Parameters
    ----------
    r : (W, N) ndarray
        Residuals of one channel for W walkers.
    rho, q : float or (W,) ndarray
        Noise parameters, shared or per walker.
    dt_ratio : (N - 1,) ndarray

    Returns
    -------
    ss : (W,) ndarray
        ``sum u_i^2`` [m^2 or m^2/s^2].
    logdet : (W,) ndarray
        ``sum log F_i``.
    """
    r = np.asarray(r, dtype=float)
    W = r.shape[0]
    rho = np.asarray(rho, float)
    q = np.asarray(q, float)
    dt_ratio = np.ascontiguousarray(dt_ratio, dtype=float)
    if rho.ndim == 0 and q.ndim == 0:     # the plug-in noise parameters: one filter for all walkers
        return _whitened_ss_shared(np.ascontiguousarray(r.T), float(rho), float(q), dt_ratio)
    return _whitened_ss(np.ascontiguousarray(r),
                        np.ascontiguousarray(np.broadcast_to(rho, (W,))),
                        np.ascontiguousarray(np.broadcast_to(q, (W,))), dt_ratio)


def profile_loglik(e, rho, q, dt_ratio):
    """Log likelihood of residuals ``e`` (N,) with the white noise sd profiled out (up to a
    constant): ``-1/2 sum log F - N/2 log(SS / N)``."""
    ss, ld = whitened_ss(np.asarray(e, float)[None], np.array([rho]), np.array([q]), dt_ratio)
    N = e.shape[0]
    return float(-0.5 * ld[0] - 0.5 * N * math.log(max(ss[0], 1e-300) / N))


def fit_noise(e, dt_ratio, start=None):
    """Maximum-likelihood noise parameters of one channel's residuals.

    Parameters
    ----------
    e : (N,) ndarray
        Residuals [m or m/s].
    dt_ratio : (N - 1,) ndarray
    start : (rho, q), optional
        Previous estimate (the relaxation's last), tried first.

    Returns
    -------
    sigma : float
        White noise sd [m or m/s].
    rho, q : float
        Model-error AR coefficient and variance ratio.
    lr : float
        ``2 (log L - log L_white)``: the evidence for a model-error component.
    """
    e = np.asarray(e, float)
    N = e.size
    white = -0.5 * N * math.log(max(float(e @ e) / N, 1e-300))
    rows = np.ascontiguousarray(e[None])
    dtr = np.ascontiguousarray(dt_ratio, dtype=float)
    if start is not None:
        # warm start (the relaxation's previous optimum, which moves little): that one only
        starts = [(math.log(max(1.0 - start[0], 1e-5)), math.log(max(start[1], 1e-6)))]
    else:
        starts = [(math.log(0.01), 0.0), (math.log(1e-3), 2.0), (math.log(1e-4), 5.0)]
    best = None
    for x0 in starts:
        a, b, fun, _ = _noise_nelder_mead(rows, dtr, float(x0[0]), float(x0[1]), 1e-3, 1e-4, 400)
        if best is None or fun < best[1]:
            best = ((a, b), fun)
    rho = 1.0 - math.exp(min(max(best[0][0], LOG_1M_RHO_RANGE[0]), 0.0))
    q = math.exp(min(max(best[0][1], LOG_Q_RANGE[0]), LOG_Q_RANGE[1]))
    lr = 2.0 * (-best[1] - white)
    if lr <= 0.0:
        rho, q, lr = 0.0, 0.0, 0.0
    u, _ = standardize(e, rho, q, dt_ratio)
    sigma = max(math.sqrt(float(u @ u) / N), 1e-9)
    return sigma, rho, q, lr


@njit(cache=True)
def _py_max(a, b):
    """Python's ``max(a, b)`` of floats: ``a`` unless ``b`` is larger (a NaN ``a`` stays)."""
    return b if b > a else a


@njit(cache=True)
def _py_min(a, b):
    """Python's ``min(a, b)`` of floats: ``a`` unless ``b`` is smaller."""
    return b if b < a else a


@njit(cache=True)
def _noise_nll(rows, dtr, rho_a, q_a, a, b):
    """Minus the profile log-likelihood (:func:`profile_loglik`) of ``rows`` (1, N) at
    ``(log(1 - rho), log q) = (a, b)``, each clamped to its range."""
    N = rows.shape[1]
    rho_a[0] = 1.0 - math.exp(_py_min(_py_max(a, LOG_1M_RHO_RANGE[0]), 0.0))
    q_a[0] = math.exp(_py_min(_py_max(b, LOG_Q_RANGE[0]), LOG_Q_RANGE[1]))
    ss, ld = _whitened_ss(rows, rho_a, q_a, dtr)
    return -(-0.5 * ld[0] - 0.5 * N * math.log(_py_max(ss[0], 1e-300) / N))


@njit(cache=True)
def _less(x, y):
    """numpy's sort order of floats: NaN after every number."""
    return x < y or (y != y and x == x)


@njit(cache=True)
def _noise_nelder_mead(rows, dtr, a0, b0, xatol, fatol, maxiter):
    """Minimise :func:`_noise_nll` by Nelder-Mead from ``(a0, b0)``: scipy's
    ``minimize(method="Nelder-Mead")`` (standard coefficients, its initial simplex and stopping
    rules, no bounds) step for step and bit for bit on two floats, compiled with the likelihood
    (the noise ML calls it ~100 times per fit; tests/unit/test_colored.py compares it with
    scipy's).

    Returns
    -------
    a, b : float
        The best vertex.
    fun : float
        Its value (NaN when a vertex's value is NaN).
    nfev : int
        Values taken.
    """
    rho_a, q_a = np.empty(1), np.empty(1)
    sa = np.empty(3)
    sb = np.empty(3)
    fs = np.empty(3)
    sa[0], sb[0] = a0, b0
    sa[1], sb[1] = ((1.0 + 0.05) * a0 if a0 != 0 else 0.00025), b0
    sa[2], sb[2] = a0, ((1.0 + 0.05) * b0 if b0 != 0 else 0.00025)
    for j in range(3):
        fs[j] = _noise_nll(rows, dtr, rho_a, q_a, sa[j], sb[j])
    nfev = 3
    it = 1
    while True:
        # the vertices in numpy's order of their values (a stable sort: ties keep their order)
        for i in range(1, 3):
            j = i
            while j > 0 and _less(fs[j], fs[j - 1]):
                sa[j], sa[j - 1] = sa[j - 1], sa[j]
                sb[j], sb[j - 1] = sb[j - 1], sb[j]
                fs[j], fs[j - 1] = fs[j - 1], fs[j]
                j -= 1
        if it >= maxiter:
            break
        dx = (abs(sa[1] - sa[0]), abs(sb[1] - sb[0]), abs(sa[2] - sa[0]), abs(sb[2] - sb[0]))
        df = (abs(fs[0] - fs[1]), abs(fs[0] - fs[2]))
        if (not (dx[0] != dx[0] or dx[1] != dx[1] or dx[2] != dx[2] or dx[3] != dx[3])
                and max(max(dx[0], dx[1]), max(dx[2], dx[3])) <= xatol
                and not (df[0] != df[0] or df[1] != df[1]) and max(df[0], df[1]) <= fatol):
            break
        xa, xb = (sa[0] + sa[1]) / 2, (sb[0] + sb[1]) / 2
        ra, rb = 2 * xa - sa[2], 2 * xb - sb[2]
        fxr = _noise_nll(rows, dtr, rho_a, q_a, ra, rb)
        nfev += 1
        if fxr < fs[0]:
            ea, eb = 3 * xa - 2 * sa[2], 3 * xb - 2 * sb[2]
            fxe = _noise_nll(rows, dtr, rho_a, q_a, ea, eb)
            nfev += 1
            if fxe < fxr:
                sa[2], sb[2], fs[2] = ea, eb, fxe
            else:
                sa[2], sb[2], fs[2] = ra, rb, fxr
        elif fxr < fs[1]:
            sa[2], sb[2], fs[2] = ra, rb, fxr
        else:
            if fxr < fs[2]:
                ca, cb = 1.5 * xa - 0.5 * sa[2], 1.5 * xb - 0.5 * sb[2]
                fxc = _noise_nll(rows, dtr, rho_a, q_a, ca, cb)
                nfev += 1
                shrink = not fxc <= fxr
                if not shrink:
                    sa[2], sb[2], fs[2] = ca, cb, fxc
            else:
                ca, cb = 0.5 * xa + 0.5 * sa[2], 0.5 * xb + 0.5 * sb[2]
                fxcc = _noise_nll(rows, dtr, rho_a, q_a, ca, cb)
                nfev += 1
                shrink = not fxcc < fs[2]
                if not shrink:
                    sa[2], sb[2], fs[2] = ca, cb, fxcc
            if shrink:
                for j in (1, 2):
                    sa[j] = sa[0] + 0.5 * (sa[j] - sa[0])
                    sb[j] = sb[0] + 0.5 * (sb[j] - sb[0])
                    fs[j] = _noise_nll(rows, dtr, rho_a, q_a, sa[j], sb[j])
                    nfev += 1
        it += 1
    fun = fs[0]
    for j in range(3):
        if fs[j] != fs[j]:
            fun = math.nan
    return sa[0], sb[0], fun, nfev
