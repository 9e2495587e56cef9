"""The arrays of a Bayesian fit's posterior file, grouped as ArviZ groups them, without ArviZ.

:func:`fit_arrays` computes once what ``posterior.nc`` and
:func:`bayesdrag.estimate.bayes.inference.to_inference_data` hold for Scheme 1 (the Cd draws,
the posterior predictive tracks, the thinned log-likelihood, the constants); :func:`fit_groups`
arranges them as ``arviz.from_dict`` would (``chain`` and ``draw`` coordinates, each group's
attributes) for :func:`bayesdrag.io.netcdf.write_groups`, which writes the file
``arviz.from_netcdf`` reads (Scheme 2's small file is still written through ArviZ). Writing
through ArviZ and xarray cost a fit's folder ~1 s more on the demo (their imports and xarray's
probe for dask), most of what the folder took beside its figures (docs/measurements.md,
"posterior.nc without ArviZ").
"""
from __future__ import annotations

import datetime
from dataclasses import dataclass, field
from importlib import metadata

import numpy as np

from .loglik import draws_log_likelihood, thinned_draws

__all__ = ["LOG_LIKELIHOOD_VAR", "Group", "FitArrays", "fit_arrays", "fit_groups", "log_likelihood_group"]

#: the ``log_likelihood`` group's one variable (every sample of every channel of the track)
LOG_LIKELIHOOD_VAR = "track"


@dataclass(frozen=True)
class Group:
    """One group of the file: ``data_vars`` and ``coords`` map a name to ``(dims, array)``."""

    data_vars: dict
    coords: dict
    attrs: dict = field(default_factory=dict)


@dataclass(frozen=True)
class FitArrays:
    """What a Scheme 1 posterior file holds, as ``arviz.from_dict`` takes it (see
    :func:`fit_arrays`)."""

    posterior: dict
    sample_stats: dict
    observed_data: dict
    constant_data: dict
    predictive: dict
    predictive_draws: np.ndarray
    coords: dict
    dims: dict
    attrs: dict
    log_likelihood: Group | None


def fit_arrays(result, post, mach, cd, reference=None, *, n_ppc_per_chain=5, rng=None, seed=None,
               log_likelihood_draws=0):
    """The arrays of a Scheme 1 posterior (arguments as
    :func:`bayesdrag.estimate.bayes.inference.to_inference_data`, which documents the groups).

    Returns
    -------
    FitArrays
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
    drag_k = [k for k, n in enumerate(result.names) if k < post.n_theta and post.idx[k] < post.P]
    other = {n: result.draws[..., k] for k, n in enumerate(result.names) if k not in drag_k}
    posterior = {"cd": np.asarray(cd, np.float64), **other}
    if drag_k:
        posterior["drag_coefficients"] = result.draws[..., drag_k]
    ll = None
    if log_likelihood_draws is None or log_likelihood_draws > 0:
        ll = log_likelihood_group(result, post, log_likelihood_draws)
    return FitArrays(
        posterior=posterior, sample_stats={"lp": result.lp},
        observed_data={c: post.problem.z[:, j] for j, c in enumerate(post.channels)},
        constant_data=_constant_data(post, mach, reference), predictive=ppc, predictive_draws=pick,
        coords={"time": t, "mach": mach, "theta": list(post.names[:post.n_theta]),
                "coefficient": [result.names[k] for k in drag_k] or ["none"],
                "fixed": [n for j, n in enumerate(post.problem.names) if not post.problem.free[j]] or ["none"]},
        dims={**{c: ["time"] for c in post.channels}, "t": ["time"], "mach_grid": ["mach"],
              "cd": ["mach"], "drag_coefficients": ["coefficient"],
              "reference_cd": ["mach"], "ml_estimate": ["theta"], "crb_sd": ["theta"],
              "fixed_values": ["fixed"]},
        attrs={"likelihood": result.likelihood, "moves": result.moves, "steps": result.steps,
               "burn": result.burn, "thin": result.thin, "converged": int(result.converged),
               "message": result.message, "inference_library": "emcee"},
        log_likelihood=ll)


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
    Group
        ``draw`` holds the posterior draw indices kept; ``observation`` runs channel by channel
        (coordinates ``obs_channel`` and ``obs_time`` [s] along it); attrs say how the draws were
        thinned and what the terms are (:mod:`~.loglik`: conditional on each draw's noise sd).
    """
    W, S = result.draws.shape[:2]
    pick = thinned_draws(S, W, total)
    ll = draws_log_likelihood(result, post, pick).astype(np.float32)
    t = np.asarray(post.problem.track.t, float)
    chans = np.repeat(np.array(post.channels), t.size)
    return Group(
        {LOG_LIKELIHOOD_VAR: (("chain", "draw", "observation"), ll)},
        {"chain": (("chain",), np.arange(W)), "draw": (("draw",), pick),
         "observation": (("observation",), np.arange(ll.shape[-1])),
         "obs_channel": (("observation",), chans), "obs_time": (("observation",), np.tile(t, len(post.channels)))},
        {"thinned": int(pick.size < S), "draws_per_chain": int(pick.size), "draws_in_posterior": int(S),
         "terms": "log p(z_i | theta, sigma) per sample and channel, conditional on the draw's noise sd; "
                  "ar1 channels by their Kalman prediction errors",
         "likelihood": result.likelihood})


