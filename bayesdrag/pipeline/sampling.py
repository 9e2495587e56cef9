"""Stage 4 of a Scheme 1 fit, *sample*: its posterior sampled by emcee from the ML fit's answer
(:func:`sample_stage`), the Cd rows' posterior columns and draws, and the ``posterior`` and
``mcmc`` records of ``result.json``."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

__all__ = ["sample_stage", "run_sampler", "sampled_rows", "posterior_json", "mcmc_json"]


def sample_stage(prep, chk, chain_path, resume, log, progress, diag, timing, ml_progress):
    """The posterior of the checked answer ``chk`` (None, None without ``mcmc``) and the model
    check made after it when it was deferred (it cannot change what is sampled: its diagnosis ran
    beside the sampling). Returns ``(BayesResult, LogPosterior, chk)``, ``chk`` with the gap of a
    deferred check."""
    from .check import checked

    if not prep.opts.mcmc:
        return None, None, chk
    ans = chk.answer
    bayes, post = run_sampler(ans.f1, prep.opts, chain_path, resume, log, progress)
    if chk.deferred:
        gap, _ = checked(prep.track, prep.rnd, prep.opts, prep.chans, ans.f1, ans.grid, ans.rows, diag, timing,
                         ml_progress)
        chk = replace(chk, gap=gap)
    return bayes, post, chk


def run_sampler(f1, opts, chain_path, resume, log, progress):
    """The posterior of the Scheme 1 fit ``f1``, sampled: ``(BayesResult, LogPosterior)``."""
    from ..estimate.bayes.posterior import LogPosterior
    from ..estimate.bayes.sampler import default_walkers, sample_posterior

    post = LogPosterior(f1.problem, f1.ml, likelihood=opts.likelihood, nu=opts.nu, sample_ar=opts.sample_ar)
    walkers = opts.walkers if opts.walkers is not None else default_walkers(post, opts.moves)
    bayes = sample_posterior(post, nwalkers=walkers, moves=opts.moves, max_steps=opts.max_steps, seed=opts.seed,
                             backend_path=chain_path, resume=bool(resume and chain_path and Path(chain_path).exists()),
                             progress=progress, log=log)
    return bayes, post


def sampled_rows(bayes, f1, rows, grid):
    """The ``cd`` rows with the posterior's columns, and the Cd draws (the sampled ones widened
    to the rows' band where the model error widens it)."""
    from ..estimate.bayes.draws import cd_draws, cd_posterior_rows, needs_widening, widen_to_floor

    sampled = cd_draws(bayes, f1.drag_model, grid, f1.problem.P)
    cd = widen_to_floor(sampled, rows) if needs_widening(rows) else sampled
    return cd_posterior_rows(rows, cd, sampled), cd


def posterior_json(b):
    """``result.json`` ``posterior``: each sampled coordinate's mean, sd, R-hat, bulk and tail ESS and
    5 and 95 % quantiles."""
    s = b.convergence
    col = lambda k: {n: float(v) for n, v in zip(s.index, s[k])}  # noqa: E731
    return {"mean": col("mean"), "sd": col("sd"), "r_hat": col("r_hat"), "ess_bulk": col("ess_bulk"),
            "ess_tail": col("ess_tail"), "q05": col("q05"), "q95": col("q95")}


def mcmc_json(b, post):
    """``result.json`` ``mcmc``: how the chain ran (convergence, steps, burn-in, thinning, walkers,
    autocorrelation times, acceptance, moves) and the sampled noise sd of each channel."""
    def sig(c):
        x = b.draws[..., b.names.index(f"log_sigma_{c}")]
        return {"median": float(np.exp(np.median(x))), "q05": float(np.exp(np.quantile(x, 0.05))),
                "q95": float(np.exp(np.quantile(x, 0.95)))}

    return {"converged": b.converged, "message": b.message, "steps": b.steps, "burn": b.burn,
            "thin": b.thin, "walkers": b.nwalkers, "draws": int(b.draws.shape[0] * b.draws.shape[1]),
            "tau_max": float(np.max(b.tau)), "tau_mean": float(np.mean(b.tau)),
            "acceptance": b.acceptance, "moves": b.moves, "likelihood": b.likelihood,
            "nu": post.nu, "resumed_from": b.resumed_from, "seconds": round(b.elapsed, 3),
            "sigma": {c: sig(c) for c in post.channels}}
