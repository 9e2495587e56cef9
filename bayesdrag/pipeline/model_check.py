"""The checks a default fit makes of its own Cd: the model error of the misfit that remains
(:mod:`bayesdrag.estimate.cd.model_error`: the diagnosis's material effects fitted, a robust
fit where the noise is correlated or has gross outliers), what the Cd assumes of the air, and
the reason and next step the outcome line of a not-clean answer gives."""
from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from ..errors import FitError, FitWarning, InputError
from ..estimate.cd.claims import BandTerm, add_model_error, set_model_error
from ..results.words import CHECK_NAMES, NOISE_FREE_SD, SITE_NOT_GIVEN, why_not_clean
from ..estimate.cd.model_error import check_sd, describe, shift_sd
from ..estimate.cd.quality import assess
from ..estimate.cd.table import cd_table, model_error_floor
from ..estimate.scheme1.fit import fit_scheme1
from ..estimate.build.winds import WIND_AXES
from .ml import diagnosis_layers
from ..effects import DENSITY, DRAG_SHAPE, EFFECTS, RADAR_POSITION, RADAR_TIME, TEMPERATURE, WIND_PROFILE, \
    YAW_DRAG, air_state_effects, not_alternatives, partly_trading_with_cd

__all__ = ["air_contradiction", "air_measured", "own_table", "model_error", "diagnosis_record", "close_alternative", "shape_confounded", "alternative_error", "note_model_error", "air", "why_not_clean", "clock_note", "level_shift",
           "gross_outliers", "withdrawn_by_check", "CHECK_TERMS", "AIR_CONTRADICTION_SD", "NOISE_FREE_SD", "LEVEL_EFFECTS"]


#: the model-error terms the check sizes (``ml.quality.model_error.parts``)
EFFECTS_TERM = BandTerm("effects", why="the Cd shift of the undeclared material effects the check fits")
SHAPE_TERM = BandTerm("shape_confounded", why="a table's shape the data cannot tell from a decaying yaw")
ALTERNATIVE_TERM = BandTerm("alternative", why="the Cd of a close alternative explanation")
NOISE_TERM = BandTerm("noise", why="a robust or white-noise fit of the same track")
CHECK_TERMS = (EFFECTS_TERM, SHAPE_TERM, ALTERNATIVE_TERM, NOISE_TERM)


