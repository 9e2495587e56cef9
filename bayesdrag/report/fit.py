"""Figures and ``report.html`` of a fit (:class:`~bayesdrag.results.FitResult`), both schemes."""
from __future__ import annotations

import math

import datetime
from pathlib import Path

import numpy as np

from .._runtime.garbage import paused_gc
from ..errors import MissingDataError
from ..io.outputs import OutputRun, atomic_write, ensure_space, write_bytes, write_json
from ..results.words import determined_words, effect_lines
from ..plots.cd import (plot_cd_ml, plot_cd_ml_relative, plot_cd_posterior, plot_cd_posterior_relative, plot_cd_relative,
                        plot_uncertainty_budget, plot_windows)
from ..plots.mcmc import plot_corner, plot_traces
from ..plots.wind import plot_fitted_wind
from ..plots.common import channel_scale
from ..plots.residuals import plot_residuals, plot_residuals_acf
from .render import figure_png, png_base64, render_report, rendered_elsewhere, versions

__all__ = ["write_fit", "write_fit_files", "write_fit_report", "fit_figures", "fit_figure_specs", "cd_figure", "cd_relative_figure",
           "sd_ratio_figure", "budget_figure", "residuals_figure", "corner_figure", "traces_figure"]

#: resolution of the corner plot [dpi] (many panels)
CORNER_DPI = 80


def _rows(result):
    return result.record["cd"]


def _reference_curve(result):
    """The reference Cd(M) as a callable: the round's drag, else the ``cd`` rows' reference
    column (a loaded result), else None."""
    rnd = result.round
    if rnd is not None:
        return rnd.reference_drag.value if rnd.reference_drag is not None else None
    ref = result.cd.reference
    if np.all(np.isfinite(ref)):
        return lambda m: np.interp(m, result.cd.mach, ref)
    return None


def cd_figure(result, ax=None):
    """``cd.png``: the ML curve with its 90 % band (each row's band sd) and the reference; after
    sampling the posterior's 50 % and 90 % bands with the ML curve's Cramér-Rao band; Scheme 2
    the windows. Returns the Axes."""
    if result.record["scheme"] == 2:
        rows = [result.record["windows"][k] for k in result.windows_ok]
        return plot_windows(rows, ax=ax, reference=_reference_curve(result))
    dm = result.record["drag_model"]
    if result.sampled:
        return plot_cd_posterior(_rows(result), ax=ax, label=f"posterior ({dm})")
    return plot_cd_ml(_rows(result), ax=ax, label=f"ML ({dm})")


def _need_sampled(result, what):
    if not result.sampled or result.record["scheme"] != 1:
        raise MissingDataError(f"{what} draws the Scheme 1 posterior and this fit did not sample: fit with "
                               f"mcmc=True (the default)")


def cd_relative_figure(result, ax=None):
    """``cd_relative.png``: the posterior bands in percent of the reference curve (Scheme 1,
    sampled, with a reference drag); after an ML fit, its curve and band in percent of the
    reference (of the curve itself without one). Returns the Axes."""
    if result.record["scheme"] == 1 and not result.sampled:
        return plot_cd_ml_relative(_rows(result), ax=ax, label=f"ML ({result.record['drag_model']})")
    _need_sampled(result, "plot_cd_relative")
    if not all(r.get("reference") for r in _rows(result)):
        raise MissingDataError("plot_cd_relative draws the Cd relative to the reference drag, and the round has none")
    return plot_cd_posterior_relative(_rows(result), ax=ax)


def sd_ratio_figure(result, ax=None):
    """``cd_sd_ratio.png``: the posterior sd over the Cramér-Rao sd against Mach (Scheme 1,
    sampled). Returns the Axes."""
    _need_sampled(result, "plot_sd_ratio")
    return plot_cd_relative(_rows(result), ax=ax)


def budget_figure(result, ax=None):
    """``cd_budget.png``: the Cd sd by source against Mach in percent of Cd. Returns the Axes."""
    budget = result.record.get("uncertainty_budget")
    if not budget:
        raise MissingDataError("plot_budget draws result.json's uncertainty_budget, and this result has none")
    cd = [r["ml"] for r in _rows(result)] if result.record["scheme"] == 1 else None
    return plot_uncertainty_budget(budget, ax=ax, cd=cd)


