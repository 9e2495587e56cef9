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
    # profile_loglik's kernel called directly on arrays made once: the optimiser evaluates this
    # ~100 times per call, and the wrapper's conversions cost more than the filter
    rows = np.ascontiguousarray(e[None])
    dtr = np.ascontiguousarray(dt_ratio, dtype=float)
    rho_a, q_a = np.empty(1), np.empty(1)

    def nll(x):
        rho_a[0] = 1.0 - math.exp(min(max(x[0], LOG_1M_RHO_RANGE[0]), 0.0))
        q_a[0] = math.exp(min(max(x[1], LOG_Q_RANGE[0]), LOG_Q_RANGE[1]))
        ss, ld = _whitened_ss(rows, rho_a, q_a, dtr)
        return -float(-0.5 * ld[0] - 0.5 * N * math.log(max(ss[0], 1e-300) / N))

    if start is not None:
        # warm start (the relaxation's previous optimum, which moves little): that one only
        starts = [(math.log(max(1.0 - start[0], 1e-5)), math.log(max(start[1], 1e-6)))]
    else:
        starts = [(math.log(0.01), 0.0), (math.log(1e-3), 2.0), (math.log(1e-4), 5.0)]
    best = None
    for x0 in starts:
        x, fun = nelder_mead_2d(nll, x0, xatol=1e-3, fatol=1e-4, maxiter=400)
        if best is None or fun < best[1]:
            best = (x, fun)
    rho = 1.0 - math.exp(min(max(best[0][0], LOG_1M_RHO_RANGE[0]), 0.0))
    q = math.exp(min(max(best[0][1], LOG_Q_RANGE[0]), LOG_Q_RANGE[1]))
    lr = 2.0 * (-best[1] - white)
    if lr <= 0.0:
        rho, q, lr = 0.0, 0.0, 0.0
    u, _ = standardize(e, rho, q, dt_ratio)
    sigma = max(math.sqrt(float(u @ u) / N), 1e-9)
    return sigma, rho, q, lr


def _nan_max(values):
    """The largest of floats, NaN when any is NaN (as ``np.max``)."""
    return math.nan if any(v != v for v in values) else max(values)


def nelder_mead_2d(f, x0, xatol=1e-4, fatol=1e-4, maxiter=400):
    """Minimise ``f((a, b))`` by Nelder-Mead from ``x0``: scipy's ``minimize(method="Nelder-Mead")``
    (standard coefficients, its initial simplex and stopping rules, no bounds) step for step and
    bit for bit on two floats, without its per-step array work (the noise ML above calls it a
    hundred times per fit; tests/unit/test_colored.py compares the two).

    Parameters
    ----------
    f : callable
        ``f((a, b)) -> float``.
    x0 : (2,) sequence of float
    xatol, fatol : float
        Stop when every vertex is within ``xatol`` of the best in each coordinate and every
        value within ``fatol`` of the best.
    maxiter : int

    Returns
    -------
    x : (float, float)
        The best vertex.
    fun : float
        Its value (NaN when a vertex's value is NaN).
    """
    a, b = float(x0[0]), float(x0[1])
    sim = [(a, b), ((1 + 0.05) * a if a != 0 else 0.00025, b), (a, (1 + 0.05) * b if b != 0 else 0.00025)]
    fsim = [f(v) for v in sim]

    def order():
        # numpy's own sort, as scipy's (its order of equal values is the sort's to choose)
        idx = np.argsort(np.array(fsim)).tolist()
        return [sim[i] for i in idx], [fsim[i] for i in idx]

    sim, fsim = order()
    sim, fsim = order()      # scipy sorts the first simplex twice
    it = 1
    while it < maxiter:
        (x0a, x0b), (x1a, x1b), (x2a, x2b) = sim
        if (_nan_max([abs(x1a - x0a), abs(x1b - x0b), abs(x2a - x0a), abs(x2b - x0b)]) <= xatol
                and _nan_max([abs(fsim[0] - fsim[1]), abs(fsim[0] - fsim[2])]) <= fatol):
            break
        xa, xb = (x0a + x1a) / 2, (x0b + x1b) / 2
        xr = (2 * xa - x2a, 2 * xb - x2b)
        fxr = f(xr)
        if fxr < fsim[0]:
            xe = (3 * xa - 2 * x2a, 3 * xb - 2 * x2b)
            fxe = f(xe)
            sim[2], fsim[2] = (xe, fxe) if fxe < fxr else (xr, fxr)
        elif fxr < fsim[1]:
            sim[2], fsim[2] = xr, fxr
        else:
            if fxr < fsim[2]:
                xc = (1.5 * xa - 0.5 * x2a, 1.5 * xb - 0.5 * x2b)
                fxc = f(xc)
                shrink = not fxc <= fxr
                if not shrink:
                    sim[2], fsim[2] = xc, fxc
            else:
                xcc = (0.5 * xa + 0.5 * x2a, 0.5 * xb + 0.5 * x2b)
                fxcc = f(xcc)
                shrink = not fxcc < fsim[2]
                if not shrink:
                    sim[2], fsim[2] = xcc, fxcc
            if shrink:
                for j in (1, 2):
                    sim[j] = (x0a + 0.5 * (sim[j][0] - x0a), x0b + 0.5 * (sim[j][1] - x0b))
                    fsim[j] = f(sim[j])
        it += 1
        sim, fsim = order()
    return sim[0], (math.nan if any(v != v for v in fsim) else fsim[0])