def model_error(track, rnd, opts, chans, f1, grid, rows, *, diagnose_effects=True, plain=None, diagnosis=None):
    """The model-error term of each row (:mod:`bayesdrag.estimate.cd.model_error`): the Cd shift
    of the material effects the diagnosis finds and the round does not declare (fitted), and of
    a robust fit where the noise is not white or has gross outliers. Sets each row's
    ``model_error_sd``; returns the record of ``ml.quality.model_error`` and the fit with the
    effects (a ``Scheme1Fit``, or None when none is found or it fails), which the default fit
    takes as its answer (:func:`bayesdrag.pipeline.fit`). ``diagnose_effects=False`` makes the
    noise check only (the fit already carries the effects); ``plain`` is then the fit without
    them that ``f1`` was made from, whose stages its check shares (:func:`_from_plain`).
    ``diagnosis``: the :func:`diagnosis_record` of the track, when it was made already (it reads
    the track and the round only: the pipeline makes it beside the ML fit)."""
    from ..estimate.build.sources import plan_effects

    ml = np.array([r["ml"] for r in rows], float)
    band = np.array([max(r["crb_sd"], r.get("crb_sd_colored", r["crb_sd"])) for r in rows], float)
    rec = {"effects": [], "skipped": {}, "conditional_air": [], "noise_check": None}
    parts = {}
    verdict, shifts, profiles, effects_fit = [], {}, {}, None
    if diagnose_effects:              # else the fit carries the effects: the caller records them
        d = diagnosis if diagnosis is not None else diagnosis_record(track, rnd, chans)
        if "record" in d:
            dsum = d["record"]
            verdict = list(dsum["verdict"])
            shifts = {e["name"]: e.get("cd_shift_max") for e in dsum.get("effects", [])}
            profiles = {e["name"]: e["cd_shift"] for e in dsum.get("effects", [])
                        if isinstance(e.get("cd_shift"), dict) and e["cd_shift"].get("mach")}
        elif "skipped" in d:
            rec["diagnosis_skipped"] = d["skipped"]
        else:
            rec["diagnosis_failed"] = d["failed"]
    keep, skipped = plan_effects(verdict, rnd)
    rec["verdict"], rec["skipped"] = verdict, skipped
    if RADAR_POSITION.name in keep and not any(rnd.radar.position) and rnd.radar.position_sd is None:
        # the site defaulted to the muzzle: the fitted site's own Cd shift cannot size what the
        # wrong site did to every radar channel, so the reason says the site is missing instead
        rec["site_not_given"] = True
    rec["conditional_air"] = [n for n in verdict if n in air_state_effects()]
    carried = tuple(f1.effects) if diagnose_effects else ()
    if carried:
        # the effects the user named are fitted already: no model error of this fit, and no advice
        # to add them; the check's fit carries them beside what the diagnosis adds
        rec["effects_fitted"] = list(carried)
        keep = tuple(n for n in keep if n not in carried)
    if keep:
        # a wind profile on the axis the diagnosis's evidence chose (as ``--with auto`` fits it);
        # the other axis only when that fit fails (as a fit trying both would keep it)
        axis = diagnosis_layers(dsum, track, rnd) if WIND_PROFILE.name in keep and diagnose_effects and verdict else None
        alt = None
        for layers in ((axis,) + tuple(a for a in WIND_AXES if a != axis) if axis else (None,)):
            alt = _alt_rows(track, rnd, opts, chans, f1, grid, with_effects=carried + tuple(keep),
                            **({"wind_layers": layers} if layers else {}))
            if alt is not None:
                break
        if alt is not None and (f1.model_size or {}).get("narrow_span") and not own_table(rnd) \
                and aliased_with_cd(band, alt[1]):
            # one factor over a narrow span cannot be told from them (their fit beside it leaves Cd
            # undetermined) and the table is not this projectile's: Cd is the flight's effective
            # drag, them included (a long flight's effect confounded with Cd stays model error)
            rec["absorbed_in_cd"], keep = list(keep), ()
        elif alt is not None:
            parts["effects"] = shift_sd(ml, band, alt[0], alt[1])
            effects_fit = alt[2]
            confounded = level_shift(grid, ml, profiles, [n for n in keep if n in LEVEL_EFFECTS])
            if confounded is not None:
                # an effect that trades with Cd: its fit with Cd free cannot size it, the
                # diagnosis (against the firing table) can; the larger of the two stands
                parts["effects"] = np.maximum(parts["effects"], confounded)
                rec["effects_sized_by_diagnosis"] = [n for n in keep if n in LEVEL_EFFECTS and n in profiles]
        else:
            # the effect could not be fitted with Cd: the diagnosis's own largest Cd shift of each,
            # taken at every row (a bound where the fit cannot say where along the flight)
            rel = [shifts.get(n) for n in keep]
            rec["effects_from"] = "the diagnosis's Cd shift (the fit with the effects failed or dropped them)"
            if all(r is not None for r in rel):
                parts["effects"] = np.full(ml.size, math.sqrt(sum(r**2 for r in rel))) * np.abs(ml)
            else:
                rec["unsized"] = [n for n, r in zip(keep, rel) if r is None]   # no size: no row is claimed
        rec["effects"] = list(keep)
    hidden = shape_confounded(dsum, verdict) if diagnose_effects and verdict else []
    if hidden:
        # the verdict's drag shape is Cd itself (nothing to add), but the data cannot tell it from
        # a decaying yaw's drag, which would put the Cd of the first seconds elsewhere: its shift
        # as the diagnosis sized it is model error
        sized = level_shift(grid, ml, profiles, hidden)
        if sized is not None:
            parts["shape_confounded"] = sized
            rec["shape_confounded"] = hidden
    if keep and diagnose_effects and verdict:
        other = close_alternative(dsum, keep, rnd)
        if other is not None:
            names, instead_of, ratio = other
            alt2 = _alt_rows(track, rnd, opts, chans, f1, grid, with_effects=carried + names)
            rec["alternative"] = {"effects": list(names), "instead_of": instead_of, "gap_ratio": float(f"{ratio:.3g}")}
            if alt2 is not None:
                # the answer must hold under either explanation: its shift to this one is model
                # error too (for the plain answer here; the default's answer, the verdict's fit,
                # adds its own shift to it: alternative_error)
                parts["alternative"] = shift_sd(ml, band, alt2[0], alt2[1])
                rec["alternative"].update(mach=[float(f"{v:.6g}") for v in grid],
                                          cd=[float(f"{v:.6g}") for v in alt2[0]],
                                          band_sd=[float(f"{v:.4g}") for v in alt2[1]])
            else:
                rec["alternative"]["failed"] = True
                rec["unsized"] = rec.get("unsized", []) + list(names)     # no size: no row is claimed
    noisy = f1.white_ml is not None or opts.noise_model == "ar1"
    flagged = 0
    if opts.likelihood == "gaussian":
        flagged = gross_outliers(track, f1, rnd.radar.sigma)
    if opts.likelihood == "gaussian" and flagged:
        # gross outliers: a Student-t fit (white, outliers reweighted) is the check
        alt = _alt_rows(track, rnd, opts, chans, f1, grid, likelihood="student-t", **_same_effects(f1))
        if alt is not None:
            # the reported fit's sd is its band (an AR(1) fit's floored at the white fit's sd: its
            # own bound trusts the AR(1) form, which a rho near 1 hides)
            parts["noise"] = check_sd(ml, band, alt[0], alt[1])
            rec["noise_check"] = {"why": "gross outliers" + (" and correlated (AR(1)) residuals" if noisy else ""),
                                  "against": "student-t", "outlier_samples": flagged}
    elif f1.white_ml is not None and diagnose_effects:
        # correlated residuals the auto noise model took as AR(1): the white-noise fit it started
        # from is the check (no new fit: both are consistent when the model is right)
        white_sd = np.array([r.get("model_error_floor", r["crb_sd"]) for r in rows], float)
        gls_sd = np.array([r["crb_sd"] for r in rows], float)
        parts["noise"] = check_sd(ml, gls_sd, f1.drag_model.cd(f1.white_ml.drag_params, grid), white_sd)
        rec["noise_check"] = {"why": "correlated (AR(1)) residuals", "against": "white", "outlier_samples": 0}
    elif f1.white_ml is not None:
        # a fit carrying effects started from a white fit without them: the check is the same
        # effects fitted with white noise (one more fit)
        alt = _alt_rows(track, rnd, opts, chans, f1, grid, plain=plain, noise_model="white", **_same_effects(f1))
        near = _white_near(f1, track, rnd, grid)
        if near is not None and (alt is None or _data_chi2(alt[2]) > _data_chi2(near[2]) + CHECK_CHI2_SLACK):
            # the refit from the start stopped at a worse optimum than the white fit started at this
            # fit's own estimate: that one is the check
            alt, rec["noise_check_from"] = near, "the white-noise fit started at this fit's estimate"
        if alt is not None:
            # its band's excess over the AR(1) fit's is kept too, not taken as the difference's
            # noise: near rho = 1 the AR(1) bound is too narrow
            parts["noise"] = shift_sd(ml, band, alt[0], alt[1])
            rec["noise_check"] = {"why": "correlated (AR(1)) residuals", "against": "white", "outlier_samples": 0}
    rec["parts"] = {k: [float(f"{v:.4g}") for v in p] for k, p in parts.items()}
    set_model_error(rows, parts, CHECK_TERMS)
    return rec, effects_fit


