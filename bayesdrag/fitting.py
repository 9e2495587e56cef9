"""``bayesdrag fit``: read a track and a round, fit, write result.json, posterior.nc, figures
and report.html.

Kept apart from :mod:`bayesdrag.cli` (argument parsing, exit codes) and from the estimators
(:mod:`bayesdrag.estimate`), which stay free of I/O.

Outputs (DESIGN.md): ``result.json``; with sampling (the default) also ``posterior.nc``
(ArviZ), ``chain.h5`` (the emcee chain); always ``report.html`` and the figures. While sampling,
the chain is written to ``chain.partial.h5``; ``--resume`` continues it after a kill, and it is
renamed to ``chain.h5`` when the run finishes. A fresh run refuses to start over an unfinished
chain (it would destroy it): resume it or delete it.
"""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from .errors import FitError, InputError
from .io.outputs import atomic_write as _atomic_write
from .io.outputs import write_json as _write_json
from .io.outputs import write_figure as _write_figure

PARTIAL = "chain.partial.h5"
CHAIN = "chain.h5"


def _echo_err(msg):
    print(msg, file=sys.stderr, flush=True)


def _ml_nu(args):
    """Degrees of freedom for the robust ML fit: --nu when a number, else the default."""
    from .estimate.scheme1 import ROBUST_NU

    try:
        return float(getattr(args, "nu", None))
    except (TypeError, ValueError):
        return ROBUST_NU


