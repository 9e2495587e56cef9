"""Restricted-likelihood (REML) noise of one channel with white + AR(1) noise (:mod:`colored`).

Why
---
The residuals of a fit are the noise less what the fitted parameters absorb. A fit flexible
enough to absorb part of a slow noise (a spline in Cd) leaves residuals less correlated than the
noise, so the plain likelihood of the residuals (:func:`colored.fit_noise`) finds too short a
correlation and the bands that rest on it are too narrow. The restricted likelihood
(:func:`restricted_objective`) lets the parameters move with the candidate noise and counts the
volume they take out of the data; :func:`fit_noise_restricted` searches it.
:meth:`~bayesdrag.estimate.model.problem.OutputErrorProblem.update_noise_restricted` runs it for
every ``ar1`` channel of a fit, and :mod:`ml` holds the result for a few steps.

Functions here are pure; the whitening is :mod:`colored`'s compiled Kalman filter.
"""
from __future__ import annotations

import math

import numpy as np

from .colored import LOG_1M_RHO_RANGE, LOG_Q_RANGE, standardize

#: stencil step of the restricted search's quadratic models, in log(1 - rho) and log q [-]
REML_STEP = 0.4
#: most trust-region rounds of one restricted search (each builds one model: five new values)
REML_ROUNDS = 12
#: a search stops when a round's step is below this in both coordinates [-] ...
REML_XTOL = 1e-3
#: ... or the decrease its model predicts is below this [log-likelihood units]: a flat direction
#: (log q of a channel with no white part) is then left where it is
REML_FTOL = 1e-3
#: fixed-point iterations of the restricted white-noise variance at one (rho, q), and their tolerance
REML_S2_ITER, REML_S2_TOL = 30, 1e-9


def _nodes(c, lo, hi):
    """Three stencil nodes around ``c`` inside ``[lo, hi]``: centred, or one-sided at a bound."""
    h = REML_STEP
    if c + h > hi:
        return (c - 2 * h, c - h, c)
    if c - h < lo:
        return (c, c + h, c + 2 * h)
    return (c - h, c, c + h)


def _quadratic_model(f, center, f_center, a_fixed=False):
    """Coefficients of the quadratic in ``(a, b) - center`` through ``f`` at a six-point stencil
    (the centre row and column of a 3 x 3 grid and one corner), or None where ``f`` is not finite.
    ``a_fixed``: the search cannot move in ``a`` (its bounds meet), so only the terms in ``b``
    are fitted, from the centre column alone (the same ones the six points give at ``a`` = its
    centre, for half the values)."""
    ca, cb = center
    nb = _nodes(cb, *LOG_Q_RANGE)
    if a_fixed:
        X, y = [], []
        for b in nb:
            db = b - cb
            X.append((1.0, db, db * db))
            y.append(f_center if b == cb else f(ca, b))
        if not np.all(np.isfinite(y)):
            return None
        c0, c2, c5 = np.linalg.solve(np.array(X), np.array(y))
        return np.array([c0, 0.0, c2, 0.0, 0.0, c5])
    na = _nodes(ca, LOG_1M_RHO_RANGE[0], 0.0)
    pa = [x for x in na if x != ca][0]
    pb = [x for x in nb if x != cb][0]
    points = [(ca, cb)] + [(x, cb) for x in na if x != ca] + [(ca, x) for x in nb if x != cb] + [(pa, pb)]
    X, y = [], []
    for k, (a, b) in enumerate(points):
        da, db = a - ca, b - cb
        X.append((1.0, da, db, da * da, da * db, db * db))
        y.append(f_center if k == 0 else f(a, b))
    if not np.all(np.isfinite(y)):
        return None
    return np.linalg.solve(np.array(X), np.array(y))


