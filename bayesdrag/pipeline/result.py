"""Stage 6 of a fit, *result*: the frozen :class:`~bayesdrag.results.FitResult` of a Scheme 1
fit (``result.json``'s record: the ML part, the claimed rows, the budget folded to add up to each
row's band, the added effects' sizes, the sampled columns, the timing and the headline), and the
outcome line the command prints (:func:`outcome_line`)."""
from __future__ import annotations

import time

import numpy as np

from .._runtime.renamed import renamed_getattr
from ..results.words import outcome_line, why_not_clean
from ..estimate.cd.headline import headline
from ..estimate.cd.model_error import fold_into_budget
from ..estimate.cd.table import determined_range
from ..estimate.scheme1.fit import noise_record
from ..effects import WIND_PROFILE
from ..results import FitResult
from .check import Checked, effect_sizes_record
from .model_check import clock_note
from .preparation import Prepared
from .sampling import mcmc_json, posterior_json, sampled_rows

__all__ = ["result_stage", "with_effects_record", "fitted_layers", "layers_wind_sd", "ml_record", "outcome_line"]


def result_stage(prep: Prepared, chk: Checked, quality, placement, bayes, post, timing, t_start):
    """The :class:`~bayesdrag.results.FitResult` of the claimed answer ``chk`` with its
    ``quality`` (:func:`~.claim.claim_stage`), the sampler's ``bayes`` and ``post`` (None without
    sampling) and the stages' ``timing`` [s] since ``t_start``."""
    track, rnd, opts = prep.track, prep.rnd, prep.opts
    ans, with_note, sizes_job = chk.answer, chk.with_note, chk.sizes_job
    f1, grid, rows, budget = ans.f1, ans.grid, ans.rows, ans.budget
    res = f1.ml
    cd = sizes = None
    record = ml_record(f1, rows, quality, ans.lo, ans.hi, opts)
    record["uncertainty_budget"] = budget
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
            made = effect_sizes_record(f1)
            sizes, timing["effect_sizes"] = made["sizes"], round(made["seconds"], 3)
        record["ml"]["with_effects"] = with_effects_record(f1, with_note, sizes, placement)
    if ans.floored:
        budget["model_error_floor"] = [float(f"{r['model_error_floor']:.6g}") for r in rows]
    nm = [r.get("noise_model_sd", 0.0) for r in rows]
    if any(v > 0 for v in nm):
        # the ar1 noise's own uncertainty (noise_spread), statistical but shown apart
        budget["by_source"]["noise_model"] = [float(f"{v:.6g}") for v in nm]
    fold_into_budget(budget, rows)
    # what the Cd is conditional on is one line of the report and uncertainty_budget.conditional_on
    warnings = [w for w in res.warnings if w.kind != "at_bound"] + list(quality["problems"])
    warnings += clock_note(record["ml"])
    if opts.mcmc:
        rows, cd = sampled_rows(bayes, f1, rows, grid)
        record["cd"] = rows
        record["posterior"] = posterior_json(bayes)
        record["mcmc"] = mcmc_json(bayes, post)
        warnings += list(bayes.warnings)
        info = [r for r in rows if r["crb_sd"] > 0 and r["ml"] > 0 and r["crb_sd"] / r["ml"] < 0.01]
        ratios = [r["sd_over_crb"] for r in info if r.get("sd_over_crb") is not None]
        if ratios:
            record["mcmc"]["sd_over_crb_determined_range"] = [float(min(ratios)), float(max(ratios))]
        timing["sampling"] = round(float(bayes.elapsed), 3)
    timing["total"] = round(time.perf_counter() - t_start, 3)
    record["timing"] = timing
    record["headline"] = headline(record["cd"], record["ml"]["mach_range_determined"], quality["ok"],
                                   None if quality["ok"] else why_not_clean(quality))
    return FitResult(record=record, track=track, round=rnd, options=opts, scheme1=f1, posterior=bayes,
                     log_posterior=post, grid=grid, warnings=tuple(warnings),
                     seconds=time.perf_counter() - t_start, cd_draws=cd)


def with_effects_record(f1, with_note, sizes, placement):
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
    lay = fitted_layers(f1)
    if lay is not None:
        if placement is not None:
            lay["placement_sd_max"] = placement
        note["wind_layers"] = lay
    return note


def fitted_layers(f1):
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
            "wind_sd": layers_wind_sd(f1), "layers": rows}


def layers_wind_sd(f1):
    """The declared ``[atmosphere] wind_sd`` of the fit's layers' prior [m/s], or None."""
    sds = [p.sd for p in f1.problem.priors if p.name.startswith("wind_sd.")]
    return float(sds[0]) if sds else None


def ml_record(f1, rows, quality, lo, hi, opts):
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

#: old names, kept with a warning until release 0.3
__getattr__ = renamed_getattr(__name__, {"summary_line": "outcome_line", "ml_summary": "ml_record"}, globals())