def run_fit(args, echo=print, on_fit=None):
    """Run the ``fit`` command; returns the exit status. ``args`` as parsed by the CLI.

    ``on_fit``, when given, is called once the outputs are written as
    ``on_fit(res=MLResult, prob=OutputErrorProblem, rnd=Round, track=RadarTrack, result=dict)``
    (campaigns use it to keep each round's Cd covariance for pooling).
    """
    import numpy as np

    from .estimate.quality import assess, check_against_flexible
    from .estimate.scheme1 import cd_grid, cd_table, determined_range, fit_scheme1
    from .io.rounds import read_round
    from .io.tracks import read_track

    t_start = time.perf_counter()
    track = read_track(args.track)
    rnd = read_round(args.round)
    quiet = getattr(args, "quiet", False)
    for note in getattr(track, "notes", ()):
        if not quiet:
            _echo_err(f"bayesdrag: note: {note}")
    chans = None
    if args.channels:
        chans = tuple(c.strip() for c in args.channels.split(",") if c.strip())
        bad = [c for c in chans if c not in track.names]
        if bad or not chans:
            raise InputError(f"command line: --channels {args.channels!r}: {', '.join(bad) or 'empty'} not in "
                             f"the track {args.track} (it has {', '.join(track.names)})")
    out = Path(args.output)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: output path exists and is not a folder")
    mcmc = not args.no_mcmc
    resume = getattr(args, "resume", False)
    if mcmc and (out / PARTIAL).exists() and not resume:
        raise InputError(f"{out / PARTIAL}: an unfinished chain from an earlier run is there; rerun with "
                         f"--resume to continue it, or delete it to start afresh")
    if getattr(args, "scheme", 1) == 2:
        return _run_scheme2(args, track, rnd, chans, out, echo, quiet)
    lik = getattr(args, "likelihood", "gaussian")
    res, prob = fit_scheme1(track, rnd, drag=args.drag, channels=chans, free_ic=not args.fix_ic,
                            likelihood=lik, nu=_ml_nu(args))
    if not res.success:
        raise FitError(f"{args.track}: {res.message}")
    out.mkdir(parents=True, exist_ok=True)
    dm = prob.model.drag
    lo, hi = float(np.min(res.mach)), float(np.max(res.mach))
    grid = cd_grid(lo, hi)
    rows = cd_table(res, dm, grid, rnd.reference_drag)
    quality = assess(res, prob, rows, track, rnd.radar.sigma)
    if dm.name != "spline":
        # a rigid model's band holds no shape error: check its curve against the flexible fit
        res_f, prob_f = fit_scheme1(track, rnd, drag="spline", channels=chans, free_ic=not args.fix_ic,
                                    likelihood=lik, nu=_ml_nu(args), start=prob.start)
        if res_f.success:
            rows_f = cd_table(res_f, prob_f.model.drag, grid, rnd.reference_drag)
            assess(res_f, prob_f, rows_f, track, rnd.radar.sigma)
            check_against_flexible(rows, rows_f, quality, dm.name)
    det = determined_range(rows)
    free = [n for n, f in zip(res.names, res.free) if f]
    result = {
        "scheme": 1, "drag_model": dm.name,
        "ml": {"params": res.params, "crb": {n: float(s) for n, s, f in zip(res.names, res.crb, res.free) if f},
               "crb_colored": {n: float(s) for n, s, f in zip(res.names, res.crb_colored, res.free) if f},
               "fixed": [n for n in res.names if n not in free],
               "converged": res.converged, "iterations": res.iterations, "cost": res.cost,
               "message": res.message, "sigma": res.sigma,
               "rms": {c: float(np.sqrt(np.mean(r**2))) for c, r in res.residuals.items()},
               "warnings": list(res.warnings),
               "mach_range_data": [lo, hi], "mach_range_determined": list(det) if det else None,
               "likelihood": lik,
               "rejected_samples": getattr(prob, "rejected", None),
               "smoothing": ({k: v for k, v in prob.smoothing.items() if k != "grid"}
                             if getattr(prob, "smoothing", None) else None),
               "quality": quality},
        "cd": rows,
    }
    smoothing = getattr(prob, "smoothing", None)
    if smoothing:
        result["ml"]["smoothing"] = {k: v for k, v in smoothing.items() if isinstance(v, (int, float, str))}
    warnings = [w for w in res.warnings if "is at its bound" not in w] + list(quality["problems"])
    bayes = post = idata = None
    if mcmc:
        bayes, post, idata, rows = _sample(args, prob, res, rows, dm, grid, rnd, out, quiet)
        result["cd"] = rows
        result["posterior"] = _posterior_json(bayes)
        result["mcmc"] = _mcmc_json(bayes, post)
        warnings += list(bayes.warnings)
        info = [r for r in rows if r["crb_sd"] > 0 and r["ml"] > 0 and r["crb_sd"] / r["ml"] < 0.01]
        ratios = [r["sd_over_crb"] for r in info if r.get("sd_over_crb") is not None]
        if ratios:
            result["mcmc"]["sd_over_crb_determined_range"] = [float(min(ratios)), float(max(ratios))]
    _write_json(out / "result.json", result)
    if idata is not None:
        _atomic_write(out / "posterior.nc", lambda tmp: idata.to_netcdf(tmp))
    figs = _fit_figures(out, res, prob, dm, rows, rnd, track, bayes, post)
    _report(out, args, track, rnd, res, prob, rows, bayes, post, figs, warnings, result,
            time.perf_counter() - t_start)
    if not quiet:
        for w in warnings:
            _echo_err(f"bayesdrag: warning: {w}")
    caveat = "" if quality["ok"] else " -- NOT a clean answer: the model misses the track (warnings above)"
    echo((f"fit: {res.message} in {res.iterations} iterations; Cd determined over Mach "
          f"{det[0]:.2f}-{det[1]:.2f}" if det else f"fit: {res.message}; Cd nowhere determined to 1 %") + caveat)
    if bayes is not None:
        echo(f"mcmc: {bayes.message}; {bayes.steps} steps x {bayes.nwalkers} walkers in {bayes.elapsed:.1f} s")
        echo(f"  wrote {out / 'result.json'}, posterior.nc, chain.h5, report.html and figures")
    else:
        echo(f"  wrote {out / 'result.json'}, report.html, cd.png, residuals.png")
    if on_fit is not None:
        on_fit(res=res, prob=prob, rnd=rnd, track=track, result=result)
    return 0


