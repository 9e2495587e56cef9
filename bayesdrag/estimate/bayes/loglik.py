"""Pointwise log-likelihood of posterior draws: one term per sample and channel, what
``arviz.loo`` and ``arviz.compare`` need to rank drag models.

Definition (a choice, documented in ``docs/bayes.md``)
    The sampler's Gaussian likelihood has the noise sd integrated out analytically; each
    retained draw carries its exact conditional noise sd ``sigma_c`` (drawn from
    ``sigma_c^2 | theta, z``, :meth:`~bayesdrag.estimate.bayes.posterior.LogPosterior.sigma_draws`).
    The pointwise terms are those of the likelihood *conditional on that sigma draw*, so
    ``(theta, sigma)`` is one draw of the joint posterior and the terms of a draw sum to
    ``log p(z | theta, sigma)``:

    * a white channel: ``log N(z_i; y_i(theta), sigma_c^2)``;
    * an ``ar1`` channel (white noise plus an AR(1) model-error process,
      :mod:`~bayesdrag.estimate.model.colored`): the Kalman innovations ``nu_i`` are independent
      with variances ``F_i sigma_c^2``, so sample i contributes
      ``log N(nu_i; 0, F_i sigma_c^2)`` (its prediction error given the samples before it);
      ``rho`` and ``q`` are the ML plug-in values, or the draw's own with ``--sample-ar``;
    * Student-t: ``log t_nu((z_i - y_i) / s_c) - log s_c`` with the draw's scale ``s_c`` and
      ``nu`` (fixed or sampled).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.special import gammaln

from ..model import colored

__all__ = ["pointwise_log_likelihood", "draws_log_likelihood", "thinned_draws"]

_LOG_2PI = math.log(2.0 * math.pi)


def pointwise_log_likelihood(resid, log_sigma, *, likelihood="gaussian", nu=None, ar=None, dt_ratio=None):
    """Log-likelihood of every sample of every channel for a set of draws.

    Parameters
    ----------
    resid : (S, N, C) array_like
        Residuals ``z - y(theta)`` of S draws [m or m/s].
    log_sigma : (S, C) array_like
        Log noise sd per draw and channel (the white part of an ``ar1`` channel; the Student-t
        scale) [log m or log m/s].
    likelihood : {"gaussian", "student-t"}, keyword-only
    nu : (S,) array_like, keyword-only
        Student-t degrees of freedom per draw.
    ar : dict int -> (rho, q), keyword-only
        The ``ar1`` channels by column index, their AR coefficient and variance ratio (floats,
        or (S,) arrays per draw); Gaussian only.
    dt_ratio : (N - 1,) array_like, keyword-only
        Sample intervals over their median (needed with ``ar``).

    Returns
    -------
    (S, N, C) ndarray
        Log densities [log of 1/m or s/m]; ``-inf`` where a residual is not finite.
    """
    r = np.asarray(resid, float)
    ls = np.asarray(log_sigma, float)
    S, N, C = r.shape
    sig2 = np.exp(2.0 * ls)[:, None, :]                              # (S, 1, C)
    if likelihood == "student-t":
        nu = np.asarray(nu, float).reshape(S, 1, 1)
        u2 = r ** 2 / sig2
        const = gammaln((nu + 1) / 2) - gammaln(nu / 2) - 0.5 * np.log(nu * np.pi)
        out = const - ls[:, None, :] - 0.5 * (nu + 1) * np.log1p(u2 / nu)
    elif likelihood == "gaussian":
        out = -0.5 * (_LOG_2PI + np.log(sig2) + r ** 2 / sig2)
        for j, (rho, q) in (ar or {}).items():
            u, F = _innovations(r[:, :, j], rho, q, dt_ratio)        # (S, N), (S, N) or (N,)
            out[:, :, j] = -0.5 * (_LOG_2PI + np.log(F * sig2[:, :, j]) + u ** 2 / sig2[:, :, j])
    else:
        raise ValueError(f"likelihood {likelihood!r} is not known (allowed: gaussian, student-t)")
    return np.where(np.isfinite(r), out, -np.inf)


def _innovations(r, rho, q, dt_ratio):
    """Standardised innovations ``u = nu / sqrt(F)`` (S, N) of residual rows ``r`` (S, N) and
    the innovation variances ``F`` ((N,) when shared, else (S, N))."""
    rho, q = np.asarray(rho, float), np.asarray(q, float)
    if rho.ndim == 0 and q.ndim == 0:
        u, _ = colored.standardize(r.T, float(rho), float(q), dt_ratio)
        return u.T, colored.innovation_variances(rho, q, dt_ratio)
    S = r.shape[0]
    rho, q = np.broadcast_to(rho, (S,)), np.broadcast_to(q, (S,))
    u = np.stack([colored.standardize(r[s], float(rho[s]), float(q[s]), dt_ratio)[0] for s in range(S)])
    return u, colored.innovation_variances(rho, q, dt_ratio)


def thinned_draws(n_draws, n_chains, total):
    """Draw indices kept per chain: ``total`` draws over all chains, evenly spaced in each
    chain (every draw when ``total`` is None or at least the chains' draws)."""
    if total is None or total >= n_draws * n_chains:
        return np.arange(n_draws)
    k = max(1, min(n_draws, int(total) // max(n_chains, 1)))
    return np.unique(np.linspace(0, n_draws - 1, k).round().astype(int))


def draws_log_likelihood(result, post, pick):
    """Pointwise log-likelihood of the draws ``pick`` of every chain of a sampling run.

    Parameters
    ----------
    result : BayesResult
        The run (``draws`` with the noise columns, ``thetas``).
    post : LogPosterior
        The posterior it sampled (problem, channels, likelihood, AR plug-in values).
    pick : (k,) array_like of int
        Draw indices, the same in every chain.

    Returns
    -------
    (chains, k, C * N) ndarray
        Observations channel by channel: index ``j * N + i`` is sample i of channel j.
    """
    pick = np.asarray(pick, int)
    W = result.draws.shape[0]
    names = list(result.names)
    d = result.draws[:, pick].reshape(W * pick.size, -1)
    th = result.thetas[:, pick].reshape(W * pick.size, -1)
    y, _ = post.problem.predict(th)
    r = (post.problem.z[None] - y) / post.problem.noise_scale[None]  # (S, N, C), each sample's sd out
    if post.likelihood == "student-t":
        ls = d[:, [names.index(f"log_sigma_{c}") for c in post.channels]]
        nu = np.exp(d[:, names.index("log_nu")]) if post.sample_nu else np.full(d.shape[0], float(post.nu))
        ll = pointwise_log_likelihood(r, ls, likelihood="student-t", nu=nu)
    else:
        ls = d[:, [names.index(f"log_sigma_{c}") for c in post.channels]]
        ar = {}
        for c in post.ar_channels:
            if c in post.ar_sampled:
                ar[post.channels.index(c)] = (1.0 - np.exp(d[:, names.index(f"log_1m_rho_{c}")]),
                                              np.exp(d[:, names.index(f"log_q_{c}")]))
            else:
                ar[post.channels.index(c)] = post.ar_ml[c]
        ll = pointwise_log_likelihood(r, ls, ar=ar, dt_ratio=post.problem.dt_ratio)
    ll = ll - np.log(post.problem.noise_scale)[None]     # the density of z, not of z / scale
    return np.swapaxes(ll, 1, 2).reshape(W, pick.size, -1)
