"""ArviZ output of a Bayesian fit: the one module of bayesdrag that imports :mod:`arviz`.

:func:`to_inference_data` turns a :class:`~bayesdrag.estimate.bayes.sampler.BayesResult` and its
:class:`~bayesdrag.estimate.bayes.posterior.LogPosterior` into an ``arviz.InferenceData``, written by
``bayesdrag fit`` as ``posterior.nc``. The convergence numbers of the run itself
(R-hat, ESS) are computed by :mod:`bayesdrag.estimate.bayes.sampler` with ArviZ's definitions.
"""
from __future__ import annotations

import warnings

import arviz as az
import numpy as np
import xarray as xr

from .loglik import draws_log_likelihood, thinned_draws

#: the ``log_likelihood`` group's one variable (every sample of every channel of the track)
LOG_LIKELIHOOD_VAR = "track"


def to_inference_data(result, post, mach, cd, reference=None, *, n_ppc_per_chain=5, rng=None, seed=None,
                      log_likelihood_draws=0):
    """ArviZ InferenceData of a Bayesian fit.

    Parameters
    ----------
    result : BayesResult
        The sampling run (``draws`` (chains, draws, K), ``thetas`` (chains, draws, n), ``lp``).
    post : LogPosterior
        The posterior it sampled (problem, channels, likelihood, ML fit).
    mach : (M,) array_like
        Mach grid of ``cd`` [-].
    cd : (chains, draws, M) ndarray
        Cd draws on ``mach`` (:func:`~bayesdrag.estimate.bayes.draws.cd_draws`).
    reference : DragModel, optional
        Reference drag; its Cd on ``mach`` goes to ``constant_data.reference_cd``.
    n_ppc_per_chain : int, keyword-only
        Posterior-predictive draws per chain (evenly spaced).
    rng : numpy.random.Generator, keyword-only
        Consumed for the posterior-predictive noise.
    seed : int, keyword-only
        Alternative to ``rng`` (``numpy.random.default_rng(seed)``).
    log_likelihood_draws : int or None, keyword-only
        Draws (over all chains, evenly thinned in each) of the ``log_likelihood`` group, computed
        on request: 0 (the default) for no group, None for every draw (draws x observations x 4
        bytes: ~200 MB on the demo track); a fit's result asks for
        :data:`bayesdrag.results.LOG_LIKELIHOOD_DRAWS`.

    Returns
    -------
    arviz.InferenceData
        Groups ``posterior`` (``cd`` over ``mach``: the Cd curve of every draw; the drag
        coefficients as one vector ``drag_coefficients`` over ``coefficient``; the initial state,
        effect, systematic and ``log_sigma_<c>`` parameters by name), ``sample_stats``
        (``lp``), ``observed_data`` (the track's channels against ``time`` [s]),
        ``constant_data`` (time, Mach grid, ML estimate and Cramér-Rao sd, fixed parameters,
        reference Cd), ``posterior_predictive`` (``cd`` on the Mach grid and the track channels
        with noise [m, m/s]; its ``draw`` coordinate holds the posterior draw indices),
        ``log_likelihood`` (:func:`log_likelihood_group`).
    """
    if rng is not None and seed is not None:
        raise TypeError("to_inference_data: give rng or seed, not both")
    if rng is None:
        rng = np.random.default_rng(seed)
    mach = np.asarray(mach, float)
    S = result.draws.shape[1]
    k = max(1, min(n_ppc_per_chain, S))
    pick = np.unique(np.linspace(0, S - 1, k).round().astype(int))
    yy = _predictive_tracks(result, post, pick, rng)
    ppc = {"cd": cd[:, pick].astype(np.float64), **{c: yy[..., j] for j, c in enumerate(post.channels)}}
    t = post.problem.track.t
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        idata_pp = az.from_dict(posterior_predictive=ppc, coords={"mach": mach, "time": t},
                                dims={"cd": ["mach"], **{c: ["time"] for c in post.channels}})
        drag_k = [k for k, n in enumerate(result.names) if k < post.n_theta and post.idx[k] < post.P]
        other = {n: result.draws[..., k] for k, n in enumerate(result.names) if k not in drag_k}
        posterior = {"cd": np.asarray(cd, np.float64), **other}
        if drag_k:
            posterior["drag_coefficients"] = result.draws[..., drag_k]
        idata = az.from_dict(
            posterior=posterior,
            sample_stats={"lp": result.lp},
            observed_data={c: post.problem.z[:, j] for j, c in enumerate(post.channels)},
            constant_data=_constant_data(post, mach, reference),
            coords={"time": t, "mach": mach, "theta": list(post.names[:post.n_theta]),
                    "coefficient": [result.names[k] for k in drag_k] or ["none"],
                    "fixed": [n for j, n in enumerate(post.problem.names) if not post.problem.free[j]] or ["none"]},
            dims={**{c: ["time"] for c in post.channels}, "t": ["time"], "mach_grid": ["mach"],
                  "cd": ["mach"], "drag_coefficients": ["coefficient"],
                  "reference_cd": ["mach"], "ml_estimate": ["theta"], "crb_sd": ["theta"],
                  "fixed_values": ["fixed"]},
            attrs={"likelihood": result.likelihood, "moves": result.moves, "steps": result.steps,
                   "burn": result.burn, "thin": result.thin, "converged": int(result.converged),
                   "message": result.message, "inference_library": "emcee"})
    # the posterior predictive draws are a subset of the posterior draws: their draw
    # coordinate holds the posterior draw indices they belong to
    idata.add_groups({"posterior_predictive": idata_pp.posterior_predictive.assign_coords(draw=pick)})
    if log_likelihood_draws is None or log_likelihood_draws > 0:
        idata.add_groups({"log_likelihood": log_likelihood_group(result, post, log_likelihood_draws)})
    return idata


