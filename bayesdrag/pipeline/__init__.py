"""What ``bayesdrag.fit`` and ``bayesdrag.diagnose`` compute: a track and a round in, a frozen
result out (:class:`~bayesdrag.results.FitResult`, :class:`~bayesdrag.results.DiagnosisResult`).

No file is read or written here (except the sampler's chain file when the caller names one) and
nothing is printed: the commands (:mod:`bayesdrag.commands`) read the files, call these functions
and write the output folder. Scheme 1 (Cd(M) over the whole flight, the default) and Scheme 2 (a
constant Cd per window) share :func:`fit`; ``--with auto`` and the default effect search call the
diagnosis from here.
"""
from __future__ import annotations

import contextlib
import functools
import sys
import time
import warnings as py_warnings
from typing import Any, Callable

import numpy as np

from .._runtime.beside import started_beside
from .._runtime.threads import single_blas
from ..errors import BayesdragWarning, FitError, FitWarning, InputError
from ..results.words import determined_words
from ..estimate.build.model_size import narrow_shape_sd
from ..estimate.cd.headline import headline
from ..estimate.cd.model_error import add_in_squares, fold_into_budget
from ..estimate.cd.quality import assess, check_against_flexible, intervals
from ..estimate.cd.table import cd_grid, cd_table, determined_range, model_error_floor
from ..estimate.scheme1.effect_sizes import effect_sizes
from ..estimate.scheme1.fit import fit_scheme1, noise_record
from ..estimate.scheme2 import fit_scheme2, windows_table
from .model_check import (LEVEL_EFFECTS, air, air_contradiction, alternative_error, clock_note, diagnosis_record, model_error, note_model_error,
                          why_not_clean)
from ..options import DiagnoseOptions, FitOptions
from ..results import DiagnosisResult, FitResult
from ..round import Round
from .sampling import mcmc_json, posterior_json, run_sampler, sampled_rows
from ..track import RadarTrack, thin_for_fit
from ..measure.chronograph import chronograph_site
from ..effects import RADAR_POSITION, WIND_PROFILE

__all__ = ["fit", "diagnose", "summary_line"]


def fit(track: RadarTrack, rnd: Round, options: FitOptions | None = None, *, chain_path: Any = None,
        resume: bool = False, log: Callable[[str], None] | None = None, progress: bool | None = None,
        ml_progress: Callable[[str], None] | None = None, **kwargs: Any) -> FitResult:
    """Estimate Cd(M) from a track.

    Parameters
    ----------
    track : RadarTrack
    rnd : Round
    options : FitOptions, optional
        Everything that changes the result (default :class:`FitOptions`); keyword arguments
        (``mcmc=False``, ``drag="poly2"``, ...) override single fields.
    chain_path : path, optional
        Scheme 1 with sampling: write the emcee chain to this HDF5 file as it runs (a killed run
        can then be resumed).
    resume : bool
        Continue the unfinished chain in ``chain_path``.
    log : callable, optional
        ``log(str)`` receives status lines of long work (the sampler's progress).
    progress : bool or None
        Show a progress bar (tqdm: a widget in a notebook, a line on stderr in a terminal) while
        sampling. None (default): when someone is watching, i.e. stderr is a terminal or the code
        runs in a Jupyter kernel; ``False`` never.
    ml_progress : callable, optional
        ``ml_progress(step)`` receives the step the maximum-likelihood fit is at
        (:class:`~bayesdrag.commands.runs.StageProgress` prints it when the fit is slow); its
        ``done()`` is called at the end when it has one.

    Returns
    -------
    FitResult
        Frozen; ``to_dict()`` is the content of ``result.json``.

    Warns
    -----
    BayesdragWarning
        Each of the result's ``warnings`` worth reading (misfits, undetermined ranges, sampler
        problems; not the strong correlations and single coefficients' sds, which stay in
        ``warnings``), after the fit; filter the category to silence them.

    Raises
    ------
    InputError
        Options or inputs that do not fit together (a channel the track lacks).
    FitError
        No solution: the message says why.
    """
    with single_blas():   # the kernel's threads use the cores, not BLAS's
        t_start = time.perf_counter()
        progress = watched() if progress is None else bool(progress)
        track = thin_for_fit(track)           # a very dense track: every k-th sample, with a note
        opts = options if options is not None else FitOptions()
        if kwargs:
            opts = FitOptions(**{**opts.to_dict(), **kwargs})
        chans = opts.channels
        if chans is not None:
            missing = [c for c in chans if c not in track.names]
            if missing:
                raise InputError(f"{track.source or 'track'}: channel(s) {', '.join(missing)} asked for but not in the "
                                 f"track (it has {', '.join(track.names)})")
        rnd, site_note = chronograph_site(track, rnd, chans or track.names)
        if opts.scheme == 2:
            opts.check_windows(track.n)       # a bound on the windows, before any is fitted
            return _emitted(_fit_scheme2(track, rnd, opts, chans, log, t_start))
        return _emitted(_fit_scheme1(track, rnd, opts, chans, chain_path, resume, log, progress, t_start, ml_progress,
                                     notes=(site_note,) if site_note else ()))


