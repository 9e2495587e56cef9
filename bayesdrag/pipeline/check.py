"""Stage 3 of a fit, *the model check*: the default fit checks its own Cd against the misfit
that remains (:mod:`.model_check`: the diagnosis's undeclared material effects fitted, a robust
or white fit of the noise), and where the check's fit with those effects is the better answer
the default takes it (the plain Cd stays beside it as ``ml_without_effects``).

The two places a fit's work runs in a forked helper process (:mod:`bayesdrag._runtime.beside`)
are here: the check's diagnosis beside the ML fit (:func:`diagnosis_beside`) and the added
effects' split fits beside everything after the answer is known (:func:`sizes_beside`).
"""
from __future__ import annotations

import functools
import time
from dataclasses import dataclass

import numpy as np

from .._runtime.beside import started_beside
from ..estimate.cd.claims import BandTerm, add_model_error
from ..estimate.scheme1.effect_sizes import effect_sizes
from ..effects import RADAR_POSITION
from .ml import Answer, answer_of, wholly_fitted
from .model_check import LEVEL_EFFECTS, alternative_error, diagnosis_record, model_error
from .preparation import Prepared

__all__ = ["Checked", "check_stage", "checked", "diagnosis_beside", "sizes_beside", "effect_sizes_record",
           "EFFECT_RESIDUAL_SHARE", "EFFECT_RESIDUAL_TERM", "structured_power", "residual_share", "effect_residual", "trades_with_cd"]


@dataclass(frozen=True)
class Checked:
    """What the model check leaves for the later stages.

    Attributes
    ----------
    answer : Answer
        The plain fit's, or the check's fit with the effects it found (the default's answer).
    gap : dict or None
        ``ml.quality.model_error`` (None: no check yet, or none asked for).
    with_note : dict or None
        Who added the answer's effects and why (``ml.with_effects``).
    sizes_job : BesideJob or None
        The added effects' split fits, running (:func:`sizes_beside`).
    deferred : bool
        The check is made after the sampling (it cannot change what is sampled).
    """

    answer: Answer
    gap: dict | None
    with_note: dict | None
    sizes_job: object = None
    deferred: bool = False


def diagnosis_beside(prep: Prepared, fork: bool):
    """The check's diagnosis (:func:`~.model_check.diagnosis_record`: it reads the track and the
    round only) started in a forked process beside the ML fit: a ``with`` context yielding its
    :class:`~bayesdrag._runtime.beside.BesideJob`."""
    return started_beside(functools.partial(diagnosis_record, prep.track, prep.rnd, prep.chans), fork=fork)


def sizes_beside(later, prep: Prepared, fit):
    """The added effects' sizes (their split fits, :func:`effect_sizes_record`) started in a
    forked process, entered on the exit stack ``later``: they change nothing the fit does after,
    so they run from the moment the fit with the effects is the answer. None without effects."""
    if later is None or not fit.effects:
        return None
    return later.enter_context(started_beside(
        functools.partial(effect_sizes_record, fit), fork=True))


def check_stage(prep: Prepared, ans: Answer, diag, timing, ml_progress, with_note, later) -> Checked:
    """The model check of the ML fit's answer ``ans`` with the diagnosis of job ``diag`` (None:
    no check), its times in ``timing``; the default's answer replaced by the check's fit with the
    undeclared material effects unless one of them trades with Cd (:func:`trades_with_cd`)."""
    track, rnd, opts, chans = prep.track, prep.rnd, prep.opts, prep.chans
    f1, grid, rows = ans.f1, ans.grid, ans.rows
    gap = effects_fit = None
    sizes_job = None
    default = opts.with_effects == "default"
    # effects the user names are fitted, and the misfit they leave is checked like any other (an
    # effect named is not the only one the day had). Only the default takes the check's fit as its
    # answer: otherwise the check cannot change what is sampled, and it is made after the sampling
    deferred = diag is not None and opts.mcmc and not default
    if diag is not None and not deferred:
        gap, effects_fit = checked(track, rnd, opts, chans, f1, grid, rows, diag, timing, ml_progress)
    if default and effects_fit is not None and effects_fit.effects and not trades_with_cd(effects_fit, rnd):
        # the default fit fits the cause: the check's fit with the undeclared material effects
        # (already made, from the plain fit's start) is the answer; the plain Cd stays beside it
        t0 = time.perf_counter()
        plain, f1 = f1, effects_fit
        sizes_job = sizes_beside(later, prep, f1)
        ans = answer_of(f1, rnd, (plain.drag_model, plain.ml.drag_params))
        grid, rows = ans.grid, ans.rows
        found = gap
        gap, _ = model_error(track, rnd, opts, chans, f1, grid, rows, diagnose_effects=False, plain=plain)
        gap.update(verdict=found["verdict"], skipped=found["skipped"], conditional_air=found["conditional_air"],
                   effects_fitted=list(f1.effects))
        effect_residual(rows, gap, residual_share(plain.ml, f1.ml, f1.problem.channels, rnd.radar.sigma))
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
    if sizes_job is None:
        sizes_job = sizes_beside(later, prep, f1)
    return Checked(ans, gap, with_note, sizes_job, deferred)


def checked(track, rnd, opts, chans, f1, grid, rows, diag, timing, ml_progress):
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


def effect_sizes_record(f1):
    """The added effects' sizes (:func:`~bayesdrag.estimate.scheme1.effect_sizes.effect_sizes`)
    and their ``seconds``, JSON-ready (for :func:`~bayesdrag._runtime.beside.started_beside`)."""
    t0 = time.perf_counter()
    return {"sizes": effect_sizes(f1), "seconds": time.perf_counter() - t0}


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


#: what an added effect's simple form (a constant wind, a few layers, one clock offset) leaves
EFFECT_RESIDUAL_TERM = BandTerm("effect_residual", why="what an added effect's simple form leaves of the real one")


def effect_residual(rows, gap, share=EFFECT_RESIDUAL_SHARE):
    """Add ``share`` (at most :data:`EFFECT_RESIDUAL_SHARE`) of each row's correction (``ml``
    against ``ml_without_effects``) to its ``model_error_sd`` in squares, and record it in ``gap``."""
    res = [share * abs(r["ml"] - r["ml_without_effects"]) for r in rows]
    add_model_error(rows, EFFECT_RESIDUAL_TERM, res)
    gap.setdefault("parts", {})["effect_residual"] = [float(f"{v:.4g}") for v in res]
    gap["effect_residual_share"] = float(f"{share:.4g}")


def trades_with_cd(f1, rnd):
    """Whether a fit with effects carries one that trades against Cd itself (an undeclared
    temperature offset, yaw drag), or the radar's site seen along some coordinates only (the
    others held: a chronograph's sideways offset, which the fitted coordinates then absorb for
    the wrong reason): the default does not take such a fit as its answer, the plain fit stands
    with the shift as model error (and the Cd conditional on the stated air or site)."""
    declared = rnd.systematics.declared()
    partial = RADAR_POSITION.name in f1.effects and RADAR_POSITION.name not in wholly_fitted(f1)
    return partial or any(e in LEVEL_EFFECTS and e not in declared for e in f1.effects)