def _quadratic_box_min(coef, lo, hi):
    """Minimum of ``c0 + c1 a + c2 b + c3 a^2 + c4 a b + c5 b^2`` over the box ``lo <= (a, b) <=
    hi`` (offsets from the model's centre): the interior stationary point when the quadratic is
    convex, else the best of each edge's own minimum and the corners.

    Returns
    -------
    (a, b), value
    """
    c0, c1, c2, c3, c4, c5 = (float(v) for v in coef)

    def q(a, b):
        return c0 + c1 * a + c2 * b + c3 * a * a + c4 * a * b + c5 * b * b

    cands = [(lo[0], lo[1]), (lo[0], hi[1]), (hi[0], lo[1]), (hi[0], hi[1])]
    det = 4.0 * c3 * c5 - c4 * c4
    if c3 > 0 and det > 0:
        a = (-2.0 * c5 * c1 + c4 * c2) / det
        b = (-2.0 * c3 * c2 + c4 * c1) / det
        cands.append((a, b))
    for b in (lo[1], hi[1]):             # edges at fixed b: minimise in a
        if c3 > 0:
            cands.append((-(c1 + c4 * b) / (2.0 * c3), b))
    for a in (lo[0], hi[0]):             # edges at fixed a: minimise in b
        if c5 > 0:
            cands.append((a, -(c2 + c4 * a) / (2.0 * c5)))
    best = None
    for a, b in cands:
        a, b = min(max(a, lo[0]), hi[0]), min(max(b, lo[1]), hi[1])
        v = q(a, b)
        if best is None or v < best[1]:
            best = ((a, b), v)
    return best


def restricted_objective(EJ, dt_ratio, A_other, g_other, a, b):
    """Minus the restricted log-likelihood of one channel's noise ``(log(1 - rho), log q)``, the
    fit's parameters profiled in their linearisation and the channel's white variance profiled.

    With ``e~`` and ``J~`` the channel's residuals and sensitivities whitened by the candidate
    noise (unit innovation variance), ``G = J~' J~``, ``h = J~' e~``, the step of the parameters
    is ``delta = H^-1 (g_other + h / s2)``, ``H = A_other + G / s2``, and the white variance
    solves ``s2 = (|e~ - J~ delta|^2 + tr(H^-1 G)) / N`` (the restricted estimate: the residual
    sum of squares plus what the fitted parameters took out of it). The value is
    ``1/2 sum log F + N/2 log s2 + 1/2 (|e~ - J~ delta|^2 / s2 - 2 g_other' delta
    + delta' A_other delta) + 1/2 log det H``, up to a constant.

    Parameters
    ----------
    EJ : (N, 1 + K) ndarray, C-contiguous
        The channel's residuals over the noise scale, then its sensitivities to the K free
        parameters over the noise scale.
    dt_ratio : (N - 1,) ndarray
    A_other : (K, K) ndarray
        Information of the other channels (at their held noise) and the priors.
    g_other : (K,) ndarray
        Their gradient ``A' r`` at the linearisation point (whitened residuals, priors' residuals).
    a, b : float

    Returns
    -------
    value : float
        ``inf`` where the information is not positive definite.
    s2 : float
        The restricted white variance [(noise scale)^2].
    """
    rho, q = 1.0 - math.exp(a), math.exp(b)
    U, ld = standardize(EJ, rho, q, dt_ratio)
    with np.errstate(over="ignore", invalid="ignore"):
        # a track far off the model (an attacker's 1 km offset) moves the parameters beyond the
        # float range: no value there, and no numpy warning on the user's console
        P = U.T @ U
        value, s2 = _profiled(P, ld, EJ.shape[0], A_other, g_other)
    return (value if math.isfinite(value) else math.inf), s2