def watched():
    """Whether someone watches this process: its stderr is a terminal, or it runs in a Jupyter
    kernel (where tqdm draws a widget)."""
    try:
        if sys.stderr is not None and sys.stderr.isatty():
            return True
    except (AttributeError, ValueError):      # a closed or replaced stderr
        pass
    return "ipykernel" in sys.modules


def _emitted(result):
    """``result``, each of its warnings worth reading (``shown``: not one of
    :data:`~bayesdrag.errors.QUIET_KINDS`) emitted through :mod:`warnings` as a
    :class:`~bayesdrag.errors.BayesdragWarning` (attributed to the caller of :func:`fit`)."""
    for w in result.warnings:
        if w.shown:
            py_warnings.warn(w.message, BayesdragWarning, stacklevel=3)
    return result


def _fit_scheme1(track, rnd, opts, chans, chain_path, resume, log, progress, t_start, ml_progress=None, notes=()):
    check = opts.model_check and opts.with_effects != "auto"
    # the model check's diagnosis reads the track and the round only: it runs in a forked process
    # beside the ML fit, and beside the sampling too where the check cannot change what is sampled
    with started_beside(functools.partial(diagnosis_record, track, rnd, chans), fork=check) as diag, \
            contextlib.ExitStack() as later:
        return _scheme1(track, rnd, opts, chans, chain_path, resume, log, progress, t_start, ml_progress,
                        diag if check else None, notes, later)