def wind_figure(result, ax=None):
    """``wind.png``: the layers of wind the fit found and fitted (``ml.with_effects.wind_layers``)
    beside the round's met file's wind (a fit of this process). Returns the Axes."""
    layers = ((result.record.get("ml") or {}).get("with_effects") or {}).get("wind_layers")
    if not layers:
        raise MissingDataError("plot_wind draws the layers of wind the fit added (ml.with_effects.wind_layers), "
                               "and this fit added none")
    wind = getattr(result.round.atmosphere, "wind", None) if result.round is not None else None
    met = None
    if wind is not None and getattr(wind, "axis", None) == "altitude":
        met = (np.asarray(wind.levels, float), np.asarray(wind.wind_x, float), np.asarray(wind.wind_y, float))
    return plot_fitted_wind(layers, met=met, ax=ax)


def residuals_figure(result, fig=None):
    """``residuals.png``: measured minus fitted with ±σ bands (after sampling: minus the
    posterior-mean trajectory, with the residuals' autocorrelation). Needs the fit's objects.
    Returns the Figure."""
    result.require("plot_residuals", "scheme1", "track")
    f1, bayes, track = result.scheme1, result.posterior, result.track
    if bayes is None:
        res = f1.ml
        return plot_residuals(track.t, res.residuals, res.sigma, fig=fig)
    prob = f1.problem
    flat = bayes.thetas.reshape(-1, bayes.thetas.shape[-1])
    y, _ = prob.predict(flat.mean(axis=0)[None])
    resid = {c: prob.z[:, j] - y[0, :, j] for j, c in enumerate(prob.channels)}
    sig = {c: float(np.exp(np.median(bayes.draws[..., bayes.names.index(f"log_sigma_{c}")]))) for c in prob.channels}
    return plot_residuals_acf(track.t, resid, sig, fig=fig)


def corner_figure(result, fig=None):
    """``corner.png``: Cd at three Mach numbers of the determined range and the initial state.
    Needs the fit's objects (after sampling). Returns the Figure."""
    result.require("plot_corner", "scheme1", "posterior")
    f1, bayes = result.scheme1, result.posterior
    prob, dm, rows = f1.problem, f1.drag_model, _rows(result)
    flat = bayes.thetas.reshape(-1, bayes.thetas.shape[-1])
    det = [r["mach"] for r in rows if r.get("determined")] or [r["mach"] for r in rows]
    ms = np.quantile(det, [0.1, 0.5, 0.9]).round(2)
    B = dm.jacobian(ms)
    sel = {f"Cd(M{m:.2f})": flat[:, :prob.P] @ B[i] for i, m in enumerate(ms)}
    for n in ("X0", "Z0", "Ux0", "Uz0", "Uy0"):
        if n in bayes.names:
            sel[n] = flat[:, list(prob.names).index(n)]
    return plot_corner(sel, fig=fig)