def _profiled(P, ld, N, A_other, g_other):
    """:func:`restricted_objective`'s value and white variance from the whitened products
    ``P = [e~ J~]' [e~ J~]`` and the whitening's ``sum log F`` (``ld``)."""
    ee, h, G = P[0, 0], P[1:, 0], P[1:, 1:]
    # the other channels' terms come as scalars (0) when no other channel is fitted
    A_other = np.broadcast_to(np.asarray(A_other, float), G.shape)
    g_other = np.broadcast_to(np.asarray(g_other, float), h.shape)
    s2 = max(ee / N, 1e-300)
    rhs = np.empty((G.shape[0], G.shape[0] + 1))
    rhs[:, 1:] = G
    for _ in range(REML_S2_ITER):
        H = A_other + G / s2
        rhs[:, 0] = g_other + h / s2
        try:
            sol = np.linalg.solve(H, rhs)          # delta, then H^-1 G: one factorisation
        except np.linalg.LinAlgError:
            return math.inf, math.nan
        delta = sol[:, 0]
        rss = max(ee - 2.0 * delta @ h + delta @ G @ delta, 0.0)
        new = max((rss + float(np.trace(sol[:, 1:]))) / N, 1e-300)
        done = abs(new / s2 - 1.0) < REML_S2_TOL
        s2 = new
        if done:
            break
    H = A_other + G / s2
    try:
        L = np.linalg.cholesky(H)
        # a factorable H may still be singular to LU in the last bits (seen on a track 1 km off the
        # model compiled for another instruction set): no value there either
        delta = np.linalg.solve(H, g_other + h / s2)
    except np.linalg.LinAlgError:
        return math.inf, math.nan
    rss = max(ee - 2.0 * delta @ h + delta @ G @ delta, 0.0)
    other = -2.0 * g_other @ delta + delta @ A_other @ delta
    return float(0.5 * ld + 0.5 * N * math.log(s2) + 0.5 * (rss / s2 + other) + np.sum(np.log(np.diag(L)))), s2


def fit_noise_restricted(e, dt_ratio, start, J, A_other, g_other):
    """Restricted-likelihood (REML) noise parameters of one channel.

    The residuals of a fit are the noise less what the fitted parameters absorb; for a flexible
    fit that is much of the slow part of a correlated noise, so the plain likelihood of the
    residuals (:func:`fit_noise`) finds too short a correlation and too small a variance, and the
    bands that rest on them are too narrow. The restricted likelihood
    (:func:`restricted_objective`) lets the parameters move with the candidate noise (the
    generalised least squares at that noise, linearised) and adds
    ``-1/2 log det`` of their information: the volume they take out of the data.

    Each value whitens all K sensitivity columns; the objective is smooth in
    ``(log(1 - rho), log q)``, so the search is a trust region on quadratic models of it from six
    values each, with the step judged by the exact value and the radius grown after good steps
    (a channel whose plain estimate has no white part, where the objective is flat in ``log q``,
    must travel far).

    The search is bounded to correlations no shorter than the plain likelihood's (the fit's
    absorption of slow noise only shortens them) and no longer than the track (beyond it the
    fitted parameters take the noise whole, and the restricted likelihood, with nothing to tell
    its size, runs off to a random walk); a plain estimate already beyond the track is kept.

    Parameters
    ----------
    e : (N,) ndarray
        Residuals over the noise scale at the linearisation point.
    dt_ratio : (N - 1,) ndarray
    start : (rho, q)
        The plain likelihood's estimate: where the search starts, and its bound.
    J : (N, K) ndarray
        The channel's sensitivities to the free parameters, over the noise scale.
    A_other : (K, K) ndarray
        Information from the other channels and the priors.
    g_other : (K,) ndarray
        Their gradient at the linearisation point.

    Returns
    -------
    sigma : float
        The white noise sd [noise scale] (the restricted estimate).
    rho, q : float
    """
    e = np.asarray(e, float)
    N = e.size
    EJ = np.ascontiguousarray(np.column_stack([e, np.asarray(J, float)]))
    dtr = np.ascontiguousarray(dt_ratio, dtype=float)
    hi = min(math.log(max(1.0 - start[0], 1e-300)), 0.0)
    lo = max(LOG_1M_RHO_RANGE[0], min(hi, -math.log(N)))

    s2_at = {}

    def f(a, b):
        # the white variance of each value kept: the search's end needs the one at its point
        value, s2_at[(a, b)] = restricted_objective(EJ, dtr, A_other, g_other, a, b)
        return value

    x = (min(max(math.log(max(1.0 - start[0], 1e-5)), lo), hi),
         min(max(math.log(max(start[1], 1e-6)), LOG_Q_RANGE[0]), LOG_Q_RANGE[1]))
    f_x = f(*x)
    radius = 1.5 * REML_STEP
    coef = None
    for _ in range(REML_ROUNDS):
        if not math.isfinite(f_x):
            break
        if coef is None:                     # a model at each new centre; a rejected step keeps it
            coef = _quadratic_model(f, x, f_x, a_fixed=lo >= hi)
            if coef is None:
                break
        # the model's minimum within the radius and the search's bounds (offsets from x)
        d, m_y = _quadratic_box_min(
            coef, (max(lo, x[0] - radius) - x[0], max(LOG_Q_RANGE[0], x[1] - radius) - x[1]),
            (min(hi, x[0] + radius) - x[0], min(LOG_Q_RANGE[1], x[1] + radius) - x[1]))
        y = (x[0] + d[0], x[1] + d[1])
        predicted = f_x - m_y
        if not predicted > 1e-12:
            break
        f_y = f(*y)
        ratio = (f_x - f_y) / predicted
        step = max(abs(y[0] - x[0]), abs(y[1] - x[1]))
        if ratio > 0.1:
            x, f_x, coef = y, f_y, None
        if ratio > 0.75 and step > 0.9 * radius:
            radius *= 3.0
        elif ratio < 0.25:
            radius *= 0.25
        if (ratio > 0.1 and step < REML_XTOL) or predicted < REML_FTOL or radius < REML_XTOL:
            break
    s2 = s2_at.get(x, math.nan)
    if not math.isfinite(s2):       # no positive definite information at the start: the plain estimate
        u, _ = standardize(e, start[0], start[1], dt_ratio)
        s2 = float(u @ u) / N
    return max(math.sqrt(s2), 1e-9), 1.0 - math.exp(x[0]), math.exp(x[1])