#: a single effect the verdict leaves out is an alternative explanation when the misfit it leaves
#: alone is at most this many times what the verdict member it would replace leaves alone: the
#: data barely prefer the verdict (docs/measurements.md, "Where the constants come from")
ALTERNATIVE_GAP_RATIO = 1.5
#: effects never taken as an alternative: the air (its Cd is conditional on the stated air, said
#: apart) and those that trade with the Cd level (LEVEL_EFFECTS: sized by the diagnosis, level_shift)
NOT_ALTERNATIVES = not_alternatives()


#: a yaw fit that stands for a launch yaw: its decay above this many times the slowest allowed
#: (YAW_DECAY_MIN) and its delta0 below this share of the largest (sqrt(YAW_AMP_MAX / K_YAW)). A
#: table of another shell drives the yaw to the largest amplitude, never damping: that is the
#: table's error, which the fit's free curve estimates
PLAUSIBLE_YAW_DECAY_FACTOR, PLAUSIBLE_YAW_SHARE = 1.5, 0.8


def plausible_launch_yaw(params):
    """Whether a diagnosis's ``yaw_drag`` parameters (``delta0`` [rad], ``decay`` [1/s]) describe
    a launch yaw that damps, not a stand-in pinned at the effect's bounds (bool)."""
    from ..effects import K_YAW, YAW_AMP_MAX, YAW_DECAY_MIN

    d0, decay = params.get("delta0"), params.get("decay")
    if d0 is None or decay is None:
        return False
    return decay > PLAUSIBLE_YAW_DECAY_FACTOR * YAW_DECAY_MIN and \
        abs(d0) < PLAUSIBLE_YAW_SHARE * math.sqrt(YAW_AMP_MAX / K_YAW)


def shape_confounded(dsum, verdict):
    """The effects that trade with the Cd curve (:data:`LEVEL_EFFECTS` but the air, which is said
    apart: ``yaw_drag``) standing behind a verdict's ``drag_shape``: significant and material,
    confounded with it, and explaining the gap alone nearly as well
    (:data:`ALTERNATIVE_GAP_RATIO` of what ``drag_shape`` leaves alone, or better).

    The yaw must be one that damps (:func:`plausible_launch_yaw`).

    Why: a verdict's ``drag_shape`` adds nothing to the fit (the fit estimates the curve), so its
    Cd stands unwidened; where a decaying yaw explains the same misfit, the drag of the first
    seconds is the yaw's and the zero-yaw Cd lies elsewhere. Measured: a point-mass flight with
    a 5 deg launch yaw decaying at 0.3 /s (QE 45) got the verdict ``drag_shape, density``, with
    ``yaw_drag`` removing the whole gap alone (``drag_shape`` 77 %), and claimed every row, 6 %
    high at Mach 2.3 with bands of 0.1-0.3 %.

    Returns
    -------
    list of str
    """
    if DRAG_SHAPE.name not in verdict:
        return []
    rows = {e.get("name"): e for e in dsum.get("effects", [])}
    shape = rows.get("drag_shape") or {}
    s_shape = shape.get("shrink")
    if s_shape is None:
        return []
    out = []
    for n in LEVEL_EFFECTS:
        e = rows.get(n) or {}
        sn = e.get("shrink")
        if (n in verdict or n in (TEMPERATURE.name,) or sn is None or not e.get("significant")
                or not e.get("material")):
            continue
        if DRAG_SHAPE.name not in (e.get("confounded_with") or []) and n not in (shape.get("confounded_with") or []):
            continue
        if n == YAW_DRAG.name and not plausible_launch_yaw(e.get("params") or {}):
            continue
        if 1.0 - sn <= ALTERNATIVE_GAP_RATIO * (1.0 - s_shape):
            out.append(n)
    return out


