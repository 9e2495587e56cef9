"""Stage 2 of a fit, *the ML fit*: the Scheme 1 maximum-likelihood fit with the effects
``--with`` asks for, and its :class:`Answer` (the Cd rows on the flown Mach grid, the
uncertainty budget, the AR(1) noise's floor). The model check may replace the answer with its
fit carrying the effects it finds (:mod:`.check`)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import FitError
from ..estimate.cd.table import cd_grid, cd_table, model_error_floor
from ..estimate.scheme1.fit import fit_scheme1
from ..effects import WIND_PROFILE
from .preparation import Prepared

__all__ = ["Answer", "answer_of", "ml_stage", "requested_effects", "wholly_fitted", "budget_of"]


@dataclass(frozen=True)
class Answer:
    """The fit whose Cd is the answer and what is read off it before the band is claimed.

    Attributes
    ----------
    f1 : Scheme1Fit
    grid : (M,) ndarray
        The rows' Mach numbers (:func:`~bayesdrag.estimate.cd.table.cd_grid` of the flown span).
    rows : list of dict
        The ``cd`` rows (:func:`~bayesdrag.estimate.cd.table.cd_table`); the later stages add
        their terms to them.
    budget : dict
        ``uncertainty_budget`` as linearised (:func:`budget_of`).
    floored : bool
        Whether the AR(1) noise's floor was applied (:func:`~bayesdrag.estimate.cd.table.model_error_floor`).
    lo, hi : float
        The flown Mach span.
    """

    f1: object
    grid: np.ndarray
    rows: list
    budget: dict
    floored: bool
    lo: float
    hi: float


def answer_of(f1, rnd, without=None):
    """The :class:`Answer` of fit ``f1``; ``without`` = ``(drag_model, drag_params)`` of the fit
    without its effects, whose Cd each row keeps as ``ml_without_effects`` (None: none)."""
    res, dm = f1.ml, f1.drag_model
    lo, hi = float(np.min(res.mach)), float(np.max(res.mach))
    grid = cd_grid(lo, hi)
    rows = cd_table(res, dm, grid, rnd.reference_drag)
    if without is not None:
        for r, v in zip(rows, without[0].cd(without[1], grid)):
            r["ml_without_effects"] = float(v)
    budget = budget_of(f1, grid, rows)
    floored = model_error_floor(f1, rows)
    return Answer(f1, grid, rows, budget, floored, lo, hi)


def ml_stage(prep: Prepared, log, ml_progress):
    """The ML fit of :class:`~.preparation.Prepared` ``prep`` with the effects ``--with`` asks for:
    ``(Answer, with_note)``, ``with_note`` the record of the effects asked for (None without
    ``--with``).

    Raises
    ------
    FitError
        The fit found no solution (its message says why).
    """
    track, rnd, opts = prep.track, prep.rnd, prep.opts
    with_effects, with_note, layers = requested_effects(track, rnd, opts, log)
    f1 = fit_scheme1(track, rnd, drag=opts.drag, channels=prep.chans, free_ic=not opts.fix_ic,
                     likelihood=opts.likelihood, nu=opts.ml_nu, noise_model=opts.noise_model,
                     with_effects=with_effects, progress=ml_progress, wind_layers=layers)
    if not f1.ml.success:
        raise FitError(f"{track.source or 'track'}: {f1.ml.message}")
    without = None if f1.ml_without_effects is None else (f1.drag_model, f1.ml_without_effects.drag_params)
    return answer_of(f1, rnd, without), with_note


def requested_effects(track, rnd, opts, log):
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
        names = list(d.record["verdict"])
        if WIND_PROFILE.name in names:
            layers = diagnosis_layers(d.record, track, rnd)
        if log is not None:
            log(f"--with auto: the diagnosis names {', '.join(names) if names else 'no material effect'}")
    else:
        names = list(req)
        check_radar_effects(names, opts.channels or track.names, track.source or "track")
    keep, skipped = plan_effects(names, rnd)
    return keep, {"added_by": "user", "requested": req if req == "auto" else list(req), "candidates": names,
                  "skipped": skipped, "reason": "asked for with --with " + (req if req == "auto" else ",".join(req))}, \
        layers


def diagnosis_layers(record, track, rnd):
    """The axis of the diagnosis's ``wind_profile`` row (``altitude`` or ``downrange``; the fit
    lays its own layers on it), or None."""
    row = next((e for e in record.get("effects", []) if e.get("name") == WIND_PROFILE.name), None)
    return ((row or {}).get("layers") or {}).get("axis")


def wholly_fitted(f1):
    """The effects of a fit whose parameters are all estimated: an effect with some held (the
    radar's site seen along one coordinate only) leaves the Cd conditional on the rest."""
    res = f1.ml
    free = {n: bool(f) for n, f in zip(res.names, res.free)}
    return {e for e in f1.effects if all(f for n, f in free.items() if n.split(".")[0] == e)}


def budget_of(f1, grid, rows):
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
        radar_conditional(f1.problem.channels, declared | wholly_fitted(f1))   # a radar's own: its native channels
    if getattr(f1.problem.model.atmosphere, "wind", None) is not None and WIND_PROFILE.name not in f1.effects:
        out["conditional_on"].append("wind_profile")    # the round's winds, held as stated
    assumed = assumed_record(declared)
    if assumed:
        out["assumed"] = assumed
    return out