def restricted_spread(e, dt_ratio, J, A_other, g_other, rho, q):
    """How far the restricted likelihood leaves a channel's correlation open: its sd in
    ``log(1 - rho)`` and the two noises one sd either side (``log q`` following its ridge, the
    white variance profiled), for :mod:`noise_spread`.

    The curvature is that of a quadratic model at the estimate (:func:`_quadratic_model`); the sd
    is the profile's (``log q`` free), no larger than a uniform spread over the correlations the
    search allows (``rho`` from 0 to the track's length). A correlation beyond the track (the
    search held it there, the fitted parameters take such noise whole) has no spread.

    Parameters
    ----------
    e, dt_ratio, J, A_other, g_other
        As in :func:`fit_noise_restricted`.
    rho, q : float
        The channel's estimate.

    Returns
    -------
    sd : float
        sd of ``log(1 - rho)`` [-] (0 where there is no spread).
    points : tuple of (rho, q, s2)
        The noises at one sd below and above (``s2``: the restricted white variance [(noise
        scale)^2]); empty where there is no spread or a value is not finite.
    """
    e = np.asarray(e, float)
    N = e.size
    EJ = np.ascontiguousarray(np.column_stack([e, np.asarray(J, float)]))
    dtr = np.ascontiguousarray(dt_ratio, dtype=float)
    lo = max(LOG_1M_RHO_RANGE[0], -math.log(N))
    a0 = math.log(max(1.0 - rho, 1e-300))
    b0 = min(max(math.log(max(q, 1e-300)), LOG_Q_RANGE[0]), LOG_Q_RANGE[1])
    if not a0 > lo + 1e-9:
        return 0.0, ()

    def f(a, b):
        return restricted_objective(EJ, dtr, A_other, g_other, a, b)[0]

    f0 = f(a0, b0)
    coef = _quadratic_model(f, (a0, b0), f0) if math.isfinite(f0) else None
    if coef is None:
        return 0.0, ()
    c3, c4, c5 = (float(v) for v in coef[3:])
    det = 4.0 * c3 * c5 - c4 * c4
    if c5 > 0 and det > 0:
        var, slope = 2.0 * c5 / det, -c4 / (2.0 * c5)
    elif c3 > 0:
        var, slope = 1.0 / (2.0 * c3), 0.0
    else:
        var, slope = math.inf, 0.0
    sd = math.sqrt(min(var, lo * lo / 12.0))
    points = []
    for a in (max(a0 - sd, lo), min(a0 + sd, 0.0)):
        b = min(max(b0 + slope * (a - a0), LOG_Q_RANGE[0]), LOG_Q_RANGE[1])
        value, s2 = restricted_objective(EJ, dtr, A_other, g_other, a, b)
        if not (math.isfinite(value) and math.isfinite(s2)):
            return sd, ()
        points.append((1.0 - math.exp(a), math.exp(b), s2))
    return sd, tuple(points)