def close_alternative(dsum, keep, rnd):
    """The explanation the diagnosis ranks next to the verdict: the verdict with its leading
    member (the one that explains most of the gap alone) replaced by a significant, material
    single effect with no more parameters that explains the gap alone nearly as well
    (:data:`ALTERNATIVE_GAP_RATIO`).

    Only a simpler (or as simple) one: the diagnosis keeps the simpler of two explanations unless
    the larger is significantly better, so a larger one it passed over is not supported by the
    data (a wind profile beside a constant wind on a Doppler track, whose layers the data cannot
    place, moved Cd by 30 %), while a simpler one it passed over by a hair is (a constant head
    wind beside the profile a 6-DOF flight's other misfit made slightly better).

    Parameters
    ----------
    dsum : dict
        The diagnosis's record (its ``effects`` rows carry ``shrink``: the share of the gap each
        effect removes alone).
    keep : tuple of str
        The verdict's effects the fit adds.
    rnd : Round

    Returns
    -------
    (names, instead_of, ratio) or None
        The alternative's effects (fittable, :func:`plan_effects`), the member it replaces and the
        ratio of the misfits they leave alone; None without one.
    """
    from ..estimate.build.sources import plan_effects

    rows = {e.get("name"): e for e in dsum.get("effects", [])}
    alone = [(rows[m]["shrink"], m) for m in keep if rows.get(m, {}).get("shrink") is not None]
    best = None
    # the member that explains most alone: the others entered beside it, conditionally, and an
    # effect compared with one of them alone is no alternative to it
    for sm, m in sorted(alone, reverse=True)[:1]:
        if not sm < 1.0:
            continue
        k_member = len(rows[m].get("params") or {})
        for n, e in rows.items():
            sn = e.get("shrink")
            if (n in keep or n in NOT_ALTERNATIVES or sn is None or not e.get("significant")
                    or not e.get("material") or len(e.get("params") or {}) > k_member):
                continue
            ratio = (1.0 - sn) / (1.0 - sm)
            if ratio <= ALTERNATIVE_GAP_RATIO and (best is None or ratio < best[2]):
                names, _ = plan_effects([n if k == m else k for k in keep], rnd)
                if names and set(names) != set(keep):
                    best = (tuple(names), m, ratio)
    return best


def alternative_error(rows, gap):
    """Add the shift of each row (the answer: the verdict's fit) to the alternative explanation's
    Cd (:func:`close_alternative`, fitted by :func:`model_error`) to its ``model_error_sd`` in
    squares, with the alternative's band beyond the row's (:func:`shift_sd`); recorded in ``gap``."""
    alt = gap.get("alternative") or {}
    if "cd" not in alt:
        return
    ml = np.array([r["ml"] for r in rows], float)
    band = np.array([max(r["crb_sd"], r.get("crb_sd_colored", r["crb_sd"])) for r in rows], float)
    mach = np.array([r["mach"] for r in rows], float)
    # the answer's grid is its own flight's (beyond the alternative's span, its end values)
    sd = shift_sd(ml, band, np.interp(mach, alt["mach"], alt["cd"]), np.interp(mach, alt["mach"], alt["band_sd"]))
    add_model_error(rows, ALTERNATIVE_TERM, sd)
    gap.setdefault("parts", {})["alternative"] = [float(f"{v:.4g}") for v in sd]


def diagnosis_record(track, rnd, chans):
    """The diagnosis the model check reads (:func:`bayesdrag.diagnosis.diagnose`), as JSON-ready
    values: ``{"record": ...}``, ``{"skipped": why}`` (a track too short for it) or
    ``{"failed": why}`` (the check never costs the fit its answer: the record says it could not
    be made), with its ``seconds`` (the diagnosis package's import included, the first time in
    a process). It reads the track, the round and the channels only."""
    t0 = time.perf_counter()     # the diagnosis's import counts: a forked child may make it
    from ..diagnosis import MIN_DIAGNOSIS_SAMPLES, diagnose

    if track.n < MIN_DIAGNOSIS_SAMPLES:
        out = {"skipped": f"{track.n} samples, fewer than the {MIN_DIAGNOSIS_SAMPLES} the diagnosis needs"}
    else:
        try:
            out = {"record": diagnose(track, rnd, channels=chans).record}
        except (InputError, FitError, ValueError, np.linalg.LinAlgError) as exc:
            out = {"failed": f"{type(exc).__name__}: {exc}"}
    out["seconds"] = time.perf_counter() - t0
    return out


#: running median [samples] the fit's residuals are taken about when a flagged sample is judged
#: against the fit (:func:`gross_outliers`)
SPIKE_WINDOW = 5


def gross_outliers(track, f1, sigma=None):
    """Samples that are gross outliers of the track: flagged by the track's own local scale
    (:func:`bayesdrag.estimate.model.noise.noise_and_outliers`) *and* standing out of the fit's
    residuals (more than ``OUTLIER_K`` robust sd from their :data:`SPIKE_WINDOW`-sample running
    median). The track alone cannot tell a radar's fast-changing view of a shell near it (range
    rate from 127 to 280 m/s in 50 ms, 10 m behind the gun) from a spike; the fit, which flies
    that geometry, can. Returns their number (samples with any channel flagged)."""
    from scipy.ndimage import median_filter

    from ..estimate.model.noise import OUTLIER_K, noise_and_outliers, robust_sd

    chans = f1.problem.channels
    _, _, out = noise_and_outliers(track, chans, sigma)
    if not out.any():
        return 0
    for j, c in enumerate(chans):
        r = np.asarray(f1.ml.residuals[c], float)
        d = r - median_filter(r, SPIKE_WINDOW, mode="nearest")
        s = robust_sd(d[np.isfinite(d)])
        out[:, j] &= np.isfinite(d) & (np.abs(d) > OUTLIER_K * s) if s > 0 else out[:, j]
    return int(out.any(axis=1).sum())


#: effects whose fit with Cd free trades against Cd itself: the temperature's density part is a
#: factor on the drag, and the induced drag of a decaying yaw is a change of the drag's shape over
#: the Mach numbers flown first
LEVEL_EFFECTS = partly_trading_with_cd()


#: the Cd sd grows by more than this factor when an effect is fitted beside it: the two are one
#: signature on this track (a canonical correlation above 0.995), as a decaying yaw or a head wind
#: and the drag level on a chronograph shot of 0.1 s
ALIAS_INFLATION = 10.0