def _sample(args, prob, res, rows, dm, grid, rnd, out, quiet):
    from .estimate.bayes import LogPosterior, cd_draws, cd_posterior_rows, sample_posterior, to_inference_data

    nu = getattr(args, "nu", "4")
    nu = "sample" if str(nu) == "sample" else float(nu)
    post = LogPosterior(prob, res, likelihood=getattr(args, "likelihood", "gaussian"), nu=nu)
    progress = (not quiet) and sys.stderr.isatty()
    log = None if (quiet or progress) else _echo_err
    partial = out / PARTIAL
    resume = getattr(args, "resume", False)
    if resume and not partial.exists() and not quiet:
        _echo_err(f"bayesdrag: note: --resume: no unfinished chain in {out}; starting afresh")
    moves = getattr(args, "moves", "auto") or "auto"
    walkers = getattr(args, "walkers", None)
    if moves != "auto" and walkers is None:
        walkers = 2 * post.ndim + 2
    bayes = sample_posterior(post, nwalkers=walkers, moves=moves,
                             max_steps=getattr(args, "max_steps", 20000), seed=getattr(args, "seed", None),
                             backend_path=partial, resume=resume and partial.exists(),
                             progress=progress, log=log)
    os.replace(partial, out / CHAIN)
    cd = cd_draws(bayes, dm, grid, prob.P)
    rows = cd_posterior_rows(rows, cd)
    idata = to_inference_data(bayes, post, grid, cd, rnd.reference_drag, seed=getattr(args, "seed", None))
    return bayes, post, idata, rows


def _posterior_json(b):
    s = b.summary
    col = lambda k: {n: float(v) for n, v in zip(s.index, s[k])}  # noqa: E731
    return {"mean": col("mean"), "sd": col("sd"), "r_hat": col("r_hat"), "ess_bulk": col("ess_bulk"),
            "ess_tail": col("ess_tail"), "q05": col("q05"), "q95": col("q95")}


def _mcmc_json(b, post):
    import numpy as np

    return {"converged": b.converged, "message": b.message, "steps": b.steps, "burn": b.burn,
            "thin": b.thin, "walkers": b.nwalkers, "draws": int(b.draws.shape[0] * b.draws.shape[1]),
            "tau_max": float(np.max(b.tau)), "tau_mean": float(np.mean(b.tau)),
            "acceptance": b.acceptance, "moves": b.moves, "likelihood": b.likelihood,
            "nu": post.nu, "resumed_from": b.resumed_from, "seconds": round(b.elapsed, 3),
            "sigma": {c: {"median": float(np.exp(np.median(b.draws[..., b.names.index(f"log_sigma_{c}")]))),
                          "q05": float(np.exp(np.quantile(b.draws[..., b.names.index(f"log_sigma_{c}")], 0.05))),
                          "q95": float(np.exp(np.quantile(b.draws[..., b.names.index(f"log_sigma_{c}")], 0.95)))}
                      for c in post.channels}}