def _scheme1(track, rnd, opts, chans, chain_path, resume, log, progress, t_start, ml_progress, diag, notes=(),
             later=None):
    timing = {"beside": []}
    sizes_job = None

    def sizes_beside(fit):
        # the added effects' sizes (their split fits) change nothing the fit does after: they
        # run in a forked process from the moment the fit with the effects is the answer
        if later is None or not fit.effects:
            return None
        return later.enter_context(started_beside(
            functools.partial(_effect_sizes_record, track, rnd, opts, chans, fit), fork=True))
    with_effects, with_note, layers = _with_effects(track, rnd, opts, log)
    f1 = fit_scheme1(track, rnd, drag=opts.drag, channels=chans, free_ic=not opts.fix_ic,
                     likelihood=opts.likelihood, nu=opts.ml_nu, noise_model=opts.noise_model,
                     with_effects=with_effects, progress=ml_progress, wind_layers=layers)
    res = f1.ml
    if not res.success:
        raise FitError(f"{track.source or 'track'}: {res.message}")
    dm = f1.drag_model
    lo, hi = float(np.min(res.mach)), float(np.max(res.mach))
    grid = cd_grid(lo, hi)
    rows = cd_table(res, dm, grid, rnd.reference_drag)
    if f1.ml_without_effects is not None:
        for r, v in zip(rows, dm.cd(f1.ml_without_effects.drag_params, grid)):
            r["ml_without_effects"] = float(v)
    budget = _budget(f1, grid, rows)
    floored = model_error_floor(f1, rows)
    gap = effects_fit = None
    default = opts.with_effects == "default"
    timing["ml"] = round(time.perf_counter() - t_start, 3)
    # effects the user names are fitted, and the misfit they leave is checked like any other: a
    # warm day under `--with wind_profile` otherwise gave rows 50 sd off marked determined. Only
    # the default takes the check's fit as its answer: otherwise the check cannot change what is
    # sampled, and it is made once the sampling (beside which its diagnosis runs on) is done
    deferred = diag is not None and opts.mcmc and not default
    if diag is not None and not deferred:
        gap, effects_fit = _checked(track, rnd, opts, chans, f1, grid, rows, diag, timing, ml_progress)
    if default and effects_fit is not None and effects_fit.effects and not _trades_with_cd(effects_fit, rnd):
        # the default fit fits the cause: the check's fit with the undeclared material effects
        # (already made, from the plain fit's start) is the answer; the plain Cd stays beside it
        t0 = time.perf_counter()
        plain, f1 = f1, effects_fit
        sizes_job = sizes_beside(f1)
        res, dm = f1.ml, f1.drag_model
        lo, hi = float(np.min(res.mach)), float(np.max(res.mach))
        grid = cd_grid(lo, hi)
        rows = cd_table(res, dm, grid, rnd.reference_drag)
        for r, v in zip(rows, plain.drag_model.cd(plain.ml.drag_params, grid)):
            r["ml_without_effects"] = float(v)
        budget = _budget(f1, grid, rows)
        floored = model_error_floor(f1, rows)
        found = gap
        gap, _ = model_error(track, rnd, opts, chans, f1, grid, rows, diagnose_effects=False, plain=plain)
        gap.update(verdict=found["verdict"], skipped=found["skipped"], conditional_air=found["conditional_air"],
                   effects_fitted=list(f1.effects))
        _effect_residual(rows, gap, residual_share(plain.ml, f1.ml, f1.problem.channels, rnd.radar.sigma))
        if "alternative" in found:
            gap["alternative"] = found["alternative"]
            alternative_error(rows, gap)
        if found.get("unsized"):
            gap["unsized"] = sorted(set(gap.get("unsized", [])) | set(found["unsized"]))
        with_note = {"added_by": "default", "requested": "default", "effects": list(f1.effects),
                     "candidates": list(found["verdict"]), "skipped": found["skipped"],
                     "reason": (f"the model check's diagnosis names {', '.join(found['verdict'])}, which the round "
                                f"does not declare: Cd is fitted with {', '.join(f1.effects)} as nuisance "
                                f"parameters (ml_without_effects: the plain fit; --with none keeps the plain fit "
                                f"with the shift as model error)")}
        timing["refit"] = round(time.perf_counter() - t0, 3)
    bayes = post = cd = sizes = None
    if sizes_job is None:
        sizes_job = sizes_beside(f1)
    if opts.mcmc:
        bayes, post = run_sampler(f1, opts, chain_path, resume, log, progress)
        if deferred:
            gap, _ = _checked(track, rnd, opts, chans, f1, grid, rows, diag, timing, ml_progress)
    placement = _placement_error(f1, grid, rows)
    if (f1.model_size or {}).get("narrow_span"):   # one factor on the table: the shape may lean
        add_in_squares(rows, narrow_shape_sd(f1.model_size["narrow_span"], grid, [r["ml"] for r in rows]))
    quality = assess(f1, rows, track, rnd.radar.sigma)
    if notes:
        quality["notes"] = list(notes) + list(quality.get("notes") or [])
    if gap is not None:
        note_model_error(gap, quality, grid, rows)
    quality["air"] = air(f1, gap)
    air_contradiction(rnd, quality["air"], quality, rows)
    if dm.name != "spline":
        if ml_progress is not None:
            ml_progress("the flexible fit the rigid model is checked against")
        _rigid_check(track, rnd, opts, chans, f1, grid, rows, quality)
    if ml_progress is not None and hasattr(ml_progress, "done"):
        ml_progress.done()
    summary = _ml_summary(f1, rows, quality, lo, hi, opts)
    summary["uncertainty_budget"] = budget
    stated = getattr(rnd.atmosphere, "stated_error", None)
    if stated is not None and rnd.systematics.from_met_file:
        # the sds the met file carried into the band, and why (docs/fitting.md)
        budget["met_file"] = {"sources": list(rnd.systematics.from_met_file), "why": stated.why,
                              "wind_sd": stated.wind_sd, "temperature_sd": float(f"{stated.temperature_sd:.4g}"),
                              "density_sd": float(f"{stated.density_sd:.4g}")}
    if sizes_job is not None:
        made = sizes_job.result()
        sizes, timing["effect_sizes"] = made["sizes"], round(made["seconds"], 3)
        timing["beside"] += ["effect_sizes"] if sizes_job.forked else []
    if with_note is not None or WIND_PROFILE.name in f1.effects:
        if sizes is None:
            made = _effect_sizes_record(track, rnd, opts, chans, f1)
            sizes, timing["effect_sizes"] = made["sizes"], round(made["seconds"], 3)
        summary["ml"]["with_effects"] = _with_effects_record(f1, with_note, sizes, placement)
    if floored:
        budget["model_error_floor"] = [float(f"{r['model_error_floor']:.6g}") for r in rows]
    nm = [r.get("noise_model_sd", 0.0) for r in rows]
    if any(v > 0 for v in nm):
        # the ar1 noise's own uncertainty (noise_spread), statistical but shown apart
        budget["by_source"]["noise_model"] = [float(f"{v:.6g}") for v in nm]
    fold_into_budget(budget, rows)
    # what the Cd is conditional on is one line of the report and uncertainty_budget.conditional_on
    warnings = [w for w in res.warnings if w.kind != "at_bound"] + list(quality["problems"])
    warnings += clock_note(summary["ml"])
    if opts.mcmc:
        rows, cd = sampled_rows(bayes, f1, rows, grid)
        summary["cd"] = rows
        summary["posterior"] = posterior_json(bayes)
        summary["mcmc"] = mcmc_json(bayes, post)
        warnings += list(bayes.warnings)
        info = [r for r in rows if r["crb_sd"] > 0 and r["ml"] > 0 and r["crb_sd"] / r["ml"] < 0.01]
        ratios = [r["sd_over_crb"] for r in info if r.get("sd_over_crb") is not None]
        if ratios:
            summary["mcmc"]["sd_over_crb_determined_range"] = [float(min(ratios)), float(max(ratios))]
        timing["sampling"] = round(float(bayes.elapsed), 3)
    timing["total"] = round(time.perf_counter() - t_start, 3)
    summary["timing"] = timing
    summary["headline"] = headline(summary["cd"], summary["ml"]["mach_range_determined"], quality["ok"],
                                   None if quality["ok"] else why_not_clean(quality))
    return FitResult(summary=summary, track=track, round=rnd, options=opts, scheme1=f1, posterior=bayes,
                     log_posterior=post, grid=grid, warnings=tuple(warnings),
                     seconds=time.perf_counter() - t_start, cd_draws=cd)