def aliased_with_cd(band, band_with):
    """Whether fitting the effects beside Cd leaves Cd undetermined: the median ratio of the rows'
    sd with them (``band_with``) to without (``band``) exceeds :data:`ALIAS_INFLATION`."""
    band, band_with = np.asarray(band, float), np.asarray(band_with, float)
    ok = band > 0
    return bool(ok.any() and np.median(band_with[ok] / band[ok]) > ALIAS_INFLATION)


def level_shift(grid, ml, profiles, names):
    """Cd shift [Cd] at each grid row of effects that trade with Cd, as the diagnosis sized them
    against the firing table (its ``cd_shift`` profile: the Cd change a fit that ignores the
    effect absorbs, at a few Mach numbers; linear between them, held beyond): the effects added
    in squares. None when none of ``names`` has a profile."""
    have = [profiles[n] for n in names if n in profiles]
    if not have:
        return None
    grid, ml = np.asarray(grid, float), np.asarray(ml, float)
    rel = [np.interp(grid, np.asarray(p["mach"], float), np.abs(np.asarray(p["cd_relative"], float)))
           for p in have]
    return np.sqrt(sum(r**2 for r in rel)) * np.abs(ml)


def _same_effects(f1):
    """Keywords that give a check of ``f1`` the same effects (and wind layers) as ``f1``: a check
    of the noise model compares like with like."""
    if not f1.effects:
        return {}
    kw = {"with_effects": tuple(f1.effects)}
    layers = getattr(f1.problem.model, "layers", None)
    if WIND_PROFILE.name in f1.effects and layers is not None:
        kw["wind_layers"] = layers
    return kw


def _alt_rows(track, rnd, opts, chans, f1, grid, plain=None, **change):
    """``(cd, band_sd, fit)`` on ``grid`` of the same fit with ``change`` (effects, likelihood);
    None when it fails or does not carry every effect asked for. ``plain``: the fit without
    effects ``f1`` was made from (default ``f1``), whose stages the changed fit shares when
    :func:`_from_plain` can take them over."""
    kw = dict(drag=f1.drag_model.name, channels=chans, free_ic=not opts.fix_ic, likelihood=opts.likelihood,
              nu=opts.ml_nu, noise_model=opts.noise_model, start=f1.start)   # the plain fit's start: no new search
    kw.update(change)
    try:
        alt = _from_plain(plain if plain is not None else f1, rnd, opts, **change)
        if alt is None:
            alt = fit_scheme1(track, rnd, **kw)
    except (InputError, FitError):
        return None
    if not alt.ml.success or set(change.get("with_effects", ())) - set(alt.effects):
        return None     # a fit that dropped an effect asked for is no fit of it (its shift would read 0)
    return _rows_of(alt, grid, track, rnd)


#: a refit of the white-noise check counts as stuck when its data chi2 exceeds that of the white
#: fit started at the checked fit's estimate by more than this (a few units: a real optimum of
#: the same model is never worse than a point next to it)
CHECK_CHI2_SLACK = 10.0


def _data_chi2(fit):
    """The data's chi2 of a Scheme 1 fit at its own noise sd (weighted; priors left out)."""
    prob, res = fit.problem, fit.ml
    w = np.asarray(prob.weights, float)
    return float(sum(np.nansum(w[:, j] * (np.asarray(res.residuals[c], float) / res.sigma[c]) ** 2)
                     for j, c in enumerate(prob.channels)))


def _rows_of(alt, grid, track, rnd):
    """``(cd, band_sd, fit)`` on ``grid`` of a check's fit, its band as the answer's is made
    (model-error floor, quality assessment)."""
    ra = cd_table(alt.ml, alt.drag_model, grid)
    model_error_floor(alt, ra)
    assess(alt, ra, track, rnd.radar.sigma)
    return np.array([r["ml"] for r in ra]), np.array([r["band_sd"] for r in ra]), alt


def _white_near(f1, track, rnd, grid):
    """``(cd, band_sd, fit)`` of the fit's own problem with white noise, started at its estimate
    (the same effects, priors and smoothing): the white-noise check where a refit from the start
    does not reach the optimum. None when it fails."""
    prob = f1.problem.replace(noise_model={c: "white" for c in f1.problem.channels}, theta0=f1.ml.theta)
    try:
        res = prob.fit(fallback=True)
    except FitError:
        return None
    if not res.success:
        return None
    alt = replace(f1, ml=res, problem=prob, white_ml=None,
                  noise={"requested": "white", "model": dict(prob.noise_model)})
    return _rows_of(alt, grid, track, rnd)