def log_likelihood_group(result, post, total):
    """The ``log_likelihood`` group: one variable :data:`LOG_LIKELIHOOD_VAR` over ``(chain,
    draw, observation)`` (one variable, so that ``arviz.loo`` and ``arviz.compare`` use it
    without being told which), float32.

    Parameters
    ----------
    result : BayesResult
    post : LogPosterior
    total : int or None
        Draws over all chains (evenly thinned in each, :func:`~.loglik.thinned_draws`); None for
        every draw.

    Returns
    -------
    xarray.Dataset
        ``draw`` holds the posterior draw indices kept; ``observation`` runs channel by channel
        (coordinates ``obs_channel`` and ``obs_time`` [s] along it); attrs say how the draws were
        thinned and what the terms are (:mod:`~.loglik`: conditional on each draw's noise sd).
    """
    W, S = result.draws.shape[:2]
    pick = thinned_draws(S, W, total)
    ll = draws_log_likelihood(result, post, pick).astype(np.float32)
    t = np.asarray(post.problem.track.t, float)
    chans = np.repeat(np.array(post.channels), t.size)
    return xr.Dataset(
        {LOG_LIKELIHOOD_VAR: (("chain", "draw", "observation"), ll)},
        coords={"chain": np.arange(W), "draw": pick, "observation": np.arange(ll.shape[-1]),
                "obs_channel": ("observation", chans), "obs_time": ("observation", np.tile(t, len(post.channels)))},
        attrs={"thinned": int(pick.size < S), "draws_per_chain": int(pick.size), "draws_in_posterior": int(S),
               "terms": "log p(z_i | theta, sigma) per sample and channel, conditional on the draw's noise sd; "
                        "ar1 channels by their Kalman prediction errors",
               "likelihood": result.likelihood})


def read_inference_data(path):
    """An ``InferenceData`` written by :func:`to_inference_data` (``posterior.nc``), read into
    memory (the file is closed again).

    Parameters
    ----------
    path : path

    Returns
    -------
    arviz.InferenceData
    """
    with az.rc_context({"data.load": "eager"}):
        return az.from_netcdf(str(path))


def _predictive_tracks(result, post, pick, rng):
    """Simulated tracks with noise at draws ``pick`` of every chain: (chains, picks, N, C)
    float32 [m, m/s]."""
    W = result.draws.shape[0]
    th = result.thetas[:, pick].reshape(-1, result.thetas.shape[-1])
    y, _ = post.problem.predict(th)
    sig_cols = [result.names.index(f"log_sigma_{c}") for c in post.channels]
    sig = np.exp(result.draws[:, pick][..., sig_cols]).reshape(-1, post.C)
    if post.likelihood == "gaussian":
        noise = rng.standard_normal(y.shape) * sig[:, None, :]
    else:
        nu = np.exp(result.draws[:, pick][..., -1]).reshape(-1) if post.sample_nu else np.full(y.shape[0], post.nu)
        noise = rng.standard_t(nu[:, None, None], size=y.shape) * sig[:, None, :]
    return (y + noise).reshape(W, pick.size, y.shape[1], post.C).astype(np.float32)


def _constant_data(post, mach, reference):
    """``constant_data`` group: time [s], Mach grid, ML estimate and CRB sd of the sampled
    parameters, fixed parameters' values, reference Cd."""
    crb_ml = dict(zip(post.ml.names, post.ml.crb))
    theta_names = post.names[:post.n_theta]
    const = {"t": post.problem.track.t, "mach_grid": mach,
             "ml_estimate": np.array([post.ml.params[n] for n in theta_names]),
             "crb_sd": np.array([crb_ml[n] for n in theta_names]),
             "fixed_values": np.array([post.theta_ml[j] for j in range(post.theta_ml.size)
                                       if not post.problem.free[j]] or [np.nan])}
    if reference is not None:
        const["reference_cd"] = np.asarray(reference.value(mach), float)
    return const


def windows_inference_data(windows, ok, draws, track, channels):
    """ArviZ InferenceData of a Scheme 2 fit: Cd per window (``cd`` over a ``window`` dim) with
    the windows' Mach, Cramér-Rao sd and times, and the track as observed data.

    Parameters
    ----------
    windows : list of dict
        ``result.json`` ``windows`` rows.
    ok : sequence of int
        Windows that converged (and were sampled).
    draws : dict int -> (chains, draws) ndarray
        Cd draws per window.
    track : RadarTrack
    channels : sequence of str
    """
    ok = list(ok)
    S = min(d.shape[1] for d in draws.values())
    W = min(d.shape[0] for d in draws.values())
    cd = np.stack([draws[k][:W, :S] for k in ok], axis=-1)
    per = ["window"]
    return az.from_dict(
        posterior={"cd": cd},
        observed_data={c: track.channels[c] for c in channels},
        constant_data={"mach": np.array([windows[k]["mach"] for k in ok]),
                       "crb_sd": np.array([windows[k]["crb_sd"] for k in ok]),
                       "t_start": np.array([windows[k]["t_start"] for k in ok]),
                       "t_end": np.array([windows[k]["t_end"] for k in ok]), "t": track.t},
        coords={"window": np.array(ok), "time": track.t},
        dims={"cd": per, "mach": per, "crb_sd": per, "t_start": per, "t_end": per, "t": ["time"],
              **{c: ["time"] for c in channels}})