def _checked(track, rnd, opts, chans, f1, grid, rows, diag, timing, ml_progress):
    """The model check of ``f1`` (:func:`~bayesdrag.model_check.model_error`) with the diagnosis
    of job ``diag`` (waited for, or made here); its times in ``timing`` (``diagnosis``: its own,
    wherever it ran; ``model_check``: the check's here, the wait included). Returns what
    ``model_error`` returns."""
    if ml_progress is not None:
        ml_progress("checking the Cd against the misfit that remains")
    t0 = time.perf_counter()
    diagnosis = diag.result()
    timing["diagnosis"] = round(diagnosis["seconds"], 3)
    timing["beside"] = (["diagnosis"] if diag.forked else []) + timing["beside"]
    out = model_error(track, rnd, opts, chans, f1, grid, rows, diagnosis=diagnosis)
    timing["model_check"] = round(time.perf_counter() - t0, 3)
    return out


def _effect_sizes_record(track, rnd, opts, chans, f1):
    """The added effects' sizes (:func:`~bayesdrag.estimate.scheme1.effect_sizes.effect_sizes`)
    and their ``seconds``, JSON-ready (for :func:`~bayesdrag._runtime.beside.started_beside`)."""
    t0 = time.perf_counter()
    return {"sizes": effect_sizes(track, rnd, chans, f1, free_ic=not opts.fix_ic, likelihood=opts.likelihood,
                                   nu=opts.ml_nu, noise_model=opts.noise_model), "seconds": time.perf_counter() - t0}


def _with_effects_record(f1, with_note, sizes, placement):
    """``ml.with_effects`` of a fit with effects: who added them and why (``with_note``; a round
    that declares ``wind_sd`` adds the wind layers itself), each added parameter's size with the
    sd the fit stands by (``sizes``), and the wind layers (with the largest spread of their
    equivalent placements, ``placement``)."""
    note = with_note if with_note is not None else {
        "added_by": "round", "requested": [], "candidates": [], "skipped": {},
        "added": {WIND_PROFILE.name: "[atmosphere] wind_sd is declared: the layers' prior"},
        "reason": "[atmosphere] wind_sd is declared: the wind layers are fitted with Cd"}
    note["fitted"] = list(f1.effects)
    note.setdefault("effects", list(f1.effects))
    note["sizes"] = sizes
    lay = _fitted_layers(f1)
    if lay is not None:
        if placement is not None:
            lay["placement_sd_max"] = placement
        note["wind_layers"] = lay
    return note


#: largest share of the Cd shift an effect's fit corrected that is kept as model error of the
#: corrected Cd: the effect's model (a constant wind, a few wind layers, one clock offset) is the
#: real effect's simplest form, and what it leaves is taken as at most a quarter of what it removed
#: (the diagnosis accepts an effect that removes >= 90 % of the gap and a size within 25 %)
EFFECT_RESIDUAL_SHARE = 0.25


def structured_power(res, channels, var):
    """The structured (correlated) part of a fit's residuals: their lag-1 autocovariance in units
    of each channel's noise variance ``var[c]``, summed over the channels (white noise and outliers
    add nothing to it on average), and the sd with which white noise alone would give it
    (``sqrt(C / n)``)."""
    p, n = 0.0, 1
    for c in channels:
        r = np.asarray(res.residuals[c], float)
        r = r[np.isfinite(r)]
        s2 = var.get(c, 0.0)
        if r.size < 3 or s2 <= 0:
            continue
        p += float(r[1:] @ r[:-1]) / (r.size - 1) / s2
        n = max(n, r.size)
    return p, float(np.sqrt(len(channels) / n))


def residual_share(plain, fitted, channels, sigma):
    """Share of an effect's correction kept as model error: the square root of the structured
    residual power the effect's fit leaves over the power it removed (the effect's model misses
    the real effect by as much as the misfit that remains says), never below what white noise
    would show (two sd of the lag-1 estimate) nor above :data:`EFFECT_RESIDUAL_SHARE`."""
    # the round's noise sd, else the plain fit's residual rms (one scale for both fits)
    var = {c: float(sigma[c]) ** 2 if sigma and sigma.get(c) else float(np.mean(np.square(plain.residuals[c])))
           for c in channels}
    before, noise = structured_power(plain, channels, var)
    after, _ = structured_power(fitted, channels, var)
    if before <= 0:
        return EFFECT_RESIDUAL_SHARE
    return float(min(EFFECT_RESIDUAL_SHARE, np.sqrt(max(after, 2.0 * noise) / before)))