def _from_plain(plain, rnd, opts, *, with_effects=(), noise_model=None, wind_layers=None, **other):
    """The Scheme 1 fit with ``with_effects`` (and ``noise_model="white"``) built on the stages
    the plain fit ``plain`` already made, or None when they are not the changed fit's own.

    :func:`~bayesdrag.estimate.scheme1.fit.fit_scheme1` with effects repeats the plain fit's
    stages (start, curve, launch check, smoothing walk, noise model) unchanged and then adds
    the effects to its last problem (stage C, :func:`~bayesdrag.estimate.build.sources.fit_with_sources`);
    its white-noise form adds them to the white fit it started from. So the same numbers come
    from stage C alone, or from the noise model and stage C for a wind profile (fitted before the
    noise model: :func:`_winds_first`), unless the effects change an earlier stage (a radar clock
    the launch check allows for), the plain fit carries declared sources or effects, or the
    change is another likelihood."""
    from ..estimate.build.smoothing import drop_coefficient_correlations
    from ..estimate.build.sources import fit_with_sources

    effects = tuple(with_effects)
    if (other or not effects or plain.effects or plain.sources or plain.problem.E or plain.rejected is not None
            or opts.likelihood != "gaussian" or rnd.systematics.declared() or rnd.systematics.wind_profile is not None
            or RADAR_TIME.name in effects or noise_model not in (None, "white")):
        return None
    if WIND_PROFILE.name in effects:
        return _winds_first(plain, rnd, opts, effects, noise_model, wind_layers)
    prob, res, noise, white_ml = plain.problem, plain.ml, plain.noise, plain.white_ml
    if noise_model == "white" and opts.noise_model != "white":
        if plain.white_ml is None:      # the plain fit is white already when auto chose no AR(1)
            if any(m != "white" for m in prob.noise_model.values()):
                return None
        else:
            prob, res = prob.replace(noise_model={c: "white" for c in prob.channels}), plain.white_ml
        noise, white_ml = {"requested": "white", "model": dict(prob.noise_model)}, None
    p2, res2, sources, fitted, placements = fit_with_sources(prob, res, rnd, effects, wind_layers)
    if plain.base is not None:          # a penalised spline: its neighbours' correlations are by design
        res2 = drop_coefficient_correlations(res2, prob.P)
    return replace(plain, ml=res2, problem=p2, noise=noise, white_ml=white_ml, sources=sources, effects=fitted,
                   ml_without_effects=res if fitted else None, layer_placements=placements)




def _winds_first(plain, rnd, opts, effects, noise_model, wind_layers):
    """The fit with a wind profile among ``effects`` from the plain fit's state before its noise
    model: :func:`~bayesdrag.estimate.scheme1.fit.fit_scheme1` fits a profile before the noise
    model (:func:`~bayesdrag.estimate.scheme1.fit.noise_and_effects`), on the smoothed white fit
    the plain fit kept (``white_ml``, or the plain fit itself when it stayed white). None when
    that state is gone: one-sided outliers reweighted it, or AR(1) was asked for outright."""
    from ..estimate.build.smoothing import drop_coefficient_correlations
    from ..estimate.scheme1.fit import noise_and_effects

    if (plain.noise or {}).get("contamination", {}).get("engaged"):
        return None
    prob = plain.problem
    if plain.white_ml is not None:
        prob, res = prob.replace(noise_model={c: "white" for c in prob.channels}), plain.white_ml
    elif any(m != "white" for m in prob.noise_model.values()):
        return None
    else:
        res = plain.ml
    prob, res, smoothing, noise, _, white_ml, sources, fitted, before, placements = noise_and_effects(
        prob, res, plain.smoothing, rnd, "gaussian", noise_model or opts.noise_model, dict(rnd.radar.sigma),
        opts.ml_nu, effects, wind_layers, lambda step: None)
    if plain.base is not None:          # a penalised spline: its neighbours' correlations are by design
        res = drop_coefficient_correlations(res, prob.P)
    return replace(plain, ml=res, problem=prob, smoothing=smoothing, noise=noise, white_ml=white_ml, sources=sources,
                   effects=fitted, ml_without_effects=before if fitted else None, layer_placements=placements)


def _beyond_half_band(rows, part):
    """A model-error part's shift per row [Cd] when anywhere above half the row's band, else None:
    a shift that small is not worth a line of its own."""
    shift = np.asarray(part, float)
    return shift if np.any(shift > 0.5 * np.array([r["band_sd"] for r in rows], float)) else None


def _part_problem(quality, rows, gap, part, words):
    """A problem line (``words(shift)``) for the model-error part ``part`` where it reaches half a
    row's band (:func:`_beyond_half_band`); the answer is then not clean."""
    shift = _beyond_half_band(rows, gap["parts"][part]) if part in gap["parts"] else None
    if shift is not None:
        quality["problems"].append(FitWarning("model_error", words(shift)))
        quality["ok"] = False




def withdrawn_by_check(gap):
    """Whether the check withdraws every row's claim: the track is seen from a site the round
    does not give (:data:`SITE_NOT_GIVEN`), or an effect it found could be neither fitted with Cd
    nor sized (``unsized``)."""
    return bool(gap.get("site_not_given") or gap.get("unsized"))