def traces_figure(result, fig=None):
    """``traces.png``: walkers against step with the burn-in marked. Needs the fit's objects
    (after sampling). Returns the Figure (None when no traced parameter was sampled)."""
    result.require("plot_traces", "scheme1", "posterior", "log_posterior")
    prob, bayes, post = result.scheme1.problem, result.posterior, result.log_posterior
    picks = [n for n in ("Ux0", "Uz0", "log_sigma_x", "log_sigma_v") if n in post.names]
    chains = {n: bayes.chain[:, :, post.names.index(n)] for n in picks}
    mid = prob.names[prob.P // 2]
    if mid in post.names:
        chains[mid] = bayes.chain[:, :, list(post.names).index(mid)]
    if not chains:
        return None
    fig = plot_traces(chains, fig=fig)
    for ax in fig.axes:
        ax.axvline(bayes.burn, color="k", lw=0.8, ls="--")
    return fig


def fit_figures(result):
    """The figures of a fit: ``[(file name, title, caption, Figure, dpi)]``."""
    out = []
    for name, title, caption, make, dpi in fit_figure_specs(result):
        fig = make()
        if fig is not None:
            out.append((name, title, caption, fig, dpi))
    return out


#: figures a forked process renders while the report's other work goes on, when a core is free
#: (:func:`render.rendered_elsewhere`): after sampling the costly ones (the corner plot's 64
#: panels, the traces) beside posterior.nc and the rest; without, the residuals beside the rest
BACKGROUND_FIGURES = ("corner.png", "traces.png")
BACKGROUND_FIGURES_ML = ("residuals.png",)


def fit_figure_specs(result):
    """The figures of a fit, not drawn yet: ``[(file name, title, caption, make, dpi)]`` with
    ``make()`` returning the Figure (None when there is nothing to draw), so that each can be
    drawn where and when it is rendered."""
    if result.record["scheme"] == 2:
        return [("windows.png", "Cd per window", "Each window's Cd at its mean Mach number with its 90 % interval; "
                 "the reference curve dashed.", lambda: cd_figure(result).figure, None)]
    rows = _rows(result)
    budget = result.record.get("uncertainty_budget")
    budget_fig = []
    if budget and (len(budget["by_source"]) > 2 or budget.get("model_error_floor")):
        budget_fig = [("cd_budget.png", "Uncertainty budget", "The Cd sd by source (GUM, linearised at the ML "
                       "estimate): statistical = what the track leaves with every declared source held (the colored "
                       "or model-error-floor sd where the residuals show model error); each source's share; "
                       "model_error = the Cd shift the remaining misfit implies; the total is the band the cd rows "
                       "report; dash-dot the model-error floor where the residuals show model error.",
                       lambda: budget_figure(result).figure, None)]
    if ((result.record.get("ml") or {}).get("with_effects") or {}).get("wind_layers"):
        budget_fig = [("wind.png", "Wind found and fitted", "The layers of wind the fit carries beside Cd, each "
                       "with its wx (along the line of fire, tail wind +) and wy (to the right) and +-1 sd (the sd "
                       "the fit stands by); dashed, the met file's wind when the round has one.",
                       lambda: wind_figure(result).figure, None)] + budget_fig
    if result.posterior is None:
        return [("cd.png", "Cd(M), maximum likelihood", "ML curve with its 90 % band (each row's band sd: the "
                 "Cramér-Rao sd, or the colored-residual sd where the residuals show model error) and the reference.",
                 lambda: cd_figure(result).figure, None),
                ("cd_relative.png", "Cd(M) relative", "The same curve and band in percent of the reference (of the "
                 "curve itself without one), where a band of 0.1 % is visible; rows not determined shaded.",
                 lambda: cd_relative_figure(result).figure, None),
                ("residuals.png", "Residuals", "Measured minus fitted with ±σ bands.",
                 lambda: residuals_figure(result), None)] + budget_fig
    figs = [("cd.png", "Cd(M) posterior", "Posterior median with the 50 % and 90 % bands the cd rows report "
             "(q05/q95: where the residuals show model error, widened beyond the posterior as sampled, drawn "
             "dash-dot), the ML curve's 90 % Cramér-Rao band (dotted) and the reference firing table (dashed).",
             lambda: cd_figure(result).figure, None)]
    if all(r.get("reference") for r in rows):
        figs.append(("cd_relative.png", "Cd(M) relative to the reference", "The same bands in percent of the "
                     "reference curve, where their widths are visible.", lambda: cd_relative_figure(result).figure,
                     None))
    figs += budget_fig
    figs.append(("cd_sd_ratio.png", "Posterior sd over Cramér-Rao sd", "The posterior as sampled (solid): 1 = as "
                 "wide as the bound, above 1 where the noise is estimated larger than the round's or the data are "
                 "weak. Dashed, where drawn: the total band the cd rows report (q05/q95), wider by the model-error "
                 "widening (the model-error floor and the Cd shift of the remaining misfit), which the sampler "
                 "does not see.",
                 lambda: sd_ratio_figure(result).figure, None))
    figs.append(("corner.png", "Corner plot", "Cd at three Mach numbers of the determined range and the initial "
                 "state; lines at the 5, 50 and 95 % quantiles.", lambda: corner_figure(result), CORNER_DPI))
    figs.append(("traces.png", "Traces", f"Walkers against step; burn-in ({result.posterior.burn} steps) left "
                 "of the dashed line.", lambda: traces_figure(result), None))
    figs.append(("residuals.png", "Residuals and their autocorrelation",
                 "Measured minus the posterior-mean trajectory with ±σ (posterior median noise sd); right: "
                 "autocorrelation with the white-noise band ±2/√N. Correlated residuals mean model error: the "
                 "bands are then too narrow (compare the colored CRB).", lambda: residuals_figure(result), None))
    return figs


def write_fit(result, directory, *, sources=None):
    """Write a fit's folder as one consistent set (:class:`~bayesdrag.io.outputs.OutputRun`):
    ``result.json``, ``posterior.nc`` (after sampling), the figures, ``report.html`` and
    ``manifest.json``; a finished chain ``chain.partial.h5`` in it becomes ``chain.h5``; an
    earlier run's files are moved to ``superseded/``. What ``FitResult.write`` calls.

    Parameters
    ----------
    result : FitResult
    directory : path
        Created if needed.
    sources : dict, optional
        ``{"track": ..., "round": ...}`` file names shown in the report (and, when they are
        files, recorded with their SHA-256 in the manifest).

    Returns
    -------
    list of Path
        The files written.
    """
    files = {k: v for k, v in (sources or {}).items() if v is not None and Path(v).is_file()}
    with OutputRun(directory, "fit", inputs=files) as run:
        result.write_into(run, sources=sources)
    return [run.folder / f["name"] for f in run.manifest["files"]]


def write_fit_files(result, directory, *, sources=None):
    """Write ``result.json``, ``posterior.nc`` (after sampling), the figures and
    ``report.html`` of ``result`` into ``directory`` as plain files (no manifest, nothing moved).

    Returns
    -------
    list of Path
    """
    out = Path(directory)
    written = [out / "result.json"]
    specs = fit_figure_specs(result)
    names = BACKGROUND_FIGURES if result.posterior is not None else BACKGROUND_FIGURES_ML
    background = [(n, make, dpi) for n, _, _, make, dpi in specs if n in names]
    with paused_gc():       # thousands of figure artists: no collections over the fit's objects
        # the costly figures drawn by a forked process meanwhile, where a core is free
        with rendered_elsewhere(background, out, meanwhile=_import_corner) as pngs:
            write_json(out / "result.json", result.to_dict())
            if _write_posterior(result, out):
                written.append(out / "posterior.nc")
            here = _render_specs([sp for sp in specs if sp[0] not in names], out)
        written += _write_report(out, result, specs, {**here, **pngs}, sources or {})
    return written


def _import_corner():
    """Import ``corner`` here while a forked renderer draws the corner plot: the next report's
    renderer inherits it (``import corner`` imports ArviZ too, 0.4 s of the 1.2 s its plot took
    in a fresh child). Nothing else here imports ArviZ since posterior.nc is written without it."""
    import corner  # noqa: F401


def _write_posterior(result, out):
    """Write ``posterior.nc`` of ``result`` into ``out`` (False: nothing sampled). A Scheme 1 fit
    of this process: written from its arrays (:func:`bayesdrag.io.netcdf.write_groups`, without
    ArviZ); otherwise (Scheme 2, a result read from a folder) through ArviZ."""
    arrays = result._posterior_arrays()
    if arrays is not None:
        from ..estimate.bayes.posterior_groups import fit_groups
        from ..io.netcdf import groups_bytes, write_groups

        groups, attrs = fit_groups(arrays)
        size, write = groups_bytes(groups), (lambda tmp: write_groups(tmp, groups, attrs))
    else:
        idata = result.to_inference_data()
        if idata is None:
            return False
        size, write = netcdf_bytes(idata), (lambda tmp: idata.to_netcdf(tmp))
    # HDF5 crashes the process (segfault) when the disk fills up inside a write: refuse first
    ensure_space(out, size + (256 << 10), "posterior.nc")   # uncompressed: an upper bound
    atomic_write(out / "posterior.nc", write)
    return True


def netcdf_bytes(idata):
    """Bytes of the arrays of an InferenceData (what its NetCDF file holds, before overhead)."""
    total = 0
    for name in idata.groups():
        ds = getattr(idata, name.lstrip("/"), None)
        if ds is not None:
            total += sum(int(v.nbytes) for v in ds.variables.values())
    return total


def write_fit_report(out, result, sources=None):
    """Write the figures (PNG) and ``report.html`` of ``result`` into ``out``.

    Returns
    -------
    list of Path
        The files written.
    """
    out = Path(out)
    specs = fit_figure_specs(result)
    return _write_report(out, result, specs, _render_specs(specs, out), sources or {})


def _render_specs(specs, out):
    """Draw and save the figures of ``specs`` into ``out``: ``{file name: PNG bytes or None}``."""
    pngs = {}
    for name, _, _, make, dpi in specs:
        fig = make()
        pngs[name] = None if fig is None else figure_png(fig, dpi) if dpi else figure_png(fig)
        if pngs[name] is not None:
            write_bytes(out / name, pngs[name])
    return pngs


def _write_report(out, result, specs, pngs, sources):
    """``report.html`` with the figures of ``specs`` (their PNG bytes in ``pngs``; None: not
    drawn); returns the files written (figures and report)."""
    written, embedded = [], []
    for name, title, caption, _, _ in specs:
        if pngs.get(name) is not None:
            written.append(out / name)
            embedded.append({"title": title, "caption": caption, "png": png_base64(pngs[name])})
    ctx = _context_scheme2(result, sources) if result.record["scheme"] == 2 else _context_scheme1(result, sources)
    ctx["figures"] = embedded
    render_report(out / "report.html", ctx)
    written.append(out / "report.html")
    return written


def _common(result, sources, title_kind):
    track_name = Path(sources.get("track", result.track.source or "track")).name
    return {"title": f"bayesdrag fit{title_kind}: {track_name}", "answer": result.record.get("headline"),
            "created": datetime.datetime.now().isoformat(timespec="seconds"),
            "warnings": [w for w in result.warnings if w.shown],
            "quiet_warnings": [w for w in result.warnings if not w.shown], "versions": versions(),
            "air_line": ((result.record["ml"].get("quality") or {}).get("air") or {}).get("line"),
            "effect_lines": effect_lines(result.record["ml"].get("with_effects")),
            "determined_words": determined_words(result.record["ml"].get("mach_range_determined"),
                                                 (result.record["ml"].get("quality") or {}).get("undetermined") or ()),
            "quality": result.record["ml"].get("quality"),
            # how each channel is shown: (factor, unit); the radar's angles in degrees
            "channel_display": {c: channel_scale(c) for c in
                                ((result.record["ml"].get("quality") or {}).get("channels") or {})}}


#: a sampled noise sd this many times the round's (or the track's) is explained in the report
NOISE_EXPLAIN_RATIO = 2.0


def noise_used(noise, white):
    """The ML fit's noise sd per channel as the report prints it: ``ml.noise.sd`` (the total),
    with an ``ar1`` channel's correlation from ``ml.noise.ar``.

    Parameters
    ----------
    noise : dict
        ``result.json``'s ``ml.noise``.
    white : dict channel -> float
        ``ml.sigma``, used where an older result has no ``sd``.

    Returns
    -------
    str
    """
    total, ar = noise.get("sd") or white, noise.get("ar") or {}
    parts = []
    for c, v in total.items():
        f, unit = channel_scale(c)
        rho = f" (AR(1), rho {ar[c]['rho']:.3g})" if c in ar else ""
        parts.append(f"{c} {f * v:.3g} {unit}{rho}")
    return ", ".join(parts)


def noise_explanation(sampled, used, source=None):
    """Rows explaining a sampled noise sd far above the one the ML fit used (the round's
    ``[radar] sigma`` or the track's own high-frequency noise): the sampler's noise sd takes up
    whatever the model cannot follow, so it then measures model error, not the radar.

    Parameters
    ----------
    sampled : dict channel -> {"median": float, ...}
        ``result.json``'s ``mcmc.sigma``.
    used : dict channel -> float
        The noise sd of the ML fit.
    source : dict channel -> str, optional
        Where each came from (``"round"`` or ``"estimated"``).

    Returns
    -------
    list of (str, str)
    """
    rows = []
    for c, v in sampled.items():
        s0 = used.get(c)
        if not s0 or v["median"] < NOISE_EXPLAIN_RATIO * s0:
            continue
        whose = "the round states" if (source or {}).get(c, "round") == "round" else "the track's scatter shows"
        rows.append((f"why the noise sd of {c} is large",
                     f"{v['median']:.3g} against the {s0:.3g} {whose}: the sampled noise sd takes up everything the "
                     f"model does not follow, so here it measures model error (see the residuals' autocorrelation "
                     f"and the warnings), not the radar; the Cd bands are widened accordingly"))
    return rows


def _noise_sources(record):
    q = (record.get("ml") or {}).get("quality") or {}
    return {c: f.get("noise_source") for c, f in (q.get("channels") or {}).items()}


def _context_scheme1(result, sources):
    s = result.record
    f1, bayes = result.scheme1, result.posterior
    res, prob = f1.ml, f1.problem
    crb_c = dict(zip(res.names, res.crb_colored))
    mlrows = []
    for n, v, sd, f in zip(res.names, res.theta, res.crb, res.free):
        r = {"name": n + ("" if f else " (fixed)"), "value": v, "crb": sd if f else None,
             "crb_colored": crb_c[n] if f else None, "mean": None, "sd": None, "ratio": None}
        if bayes is not None and n in bayes.convergence.index:
            r["mean"] = bayes.convergence.loc[n, "mean"]
            r["sd"] = bayes.convergence.loc[n, "sd"]
            r["ratio"] = r["sd"] / sd if sd > 0 else None
        mlrows.append(r)
    det = s["ml"]["mach_range_determined"]
    track, rnd = result.track, result.round
    inputs = [("track", f"{sources.get('track', track.source)} ({track.n} samples, channels "
                        f"{', '.join(prob.channels)}, t = {track.t[0]:.3f} .. {track.t[-1]:.3f} s)"),
              ("round", f"{sources.get('round', rnd.path)}: {rnd.projectile.name}, {rnd.projectile.mass} kg, "
                        f"{rnd.projectile.diameter} m"),
              ("drag model", f"{f1.drag_model.name} ({prob.P} coefficients)"),
              ("Mach range of the data", f"{s['ml']['mach_range_data'][0]:.3f} - {s['ml']['mach_range_data'][1]:.3f}"),
              ("Mach range determined (band sd < 1 % of Cd, inside the data, not clamped)",
               f"{det[0]:.2f} - {det[1]:.2f}" if det else "none"),
              ("noise sd used by the ML fit (total; an AR(1) channel's white and model-error parts together)",
               noise_used(s["ml"]["noise"], res.sigma)),
              ("wall-clock time", f"{result.seconds:.1f} s")]
    conv = post_ctx = None
    if bayes is not None:
        m = s["mcmc"]
        lik = m["likelihood"] + (f" (nu = {m['nu']})" if m["likelihood"] != "gaussian" else "")
        conv = {"converged": bayes.converged, "message": bayes.message,
                "rows": [("likelihood", lik), ("moves", m["moves"]), ("walkers", m["walkers"]), ("steps", m["steps"]),
                         ("burn-in / thinning", f"{m['burn']} / {m['thin']}"),
                         ("autocorrelation time tau (max, mean)", f"{m['tau_max']:.2f}, {m['tau_mean']:.2f} steps"),
                         ("acceptance", f"{m['acceptance']:.3f}"), ("retained draws", m["draws"]),
                         ("resumed from step", m["resumed_from"]),
                         ("max r_hat", f"{bayes.convergence['r_hat'].max():.4f}"),
                         ("min ESS bulk / tail",
                          f"{bayes.convergence['ess_bulk'].min():.0f} / {bayes.convergence['ess_tail'].min():.0f}"),
                         ("noise sd (posterior median)",
                          ", ".join(f"{c} {v['median']:.3g}" for c, v in m["sigma"].items())),
                         *noise_explanation(m["sigma"], res.sigma, _noise_sources(s)),
                         ("sampling time", f"{m['seconds']:.1f} s")]}
        cols = ["mean", "sd", "q05", "q50", "q95", "r_hat", "ess_bulk", "ess_tail", "mcse_mean"]
        post_ctx = {"columns": cols,
                    "rows": [(n, [bayes.convergence.loc[n, c] for c in cols]) for n in bayes.convergence.index]}
    headline = (f"Scheme 1, {f1.drag_model.name} drag. ML: {res.message}. "
                + (f"Posterior: {bayes.message}." if bayes is not None else "No sampling (maximum likelihood only)."))
    ctx = _common(result, sources, "")
    cd_rows = [dict(r, crb_sd_systematic=math.sqrt(max(r["crb_sd"] ** 2 - r["crb_sd_statistical"] ** 2, 0.0)))
               if r.get("crb_sd_statistical") is not None else r for r in s["cd"][::2]]
    ctx.update(headline=headline, inputs=inputs, convergence=conv, posterior=post_ctx, windows=None,
               ml={"message": res.message, "iterations": res.iterations, "cost": res.cost, "rows": mlrows},
               cd_rows=cd_rows, budget=budget_context(s))
    return ctx


def budget_context(record, n=6):
    """The report's budget section: one line on what the Cd is conditional on or includes, and
    the sd by source in percent of Cd at ``n`` Mach values of the determined range."""
    b = record.get("uncertainty_budget")
    if not b:
        return None
    cond = b.get("conditional_on") or []
    srcs = [k for k in b["by_source"] if k not in ("statistical", "cross")]
    assumed = b.get("assumed") or {}
    effects = [k for k in srcs if k in ((record["ml"].get("with_effects") or {}).get("fitted") or [])]
    declared = [k for k in srcs if k not in ("model_error", "noise_model") and k not in assumed and k not in effects]
    note = ("Includes the declared sources " + ", ".join(declared) + " (fitted with their priors); "
            if declared else "No systematic source is declared: ")
    if effects:
        note += "includes the effects " + ", ".join(effects) + " (fitted beside Cd: ml.with_effects); "
    for k, a in assumed.items():
        note += f"includes the assumed {k} (sd {a['sd_deg']:g} deg: {a['why']}); "
    note += ("the Cd is conditional on the nominal " + ", ".join(cond) + "." if cond else "every source is included.")
    if b.get("model_error_floor"):
        note += (" The residuals show model error: the band uses the model-error floor (the colored bound of the "
                 "white-noise fit with the sources), wider than the AR(1) fit's own bound; it is inside "
                 "statistical.")
    if "model_error" in srcs:
        note += (" model_error is the Cd shift the misfit that remains implies (an undeclared effect the diagnosis "
                 "finds, fitted; or a robust fit of the noise), see ml.quality.model_error.")
    if "noise_model" in srcs:
        note += (" noise_model is what the AR(1) noise's correlation, which the track tells only so well, adds: "
                 "the band averages over it (ml.noise.ar.*.sd_log_1m_rho).")
    note += " The total is the band each cd row reports (band_sd): the squares plus cross give it."
    rows = []
    if srcs or b.get("model_error_floor"):
        mach = np.asarray(b["mach"], float)
        det = record["ml"].get("mach_range_determined") or [mach.min(), mach.max()]
        cd = {round(r["mach"], 4): r["ml"] for r in record["cd"]}
        keys = ["statistical"] + srcs + ["cross"] + (["model_error_floor"] if b.get("model_error_floor") else [])
        for x in np.linspace(det[0], det[1], n):
            i = int(np.argmin(np.abs(mach - x)))
            c = cd.get(round(float(mach[i]), 4)) or 1.0
            parts = []
            for k in keys:
                v = b["model_error_floor"][i] if k == "model_error_floor" else b["by_source"][k][i]
                # cross is signed variance: shown as a signed sd
                parts.append(100 * (math.copysign(math.sqrt(abs(v)), v) if k == "cross" else v) / c)
            rows.append({"mach": float(mach[i]), "total": 100 * b["total_sd"][i] / c, "parts": parts})
        return {"note": note, "columns": [k if k != "cross" else "cross (signed)" for k in keys], "rows": rows}
    return {"note": note, "columns": [], "rows": []}


def _context_scheme2(result, sources):
    s = result.record
    rows = s["windows"]
    inputs = [("track", f"{sources.get('track', result.track.source)} ({result.track.n} samples)"),
              ("round", str(sources.get("round", result.round.path))),
              ("windows", f"{len(rows)} of {s['window']} samples"), ("wall-clock time", f"{result.seconds:.1f} s")]
    conv = None
    if "mcmc" in s:
        m = s["mcmc"]
        conv = {"converged": m["windows_converged"] == s["ml"]["windows_converged"],
                "message": f"{m['windows_converged']} of {s['ml']['windows_converged']} windows converged "
                           f"(max r_hat {m['r_hat_max']:.4f})", "rows": []}
    ctx = _common(result, sources, " (Scheme 2)")
    ctx.update(headline="Scheme 2: a constant Cd per window, ML with Cramér-Rao bounds"
                        + (" and a posterior per window." if conv else "."),
               inputs=inputs, convergence=conv, posterior=None, windows=rows, cd_rows=s["cd"][::2],
               ml={"message": f"{s['ml']['windows_converged']} windows converged", "iterations": "—", "cost": None,
                   "rows": []})
    return ctx