def _effect_residual(rows, gap, share=EFFECT_RESIDUAL_SHARE):
    """Add ``share`` (at most :data:`EFFECT_RESIDUAL_SHARE`) of each row's correction (``ml``
    against ``ml_without_effects``) to its ``model_error_sd`` in squares, and record it in ``gap``."""
    res = [share * abs(r["ml"] - r["ml_without_effects"]) for r in rows]
    add_in_squares(rows, res)
    gap.setdefault("parts", {})["effect_residual"] = [float(f"{v:.4g}") for v in res]
    gap["effect_residual_share"] = float(f"{share:.4g}")


def _placement_error(f1, grid, rows):
    """Add the Cd spread of the wind layers' equivalent placements
    (:func:`~bayesdrag.estimate.build.winds.placement_sd`) to each row's ``model_error_sd`` in
    squares: where the track cannot tell where a wind step lies, the Cd that follows from each
    choice is as good as the kept one. Returns its largest value [Cd], or None without such
    placements."""
    from ..estimate.build.winds import placement_sd

    if not f1.layer_placements:
        return None
    sd = placement_sd(f1.drag_model, f1.layer_placements, grid)
    add_in_squares(rows, sd)
    return float(f"{float(np.max(sd)):.4g}")




def _trades_with_cd(f1, rnd):
    """Whether a fit with effects carries one that trades against Cd itself (an undeclared
    temperature offset, yaw drag), or the radar's site seen along some coordinates only (the
    others held: a chronograph's sideways offset, which the fitted coordinates then absorb for
    the wrong reason): the default does not take such a fit as its answer, the plain fit stands
    with the shift as model error (and the Cd conditional on the stated air or site)."""
    declared = rnd.systematics.declared()
    partial = RADAR_POSITION.name in f1.effects and RADAR_POSITION.name not in _wholly_fitted(f1)
    return partial or any(e in LEVEL_EFFECTS and e not in declared for e in f1.effects)


def _rigid_check(track, rnd, opts, chans, f1, grid, rows, quality):
    """A rigid model's band holds no shape error: check its curve against the flexible fit of
    the same track (:func:`check_against_flexible`). The check never refuses a track the rigid
    model fits: when the flexible fit cannot be made (a track too short for it) or does not
    converge, ``quality.rigid_check`` and a note say so and the rows stand as fitted."""
    try:
        ff = fit_scheme1(track, rnd, drag="spline", channels=chans, free_ic=not opts.fix_ic,
                         likelihood=opts.likelihood, nu=opts.ml_nu, start=f1.start, span_rule=False)
    except (InputError, FitError) as exc:
        ff, why = None, str(exc)
    else:
        why = None if ff.success else ff.message
        if why is None and ff.drag_model.name != "spline":
            why = "the track is too short for it"
    if why is not None:
        quality["rigid_check"] = {"against": "spline", "skipped": why}
        quality.setdefault("notes", []).append(
            f"the {f1.drag_model.name} curve could not be checked against the flexible fit of the same track "
            f"({why}): its band holds the noise only, not its shape error")
        return
    rows_f = cd_table(ff.ml, ff.drag_model, grid, rnd.reference_drag)
    assess(ff, rows_f, track, rnd.radar.sigma)
    check_against_flexible(rows, rows_f, quality, f1.drag_model.name)


def _with_effects(track, rnd, opts, log):
    """The effects ``--with`` asks for (``auto``: the diagnosis' verdict), checked: those that
    share a declared source's quantity or are confounded with Cd are left out with a reason.
    Returns ``(names, record, layers)``; ``record`` (``requested``, ``skipped``) is None without
    ``--with``; ``layers`` the axis of the diagnosis's ``wind_profile`` when ``auto`` names it
    (else None: the fit tries both)."""
    from ..effects import check_radar_effects
    from ..estimate.build.sources import plan_effects

    req = opts.with_effects
    if not req or req == "default":
        return (), None, None
    layers = None
    if req == "auto":
        from ..diagnosis import diagnose

        d = diagnose(track, rnd)
        names = list(d.summary["verdict"])
        if WIND_PROFILE.name in names:
            layers = _diagnosis_layers(d.summary, track, rnd)
        if log is not None:
            log(f"--with auto: the diagnosis names {', '.join(names) if names else 'no material effect'}")
    else:
        names = list(req)
        check_radar_effects(names, opts.channels or track.names, track.source or "track")
    keep, skipped = plan_effects(names, rnd)
    return keep, {"added_by": "user", "requested": req if req == "auto" else list(req), "candidates": names,
                  "skipped": skipped, "reason": "asked for with --with " + (req if req == "auto" else ",".join(req))}, \
        layers


def _diagnosis_layers(summary, track, rnd):
    """The axis of the diagnosis's ``wind_profile`` row (``altitude`` or ``downrange``; the fit
    lays its own layers on it), or None."""
    row = next((e for e in summary.get("effects", []) if e.get("name") == WIND_PROFILE.name), None)
    return ((row or {}).get("layers") or {}).get("axis")