def _fit_figures(out, res, prob, dm, rows, rnd, track, bayes, post):
    """Write the figures; returns [(file name, title, caption)] for the report."""
    import matplotlib

    matplotlib.use("Agg")
    import numpy as np

    from .plots.cd import plot_cd_ml, plot_cd_posterior, plot_cd_posterior_relative, plot_cd_relative
    from .plots.mcmc import plot_corner, plot_traces
    from .plots.residuals import plot_residuals, plot_residuals_acf

    figs = []
    if bayes is None:
        ax = plot_cd_ml(rows, label=f"ML ({dm.name})")
        _write_figure(out / "cd.png", ax.figure)
        figs.append(("cd.png", "Cd(M), maximum likelihood", "ML curve with its 90 % Cramér-Rao band and the reference."))
        fig = plot_residuals(track.t, res.residuals, res.sigma)
        _write_figure(out / "residuals.png", fig)
        figs.append(("residuals.png", "Residuals", "Measured minus fitted with ±σ bands."))
        return figs
    ax = plot_cd_posterior(rows, label=f"posterior ({dm.name})")
    _write_figure(out / "cd.png", ax.figure)
    figs.append(("cd.png", "Cd(M) posterior", "Posterior median with 50 % and 90 % bands, the ML curve's 90 % "
                 "Cramér-Rao band (dotted) and the reference firing table (dashed)."))
    if all(r.get("reference") for r in rows):
        ax = plot_cd_posterior_relative(rows)
        _write_figure(out / "cd_relative.png", ax.figure)
        figs.append(("cd_relative.png", "Cd(M) relative to the reference", "The same bands in percent of the "
                     "reference curve, where their widths are visible."))
    ax = plot_cd_relative(rows)
    _write_figure(out / "cd_sd_ratio.png", ax.figure)
    figs.append(("cd_sd_ratio.png", "Posterior sd over Cramér-Rao sd", "1 = the posterior is as wide as the "
                 "bound; above 1 where the noise is estimated larger than the round's or the data are weak."))
    flat = bayes.thetas.reshape(-1, bayes.thetas.shape[-1])
    det = [r["mach"] for r in rows if r["ml"] > 0 and r["crb_sd"] / r["ml"] < 0.01] or [r["mach"] for r in rows]
    ms = np.quantile(det, [0.1, 0.5, 0.9]).round(2)
    B = dm.jacobian(ms)
    sel = {f"Cd(M{m:.2f})": flat[:, :prob.P] @ B[i] for i, m in enumerate(ms)}
    for n in ("X0", "Z0", "Ux0", "Uz0", "Uy0"):
        if n in bayes.names:
            sel[n] = flat[:, list(prob.names).index(n)]
    fig = plot_corner(sel)
    _write_figure(out / "corner.png", fig, dpi=80)
    figs.append(("corner.png", "Corner plot", "Cd at three Mach numbers of the determined range and the "
                 "initial state; lines at the 5, 50 and 95 % quantiles."))
    picks = [n for n in ("Ux0", "Uz0", "log_sigma_x", "log_sigma_v") if n in post.names]
    chains = {n: bayes.chain[:, :, post.names.index(n)] for n in picks}
    mid = prob.P // 2
    chains[prob.names[mid]] = bayes.chain[:, :, list(post.names).index(prob.names[mid])] \
        if prob.names[mid] in post.names else None
    chains = {k: v for k, v in chains.items() if v is not None}
    if chains:
        fig = plot_traces(chains)
        for ax in fig.axes:
            ax.axvline(bayes.burn, color="k", lw=0.8, ls="--")
        _write_figure(out / "traces.png", fig)
        figs.append(("traces.png", "Traces", f"Walkers against step; burn-in ({bayes.burn} steps) left of the "
                     "dashed line."))
    theta_mean = flat.mean(axis=0)
    y, _ = prob.predict(theta_mean[None])
    resid = {c: prob.z[:, j] - y[0, :, j] for j, c in enumerate(prob.channels)}
    sig = {c: float(np.exp(np.median(bayes.draws[..., bayes.names.index(f"log_sigma_{c}")])))
           for c in prob.channels}
    fig = plot_residuals_acf(track.t, resid, sig)
    _write_figure(out / "residuals.png", fig)
    figs.append(("residuals.png", "Residuals and their autocorrelation",
                 "Measured minus the posterior-mean trajectory with ±σ (posterior median noise sd); right: "
                 "autocorrelation with the white-noise band ±2/√N. Correlated residuals mean model error: "
                 "the bands are then too narrow (compare the colored CRB)."))
    return figs