def note_model_error(gap, quality, grid, rows):
    """``ml.quality.model_error`` and its problem line: what moved Cd, how far, what to do (the
    rows it withdraws, :func:`withdrawn_by_check`, are claimed again by the caller first)."""
    quality["model_error"] = gap
    me = np.array([r.get("model_error_sd", 0.0) for r in rows], float)
    ml = np.array([r["ml"] for r in rows], float)
    if gap.get("site_not_given"):
        # unsized, as an effect whose shift could not be sized: no row is claimed (withdrawn_by_check)
        quality["undetermined"] = [[float(grid[0]), float(grid[-1])]]
        quality["problems"].append(FitWarning("model_error", SITE_NOT_GIVEN))
        quality["ok"] = False
    if gap.get("absorbed_in_cd"):
        eff = ", ".join(gap["absorbed_in_cd"])
        quality.setdefault("notes", []).append(
            f"the diagnosis finds {eff}, which this track cannot tell from Cd (fitted beside it, Cd is undetermined): "
            f"Cd is the flight's effective drag, {eff} included")
    if gap["effects"] and "effects" in gap["parts"] and not gap.get("site_not_given"):
        eff, them = ", ".join(gap["effects"]), "it" if len(gap["effects"]) == 1 else "them"
        quality["problems"].append(FitWarning(
            "model_error", f"the diagnosis finds {eff} that the round does not declare: "
            f"{'fitting ' + them if 'effects_from' not in gap else 'by its own estimate ' + them} moves Cd by "
            f"{describe(grid, ml, gap['parts']['effects'])}; the bands include this as model error and rows whose "
            f"band then exceeds 1 % are not determined (`bayesdrag fit ... --with {','.join(gap['effects'])}` fits "
            f"the cause)", tuple(gap["effects"])))
        quality["ok"] = False
    if gap["noise_check"] and "noise" in gap["parts"]:
        shift = _beyond_half_band(rows, gap["parts"]["noise"])
        if shift is not None:
            quality["problems"].append(FitWarning(
                "model_error", f"a {CHECK_NAMES[gap['noise_check']['against']]} of the track moves Cd by up to "
                f"{100 * float(np.max(shift / np.abs(ml))):.2g} % ({gap['noise_check']['why']}): the bands include "
                f"it as model error"))
    alt = gap.get("alternative") or {}
    _part_problem(quality, rows, gap, "alternative", lambda shift: (
        f"{' and '.join(alt['effects'])} explain{'s' if len(alt['effects']) == 1 else ''} the track nearly as "
        f"well as {alt['instead_of']} (the misfit left alone {alt['gap_ratio']:.3g} times as large), and the Cd "
        f"of that explanation differs by {describe(grid, ml, shift)}: the bands include it as model error "
        f"(what was measured on the day, or `bayesdrag fit ... --with {','.join(alt['effects'])}`, decides "
        f"between them)"))
    _part_problem(quality, rows, gap, "shape_confounded", lambda shift: (
        f"the track departs from the firing table's shape (drag_shape), which the data cannot tell from a "
        f"decaying {' and '.join(gap.get('shape_confounded', []))} early in the flight; under that explanation the "
        f"Cd differs by {describe(grid, ml, shift)}: the bands include it as model error (a measured launch yaw, "
        f"or `bayesdrag fit ... --with yaw_drag`, decides between them)"))
    if gap.get("unsized"):
        quality["undetermined"] = [[float(grid[0]), float(grid[-1])]]
        quality["problems"].append(FitWarning(
            "model_error", f"the diagnosis finds {', '.join(gap['unsized'])}, which could not be fitted with Cd nor its "
            f"Cd shift sized: no row is claimed determined (`bayesdrag diagnose TRACK ROUND -o DIR` shows the gap)",
            tuple(gap["unsized"])))
        quality["ok"] = False
    why = gap.get("diagnosis_skipped") or gap.get("diagnosis_failed")
    if why:
        # a check that could not run cannot vouch for the answer: not clean, with the reason
        quality["problems"].append(FitWarning(
            "model_error", f"the model check could not run the diagnosis ({why}): the bands hold no model error for an "
            f"undeclared effect, so no row's band is known to hold one"))
        quality["ok"] = False
    if gap["conditional_air"]:
        quality.setdefault("notes", []).append(
            f"the diagnosis finds air unlike the round's ({', '.join(gap['conditional_air'])}): Cd is conditional "
            f"on the stated air")
    if "effects" in gap["parts"]:
        e = np.asarray(gap["parts"]["effects"], float)
        quality["model_error"]["effects_max_rel"] = float(np.max(np.where(ml > 0, e / np.abs(ml), 0.0)))
    quality["model_error"]["max_rel"] = float(np.max(np.where(ml > 0, me / np.abs(ml), 0.0))) if me.size else 0.0


#: a declared air source whose fitted value lies this many declared sd from the stated value is
#: contradicted by the track
AIR_CONTRADICTION_SD = 3.0


def air(f1, gap):
    """What the Cd assumes of the air, in one line (``ml.quality.air``): declared air sources the
    track contradicts (fitted beyond :data:`AIR_CONTRADICTION_SD` declared sd), or undeclared air
    the Cd is conditional on (named by the diagnosis when it finds air unlike the round's)."""
    params = f1.ml.params
    contradicted = []
    for stem, ep, nom, sd in f1.sources:
        if stem in (DENSITY.source, TEMPERATURE.source) and ep.name in params and sd > 0:
            z = (float(params[ep.name]) - nom) / sd
            if abs(z) > AIR_CONTRADICTION_SD:
                contradicted.append({"source": stem, "fitted": float(params[ep.name]), "stated": float(nom),
                                     "z": float(z)})
    declared = {s[0] for s in f1.sources}
    undeclared = [k for k in (DENSITY.source, TEMPERATURE.source) if k not in declared]
    found = list((gap or {}).get("conditional_air", []))
    beyond = [n for n in found if n in declared]       # a declared air source the diagnosis still finds
    if contradicted or beyond:
        line = "the track contradicts the declared air: " + ", ".join(
            [f"{c['source']} fitted {c['fitted']:.4g} against the stated {c['stated']:.4g} ({c['z']:+.1f} declared sd)"
             for c in contradicted] +
            [f"the diagnosis finds {n} beyond the declared {n}_sd" for n in beyond if n not in
             {c["source"] for c in contradicted}]) + "; check the met data or widen the declared _sd"
    elif found:
        line = (f"Cd is conditional on the stated air, which the track contradicts (the diagnosis finds "
                f"{', '.join(found)}): declare {' and '.join(k + '_sd' for k in undeclared) or 'wider air _sd keys'} "
                f"in [atmosphere] to carry it in the band")
    elif undeclared:
        line = (f"Cd is conditional on the stated air ({' and '.join(undeclared)} not declared: "
                f"{', '.join(k + '_sd' for k in undeclared)} in [atmosphere] would carry it in the band)")
    else:
        line = None
    return {"contradicted": contradicted, "undeclared": undeclared, "found": found, "line": line}


