"""The candidate effects, each fitted alone (step 4 of :mod:`bayesdrag.diagnosis`).

:func:`screen_candidates` says which effects of the library this track and round can test (a
Coriolis candidate needs a latitude, ``radar_time`` the launch, ``drag_shape`` a table and a
flown Mach span; an effect whose signature the nuisance parameters absorb is not identifiable)
and why the others are skipped; :func:`fit_candidates` fits each with the initial state and
ranks them (:func:`candidate_row`: chi2 drop, colored test, shrink, parameters with sd).
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..effects import EFFECTS, K_YAW, radar_effect_missing
from ..errors import FitError
from ..track import NATIVE_CHANNELS
from .setup import (drag_shape_for, fit_effects, k_free, n_weighted, noise_floor, report_params)
from .signatures import IDENTIFIABLE_FRACTION, seen_axes, signatures
from .winds import WIND_FAMILY, fit_wind_profile, layers_for, log_evidence, occam
from .statistics import autocovariance, chi2_noise_sd, colored_inflation, tested_drop, tested_inflation, threshold
from ..effects import CORIOLIS, DRAG_SHAPE, RADAR_POSITION, RADAR_TIME, WIND, WIND_PROFILE, YAW_DRAG

__all__ = ["screen_candidates", "fit_candidates", "candidate_row"]


def screen_candidates(setup, candidates, base_theta, span, y_base=None):
    """The effects a diagnosis tests on this track, their signatures and the skipped ones.

    Sets ``setup.ctx.drag_shape`` (the table's shape functions over ``span``) when ``drag_shape``
    is tested, and ``setup.ctx.wind_layers`` (layers by height, until the evidence chooses) when
    ``wind_profile`` is.

    Parameters
    ----------
    setup : Setup
    candidates : sequence of str or None
        Effect names asked for (None: the whole library).
    base_theta : (P + 6,) array
        The baseline fit's parameters.
    span : (float, float) or None
        Flown Mach range (:func:`bayesdrag.diagnosis.setup.flown_mach_span`).
    y_base : (N, C) array, optional
        The baseline's fitted outputs (the layers of ``wind_profile``; without them it is
        skipped).

    Returns
    -------
    (list of Effect, dict, dict)
        The testable effects (library order), their :func:`signatures` and ``skipped`` (name ->
        reason in words).
    """
    names = list(candidates) if candidates is not None else list(EFFECTS)
    skipped = {}
    native = any(c in NATIVE_CHANNELS for c in setup.channels)
    for n in [n for n in names if radar_effect_missing(n, setup.channels)]:
        # a radar's bias or site acts on its own channels only: an x, y, z, v track has none (not
        # a candidate at all), a native one may lack the channel (said)
        names.remove(n)
        if native:
            skipped[n] = radar_effect_missing(n, setup.channels) + ": nothing it acts on"
    if setup.ctx.latitude_deg is None and CORIOLIS.name in names:
        skipped[CORIOLIS.name] = "the round gives no [launch] latitude: Earth rotation cannot be formed"
    if not setup.launch_known and RADAR_TIME.name in names:
        skipped[RADAR_TIME.name] = ("no [launch] velocity/elevation: a clock offset is a later start of the same "
                                    "trajectory")
    if DRAG_SHAPE.name in names:
        if not setup.has_reference:
            skipped[DRAG_SHAPE.name] = ("no reference drag: the fitted nuisance Cd already has any shape, so a "
                                     "shape error of a table cannot be asked")
        elif span is None or not span[1] > span[0]:
            skipped[DRAG_SHAPE.name] = "the nominal trajectory gives no Mach span to shape the table over"
        else:
            setup.ctx = replace(setup.ctx, drag_shape=drag_shape_for(setup, base_theta, span))
    if WIND_PROFILE.name in names:
        lay = None if y_base is None else (layers_for(setup, y_base, "altitude")
                                           or layers_for(setup, y_base, "downrange"))
        if lay is None:
            skipped[WIND_PROFILE.name] = "the track gives no height or downrange span to lay wind layers over"
        else:
            setup.ctx = replace(setup.ctx, wind_layers=lay)
    if RADAR_POSITION.name in names:   # the site's coordinates the channels see; the others held at 0
        setup.ctx = replace(setup.ctx, radar_axes=seen_axes(setup, base_theta))
        if not setup.ctx.radar_axes:
            skipped[RADAR_POSITION.name] = ("not identifiable from this track (absorbed by the initial state: the "
                                         "channels see no shift of the site apart from a shift of the flight)")
    effs = [EFFECTS[n] for n in names if n not in skipped]
    sigs = signatures(setup, base_theta, effs)
    for e in list(effs):
        Q, frac = sigs[e.name]
        if Q is None or frac < IDENTIFIABLE_FRACTION:
            why = ("absorbed by the fitted Cd and the initial state" if not setup.has_reference
                   else "absorbed by the initial state")
            skipped[e.name] = f"not identifiable from this track ({why}; {frac:.3g} of its signature left)"
            effs.remove(e)
    return effs, sigs, skipped


def fit_candidates(setup, effs, base_fit, gap, alpha, K, skipped):
    """Fit every candidate alone (with the initial state) and rank them.

    Parameters
    ----------
    setup : Setup
    effs : list of Effect
    base_fit : (MLResult, OutputErrorProblem, (N, C) outputs)
        The baseline fit.
    gap : float
        Baseline gap (chi2 above its noise floor).
    alpha : float
        Family-wise false-alarm rate.
    K : int
        Number of candidates tested (Bonferroni).
    skipped : dict
        Name -> reason; a candidate whose fit fails is added (changed in place).

    Returns
    -------
    (list of dict, dict)
        The rows (:func:`candidate_row`), best first: significant effects before the rest (a
        non-physical or non-converged fit, e.g. a yaw_drag at a negative amplitude, may drop chi2
        the most yet cannot be the answer), then by chi2 drop, ties in library order; and the
        fits by name.
    """
    base, _, y_base = base_fit
    base_theta = base.theta.copy()
    chi2_base = float(base.cost)
    rows = []
    fits = {}
    for e in effs:
        if e.name == WIND_PROFILE.name:
            got = _fit_profile_variants(setup, e, base_fit, gap, alpha, K, fits)
            if got is None:
                skipped[e.name] = "its fits failed (by height and by downrange distance)"
                continue
            fits[e.name], row = got
            rows.append(row)
            continue
        try:
            res, prob, y = fit_effects(setup, [e], base_theta)
            if not np.all(np.isfinite(y)):
                raise FloatingPointError("non-finite trajectory at the estimate")
        except (FitError, FloatingPointError, ValueError, np.linalg.LinAlgError) as exc:
            # one candidate failing is a finding about that candidate, not the end of the diagnosis
            skipped[e.name] = f"its fit failed ({type(exc).__name__}: {exc})"
            continue
        row = candidate_row(e, res, y, y_base, chi2_base, gap, setup, alpha, K, base)
        if e.name == YAW_DRAG.name and row["significant"]:
            res, prob, y, row = _yaw_restarts(setup, e, base_fit, (res, prob, y, row), gap, alpha, K)
        fits[e.name] = (res, prob, y)
        rows.append(row)
    _wind_model_choice(setup, rows, fits, base_fit)
    rows.sort(key=lambda r: (not r["significant"], -round(r["delta_chi2"], 6 if r["delta_chi2"] < 1e3 else 3),
                             list(EFFECTS).index(r["name"])))
    return rows, fits


#: further starts ``(delta0 [rad], decay [1/s])`` of a significant ``yaw_drag`` fit: a large yaw
#: that damps slowly and one that damps fast; from the one small start the fit stops at a local
#: optimum when the launch yaw is large (docs/measurements.md, "Where the constants come from")
YAW_RESTARTS = ((0.12, 0.3), (0.12, 1.5))


def _yaw_restarts(setup, e, base_fit, first, gap, alpha, K):
    """The best of the first ``yaw_drag`` fit and those from :data:`YAW_RESTARTS` (lowest cost
    at a physical, positive amplitude): ``(res, prob, y, row)``."""
    base, _, y_base = base_fit
    best = first
    for d0, decay in YAW_RESTARTS:
        start = np.concatenate([base.theta, [K_YAW * d0 * d0, decay]])
        try:
            res, prob, y = fit_effects(setup, [e], start)
        except (FitError, FloatingPointError, ValueError, np.linalg.LinAlgError):
            continue
        if not np.all(np.isfinite(y)) or res.theta[-2] <= 0 or not res.cost < best[0].cost:
            continue
        best = (res, prob, y, candidate_row(e, res, y, y_base, float(base.cost), gap, setup, alpha, K, base))
    return best


def candidate_row(e, res, y, y_base, chi2_base, gap, setup, alpha, K, base_res):
    """The row of ``diagnosis.json`` ``effects`` of one candidate fitted alone.

    Parameters
    ----------
    e : Effect
    res : MLResult
        The candidate's fit.
    y : (N, C) array
        Its fitted outputs [m, m/s].
    y_base : (N, C) array
        The baseline's outputs.
    chi2_base : float
        The baseline's cost.
    gap : float
        Baseline gap (chi2 above its noise floor).
    setup : Setup
    alpha : float
        Family-wise false-alarm rate.
    K : int
        Number of candidates tested (Bonferroni).
    base_res : MLResult
        The baseline fit.

    Returns
    -------
    dict
        Parameters with their colored and white sd, chi2 drop, shrink, remaining gap, colored
        inflation, test statistic and threshold, ``significant`` and the effect's explanation.
    """
    chans = setup.channels
    sig_vec = np.array([setup.sigma[c] for c in chans])
    d = float(chi2_base - res.cost)
    resid = np.stack([res.residuals[c] for c in chans], axis=-1)
    acov = autocovariance(resid, setup.weights)
    infl = colored_inflation(y - y_base, acov, sig_vec, setup.weights)
    stat = tested_drop(setup, e, d, base_res, res) / tested_inflation(e, infl)
    thr = threshold(e, alpha / K, k_free(setup, e))
    n_obs = n_weighted(setup)
    vals = res.theta[-e.k:] if e.k else np.zeros(0)
    idx = slice(res.theta.size - e.k, res.theta.size)
    cov = res.cov[idx, idx] if e.k else np.zeros((0, 0))
    covc = res.cov_colored[idx, idx] if e.k else np.zeros((0, 0))
    floor_e = noise_floor(setup, res)
    remaining = max(float(res.cost) - floor_e, 0.0)
    noise_sd = chi2_noise_sd(acov, sig_vec, setup.weights)
    physical = True
    if e.name == YAW_DRAG.name and vals[0] < 0:
        physical = False
    sd_c = report_params(setup, e, vals, covc) if e.k else {}
    # inflate the white sd by the colored factor where the Morelli-Klein bound is smaller
    row = {
        "name": e.name,
        "params": report_params(setup, e, vals) if e.k else {},
        "sd": sd_c,
        "sd_white": report_params(setup, e, vals, cov) if e.k else {},
        "delta_loglik": d / 2.0,
        "delta_chi2": d,
        "delta_bic": -d + k_free(setup, e) * math.log(max(n_obs, 1)),
        "shrink": float(np.clip(d / gap, 0.0, 1.0)) if gap > 0 else 0.0,
        "remaining_gap": remaining,
        "remaining_gap_fraction": float(remaining / gap) if gap > 0 else 0.0,
        # the noise-only chi2 fluctuates by this much (with the residuals' own correlation): a
        # remaining gap of this order is noise, and shrink is resolved to about shrink_sd
        "remaining_gap_noise_sd": noise_sd,
        "shrink_sd": float(noise_sd / gap) if gap > 0 else None,
        "inflation": float(infl),
        "test_statistic": float(stat),
        "threshold": thr,
        "significant": bool(stat > thr and d > 0 and physical and np.isfinite(res.cost)),
        "physical": physical,
        "converged": bool(res.converged),
        "explanation": e.explanation,
        "units": dict(zip(report_params(setup, e, vals).keys(), e.units)) if e.k else {},
    }
    if e.name == DRAG_SHAPE.name and setup.ctx.drag_shape is not None:
        ds = setup.ctx.drag_shape
        grid = np.linspace(ds.knots[0], ds.knots[-1], 9)
        row["shape"] = {"knots": [round(float(k), 3) for k in ds.knots], "mach": [round(float(m), 3) for m in grid],
                        "cd_relative": [float(v) for v in ds.correction(vals[:ds.n_shape], grid)]}
    if not res.success:
        row["message"] = res.message
    return row


def _fit_profile_variants(setup, e, base_fit, gap, alpha, K, fits):
    """``wind_profile`` fitted with layers by height and by downrange distance; the variant with
    the larger evidence is kept (``setup.ctx.wind_layers`` set to it). The evidence is chained
    through the constant wind's fit when there is one (:func:`bayesdrag.diagnosis.winds.log_evidence`).
    Returns (its fit, its row with ``layers`` and each variant's evidence) or None when both fits
    fail."""
    base, _, y_base = base_fit
    variants = fit_wind_profile(setup, y_base, base.theta, lambda st: fit_effects(st, [e], base.theta))
    chain = fits.get("wind")
    best, info = None, []
    for lay, f in variants:
        res, _, y = f
        saved = setup.ctx
        setup.ctx = replace(saved, wind_layers=lay)
        g_info = _inflation(setup, base_fit, f)
        if chain is None:
            ev = log_evidence(setup, "wind_profile", res, base, g_info, g_info)
        else:
            g_w = _inflation(setup, base_fit, chain)
            z_w = log_evidence(setup, "wind", chain[0], base, g_w, g_w)
            ev = log_evidence(setup, "wind_profile", res, chain[0], _inflation(setup, chain, f), g_info, z_w,
                              occam(setup, "wind", chain[0], g_w))
        setup.ctx = saved
        setup.ctx = replace(saved, wind_layers=lay)
        k0 = res.theta.size - e.k
        info.append({"axis": lay.axis, "edges": list(lay.edges), "log_evidence": ev,
                     "shrink": float(np.clip((base.cost - res.cost) / gap, 0.0, 1.0)) if gap > 0 else 0.0,
                     "params": report_params(setup, e, res.theta[k0:]),
                     "sd": report_params(setup, e, res.theta[k0:], res.cov_colored[k0:, k0:])})
        setup.ctx = saved
        if best is None or ev > best[0]:
            best = (ev, lay, f)
    if best is None:
        return None
    ev, lay, f = best
    setup.ctx = replace(setup.ctx, wind_layers=lay)
    res, _, y = f
    row = candidate_row(e, res, y, y_base, float(base.cost), gap, setup, alpha, K, base)
    row["layers"] = {"axis": lay.axis, "edges": list(lay.edges), "n": lay.n, "variants": info,
                     "edges_unit": "m above sea level" if lay.axis == "altitude" else "m downrange from the gun"}
    row["log_evidence"] = ev
    return f, row


def _inflation(setup, small, big):
    """Colored inflation of the output change from fit ``small`` to fit ``big`` (residual
    autocovariance of ``big``)."""
    chans = setup.channels
    sig_vec = np.array([setup.sigma[c] for c in chans])
    resid = np.stack([big[0].residuals[c] for c in chans], axis=-1)
    return colored_inflation(big[2] - small[2], autocovariance(resid, setup.weights), sig_vec, setup.weights)


def _wind_model_choice(setup, rows, fits, base_fit):
    """No wind, a constant wind or a profile: the wind models' evidence
    (:func:`bayesdrag.diagnosis.winds.log_evidence`, the profile's chained through the constant
    wind); the one with the larger evidence stands for the wind, the other is kept out of the
    selection (``superseded_by``)."""
    by = {r["name"]: r for r in rows}
    if WIND.name in by:
        g = _inflation(setup, base_fit, fits[WIND.name])
        by[WIND.name]["log_evidence"] = log_evidence(setup, "wind", fits[WIND.name][0], base_fit[0], g, g)
    present = [n for n in WIND_FAMILY if n in by and by[n].get("log_evidence") is not None]
    if len(present) < 2:
        return
    best = max(present, key=lambda n: by[n]["log_evidence"])
    for n in present:
        if n != best:
            by[n]["superseded_by"] = best