def _report(out, args, track, rnd, res, prob, rows, bayes, post, figs, warnings, result, seconds):
    import datetime

    from .report.render import render_report, versions

    def b64(name):
        import base64

        return base64.b64encode((out / name).read_bytes()).decode("ascii")

    crb_c = dict(zip(res.names, res.crb_colored))
    mlrows = []
    for n, v, s, f in zip(res.names, res.theta, res.crb, res.free):
        r = {"name": n + ("" if f else " (fixed)"), "value": v, "crb": s if f else None,
             "crb_colored": crb_c[n] if f else None, "mean": None, "sd": None, "ratio": None}
        if bayes is not None and n in bayes.summary.index:
            r["mean"] = bayes.summary.loc[n, "mean"]
            r["sd"] = bayes.summary.loc[n, "sd"]
            r["ratio"] = r["sd"] / s if s > 0 else None
        mlrows.append(r)
    det = result["ml"]["mach_range_determined"]
    inputs = [("track", f"{args.track} ({track.n} samples, channels {', '.join(prob.channels)}, "
                        f"t = {track.t[0]:.3f} .. {track.t[-1]:.3f} s)"),
              ("round", f"{args.round}: {rnd.projectile.name}, {rnd.projectile.mass} kg, "
                        f"{rnd.projectile.diameter} m"),
              ("drag model", f"{prob.model.drag.name} ({prob.P} coefficients)"),
              ("Mach range of the data", f"{result['ml']['mach_range_data'][0]:.3f} - {result['ml']['mach_range_data'][1]:.3f}"),
              ("Mach range determined (band sd < 1 % of Cd, inside the data, not clamped)",
               f"{det[0]:.2f} - {det[1]:.2f}" if det else "none"),
              ("noise sd used by the ML fit", ", ".join(f"{c} {v:.3g}" for c, v in res.sigma.items())),
              ("wall-clock time", f"{seconds:.1f} s")]
    conv = None
    post_ctx = None
    if bayes is not None:
        m = result["mcmc"]
        conv = {"converged": bayes.converged, "message": bayes.message,
                "rows": [("likelihood", f"{m['likelihood']}" + (f" (nu = {m['nu']})" if m["likelihood"] != "gaussian" else "")),
                         ("moves", m["moves"]), ("walkers", m["walkers"]), ("steps", m["steps"]),
                         ("burn-in / thinning", f"{m['burn']} / {m['thin']}"),
                         ("autocorrelation time tau (max, mean)", f"{m['tau_max']:.2f}, {m['tau_mean']:.2f} steps"),
                         ("acceptance", f"{m['acceptance']:.3f}"), ("retained draws", m["draws"]),
                         ("resumed from step", m["resumed_from"]),
                         ("max r_hat", f"{bayes.summary['r_hat'].max():.4f}"),
                         ("min ESS bulk / tail", f"{bayes.summary['ess_bulk'].min():.0f} / {bayes.summary['ess_tail'].min():.0f}"),
                         ("noise sd (posterior median)", ", ".join(f"{c} {v['median']:.3g}" for c, v in m["sigma"].items())),
                         ("sampling time", f"{m['seconds']:.1f} s")]}
        cols = ["mean", "sd", "q05", "q50", "q95", "r_hat", "ess_bulk", "ess_tail", "mcse_mean"]
        post_ctx = {"columns": cols, "rows": [(n, [bayes.summary.loc[n, c] for c in cols]) for n in bayes.summary.index]}
    headline = (f"Scheme 1, {prob.model.drag.name} drag. ML: {res.message}. "
                + (f"Posterior: {bayes.message}." if bayes is not None else "No sampling (--no-mcmc)."))
    ctx = {"title": f"bayesdrag fit: {Path(args.track).name}", "created": datetime.datetime.now().isoformat(timespec="seconds"),
           "headline": headline, "inputs": inputs, "warnings": warnings, "convergence": conv,
           "figures": [{"title": t, "caption": c, "png": b64(f)} for f, t, c in figs],
           "ml": {"message": res.message, "iterations": res.iterations, "cost": res.cost, "rows": mlrows},
           "posterior": post_ctx, "cd_rows": rows[::2], "windows": None, "versions": versions(),
           "quality": result["ml"].get("quality")}
    render_report(out / "report.html", ctx)