def air_measured(rnd):
    """True when the round's air was measured on the day (a met profile or message, or station
    readings at the gun), so that a track contradicting it is news rather than a confound."""
    from ..air.atmosphere import MetProfile
    from ..air.station import is_station_air

    return isinstance(rnd.atmosphere, MetProfile) or is_station_air(rnd.atmosphere)


def own_table(rnd):
    """True when the round's reference drag is the projectile's own table (a file the round names),
    not absent: a table of another shell differs from the track in drag level by design."""
    return rnd.projectile.reference_drag is not None and bool(rnd.projectile.reference_drag_path)


def table_level(rows):
    """The fitted Cd over the reference table, the median over the determined rows (over every
    row with a table value when none is determined); None without a table."""
    with_table = [r for r in rows if r.get("reference") and r["reference"] > 0]
    use = [r for r in with_table if r.get("determined")] or with_table
    return float(np.median([r["ml"] / r["reference"] for r in use])) if use else None


def confound_line(found, level):
    """The air line of the confound rule: the drag level against the table and the air it cannot
    be told from, blaming neither (``level``: :func:`table_level`)."""
    pct = 100.0 * (level - 1.0)
    # an air effect that is a constant factor on the drag (the density) trades one for one with the level
    level_air = any(getattr(EFFECTS.get(n), "drag_change", None) == "level" and EFFECTS[n].acts_on == "air"
                    for n in found)
    air_words = (f"the air {abs(pct):.1f} % {'denser' if pct >= 0 else 'thinner'} than stated" if level_air
                 else "the air unlike the stated air")
    return (f"Cd is {abs(pct):.1f} % {'above' if pct >= 0 else 'below'} the table, or {air_words} (the diagnosis "
            f"finds {', '.join(found)}): the track cannot tell which; Cd is conditional on the stated air "
            f"(density_sd and temperature_sd in [atmosphere] carry its doubt in the band)")


def air_contradiction(rnd, air_record, quality, rows=()):
    """The one rule for air the track contradicts (docs/fitting.md, "Air the track contradicts"):
    an implied air unlike the stated one makes the answer not clean only when the air was
    measured (:func:`air_measured`) and the reference is the projectile's own table
    (:func:`own_table`): then the met data or the table is wrong, and the Cd carries it. Otherwise
    drag level and air are one signature the answer names, without blame (``air_record["line"]``:
    with a table, how far Cd is from it and the air that would explain as much,
    ``air_record["level_vs_table"]``). Adds the problem line to ``quality`` and sets
    ``air_record["rule"]``; ``rows``: the Cd rows (``ml`` and ``reference``)."""
    found = list(air_record.get("found") or []) + [c["source"] for c in air_record.get("contradicted") or []]
    if not found:
        air_record["rule"] = None
        return
    if air_measured(rnd) and own_table(rnd):
        air_record["rule"] = "contradicted"      # measured air, the projectile's own table: not clean
        quality["problems"].append(FitWarning(
            "air", f"the track contradicts the measured air (the diagnosis finds {', '.join(dict.fromkeys(found))} unlike "
            f"the met profile's) although the reference is this projectile's own table: the met data (its datum, time "
            f"or place) or the table is wrong, and Cd carries the difference"))
        quality["ok"] = False
    else:
        air_record["rule"] = "confound"          # air not measured, or another projectile's table: named
        level = table_level(rows) if rnd.projectile.reference_drag is not None else None
        if level is not None:
            # the drag against the table and the air it trades with, in one line, neither blamed
            air_record["level_vs_table"] = float(f"{level:.5g}")
            air_record["line"] = confound_line(list(dict.fromkeys(found)), level)




#: a fitted radar clock offset this many of its sd from zero is said in words (:func:`clock_note`)
CLOCK_NOTE_SD = 3.0


def clock_note(ml):
    """A radar clock offset the fit carries (``radar_time``, added by the default or named) and
    the data determine, in words: ``[warning]`` or ``[]``. The launch check says of a late time
    origin that the track conflicts with the launch values; a fit carrying the offset no longer
    conflicts, so the offset itself is what tells the user (``ml``: the record's ``ml``)."""
    dt = (ml.get("params") or {}).get("radar_time.dt")
    if dt is None:
        return []
    size = ((ml.get("with_effects") or {}).get("sizes") or {}).get("radar_time.dt") or {}
    sd = size.get("sd", (ml.get("crb") or {}).get("radar_time.dt"))
    if sd is None or not abs(dt) > CLOCK_NOTE_SD * sd:
        return []
    when, how = ("after", "late") if dt > 0 else ("before", "early")
    return [FitWarning("clock", f"radar_time.dt = {dt:.4g} +- {sd:.2g} s: the track's time origin is {abs(dt):.3g} s "
                       f"{when} the launch, or the radar clock is that {how}; Cd is fitted with the offset (shift t so "
                       f"that t = 0 is the launch, or declare time_offset_sd in the round)", ("radar_time.dt",))]


