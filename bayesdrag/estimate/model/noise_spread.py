"""The parameters' covariance from the noise model's own uncertainty (``ar1`` channels).

Why
---
The bands of a fit with AR(1) noise rest on the channel's correlation ``rho``, and a track tells
it only so well: a correlated noise has few independent stretches, and the variance it puts on
Cd grows steeply as ``rho`` nears 1. Holding ``rho`` at its estimate makes the band a draw
itself: one estimated short gives a band too narrow (a flight of rho 0.9 noise whose speed
channel was estimated at 0.86 claimed a row at 3.08 band sd, 2.5 % off).

The estimate of the parameters is the generalised least squares at the estimated noise ``S0``;
its error under a noise ``S`` is ``B J' S0^-1 S S0^-1 J B`` (``B`` the covariance the fit
reports), linear in ``S``. Averaged over what the restricted likelihood leaves open of the noise
(:func:`~bayesdrag.estimate.model.restricted.restricted_spread`: ``log(1 - rho)`` one sd either
side, exact for a covariance quadratic in it), the increment over ``B`` is
:func:`noise_covariance`'s. :func:`~bayesdrag.estimate.model.ml` adds nothing to the fit itself:
the increment is reported beside its covariance (``MLResult.cov_noise``), and each Cd row's share
(``noise_model_sd``) widens its band (:mod:`bayesdrag.estimate.cd.quality`).

Functions here are pure.
"""
from __future__ import annotations

import numpy as np

from . import colored, restricted


def noise_covariance(problem, S, resid, sigma, ar, Minv, priors=None, Sw=None):
    """Increment of the free parameters' covariance from the ``ar1`` channels' noise uncertainty.

    Parameters
    ----------
    problem : OutputErrorProblem
    S : (N, C, K) ndarray
        Sensitivities of the K free parameters at the estimate.
    resid : (N, C) ndarray
        Residuals at the estimate.
    sigma, ar : dict
        The fit's noise (white sd in noise-scale units; ``ar1`` channels' ``(rho, q)``).
    Minv : (K, K) ndarray
        The fit's covariance of the free parameters.
    priors : (pr, pJ), optional
        The priors' residuals (M,) and Jacobian (M, K).
    Sw : (N, C, K) ndarray, optional
        ``problem.weighted(S, sigma, ar)`` where the caller has it already.

    Returns
    -------
    cov : (K, K) ndarray or None
        ``Minv D Minv`` with ``D`` the channels' averaged information change; None when no
        channel has a spread.
    spread : dict channel -> float
        sd of ``log(1 - rho)`` per ``ar1`` channel searched (0: none).
    """
    chans = [(j, c) for j, c in enumerate(problem.channels)
             if problem.noise_model[c] == "ar1" and c in (ar or {}) and ar[c][1] > 0.0]
    if not chans or not np.all(np.isfinite(Minv)):
        return None, {}
    if Sw is None:
        Sw = problem.weighted(S, sigma, ar)                            # (N, C, K)
    rw = problem.weighted(resid, sigma, ar)                            # (N, C)
    parts = [(Sw[:, j, :].T @ Sw[:, j, :], Sw[:, j, :].T @ rw[:, j]) for j in range(len(problem.channels))]
    A_all = sum(p[0] for p in parts)
    g_all = sum(p[1] for p in parts)
    if priors is not None and priors[0].size:
        A_all = A_all + priors[1].T @ priors[1]
        g_all = g_all + priors[1].T @ priors[0]
    Sn = problem.standardized(S)
    rn = problem.standardized(resid)
    D = np.zeros_like(Minv)
    spread = {}
    for j, c in chans:
        rho0, q0 = ar[c]
        sd, points = restricted.restricted_spread(rn[:, j], problem.dt_ratio, Sn[:, j, :],
                                                  A_all - parts[j][0], g_all - parts[j][1], rho0, q0)
        spread[c] = float(sd)
        if not points:
            continue
        D += channel_change(Sn[:, j, :], rho0, q0, sigma[c] ** 2, points, problem.dt_ratio)
    if not spread or not np.any(D):
        return None, spread
    D = 0.5 * (D + D.T)
    return Minv @ D @ Minv, spread


def channel_change(J, rho0, q0, s20, points, dt_ratio):
    """Average change of one channel's ``J' S0^-1 S S0^-1 J`` over the noises ``S`` of
    ``points``, from the estimate's ``S0``: the information the estimate's error sees.

    ``S = s2 (I + q R(rho))`` (:mod:`colored`); ``S0^-1 J`` is the whitening followed by its
    transpose (:func:`colored.adjoint_standardize`), and ``R`` is applied in O(N) per column
    (:func:`colored.correlation_apply`), so no N x N matrix is formed.

    Parameters
    ----------
    J : (N, K) ndarray
        The channel's sensitivities over its noise scale.
    rho0, q0, s20 : float
        The estimate's noise (``s20`` the white variance [(noise scale)^2]).
    points : sequence of (rho, q, s2)
    dt_ratio : (N - 1,) ndarray

    Returns
    -------
    (K, K) ndarray
        Zero when every point is the estimate.
    """
    U, _ = colored.standardize(J, rho0, q0, dt_ratio)
    Y = colored.adjoint_standardize(U, rho0, q0, dt_ratio)                 # s20 S0^-1 J
    YY = Y.T @ Y
    # at the estimate, s20 (YY + q0 Y' R0 Y) / s20^2 is J' S0^-1 J itself: the same formula, so
    # the change is exactly zero there
    ref = YY + q0 * (Y.T @ colored.correlation_apply(Y, rho0, dt_ratio))
    mean = sum((s2 / s20) * (YY + qp * (Y.T @ colored.correlation_apply(Y, rp, dt_ratio)))
               for rp, qp, s2 in points) / len(points)
    return (mean - ref) / s20