def _run_scheme2(args, track, rnd, chans, out, echo, quiet):
    """Scheme 2: ML per window (estimate/scheme2.py), then the same posterior sampling in each
    window (Cd, initial state, noise). Windows are sampled one after the other: each window's
    batch already runs on both cores (numba threads), a process pool would only add start-up
    and contention on a 2-core machine. Scheme 2 chains are kept in memory (no --resume: one
    window takes a few seconds)."""
    import numpy as np

    from .estimate.bayes import LogPosterior, sample_posterior
    from .estimate.scheme2 import fit_scheme2, windows_table

    t_start = time.perf_counter()
    window = getattr(args, "window", 50) or 50
    r2 = fit_scheme2(track, rnd, window=window, overlap=getattr(args, "overlap", 0) or 0, channels=chans,
                     free_ic=not args.fix_ic)
    ok = [k for k, r in enumerate(r2.results) if r.success]
    if not ok:
        raise FitError(f"{args.track}: no Scheme 2 window converged ({r2.results[0].message})")
    out.mkdir(parents=True, exist_ok=True)
    rows = windows_table(r2)
    warnings = [f"window {k} ({rows[k]['t_start']:.2f}-{rows[k]['t_end']:.2f} s): {r2.results[k].message}"
                for k in range(len(rows)) if k not in ok]
    draws = {}
    seed = getattr(args, "seed", None)
    log = None if quiet else _echo_err
    if not args.no_mcmc:
        for k in ok:
            post = LogPosterior(r2.problems[k], r2.results[k])
            b = sample_posterior(post, nwalkers=getattr(args, "walkers", None), seed=None if seed is None else seed + k,
                                 max_steps=getattr(args, "max_steps", 20000))
            cd = b.draws[..., 0]
            flat = cd.reshape(-1)
            q = np.quantile(flat, [0.05, 0.5, 0.95])
            rows[k].update(mean=float(flat.mean()), sd=float(flat.std(ddof=1)), q05=float(q[0]), q50=float(q[1]),
                           q95=float(q[2]), sd_over_crb=float(flat.std(ddof=1) / rows[k]["crb_sd"]) if rows[k]["crb_sd"] else None,
                           r_hat_max=float(b.summary["r_hat"].max()), ess_bulk_min=float(b.summary["ess_bulk"].min()),
                           mcmc_converged=b.converged, steps=b.steps)
            draws[k] = cd
            if not b.converged:
                warnings.append(f"window {k}: {b.message}")
            if log:
                log(f"window {k + 1}/{len(rows)} (Mach {rows[k]['mach']:.2f}): {b.message}")
    mach = np.array([w["mach"] for w in rows])
    lo, hi = float(min(w["mach_min"] for w in rows)), float(max(w["mach_max"] for w in rows))
    grid = np.round(np.linspace(lo, hi, 81), 4)
    order = np.argsort(mach[ok])
    mk = mach[ok][order]

    def interp(key):
        v = np.array([rows[k][key] for k in ok], float)[order]
        return np.interp(grid, mk, v)

    cd_rows = []
    cols = {key: interp(key) for key in ("ml", "crb_sd", "band_sd") + (("mean", "q05", "q95") if draws else ())}
    # a grid point is determined when the windows on both sides of it are
    det_w = np.array([rows[k]["determined"] for k in ok], bool)[order]
    j_hi = np.clip(np.searchsorted(mk, grid), 0, len(mk) - 1)
    j_lo = np.clip(j_hi - 1, 0, len(mk) - 1)
    inside = (grid >= mk[0]) & (grid <= mk[-1])
    for i, m in enumerate(grid):
        r = {key: float(v[i]) for key, v in cols.items()}
        r["mach"] = float(m)
        r["determined"] = bool(inside[i] and det_w[j_lo[i]] and det_w[j_hi[i]])
        r["reference"] = float(rnd.reference_drag.value(m)) if rnd.reference_drag is not None else None
        cd_rows.append(r)
    from .estimate.quality import intervals as _mach_intervals

    w_problems = [f"window {k} (Mach {rows[k]['mach']:.2f}): {p}" for k in ok for p in rows[k]["quality"]["problems"]]
    quality = {"ok": not w_problems and len(ok) == len(rows),
               "undetermined": _mach_intervals(grid, ~np.array([r["determined"] for r in cd_rows])),
               "windows_determined": int(det_w.sum()), "problems": w_problems}
    result = {"scheme": 2, "drag_model": "constant per window", "window": window,
              "ml": {"converged": all(r.converged for r in r2.results), "windows_converged": len(ok),
                     "windows": len(rows), "notes": list(r2.notes), "quality": quality},
              "cd": cd_rows, "windows": rows}
    warnings += w_problems
    if draws:
        result["mcmc"] = {"windows_converged": int(sum(rows[k]["mcmc_converged"] for k in ok)),
                          "r_hat_max": float(max(rows[k]["r_hat_max"] for k in ok))}
    _write_json(out / "result.json", result)
    if draws:
        import arviz as az

        S = min(d.shape[1] for d in draws.values())
        W = min(d.shape[0] for d in draws.values())
        cd = np.stack([draws[k][:W, :S] for k in ok], axis=-1)
        idata = az.from_dict(
            posterior={"cd": cd},
            observed_data={c: track.channels[c] for c in (chans or track.names)},
            constant_data={"mach": mach[ok], "crb_sd": np.array([rows[k]["crb_sd"] for k in ok]),
                           "t_start": np.array([rows[k]["t_start"] for k in ok]),
                           "t_end": np.array([rows[k]["t_end"] for k in ok]), "t": track.t},
            coords={"window": np.array(ok), "time": track.t},
            dims={"cd": ["window"], "mach": ["window"], "crb_sd": ["window"], "t_start": ["window"],
                  "t_end": ["window"], "t": ["time"], **{c: ["time"] for c in (chans or track.names)}})
        _atomic_write(out / "posterior.nc", lambda tmp: idata.to_netcdf(tmp))
    import matplotlib

    matplotlib.use("Agg")
    from .plots.cd import plot_windows

    ax = plot_windows([rows[k] for k in ok], reference=rnd.reference_drag.value if rnd.reference_drag else None)
    _write_figure(out / "windows.png", ax.figure)
    _report_scheme2(out, args, track, rnd, rows, cd_rows, warnings, result, time.perf_counter() - t_start)
    if not quiet:
        for w in warnings:
            _echo_err(f"bayesdrag: warning: {w}")
    echo(f"fit (Scheme 2): {len(ok)}/{len(rows)} windows of {window} samples converged, Mach {lo:.2f}-{hi:.2f}")
    echo(f"  wrote {out / 'result.json'}" + (", posterior.nc" if draws else "") + ", windows.png, report.html")
    return 0


