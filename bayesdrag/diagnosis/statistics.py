"""The diagnosis' test statistics (step 4 of :mod:`bayesdrag.diagnosis`): the residual
autocovariance, the colored-noise inflation of an output change, the noise-only spread of a
chi2, and the significance rule of one effect (:func:`threshold`, :func:`tested_drop`,
:func:`tested_inflation`).

A candidate's chi2 drop ``d`` is divided by the colored-noise inflation ``g' Rvv g / g' R g`` of
its fitted output change ``g`` (residual autocovariance measured on the candidate's own
residuals, summed to the lag where it drops below its noise level, as in Morelli & Klein's
colored-residual CRB) and compared with the chi2 quantile of the effect's number of parameters at
the per-test level.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.special import gammaincinv

from ..estimate.model.filters import autocovariance_window
from .setup import track_chi2
from ..effects import DRAG_SHAPE, YAW_DRAG

__all__ = ["chi2_quantile", "autocovariance", "chi2_noise_sd", "colored_inflation", "threshold", "tested_drop",
           "tested_inflation"]

#: overall false-alarm rate of the verdict on a track the nominal model explains
ALPHA = 0.05
#: Bonferroni factor for the unidentified yaw decay rate under the null (see :func:`threshold`)
YAW_DECAY_MULTIPLICITY = 5


def chi2_quantile(q, k):
    """The ``q`` quantile of the chi2 distribution with ``k`` degrees of freedom: the numbers of
    ``scipy.stats.chi2.ppf(q, k)`` bit for bit (its own formula, ``2 gammaincinv(k / 2, q)``),
    without importing ``scipy.stats`` (0.35-0.65 s, paid by every forked diagnosis).

    Parameters
    ----------
    q : float or array
        Probability in [0, 1].
    k : float or array
        Degrees of freedom (> 0).

    Returns
    -------
    float64 or ndarray
        (For ``k = 0``, which no test has, SciPy gives NaN and this 0 or inf.)
    """
    return 2.0 * gammaincinv(np.asarray(k, float) / 2.0, q)


def autocovariance(resid, weights, max_lag=None):
    """Autocovariance per channel of weighted residuals, truncated where it first drops below
    its noise level ``2 r0 / sqrt(N)`` (as the Morelli-Klein correction in ml.py).

    Parameters
    ----------
    resid : (N, C) array
    weights : (N, C) array (0 = excluded sample)

    Returns
    -------
    list of (L_c,) arrays r_c(0..L_c)
    """
    N, C = resid.shape
    out = []
    for j in range(C):
        w = weights[:, j] > 0
        e = np.where(w, resid[:, j] - (resid[w, j].mean() if w.any() else 0.0), 0.0)
        out.append(autocovariance_window(e, max(w.sum(), 1), min(N // 4, max_lag or N)))
    return out


def chi2_noise_sd(acov, sigma_vec, weights):
    """Standard deviation of the noise-only chi2 of a fit whose residuals have the
    autocovariance ``acov``: ``sqrt(sum_c 2 n_c sum_k (r_c(k) / sigma_c^2)^2)`` over lags
    -L..L (Gaussian noise; sqrt(2 n) when white at the assumed sigma, ~4.4 times that for
    AR(1) noise with rho = 0.95)."""
    v = 0.0
    for j, r in enumerate(acov):
        n = float(np.count_nonzero(weights[:, j]))
        rr = np.asarray(r, dtype=float) / sigma_vec[j] ** 2
        v += 2.0 * n * (rr[0] ** 2 + 2.0 * float(np.sum(rr[1:] ** 2)))
    return math.sqrt(max(v, 0.0))


def colored_inflation(g, acov, sigma_vec, weights):
    """Variance inflation ``g' Rvv g / g' R g`` of a weighted output change under the measured
    residual autocovariance (1 for white noise at the assumed sigma).

    Parameters
    ----------
    g : (N, C) array
        Output change (model units).
    acov : list of arrays (from :func:`autocovariance`)
    sigma_vec : (C,) assumed noise sd
    weights : (N, C)
    """
    gw = g * weights / sigma_vec[None, :] ** 2  # R^-1 g
    num = 0.0
    den = float(np.sum(g * gw))
    for j, r in enumerate(acov):
        s = gw[:, j]
        num += r[0] * float(s @ s)
        for k in range(1, len(r)):
            num += 2.0 * r[k] * float(s[:-k] @ s[k:])
    if den <= 0:
        return 1.0
    return max(num / den, 0.05)


def threshold(e, a, k=None):
    """Critical value of the colored chi2-drop statistic of effect ``e`` at level ``a``.

    chi2 quantile with the effect's number of parameters; for ``yaw_drag`` the decay rate is
    not identified when the amplitude is zero (Davies' problem: the fit maximises over it, which
    inflates the statistic under the null), so its amplitude is tested with 1 degree of freedom
    at ``a / YAW_DECAY_MULTIPLICITY`` (as if that many separate decay rates were tried)."""
    if e.name == YAW_DRAG.name:
        return float(chi2_quantile(1 - a / YAW_DECAY_MULTIPLICITY, 1))
    return float(chi2_quantile(1 - a, max(e.k if k is None else k, 1)))


def tested_drop(setup, e, d, small_res, big_res):
    """The chi2 drop a test uses. ``drag_shape`` is a hypothesis about the drag curve, so its
    evidence must be in the track: its drop counts only as far as the track's residuals fall
    (a round whose launch velocity is 15 % off leaves a launch-prior misfit that a correction
    bending the drag to nothing in the first tenths of a second, at the end of the span no speed
    sample pins, can trade against -- a sphere with its right table was named ``drag_shape``).
    Other effects keep the whole drop (``radar_time`` is *meant* to explain a start that misses
    the muzzle)."""
    if e.name != DRAG_SHAPE.name:
        return d
    return min(d, track_chi2(setup, small_res) - track_chi2(setup, big_res))


def tested_inflation(e, infl):
    """The colored inflation a test divides by. ``drag_shape``, the library's most flexible
    effect (up to 8 coefficients), gets no credit for an inflation below 1: white noise at the
    right sigma scatters the measured inflation by ~10 % either way, and below 1 it would lift
    an 8-dof chi2 of pure noise over its threshold (a null track did: chi2 drop 19.5 < 19.7,
    divided by 0.85). It must be significant in plain chi2 units too."""
    return max(infl, 1.0) if e.name == DRAG_SHAPE.name else infl
