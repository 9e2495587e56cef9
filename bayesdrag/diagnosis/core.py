"""The diagnosis itself: :func:`diagnose` runs the steps of :mod:`bayesdrag.diagnosis` in order
and returns a :class:`Diagnosis`, whose ``record`` is the content of ``diagnosis.json``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .._runtime.renamed import warn_renamed
from .._runtime.threads import single_blas
from ..effects import EFFECTS, check_radar_effects, radar_effect_missing
from ..errors import FitError
from ..track import NATIVE_CHANNELS
from ..estimate.model.layout import ParameterLayout
from .candidates import fit_candidates, screen_candidates
from .impact import MATERIAL_CD_SHIFT, MATERIAL_END_SD, judge_impacts
from .selection import (DRAG_EFFECTS, admits, conditional_shrinks, drop_one_fits, select_effects,
                        shape_beside_level, wrong_table_fit)
from .setup import (edf, fit_effects, fit_starts, flown_mach_span, gun_path, held_params, make_setup, n_weighted,
                    noise_floor, report_params, unseen_effects)
from .signatures import mark_confounded, signatures
from .statistics import autocovariance, colored_inflation
from .winds import (SHAPE_RIVAL_SHARE, WIND_FAMILY, cannot_separate, data_cost, layers_for, rechoose_wind,
                    shape_rival_share)
from .statistics import ALPHA
from .found_air import found_atmosphere
from .where import absorbed_by_launch, where_segments, with_launch_misfit
from ..effects import DRAG_SHAPE, WIND, WIND_PROFILE

__all__ = ["diagnose", "Diagnosis", "MIN_DIAGNOSIS_SAMPLES"]

#: fewest samples a diagnosis accepts: the initial state (6) and an effect (<= 2 parameters)
#: need more data values than that with room for a test; a Doppler report every 100 yd (16
#: samples of x and v) qualifies. Without [radar] sigma the noise estimate from the track's
#: high-frequency content (:func:`bayesdrag.estimate.model.noise.noise_and_outliers`) needs more.
MIN_DIAGNOSIS_SAMPLES = 12
#: parameters of two verdict effects correlated beyond this in the joint fit are reported
JOINT_CORR_WARN = 0.9


@dataclass
class Diagnosis:
    """Result of :func:`diagnose`: ``record`` is diagnosis.json; the arrays feed the figures."""

    record: dict
    t: np.ndarray
    channels: tuple
    sigma: dict
    resid_base: np.ndarray
    resid_best: np.ndarray | None
    mach: np.ndarray
    weights: np.ndarray
    best: str | None
    #: the air found (diagnosis.found_air.found_atmosphere): (MetProfile, Atmosphere with a wind
    #: by downrange distance, header lines), the first two None when the verdict leaves the air
    found_air: tuple | None = None

    @property
    def summary(self) -> dict:
        """Deprecated name of :attr:`record` (removed in release 0.3): "summary" is a result's
        printable table."""
        warn_renamed("Diagnosis.summary", "Diagnosis.record")
        return self.record


@dataclass
class _Baseline:
    """The nominal simulation fitted to the track (step 2-3): its fit, figures and gap."""

    fit: tuple
    theta: np.ndarray
    chi2: float
    floor: float
    gap: float
    resid: np.ndarray
    prior_terms: dict
    mach: np.ndarray
    span: tuple | None


def _baseline(setup):
    """Fit the baseline (no effect) and measure its gap."""
    base, base_prob, y_base = fit_effects(setup, [], setup.theta0)
    if not np.all(np.isfinite(y_base)):
        raise FitError("the nominal simulation of the round does not reach the track's times")
    base_theta = base.theta.copy()
    floor0 = noise_floor(setup, base)
    chi2_base = float(base.cost)
    mach = np.asarray(base.mach, float)
    return _Baseline(
        fit=(base, base_prob, y_base), theta=base_theta, chi2=chi2_base, floor=floor0,
        gap=max(chi2_base - floor0, 0.0), resid=np.stack([base.residuals[c] for c in setup.channels], axis=-1),
        prior_terms={p.name: float((p.mean - p.fn(base_theta)) / p.sd) for p in setup.priors},
        mach=mach, span=flown_mach_span(setup, mach))


def _select(setup, rows, fits, gap, sig_vec, alpha, K, opts):
    """Steps 6 and 10: the detected effects (ordered by what each explains alone), their joint
    fit, its drop-one fits and, beside a table of another shell, the record of the diagnosis
    against a fitted Cd (else None). A wind model the evidence did not choose
    (``superseded_by``) takes no part."""
    found, selected_fit, drop_one, wrong_table = [], None, {}, None
    rows = [r for r in rows if not r.get("superseded_by")]
    if rows and rows[0]["significant"]:
        found, selected_fit, drop_one = select_effects(setup, rows, fits, gap, sig_vec, alpha, K)
        beside_weather = DRAG_SHAPE.name in found and set(found) - set(DRAG_EFFECTS)
        level_and_shape = None if beside_weather else shape_beside_level(setup, found, selected_fit, rows, sig_vec,
                                                                           alpha, K)
        if beside_weather or level_and_shape is not None:
            found, selected_fit, drop_one, wrong_table = _beside_a_wrong_table(
                setup, rows, found, selected_fit, drop_one, fits, gap, sig_vec, alpha, opts, joint=level_and_shape)
        # ordered by what each effect explains alone (its single chi2 drop)
        rank = {r["name"]: i for i, r in enumerate(rows)}
        found = sorted(found, key=rank.get)
    return found, selected_fit, drop_one, wrong_table


def _beside_a_wrong_table(setup, rows, found, fit, drop_one, fits, gap, sig_vec, alpha, opts, joint=None):
    """The drag effects' joint fit (:func:`bayesdrag.diagnosis.selection.wrong_table_fit`) and
    every other effect judged by a diagnosis of the round without its table (candidates: all
    but the drag effects). Returns (drag effects, their joint fit, its drop-one fits, that
    diagnosis' record); the selection unchanged and None when the drag effects' fit fails.
    ``joint``: the level and shape's fit already made (:func:`~bayesdrag.diagnosis.selection.shape_beside_level`)."""
    drag = wrong_table_fit(setup, rows, found, fit, fits, gap, sig_vec, alpha, joint=joint)
    if drag is None:
        return found, fit, drop_one, None
    names, nfit, subs = drag
    rnd = setup.rnd
    no_table = replace(rnd, projectile=replace(rnd.projectile, reference_drag=None))
    sub = diagnose(setup.track, no_table, candidates=[n for n in EFFECTS if n not in DRAG_EFFECTS
                                                      and radar_effect_missing(n, setup.channels) is None],
                   sigma=dict(setup.sigma), channels=setup.channels, alpha=alpha, **opts)
    return names, nfit, subs, sub.record


def _profile_against_shape(setup, found, fit, fits, by_name, base_res):
    """A wind profile in the selection against the table's shape in its place: an along-range wind
    that changes along the flight and a drag that changes with Mach both change the drag along the
    flight. When ``drag_shape`` removes at least :data:`~bayesdrag.diagnosis.winds.SHAPE_RIVAL_SHARE`
    of what the profile removes, the data cannot separate them, and the pair is returned for
    ``cannot_separate`` (else None). A profile that explains the gap alone stays named (``named``:
    a table's shape is never named as the cause of a wind's signature); one *beside* other members
    leaves the selection (``superseded_by`` the shape; a constant wind it had superseded comes
    back): it was taking up the model error the others leave (a 6-DOF shell's drag from its yaw
    of repose near the apex, which the point mass lacks)."""
    if WIND_PROFILE.name not in found or DRAG_SHAPE.name not in fits or DRAG_SHAPE.name in found or fit is None:
        return None
    others = [n for n in found if n != WIND_PROFILE.name]
    fit_fn = _fit_names(setup)
    try:
        ref = fit_fn(others, fit) if others else None
        rival = fit_fn(others + ["drag_shape"], fit) if others else fits[DRAG_SHAPE.name]
    except (FitError, FloatingPointError, ValueError, np.linalg.LinAlgError):
        return None
    c_ref = data_cost(ref[0]) if ref is not None else float(base_res.cost)
    share = shape_rival_share(c_ref, data_cost(fit[0]), data_cost(rival[0]))
    if share < SHAPE_RIVAL_SHARE:
        return None
    pair = {"effects": [WIND_PROFILE.name, DRAG_SHAPE.name], "rival_share": round(float(share), 4), "in_verdict": False,
            "named": not others}
    if not others:
        # the profile alone explains the gap: the wind is named (a table's shape is never named as
        # the cause of a wind's signature), the pair is reported
        return pair
    by_name[WIND_PROFILE.name]["superseded_by"] = "drag_shape"
    if by_name.get("wind", {}).get("superseded_by") == WIND_PROFILE.name:
        del by_name[WIND.name]["superseded_by"]
    return pair


def _fit_names(setup):
    """``fit_fn(names, start_fit)``: the baseline plus the effects ``names`` fitted from the
    initial state of ``start_fit``."""
    def fit_fn(names, start):
        effs = [EFFECTS[n] for n in names]
        th = [start[0].theta[:ParameterLayout(setup.P).size]]
        return fit_effects(setup, effs, np.concatenate(th + [fit_starts(e) for e in effs]))
    return fit_fn


def _wind_beside_others(setup, found, fit, drop_one, fits, by_name, b, sig_vec, alpha):
    """A wind model in a verdict with other effects, chosen again in their company by evidence
    (:func:`bayesdrag.diagnosis.winds.rechoose_wind`: the constant wind, the profile by height,
    the profile by downrange distance). Returns the verdict, its joint fit and drop-one fits, and
    the evidence of the models tried (None when there was nothing to choose)."""
    wind = [n for n in found if n in WIND_FAMILY]
    if not wind or len(found) < 2 or fit is None:
        return found, fit, drop_one, None
    y_base = b.fit[2]
    alternatives = [("wind", None)] + [("wind_profile", lay) for lay in
                                       (layers_for(setup, y_base, ax) for ax in ("altitude", "downrange"))
                                       if lay is not None]

    fit_fn = _fit_names(setup)

    def infl_fn(small, big):
        resid = np.stack([big[0].residuals[c] for c in setup.channels], axis=-1)
        return colored_inflation(big[2] - small[2], autocovariance(resid, setup.weights), sig_vec, setup.weights)

    K = max(len(by_name), 1)

    def admit_fn(name, small, big):
        return admits(setup, EFFECTS[name], small, big, b.gap, sig_vec, alpha / K)[0]

    new, nfit, lay, tried = rechoose_wind(setup, found, fit, alternatives, fit_fn, infl_fn, admit_fn)
    if not tried:
        return found, fit, drop_one, None
    setup.ctx = replace(setup.ctx, wind_layers=lay)
    if new != found or nfit is not fit:
        w_new = next((n for n in new if n in WIND_FAMILY), None)
        if w_new is not None and w_new not in by_name:
            return found, fit, drop_one, tried
        drop_one = drop_one_fits(setup, new, nfit, fits) if len(new) > 1 else {}
        found, fit = new, nfit
    if WIND_PROFILE.name in by_name and lay is not None:
        by_name[WIND_PROFILE.name].setdefault("layers", {}).update(
            {"axis": lay.axis, "edges": list(lay.edges), "n": lay.n,
             "edges_unit": "m above sea level" if lay.axis == "altitude" else "m downrange from the gun"})
    return found, fit, drop_one, tried


def _joint(setup, found, selected_fit, drop_one, by_name, chi2_base, gap):
    """The joint fit of several detected effects, as ``record["joint"]`` (None for fewer than
    two); every figure of a detected effect comes from it (written into its row)."""
    if len(found) <= 1:
        return None
    res, _, y = selected_fit
    joint = {"effects": list(found), "params": {k: float(v) for k, v in res.extras.items()},
             "shrink": float(np.clip((chi2_base - res.cost) / gap, 0, 1)) if gap > 0 else 0.0,
             "shrink_given_others": conditional_shrinks(setup, res, drop_one)}
    joint["remaining_gap_fraction"] = 1.0 - joint["shrink"]
    # parameters of different effects that the joint fit can hardly tell apart: their values
    # then rest on the shapes of the models (e.g. a cross wind against the spin drift of a
    # shell whose lift differs from the generic Mach shape) more than on the data
    k0 = res.theta.size - len(joint["params"])
    pnames = list(joint["params"])
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = res.correlation()[k0:, k0:]
    joint["sd"] = {n: float(v) for n, v in zip(pnames, np.sqrt(np.clip(np.diag(res.cov_colored)[k0:], 0, None)))}
    joint["strongly_correlated"] = [
        {"params": [pnames[i], pnames[j]], "corr": float(corr[i, j])}
        for i in range(len(pnames)) for j in range(i + 1, len(pnames))
        if pnames[i].split(".")[0] != pnames[j].split(".")[0] and abs(corr[i, j]) >= JOINT_CORR_WARN]

    for n in found:
        e, r = EFFECTS[n], by_name[n]
        idx = [pnames.index(f"{e.name}.{p.name}") for p in e.params]
        vals = np.array([joint["params"][pnames[i]] for i in idx])
        cov_e = res.cov_colored[np.ix_([k0 + i for i in idx], [k0 + i for i in idx])]
        r["params_joint"] = report_params(setup, e, vals) if e.k else {}
        r["sd_joint"] = report_params(setup, e, vals, cov_e) if e.k else {}
        r["shrink_given_others"] = joint["shrink_given_others"].get(n)
    return joint


def _verdict(setup, rows, found, by_name, wrong_table):
    """The material and the immaterial detected effects; beside a table of another shell the
    other effects' rows are those of the diagnosis against a fitted Cd. Sorts ``rows`` best
    first: the verdict, the detected but immaterial, then the rest. Returns (verdict,
    immaterial, all detected)."""
    verdict = [n for n in found if by_name[n]["material"]]
    immaterial = [n for n in found if not by_name[n]["material"]]
    for r in rows:
        r["detected"] = r["name"] in found
    if wrong_table is not None:
        # effects beside a table of another shell were judged against a fitted Cd: their rows
        # (every figure) come from that diagnosis
        sub = {r["name"]: r for r in wrong_table["effects"]}
        moved = wrong_table["verdict"] + wrong_table["immaterial"]
        for k, r in enumerate(rows):
            if r["name"] in moved:
                rows[k] = dict(sub[r["name"]], detected=True, judged_against="fitted Cd")
        verdict += wrong_table["verdict"]
        immaterial += wrong_table["immaterial"]
        found = found + moved
        what = ("the firing table has another shell's shape (drag_shape)" if DRAG_SHAPE.name in verdict
                else "drag_shape was detected (immaterial)")
        setup.notes.append(f"{what}: the other effects were judged against a fitted Cd, as without a table"
                           + (f" ({', '.join(moved)} found there)" if moved else " (none found)"))
    # the effects list is "best first": the verdict, the detected but immaterial, then the rest
    order = {n: k for k, n in enumerate(verdict + immaterial)}
    rows.sort(key=lambda r: (order.get(r["name"], len(order)),))
    return verdict, immaterial, found


def _after(track, chans, rows, found, fits, selected_fit):
    """The name of the explanation the "after" residuals show and those residuals (measured
    minus its outputs, (N, C), or None): the detected effects' joint fit, the one detected
    effect, else the best-ranked candidate."""
    best_name = rows[0]["name"] if rows else None
    y_best = fits[best_name][2] if best_name else None
    if len(found) > 1:  # "after" = the detected effects' joint fit
        best_name, y_best = " + ".join(found), selected_fit[2]
    elif found:
        best_name, y_best = found[0], fits[found[0]][2]
    resid_best = (np.stack([track.channels[c] for c in chans], axis=-1) - y_best) if y_best is not None else None
    return best_name, resid_best


def _baseline_record(setup, track, b):
    """``record["baseline"]``: the nominal simulation's misfit, noise and nuisance."""
    chans = setup.channels
    base = b.fit[0]
    n_obs = n_weighted(setup)
    return {
        "rms": {c: float(np.sqrt(np.sum(setup.weights[:, j] * b.resid[:, j] ** 2)
                                 / max(setup.weights[:, j].sum(), 1))) for j, c in enumerate(chans)},
        "chi2_per_sample": float(b.chi2 / max(n_obs, 1)),
        "chi2": b.chi2, "chi2_noise_floor": float(b.floor), "gap": float(b.gap),
        # sd of chi2 under white noise: a gap or a remaining gap of this order is noise, and
        # shrink cannot be resolved better than gap_noise_sd / gap
        "gap_noise_sd": float(math.sqrt(2.0 * max(b.floor, 1.0))),
        "prior_misfit_sd": b.prior_terms, "n_samples": int(track.n), "n_weighted": n_obs,
        "sigma": {c: float(setup.sigma[c]) for c in chans}, "sigma_source": setup.sigma_source,
        "drag": "reference" if setup.has_reference else "fitted spline (no reference drag)",
        "nuisance_drag": setup.nuisance,
        "edf": float(edf(setup, base)),
        "initial_state": {n: float(v) for n, v in zip(base.names[setup.P:], b.theta[setup.P:])},
        # the highest point of the fitted flight [m above the gun] (the met file's top, diagnosis.found_air)
        "z_max": (float(np.nanmax(b.fit[2][:, chans.index("z")])) if "z" in chans
                  else None if setup.path is None else float(np.nanmax(setup.path[:, 2]))),
        "ic_time": setup.t_ic, "converged": bool(base.converged), "message": base.message,
    }


def diagnose(track, rnd, *, candidates=None, sigma=None, channels=None, alpha=ALPHA, cd_shifts=True,
             material_cd_shift=MATERIAL_CD_SHIFT, material_end_sd=MATERIAL_END_SD):
    """Diagnose the gap between a radar track and the nominal simulation of its round.

    Parameters
    ----------
    track : RadarTrack
    rnd : Round
    candidates : sequence of str, optional
        Effect names to test (default: the whole library that the round makes testable).
    sigma : dict, optional
        Noise sd per channel [m, m/s] (default the round's ``[radar] sigma``, else estimated).
    channels : sequence of str, optional
        Channels to use (default all of the track's).
    alpha : float
        Family-wise false-alarm rate of the verdict.
    cd_shifts : bool
        Compute the Cd shift of the detected and the best-ranked effects (one extra sensitivity
        batch each). Without it the Cd part of materiality is unknown and a detected effect
        counts as material.
    material_cd_shift : float
        An effect is material when ignoring it would shift a fitted Cd by more than this
        (relative; default :data:`MATERIAL_CD_SHIFT` = 0.001, i.e. 0.1 %) anywhere in the flown
        Mach range ...
    material_end_sd : float
        ... or move the track at its last sample by more than this many noise sd (default
        :data:`MATERIAL_END_SD` = 3).

    Returns
    -------
    Diagnosis
        ``record["verdict"]`` lists the detected effects that are material, best first;
        ``record["immaterial"]`` those detected but immaterial.

    Raises
    ------
    ValueError
        A materiality threshold is negative.
    FitError
        The nominal simulation does not reach the track's times, or (without a reference drag)
        the Scheme 1 fit behind the nuisance Cd failed.
    InputError
        The track has the radar's angles and the round gives no ``[launch] azimuth``, or a
        radar effect among ``candidates`` has no channel to act on (``range_bias`` without
        ``range``, an angle bias without its angle, ``radar_position`` without a native channel).
    """
    with single_blas():   # the kernel's threads use the cores, not BLAS's
        if not (material_cd_shift >= 0 and material_end_sd >= 0):
            raise ValueError(f"materiality thresholds must be >= 0, got material_cd_shift={material_cd_shift!r}, "
                             f"material_end_sd={material_end_sd!r}")
        if candidates is not None:    # a radar's bias asked of a track without its channel
            check_radar_effects(candidates, tuple(channels) if channels is not None else track.names,
                                track.source or "track")
        setup = make_setup(track, rnd, sigma=sigma, channels=channels)
        chans = setup.channels
        sig_vec = np.array([setup.sigma[c] for c in chans])
        b = _baseline(setup)
        unseen = unseen_effects(setup, candidates)
        if any(c in NATIVE_CHANNELS for c in chans) and not ("x" in chans and "z" in chans):
            # the radar's own channels: where the shell is comes from the baseline's flight
            setup.path = gun_path(setup, b.theta)
        if unseen:
            candidates = [n for n in (candidates if candidates is not None else EFFECTS) if n not in unseen]

        effs, sigs, skipped = screen_candidates(setup, candidates, b.theta, b.span, b.fit[2])
        skipped.update(unseen)
        K = max(len(effs), 1)
        rows, fits = fit_candidates(setup, effs, b.fit, b.gap, alpha, K, skipped)
        if WIND_PROFILE.name in fits:  # its signature with the layers the evidence chose
            sigs.update(signatures(setup, b.theta, [EFFECTS[WIND_PROFILE.name]]))
        mark_confounded(rows, sigs, alpha, K)
        for r in rows:   # what the radar's own channels cannot see is said, not reported as a value
            held = held_params(setup, EFFECTS[r["name"]])
            if held:
                r["not_identifiable"] = held

        opts = dict(cd_shifts=cd_shifts, material_cd_shift=material_cd_shift, material_end_sd=material_end_sd)
        by_name = {r["name"]: r for r in rows}
        shape_rival = None
        for _ in range(2):  # a second time without a profile the data cannot tell from a table's shape
            found, selected_fit, drop_one, wrong_table = _select(setup, rows, fits, b.gap, sig_vec, alpha, K, opts)
            found, selected_fit, drop_one, wind_choice = _wind_beside_others(setup, found, selected_fit, drop_one,
                                                                             fits, by_name, b, sig_vec, alpha)
            if shape_rival is not None:
                break
            shape_rival = _profile_against_shape(setup, found, selected_fit, fits, by_name, b.fit[0])
            if shape_rival is None or shape_rival["named"]:
                break
        joint = _joint(setup, found, selected_fit, drop_one, by_name, b.chi2, b.gap)
        if wind_choice and joint:
            joint["wind_models"] = wind_choice
        # the pairs the data cannot separate: verdict members in their joint fit, a wind against
        # warmer or thinner air or a table's shape fitted beside it (diagnosis.winds)
        separate = cannot_separate(setup, found, selected_fit if len(found) > 1 else None, fits, by_name,
                                   _fit_names(setup)) + ([shape_rival] if shape_rival is not None else [])
        judge_impacts(setup, rows, found, selected_fit, fits, **opts)
        verdict, immaterial, found = _verdict(setup, rows, found, by_name, wrong_table)
        best_name, resid_best = _after(track, chans, rows, found, fits, selected_fit)

        y_base = b.fit[2]
        z_model = y_base[:, chans.index("z")] if "z" in chans else (None if setup.path is None else setup.path[:, 2])
        where = where_segments(track.t, b.resid / sig_vec[None, :], setup.weights, b.mach, z_model, chans)
        where = with_launch_misfit(where, track.t[0], b.prior_terms, b.gap)
        x_end = float(y_base[-1, chans.index("x")]) if "x" in chans else (
            0.0 if setup.path is None else float(setup.path[-1, 0]))
        absorbed = absorbed_by_launch(b.prior_terms, {p.name: p.sd for p in setup.priors}, x_end)
        for r in rows:
            r.pop("inflation_raw", None)
        record = {
            "baseline": _baseline_record(setup, track, b),
            "where": where,
            "absorbed": absorbed,
            "effects": rows,
            "verdict": verdict,
            "immaterial": immaterial,
            "joint": joint,
            "cannot_separate": separate,
            "materiality": {"cd_shift": material_cd_shift, "end_sd": material_end_sd,
                            "rule": "material when ignoring it would shift a fitted Cd by more than cd_shift "
                                    "(relative) anywhere in the flown Mach range or move the track's last sample by "
                                    "more than end_sd noise sd; detected effects are judged in their joint fit"},
            "skipped": skipped,
            "outliers": {c: [int(i) for i in np.flatnonzero(setup.outliers[:, j])] for j, c in enumerate(chans)},
            "tests": {"alpha": alpha, "candidates": K, "per_test_alpha": alpha / K,
                      "rule": "chi2 drop / colored inflation > chi2_k quantile at alpha/K"},
            "notes": setup.notes,
            "reference_drag": setup.has_reference,
        }
        try:
            found = found_atmosphere(record, rnd)
        except ValueError as exc:  # an air no met file can hold (beyond the atmosphere model): said, not written
            setup.notes.append(f"the air found could not be written as a met file ({exc})")
            found = None
        return Diagnosis(record, np.asarray(track.t), chans, dict(setup.sigma), b.resid, resid_best,
                         b.mach, setup.weights, best_name, found)