def fit_groups(a):
    """The groups of :class:`FitArrays` ``a`` as ``arviz.from_dict`` makes them, and the file's
    own attributes: ``(dict name -> Group, attrs)``."""
    stamp = _stamp()
    out = {
        "posterior": _sampled(a.posterior, a.coords, a.dims, stamp),
        "posterior_predictive": _sampled(a.predictive, a.coords, a.dims, stamp, draws=a.predictive_draws),
        "sample_stats": _sampled(a.sample_stats, a.coords, a.dims, stamp),
        "observed_data": _fixed(a.observed_data, a.coords, a.dims, {**stamp, **a.attrs}),
        "constant_data": _fixed(a.constant_data, a.coords, a.dims, {**stamp, **a.attrs}),
    }
    if a.log_likelihood is not None:
        out["log_likelihood"] = a.log_likelihood
    return out, dict(a.attrs)


def _stamp():
    """The attributes ``arviz.from_dict`` gives every group it makes."""
    return {"created_at": datetime.datetime.now(datetime.timezone.utc).isoformat(),
            "arviz_version": metadata.version("arviz")}


def _sampled(data, coords, dims, attrs, draws=None):
    """A group of draws (chain, draw, ...): ``chain`` 0..W-1, ``draw`` 0..S-1 or ``draws``."""
    first = np.asarray(next(iter(data.values())))
    W, S = first.shape[:2]
    group_coords = {"chain": (("chain",), np.arange(W)),
                    "draw": (("draw",), np.arange(S) if draws is None else np.asarray(draws))}
    out = {}
    for name, arr in data.items():
        arr = np.asarray(arr)
        d = ("chain", "draw") + _dims(name, arr.ndim - 2, dims)
        out[name] = (d, arr)
    _add_coords(group_coords, out, coords)
    return Group(out, group_coords, dict(attrs))


def _fixed(data, coords, dims, attrs):
    """A group without draws (observed or constant data)."""
    out = {name: (_dims(name, np.ndim(arr), dims), np.asarray(arr)) for name, arr in data.items()}
    group_coords = {}
    _add_coords(group_coords, out, coords)
    return Group(out, group_coords, dict(attrs))


def _dims(name, ndim, dims):
    """A variable's dims after chain and draw: the named ones, else ``<name>_dim_<i>``."""
    named = tuple(dims.get(name, ()))
    return named + tuple(f"{name}_dim_{i}" for i in range(len(named), ndim))


def _add_coords(group_coords, data_vars, coords):
    """Each dim the group's variables use: its coordinate from ``coords``, else 0..n-1."""
    for d, arr in data_vars.values():
        for i, name in enumerate(d):
            if name not in group_coords:
                values = coords[name] if name in coords else np.arange(arr.shape[i])
                group_coords[name] = ((name,), np.asarray(values))


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
