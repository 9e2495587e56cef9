"""ArviZ output of a Bayesian fit: the one module of bayesdrag that imports :mod:`arviz`.

:func:`to_inference_data` turns a :class:`~bayesdrag.estimate.bayes.sampler.BayesResult` and its
:class:`~bayesdrag.estimate.bayes.posterior.LogPosterior` into an ``arviz.InferenceData``, from the
arrays (:mod:`~.posterior_groups`) that ``bayesdrag fit`` writes as ``posterior.nc`` without ArviZ
(:mod:`bayesdrag.io.netcdf`; a Scheme 2 fit's through this module). The convergence numbers of the run itself
(R-hat, ESS) are computed by :mod:`bayesdrag.estimate.bayes.sampler` with ArviZ's definitions.
"""
from __future__ import annotations

import warnings

import arviz as az
import numpy as np
import xarray as xr

from .posterior_groups import LOG_LIKELIHOOD_VAR, fit_arrays

__all__ = ["LOG_LIKELIHOOD_VAR", "to_inference_data", "as_inference_data", "read_inference_data",
           "windows_inference_data"]


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
        ``log_likelihood`` (:func:`~.posterior_groups.log_likelihood_group`).
    """
    return as_inference_data(fit_arrays(result, post, mach, cd, reference, n_ppc_per_chain=n_ppc_per_chain,
                                        rng=rng, seed=seed, log_likelihood_draws=log_likelihood_draws))


def as_inference_data(a):
    """The InferenceData of :class:`~.posterior_groups.FitArrays` ``a`` (the arrays
    ``posterior.nc`` is written from: :func:`~.posterior_groups.fit_groups`)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        idata_pp = az.from_dict(posterior_predictive=a.predictive,
                                coords={"mach": a.coords["mach"], "time": a.coords["time"]},
                                dims={k: v for k, v in a.dims.items() if k in a.predictive})
        idata = az.from_dict(posterior=a.posterior, sample_stats=a.sample_stats, observed_data=a.observed_data,
                             constant_data=a.constant_data, coords=a.coords, dims=a.dims, attrs=a.attrs)
    # the posterior predictive draws are a subset of the posterior draws: their draw
    # coordinate holds the posterior draw indices they belong to
    idata.add_groups({"posterior_predictive": idata_pp.posterior_predictive.assign_coords(draw=a.predictive_draws)})
    if a.log_likelihood is not None:
        g = a.log_likelihood
        idata.add_groups({"log_likelihood": xr.Dataset(g.data_vars, coords=g.coords, attrs=g.attrs)})
    return idata


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