def _report_scheme2(out, args, track, rnd, rows, cd_rows, warnings, result, seconds):
    import base64
    import datetime

    from .report.render import render_report, versions

    png = base64.b64encode((out / "windows.png").read_bytes()).decode("ascii")
    inputs = [("track", f"{args.track} ({track.n} samples)"), ("round", str(args.round)),
              ("windows", f"{len(rows)} of {result['window']} samples"), ("wall-clock time", f"{seconds:.1f} s")]
    conv = None
    if "mcmc" in result:
        m = result["mcmc"]
        conv = {"converged": m["windows_converged"] == result["ml"]["windows_converged"],
                "message": f"{m['windows_converged']} of {result['ml']['windows_converged']} windows converged "
                           f"(max r_hat {m['r_hat_max']:.4f})", "rows": []}
    ctx = {"title": f"bayesdrag fit (Scheme 2): {Path(args.track).name}",
           "created": datetime.datetime.now().isoformat(timespec="seconds"),
           "headline": "Scheme 2: a constant Cd per window, ML with Cramér-Rao bounds"
                       + (" and a posterior per window." if conv else "."),
           "inputs": inputs, "warnings": warnings, "convergence": conv,
           "figures": [{"title": "Cd per window", "caption": "Each window's Cd at its mean Mach number with "
                        "its 90 % interval; the reference curve dashed.", "png": png}],
           "ml": {"message": f"{result['ml']['windows_converged']} windows converged", "iterations": "—",
                  "cost": None, "rows": []},
           "posterior": None, "cd_rows": cd_rows[::2], "windows": rows, "versions": versions(),
           "quality": result["ml"].get("quality")}
    render_report(out / "report.html", ctx)