def _fitted_layers(f1):
    """``ml.with_effects.wind_layers`` of a fit with ``wind_profile``: the axis, the edges and
    each layer's fitted wind (the round's own wind not included) with its sd [m/s]: the noise's
    bound and what the wind can do inside the layer
    (:func:`~bayesdrag.estimate.build.winds.layer_sizes`)."""
    from ..estimate.build.winds import layer_sizes

    lay = getattr(f1.problem.model, "layers", None)
    if WIND_PROFILE.name not in f1.effects or lay is None:
        return None
    res = f1.ml
    rows = layer_sizes(lay, res.names, res.theta, res.free, res.crb, res.crb_colored)
    return {"axis": lay.axis, "edges": list(lay.edges),
            "edges_unit": "m above sea level" if lay.axis == "altitude" else "m downrange from the gun",
            "wind_sd": _layers_wind_sd(f1), "layers": rows}


def _layers_wind_sd(f1):
    """The declared ``[atmosphere] wind_sd`` of the fit's layers' prior [m/s], or None."""
    sds = [p.sd for p in f1.problem.priors if p.name.startswith("wind_sd.")]
    return float(sds[0]) if sds else None


def _wholly_fitted(f1):
    """The effects of a fit whose parameters are all estimated: an effect with some held (the
    radar's site seen along one coordinate only) leaves the Cd conditional on the rest."""
    res = f1.ml
    free = {n: bool(f) for n, f in zip(res.names, res.free)}
    return {e for e in f1.effects if all(f for n, f in free.items() if n.split(".")[0] == e)}


def _budget(f1, grid, rows):
    """result.json ``uncertainty_budget`` (linearised, GUM) of the Scheme 1 fit; each ``cd`` row
    gains ``crb_sd_statistical`` (the sd with the sources held). Without declared sources the
    budget is all ``statistical`` and ``conditional_on`` lists what the Cd assumes known."""
    from ..estimate.cd.budget import budget_rows, uncertainty_budget
    from ..estimate.build.sources import assumed_record, radar_conditional
    from ..round import SYSTEMATIC_SOURCES

    res = f1.ml
    P = f1.problem.P
    idx, keys = [], []
    stems = {s[1].name: s[0] for s in f1.sources}
    for j, n in enumerate(res.names):
        if n in stems:
            idx.append(j)
            keys.append(stems[n])
        elif "." in n and n.split(".")[0] in f1.effects:
            idx.append(j)
            keys.append(n.split(".")[0])
    b = uncertainty_budget(res.cov, f1.drag_model.jacobian(grid), slice(0, P), idx, keys)
    for r, v in zip(rows, b["by_source"]["statistical"]):
        r["crb_sd_statistical"] = float(v)
    out = budget_rows(b, grid)
    declared = {s[0] for s in f1.sources}
    out["conditional_on"] = [k for k in SYSTEMATIC_SOURCES if k not in declared] + \
        radar_conditional(f1.problem.channels, declared | _wholly_fitted(f1))   # a radar's own: its native channels
    if getattr(f1.problem.model.atmosphere, "wind", None) is not None and WIND_PROFILE.name not in f1.effects:
        out["conditional_on"].append("wind_profile")    # the round's winds, held as stated
    assumed = assumed_record(declared)
    if assumed:
        out["assumed"] = assumed
    return out


def _ml_summary(f1, rows, quality, lo, hi, opts):
    """The ``scheme``, ``drag_model``, ``ml`` and ``cd`` parts of result.json."""
    res = f1.ml
    det = determined_range(rows)
    free = [n for n, f in zip(res.names, res.free) if f]
    smoothing = None
    if f1.smoothing:
        smoothing = {k: v for k, v in f1.smoothing.items() if isinstance(v, (int, float, str))}
    return {
        "scheme": 1, "drag_model": f1.drag_model.name,
        "ml": {"params": res.params,
               "crb": {n: float(s) for n, s, f in zip(res.names, res.crb, res.free) if f},
               "crb_colored": {n: float(s) for n, s, f in zip(res.names, res.crb_colored, res.free) if f},
               "fixed": [n for n in res.names if n not in free],
               "converged": res.converged, "iterations": res.iterations, "cost": res.cost,
               "message": res.message, "sigma": res.sigma,
               "rms": {c: float(np.sqrt(np.mean(r**2))) for c, r in res.residuals.items()},
               "warnings": list(res.warnings),
               "mach_range_data": [lo, hi], "mach_range_determined": list(det) if det else None,
               "likelihood": opts.likelihood, "rejected_samples": f1.rejected, "smoothing": smoothing,
               "model_size": dict(f1.model_size) or None, "noise": noise_record(f1.noise, res),
               "quality": quality},
        "cd": rows,
    }


