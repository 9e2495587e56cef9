"""A Scheme 2 fit (a constant Cd per window) from prepared values to its frozen
:class:`~bayesdrag.results.FitResult`: the windows' ML fits and, with sampling, each window's
posterior one after the other; the window assembly (the level sources' budget, the rows stitched
on a Mach grid) is Scheme 2's own (:mod:`bayesdrag.estimate.scheme2`)."""
from __future__ import annotations

import time

import numpy as np

from ..errors import FitError, FitWarning
from ..estimate.cd.headline import headline
from ..estimate.cd.table import determined_range
from ..estimate.scheme2 import fit_scheme2, stitched_rows, window_budget, windows_table
from ..results import FitResult
from .preparation import Prepared

__all__ = ["scheme2_fit", "scheme2_effects_note"]


def scheme2_fit(prep: Prepared, log, t_start):
    """Scheme 2: ML per window, then (with sampling) the same posterior in each window (Cd,
    initial state, noise). Windows are sampled one after the other: each window's batch already
    runs on both cores (numba threads); a process pool would only add start-up and contention on
    a 2-core machine. Scheme 2 chains are kept in memory (one window takes a few seconds)."""
    from ..estimate.bayes.posterior import LogPosterior
    from ..estimate.build.sources import radar_conditional
    from ..estimate.bayes.sampler import sample_posterior

    track, rnd, opts, chans = prep.track, prep.rnd, prep.opts, prep.chans
    r2 = fit_scheme2(track, rnd, window=opts.window, overlap=opts.overlap, channels=chans, free_ic=not opts.fix_ic)
    ok = [k for k, r in enumerate(r2.results) if r.success]
    if not ok:
        raise FitError(f"{track.source or 'track'}: no Scheme 2 window converged ({r2.results[0].message})")
    rows = windows_table(r2)
    warnings = [FitWarning("not_converged", f"window {k} ({rows[k]['t_start']:.2f}-{rows[k]['t_end']:.2f} s): "
                                            f"{r2.results[k].message}") for k in range(len(rows)) if k not in ok]
    draws = {}
    if opts.mcmc:
        for k in ok:
            post = LogPosterior(r2.problems[k], r2.results[k])
            b = sample_posterior(post, nwalkers=opts.walkers, max_steps=opts.max_steps,
                                 seed=None if opts.seed is None else opts.seed + k)
            cd = b.draws[..., 0]
            flat = cd.reshape(-1)
            q = np.quantile(flat, [0.05, 0.5, 0.95])
            rows[k].update(mean=float(flat.mean()), sd=float(flat.std(ddof=1)), q05=float(q[0]), q50=float(q[1]),
                           q95=float(q[2]),
                           sd_over_crb=float(flat.std(ddof=1) / rows[k]["crb_sd"]) if rows[k]["crb_sd"] else None,
                           r_hat_max=float(b.convergence["r_hat"].max()), ess_bulk_min=float(b.convergence["ess_bulk"].min()),
                           mcmc_converged=b.converged, steps=b.steps)
            draws[k] = cd
            if not b.converged:
                warnings.append(FitWarning("sampler", f"window {k}: {b.message}"))
            if log:
                log(f"window {k + 1}/{len(rows)} (Mach {rows[k]['mach']:.2f}): {b.message}")
    budget = window_budget(rows, ok, draws, rnd, opts.seed)
    budget["conditional_on"] += radar_conditional(chans or track.names, ())   # windows fit no radar source
    mach = np.array([w["mach"] for w in rows])
    lo, hi = float(min(w["mach_min"] for w in rows)), float(max(w["mach_max"] for w in rows))
    grid = np.round(np.linspace(lo, hi, 81), 4)
    cd_rows, quality = stitched_rows(rows, ok, mach, grid, rnd, bool(draws))
    warnings += quality["problems"]
    record = {"scheme": 2, "drag_model": "constant per window", "window": opts.window,
               "ml": {"converged": all(r.converged for r in r2.results), "windows_converged": len(ok),
                      "windows": len(rows), "notes": list(r2.notes) + scheme2_effects_note(opts, quality),
                      "quality": quality},
               "cd": cd_rows, "windows": rows, "uncertainty_budget": budget}
    if draws:
        record["mcmc"] = {"windows_converged": int(sum(rows[k]["mcmc_converged"] for k in ok)),
                           "r_hat_max": float(max(rows[k]["r_hat_max"] for k in ok))}
    det = determined_range(cd_rows)
    record["headline"] = headline(cd_rows, det, quality["ok"],
                                   "; ".join(str(p) for p in quality["problems"][:1]) or None)
    return FitResult(record=record, track=track, round=rnd, options=opts, scheme2=r2,
                     window_draws=draws or None, windows_ok=tuple(ok), grid=grid, warnings=tuple(warnings),
                     seconds=time.perf_counter() - t_start)


def scheme2_effects_note(opts, quality):
    """Scheme 2 takes no effects (a window's constant Cd cannot carry them): with the default
    ``--with``, a note says the search for the cause of a missed window was skipped."""
    if opts.with_effects != "default" or quality["ok"]:
        return []
    return ["Scheme 2 fits no effects: the default search for the cause of a missed window is skipped "
            "(Scheme 1 with the default --with, or bayesdrag diagnose, finds it)"]