def _fit_scheme2(track, rnd, opts, chans, log, t_start):
    """Scheme 2: ML per window, then (with sampling) the same posterior in each window (Cd,
    initial state, noise). Windows are sampled one after the other: each window's batch already
    runs on both cores (numba threads); a process pool would only add start-up and contention on
    a 2-core machine. Scheme 2 chains are kept in memory (one window takes a few seconds)."""
    from ..estimate.bayes.posterior import LogPosterior
    from ..estimate.build.sources import radar_conditional
    from ..estimate.bayes.sampler import sample_posterior

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
                           r_hat_max=float(b.summary["r_hat"].max()), ess_bulk_min=float(b.summary["ess_bulk"].min()),
                           mcmc_converged=b.converged, steps=b.steps)
            draws[k] = cd
            if not b.converged:
                warnings.append(FitWarning("sampler", f"window {k}: {b.message}"))
            if log:
                log(f"window {k + 1}/{len(rows)} (Mach {rows[k]['mach']:.2f}): {b.message}")
    budget = _window_budget(rows, ok, draws, rnd, opts.seed)
    budget["conditional_on"] += radar_conditional(chans or track.names, ())   # windows fit no radar source
    mach = np.array([w["mach"] for w in rows])
    lo, hi = float(min(w["mach_min"] for w in rows)), float(max(w["mach_max"] for w in rows))
    grid = np.round(np.linspace(lo, hi, 81), 4)
    cd_rows, quality = _stitched_rows(rows, ok, mach, grid, rnd, bool(draws))
    warnings += quality["problems"]
    summary = {"scheme": 2, "drag_model": "constant per window", "window": opts.window,
               "ml": {"converged": all(r.converged for r in r2.results), "windows_converged": len(ok),
                      "windows": len(rows), "notes": list(r2.notes) + _scheme2_effects_note(opts, quality),
                      "quality": quality},
               "cd": cd_rows, "windows": rows, "uncertainty_budget": budget}
    if draws:
        summary["mcmc"] = {"windows_converged": int(sum(rows[k]["mcmc_converged"] for k in ok)),
                           "r_hat_max": float(max(rows[k]["r_hat_max"] for k in ok))}
    det = determined_range(cd_rows)
    summary["headline"] = headline(cd_rows, det, quality["ok"],
                                   "; ".join(str(p) for p in quality["problems"][:1]) or None)
    return FitResult(summary=summary, track=track, round=rnd, options=opts, scheme2=r2,
                     window_draws=draws or None, windows_ok=tuple(ok), grid=grid, warnings=tuple(warnings),
                     seconds=time.perf_counter() - t_start)



def _scheme2_effects_note(opts, quality):
    """Scheme 2 takes no effects (a window's constant Cd cannot carry them): with the default
    ``--with``, a note says the search for the cause of a missed window was skipped."""
    if opts.with_effects != "default" or quality["ok"]:
        return []
    return ["Scheme 2 fits no effects: the default search for the cause of a missed window is skipped "
            "(Scheme 1 with the default --with, or bayesdrag diagnose, finds it)"]

def _window_budget(rows, ok, draws, rnd, seed):
    """Scheme 2's budget: the declared level sources (density, mass, diameter: one factor on
    every window's Cd) added to each window's bound and, by Monte Carlo (an independent factor
    per draw), to its posterior draws; the windows stay conditional on the other sources.
    Window rows gain ``crb_sd_statistical``; ``crb_sd`` becomes the total."""
    from ..estimate.cd.budget import level_shares

    rel, cond = level_shares(rnd)
    s_rel = float(np.sqrt(sum(v * v for v in rel.values())))
    by = {"statistical": [], **{k: [] for k in rel}, "cross": []}
    total = []
    rng = np.random.default_rng(None if seed is None else seed + 10_000)
    for k, r in enumerate(rows):
        stat = float(r["crb_sd"]) if r.get("crb_sd") is not None else float("nan")
        cd = float(r["ml"]) if r.get("ml") is not None else float("nan")
        r["crb_sd_statistical"] = stat
        tot = float(np.sqrt(stat ** 2 + (s_rel * cd) ** 2))
        r["crb_sd"] = tot
        by["statistical"].append(stat)
        for n, v in rel.items():
            by[n].append(abs(cd) * v)
        by["cross"].append(0.0)
        total.append(tot)
        if k in draws and s_rel > 0:
            d = draws[k]
            d = d * (1.0 + s_rel * rng.standard_normal(d.shape))
            draws[k] = d
            flat = d.reshape(-1)
            q = np.quantile(flat, [0.05, 0.5, 0.95])
            r.update(mean=float(flat.mean()), sd=float(flat.std(ddof=1)), q05=float(q[0]), q50=float(q[1]),
                     q95=float(q[2]), sd_over_crb=float(flat.std(ddof=1) / tot) if tot else None)
    r6 = lambda a: [float(f"{v:.6g}") for v in a]  # noqa: E731
    return {"mach": [round(float(r["mach"]), 4) for r in rows], "total_sd": r6(total),
            "by_source": {k: r6(v) for k, v in by.items()}, "conditional_on": cond,
            "note": "windows: the level sources (density, mass, diameter) are included; conditional on "
                    + (", ".join(cond) if cond else "nothing")}


def _stitched_rows(rows, ok, mach, grid, rnd, sampled):
    """Scheme 2's ``cd`` rows on a Mach grid through the windows, and its ``ml.quality``: a grid
    point is determined when the windows on both sides of it are."""
    order = np.argsort(mach[ok])
    mk = mach[ok][order]

    def interp(key):
        v = np.array([rows[k][key] for k in ok], float)[order]
        return np.interp(grid, mk, v)

    cols = {key: interp(key) for key in ("ml", "crb_sd", "band_sd") + (("mean", "q05", "q95") if sampled else ())}
    det_w = np.array([rows[k]["determined"] for k in ok], bool)[order]
    j_hi = np.clip(np.searchsorted(mk, grid), 0, len(mk) - 1)
    j_lo = np.clip(j_hi - 1, 0, len(mk) - 1)
    inside = (grid >= mk[0]) & (grid <= mk[-1])
    cd_rows = []
    for i, m in enumerate(grid):
        r = {key: float(v[i]) for key, v in cols.items()}
        r["mach"] = float(m)
        r["determined"] = bool(inside[i] and det_w[j_lo[i]] and det_w[j_hi[i]])
        r["reference"] = float(rnd.reference_drag.value(m)) if rnd.reference_drag is not None else None
        cd_rows.append(r)
    problems = [p.within(f"window {k} (Mach {rows[k]['mach']:.2f}): ") for k in ok for p in rows[k]["quality"]["problems"]]
    quality = {"ok": not problems and len(ok) == len(rows),
               "undetermined": intervals(grid, ~np.array([r["determined"] for r in cd_rows])),
               "windows_determined": int(det_w.sum()), "problems": problems}
    return cd_rows, quality


def summary_line(result):
    """The outcome the command prints: converged, determined range, caveat and next step, and a
    second line on the air when the Cd is conditional on it or the track contradicts it."""
    s = result.record
    if s["scheme"] == 2:
        m = s["ml"]
        lo, hi = s["cd"][0]["mach"], s["cd"][-1]["mach"]
        return (f"fit (Scheme 2): {m['windows_converged']}/{m['windows']} windows of {s['window']} samples "
                f"converged, Mach {lo:.2f}-{hi:.2f}")
    ml = s["ml"]
    det = ml["mach_range_determined"]
    caveat = "" if ml["quality"]["ok"] else f" -- NOT a clean answer: {why_not_clean(ml['quality'])}"
    head = (f"fit: {ml['message']} in {ml['iterations']} iterations; Cd determined over "
            f"{determined_words(det, ml['quality'].get('undetermined', []))}"
            if det else f"fit: {ml['message']}; Cd nowhere determined to 1 %")
    out = ml["quality"].get("outliers")
    if out:         # the noise model took one-sided outliers (estimate.model.contamination)
        head += "; one-sided outliers down-weighted: " + ", ".join(
            f"{len(e.get('down_weighted', []))} {e['side']} {c} samples" for c, e in out["channels"].items())
    air = (ml["quality"].get("air") or {})
    return head + caveat + (f"\nair: {air['line']}" if air.get("line") else "")


def diagnose(track: RadarTrack, rnd: Round, options: DiagnoseOptions | None = None, **kwargs: Any) -> DiagnosisResult:
    """Diagnose the gap between a track and the nominal simulation of its round: where the
    simulation misses, which unmodelled effect explains it, how large it is and whether it
    matters (material).

    Parameters
    ----------
    track : RadarTrack
    rnd : Round
    options : DiagnoseOptions, optional
        Keyword arguments (``channels=("x", "z", "v")``, ``material_cd_shift=0.002``) override
        single fields.

    Returns
    -------
    DiagnosisResult
        ``verdict``, ``paragraph``, ``summary()``, ``to_dataframe()`` (the candidate effects),
        ``to_dict()`` (``diagnosis.json``), ``write(DIR)``.
    """
    from ..diagnosis import MIN_DIAGNOSIS_SAMPLES
    from ..diagnosis import diagnose as analyse
    from ..diagnosis.summary import summary_paragraph
    from ..estimate.build.model_size import check_constant_channels
    from ..estimate.build.start import check_heights

    opts = options if options is not None else DiagnoseOptions()
    track = thin_for_fit(track)           # a very dense track: every k-th sample, with a note
    if kwargs:
        opts = DiagnoseOptions(**{**opts.__dict__, **kwargs})
    if track.n < MIN_DIAGNOSIS_SAMPLES:
        raise InputError(f"{track.source or 'track'}: {track.n} samples are too few for a diagnosis "
                         f"(need >= {MIN_DIAGNOSIS_SAMPLES})")
    check_heights(track, rnd)
    check_constant_channels(track, tuple(opts.channels) if opts.channels else track.names)
    d = analyse(track, rnd, channels=opts.channels, alpha=opts.alpha, material_cd_shift=opts.material_cd_shift,
                material_end_sd=opts.material_end_sd)
    record = dict(d.summary, summary=summary_paragraph(d.summary))     # what diagnosis.json holds
    return DiagnosisResult(record, d, track, rnd)
