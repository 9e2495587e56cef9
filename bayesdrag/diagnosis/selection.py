"""Which effects explain the gap together (steps 6 and 10 of :mod:`bayesdrag.diagnosis`).

Forward selection (:func:`forward_selection`) starts from the best significant effect and adds
the candidate :func:`admits` admits with the largest conditional chi2 drop; it is also started
from up to two runners-up that explain most of the gap alone, and between the resulting
explanations parsimony wins unless the larger is significantly better (:func:`is_better`).
Backward elimination (:func:`backward_elimination`) then drops a member the others make
superfluous. Beside a wind profile an effect must also be admitted against the profile at the
fit's resolution (:func:`beyond_resolution`): else it is taking up the coarse layers' misfit.
When ``drag_shape`` (a table of another shell) is detected beside a weather effect, the drag
effects keep their joint fit (:func:`wrong_table_fit`) and the rest is judged against
a fitted Cd (:func:`bayesdrag.diagnosis.core.diagnose` on the round without its table).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..effects import DRAG_SHAPE, EFFECTS, WIND_PROFILE, YAW_DRAG, confounded_with_cd, drag_level_effects, \
    spanning_effects
from ..errors import FitError
from ..estimate.model.layout import ParameterLayout
from .setup import fit_effects, fit_starts, k_free, noise_floor
from .screen import could_be_admitted, smallest_admitted_drop
from .signatures import CONFOUND_CORR
from .winds import finer_layers, refined_start
from .statistics import (autocovariance, chi2_noise_sd, chi2_quantile, colored_inflation, tested_drop, tested_inflation,
                         threshold)

__all__ = ["select_effects", "forward_selection", "backward_elimination", "is_better", "admits", "significant_beside",
           "shape_beside_level", "drop_one_fits",
           "conditional_shrinks", "structural_twins", "wrong_table_fit", "beyond_resolution", "DRAG_EFFECTS"]

#: a second (third) effect must remove at least this fraction of the baseline gap ...
MIN_SECOND_SHARE = 0.02
#: ... or at least this fraction of what the effects already selected leave: a mismatch no
#: effect describes leaves residuals a wrong effect only nibbles at (removing a small part),
#: while a second real effect explains most of what is left (the spin drift of a shell fired
#: into a head wind is a tiny share of the wind's gap)
MIN_LEFT_SHARE = 0.8
#: ... which counts only when what is left stands out of the noise: above this many sd of the
#: noise-only chi2 (with the residuals' own autocorrelation, :func:`chi2_noise_sd`)
LEFT_NOISE_K = 5.0
#: largest number of effects forward selection puts in the verdict
MAX_VERDICT = 3
#: the runner-up starts a second forward selection when it removes this much of the gap alone
LOOKAHEAD_SHRINK = 0.5
#: forward selection is started from at most this many of the best single candidates
LOOKAHEAD_STARTS = 3
#: forward selection tries at most this many further candidates per step (best single first)
FORWARD_MAX_CANDIDATES = 7
#: the effects that are a drag (table) error or cannot be told from one: a table of another
#: shell is described by these; anything else beside it is judged against a fitted Cd
DRAG_EFFECTS = confounded_with_cd()


def select_effects(setup, rows, fits, gap, sig_vec, alpha, K):
    """Forward selection from the best candidate and from the runners-up that are real
    alternatives (a look-ahead), the best of those explanations (:func:`is_better`), then
    backward elimination.

    Parameters
    ----------
    setup : Setup
    rows : list of dict
        Candidate rows, best first, with ``confounded_with`` and ``signature_corr``; the first
        one is significant.
    fits : dict name -> (MLResult, OutputErrorProblem, (N, C) outputs)
        Every candidate's single fit.
    gap : float
        Baseline gap (chi2 above its noise floor).
    sig_vec : (C,) array
        Noise sd per channel, model units.
    alpha : float
        Family-wise false-alarm rate.
    K : int
        Number of candidates tested.

    Returns
    -------
    (list of str, fit, dict)
        The selected effects, their joint fit and its drop-one fits (:func:`drop_one_fits`).
    """
    starts = [rows[0]]
    for r in rows[1:LOOKAHEAD_STARTS]:
        # drag_shape is no start of its own: never kept out of forward selection
        # (:func:`_blocked`), it enters wherever it adds what the others cannot
        if (r["significant"] and r["shrink"] >= LOOKAHEAD_SHRINK and r["name"] != DRAG_SHAPE.name
                and not any(structural_twins(setup, r, x) for x in starts)):
            starts.append(r)
    best = None
    for r0 in starts:
        v, f = forward_selection(setup, rows, r0, fits[r0["name"]], gap, sig_vec, alpha)
        if best is None or is_better(setup, (v, f), best, sig_vec, alpha, gap, K):
            best = (v, f)
    return backward_elimination(setup, best[0], best[1], fits, gap, sig_vec, alpha, K)


def _left_share_ok(setup, res, d, left, sig_vec):
    """The what-is-left rule of forward selection: the addition removes ``MIN_LEFT_SHARE`` of
    what the smaller set leaves, and that is ``LEFT_NOISE_K`` noise sd above the noise floor.
    ``res`` is the fit *with* the addition: its residuals measure the noise's correlation (those
    of the smaller set would count the very misfit in question as correlated noise)."""
    if d < MIN_LEFT_SHARE * left:
        return False
    resid = np.stack([res.residuals[c] for c in setup.channels], axis=-1)
    return left > LEFT_NOISE_K * chi2_noise_sd(autocovariance(resid, setup.weights), sig_vec, setup.weights)


def is_better(setup, new, old, sig_vec, alpha, gap, K):
    """Is the explanation ``new`` = (effect names, fit) preferable to ``old``?

    Parsimony first, judged in colored-noise units: a set with more parameters (effects count
    one each on top of their parameters) wins only when its chi2 drop over the smaller set is
    significant (chi2 quantile of the extra parameters at ``alpha / K``, drop divided by the
    colored inflation of the output difference) and, when it merely adds effects to the smaller
    set, removes at least ``MIN_SECOND_SHARE`` of the gap (the forward-selection rule); equal
    sizes: the lower cost."""
    (vn, fn), (vo, fo) = new, old
    kn = sum(k_free(setup, EFFECTS[n]) for n in vn) + len(vn)
    ko = sum(k_free(setup, EFFECTS[n]) for n in vo) + len(vo)
    if kn == ko:
        return fn[0].cost < fo[0].cost
    big, small = (fn, fo) if kn > ko else (fo, fn)
    d = float(small[0].cost - big[0].cost)
    resid = np.stack([big[0].residuals[c] for c in setup.channels], axis=-1)
    infl = colored_inflation(big[2] - small[2], autocovariance(resid, setup.weights), sig_vec, setup.weights)
    nested = set(vn) <= set(vo) or set(vo) <= set(vn)
    big_wins = d / infl > chi2_quantile(1 - alpha / K, abs(kn - ko))
    if nested:  # the bigger set adds effects to the smaller: the forward-selection rule applies
        left = float(small[0].cost) - noise_floor(setup, small[0])
        big_wins = big_wins and (d >= MIN_SECOND_SHARE * gap or _left_share_ok(setup, big[0], d, left, sig_vec))
    return big_wins if kn > ko else not big_wins


def forward_selection(setup, rows, first, first_fit, gap, sig_vec, alpha):
    """Forward selection starting from ``first``: add the candidate that :func:`admits`
    (Bonferroni over the remaining) with the largest conditional chi2 drop, up to
    ``MAX_VERDICT`` effects; beside a wind profile the first such candidate that is also
    admitted against the profile at the fit's resolution (:func:`beyond_resolution`)."""
    verdict = [first["name"]]
    selected_fit = first_fit
    remaining = []
    for r in rows:  # one of each structural twin (density/drag_scale give the same fit)
        # every candidate, not only those significant alone: a small effect beside a large one
        # is masked alone (its residuals hold the large one's misfit, which inflates its colored
        # test), and the conditional test below is the right one -- e.g. Coriolis beside a wind
        if r is first or _blocked(r, verdict):
            continue
        if any(_blocked(r, [x["name"]]) for x in remaining):
            continue
        remaining.append(r)
    remaining = remaining[:FORWARD_MAX_CANDIDATES]
    while remaining and len(verdict) < MAX_VERDICT:
        sel_res = selected_fit[0]
        # what is left above the noise floor (an addition must remove a share of the gap or of this)
        left = float(sel_res.cost) - noise_floor(setup, sel_res)
        if left <= 0:
            break
        sel_effs = [EFFECTS[n] for n in verdict]
        passed = []
        Kr = len(remaining)
        for r in remaining:
            e = EFFECTS[r["name"]]
            needed = smallest_admitted_drop(setup, selected_fit, gap, threshold(e, alpha / Kr, k_free(setup, e)),
                                            MIN_SECOND_SHARE, MIN_LEFT_SHARE)
            if not could_be_admitted(setup, sel_effs, selected_fit, e, needed, r.get("delta_chi2")):
                continue   # the score test shows its joint fit could not be admitted: not made
            start = np.concatenate([sel_res.theta, fit_starts(e)])
            try:
                res, prob, y = fit_effects(setup, sel_effs + [e], start)
            except (FitError, FloatingPointError, ValueError, np.linalg.LinAlgError):
                continue
            if not np.all(np.isfinite(y)) or (e.name == YAW_DRAG.name and res.theta[-2] < 0):
                continue  # a failed or unphysical (negative yaw amplitude) joint fit
            ok, d = admits(setup, e, selected_fit, (res, prob, y), gap, sig_vec, alpha / Kr)
            if ok:
                passed.append((r["name"], d, (res, prob, y)))
        passed.sort(key=lambda p: -p[1])  # stable: ties keep the rows' order
        finer = {}
        best_add = next((p for p in passed
                         if beyond_resolution(setup, verdict, selected_fit, p[0], p[2], gap, sig_vec, alpha / Kr,
                                              finer)), None)
        if best_add is None:
            break
        verdict.append(best_add[0])
        selected_fit = best_add[2]
        remaining = [r for r in remaining if r["name"] != best_add[0] and not _blocked(r, verdict)]
    return verdict, selected_fit


def beyond_resolution(setup, verdict, small, name, big, gap, sig_vec, a, cache):
    """Does effect ``name`` explain what the verdict's members leave *beyond their resolution*?

    A member fitted in a coarse form (``wind_profile`` in the diagnosis's few layers) leaves the
    misfit of that form -- a wind that steps inside a layer -- and a flexible addition (the
    table's shape, a warm day) can take it up: it then explains the member's representation
    error, not an effect of its own. So the addition is admitted (:func:`admits`, the same rule,
    noise model and baseline) against the members at the fit's resolution too
    (:func:`bayesdrag.diagnosis.winds.finer_layers`): the verdict refitted with them, and that
    fit with ``name`` added. True when no member has a finer form or a refit fails (the coarse
    test stands). ``cache`` (a dict) keeps the refitted verdict for the other candidates of one
    forward step."""
    lay = setup.ctx.wind_layers
    fine = finer_layers(lay) if WIND_PROFILE.name in verdict else None
    if fine is None:
        return True
    e = EFFECTS[name]
    saved = setup.ctx
    setup.ctx = replace(saved, wind_layers=fine)
    try:
        if "ref" not in cache:
            cache["ref"] = fit_effects(setup, [EFFECTS[n] for n in verdict],
                                       refined_start(setup, verdict, small[0], lay, fine))
        ref = cache["ref"]
        vals = dict(zip(big[0].names, big[0].theta))
        plus = fit_effects(setup, [EFFECTS[n] for n in verdict] + [e],
                           np.concatenate([ref[0].theta, [vals.get(f"{name}.{p.name}", p.start) for p in e.params]]))
        if not (np.all(np.isfinite(ref[2])) and np.all(np.isfinite(plus[2]))):
            return True
        return admits(setup, e, ref, plus, gap, sig_vec, a)[0]
    except (FitError, FloatingPointError, ValueError, np.linalg.LinAlgError):
        return True
    finally:
        setup.ctx = saved


def _blocked(r, names):
    """Is candidate row ``r`` kept out of forward selection by one of ``names`` (confounded with
    it: a structural twin, or as well supported)? ``drag_shape`` and ``wind_profile`` never are: a span that *contains*
    the drag-like effects it is confounded with (a yaw drag is a shape change early in the
    flight), so after one of them it can still add what they cannot, and the conditional test
    decides."""
    if r["name"] in spanning_effects():
        return False
    return bool(set(r["confounded_with"]) & set(names))


def admits(setup, e, small, big, gap, sig_vec, a):
    """Would effect ``e`` be admitted to the explanation ``small`` to give ``big``? (fits as
    (res, prob, y)). Its conditional chi2 drop ``d`` must be significant at level ``a`` in
    colored units (inflation from the residuals of ``big``) and remove ``MIN_SECOND_SHARE`` of
    the gap or, by :func:`_left_share_ok`, most of what ``small`` leaves. Returns (ok, d)."""
    sres, bres = small[0], big[0]
    d = float(sres.cost - bres.cost)
    left = float(sres.cost) - noise_floor(setup, sres)
    ok = (significant_beside(setup, e, small, big, sig_vec, a)
          and (d >= MIN_SECOND_SHARE * gap or _left_share_ok(setup, bres, d, left, sig_vec)))
    return ok, d


def significant_beside(setup, e, small, big, sig_vec, a):
    """The significance part of :func:`admits`: the conditional chi2 drop of adding effect ``e``
    to ``small`` (giving ``big``; fits as (res, prob, y)) over its colored inflation (from the
    residuals of ``big``) above the threshold at level ``a``, without the share rules."""
    (sres, _, sy), (bres, _, by) = small, big
    d = float(sres.cost - bres.cost)
    resid = np.stack([bres.residuals[c] for c in setup.channels], axis=-1)
    infl = colored_inflation(by - sy, autocovariance(resid, setup.weights), sig_vec, setup.weights)
    return bool(tested_drop(setup, e, d, sres, bres) / tested_inflation(e, infl) > threshold(e, a, k_free(setup, e)))


def shape_beside_level(setup, found, fit, rows, sig_vec, alpha, K):
    """Is the table of another shell although the selection chose only its level? Yes (the level
    and shape's joint fit is returned, else None) when the selection is one drag-level effect (``density`` or ``drag_scale``), ``drag_shape`` is
    significant alone, and added to that level its conditional drop is significant too (the
    test of :func:`admits` without its share rules, which keep out an effect that only nibbles at
    a misfit: the shape of another shell's table is no nibble, yet beside the level it can leave
    most of what is left to a third effect, the spin's lift on the demo's 6-DOF track with G1 as
    its table). The caller then judges the round as beside a table of another shell."""
    by = {r["name"]: r for r in rows}
    if not found or not set(found) <= set(drag_level_effects()) or fit is None:
        return None
    if not by.get(DRAG_SHAPE.name, {}).get("significant"):
        return None
    e = EFFECTS[DRAG_SHAPE.name]
    try:
        big = fit_effects(setup, [EFFECTS[n] for n in found] + [e], np.concatenate([fit[0].theta, fit_starts(e)]))
    except (FitError, FloatingPointError, ValueError, np.linalg.LinAlgError):
        return None
    if not np.all(np.isfinite(big[2])) or not big[0].cost < fit[0].cost:
        return None
    return big if significant_beside(setup, e, fit, big, sig_vec, alpha / max(K, 1)) else None


def drop_one_fits(setup, verdict, fit, fits):
    """Fits (res, prob, y) of the verdict without each member, by name (single fits re-used;
    a member whose reduced fit fails is left out)."""
    res = fit[0]
    out = {}
    for n in verdict:
        others = [m for m in verdict if m != n]
        if len(others) == 1 and others[0] in fits:
            out[n] = fits[others[0]]
            continue
        effs = [EFFECTS[m] for m in others]
        try:
            out[n] = fit_effects(setup, effs, np.concatenate([res.theta[:ParameterLayout(setup.P).size]] + [fit_starts(e) for e in effs]))
        except (FitError, FloatingPointError, ValueError, np.linalg.LinAlgError):
            continue
    return out


def conditional_shrinks(setup, joint_res, subs):
    """For each member of a multi-effect verdict, the fraction of the gap left by the *other*
    members that it removes: ``(cost(others) - cost(all)) / (cost(others) - noise floor)``.
    This is "how far the gap shrinks once that effect is added" when the track carries more
    than one effect (e.g. a 6-DOF shell's spin drift besides a withheld clock offset).
    ``subs``: the verdict's drop-one fits (:func:`drop_one_fits`)."""
    out = {}
    for n, (res_o, _, _) in subs.items():
        left = float(res_o.cost) - noise_floor(setup, res_o)
        out[n] = float(np.clip((res_o.cost - joint_res.cost) / left, 0.0, 1.0)) if left > 0 else 0.0
    return out


def backward_elimination(setup, verdict, fit, fits, gap, sig_vec, alpha, K):
    """Backward elimination after forward selection: drop a member that would not be admitted
    to the verdict without it (:func:`admits` and :func:`beyond_resolution`, as in
    :func:`forward_selection`), the least useful first,
    and refit. A flexible effect chosen first because it mimics two real ones at once (a head
    wind for a density change, its cross wind for the spin drift) is thus removed once both have
    entered. Returns (verdict, fit, drop-one fits of that verdict)."""
    verdict = list(verdict)
    while True:
        subs = drop_one_fits(setup, verdict, fit, fits) if len(verdict) > 1 else {}
        worst = None
        for n, sub in subs.items():
            keep, d = admits(setup, EFFECTS[n], sub, fit, gap, sig_vec, alpha / K)
            others = [m for m in verdict if m != n]
            keep = keep and beyond_resolution(setup, others, sub, n, fit, gap, sig_vec, alpha / K, {})
            if not keep and (worst is None or d < worst[1]):
                worst = (n, d, sub)
        if worst is None:
            return verdict, fit, subs
        verdict, fit = [m for m in verdict if m != worst[0]], worst[2]


def structural_twins(setup, a, b):
    """Two candidate rows are structural twins when their projected signatures span the same
    direction (canonical correlation >= CONFOUND_CORR) *and* they have as many parameters:
    their fits are then the same fit (density and drag_scale), and forward selection need not
    start from both. A smaller effect inside a larger one's span (temperature inside what
    drag_shape and a scale can do on a flat flight) is no twin: parsimony must weigh the two."""
    cc = max(a["signature_corr"].get(b["name"], 0.0), b["signature_corr"].get(a["name"], 0.0))
    return cc >= CONFOUND_CORR and k_free(setup, EFFECTS[a["name"]]) == k_free(setup, EFFECTS[b["name"]])


def wrong_table_fit(setup, rows, found, fit, fits, gap, sig_vec, alpha, joint=None):
    """The drag effects' joint fit when ``drag_shape`` is detected beside other effects.

    When ``drag_shape`` is detected the table is of another shell, and no finite shape
    correction makes it a good reference: on a precise track what the correction leaves is
    still far above the noise, and a weather effect that changes the drag along the flight (a
    head wind changes the air speed, a temperature the Mach number) removes part of it -- a
    55 m/s head wind beside the shape of a G7 table flown by a G1 bullet. So the explanation
    keeps the drag: ``drag_scale`` (the level, when it is admitted beside the shape) and
    ``drag_shape`` in their joint fit, and every other effect is judged as a round without a
    table is: by a diagnosis against a fitted Cd (the Scheme 1 spline), which sees a wind by
    what it does to the path, not to the drag (the caller runs that diagnosis).

    The level is the twin the selection found (``density`` or ``drag_scale``; docs/diagnosis.md: a
    table error is named ``drag_scale`` when the implied air is outside the round's stated
    atmosphere, and a round that states none bounds it only by ``density``'s physical range), or
    else the better ranked of the two, kept when :func:`admits` admits it beside the shape.

    Parameters
    ----------
    setup : Setup
    rows : list of dict
        Candidate rows, best first.
    found : list of str
        The selected effects (``drag_shape`` among them, or a level alone that it is significant
        beside: :func:`shape_beside_level`).
    fit : (MLResult, OutputErrorProblem, (N, C) outputs)
        Their joint fit (its values start the drag effects' fit).
    fits : dict
        Every candidate's single fit.
    gap : float
    sig_vec : (C,) array
        Noise sd per channel.
    alpha : float
    joint : (MLResult, OutputErrorProblem, (N, C) outputs), optional
        The level and shape's joint fit from this start, already made
        (:func:`shape_beside_level`'s): taken instead of fitting them again.

    Returns
    -------
    (list of str, fit, dict) or None
        The drag effects, their joint fit and its drop-one fits; None when that fit fails.
    """
    by = {r["name"]: r for r in rows}
    level = [n for n in found if n in drag_level_effects()]
    if not level:
        level = [r["name"] for r in rows if r["name"] in drag_level_effects()][:1]
    names = level[:1] + ["drag_shape"]
    res = fit[0]
    k0 = ParameterLayout(setup.P).size
    vals = dict(zip(res.names[k0:], res.theta[k0:]))
    start = [res.theta[:k0]]
    for n in names:
        e = EFFECTS[n]
        start.append([vals.get(f"{n}.{p.name}", s0) for p, s0 in zip(e.params, fit_starts(e))])
    try:
        nfit = joint if joint is not None and list(joint[1].effect_names) == names else \
            fit_effects(setup, [EFFECTS[n] for n in names], np.concatenate(start))
        if len(names) == 2 and names[0] not in found and DRAG_SHAPE.name in fits:
            ok, _ = admits(setup, EFFECTS[names[0]], fits[DRAG_SHAPE.name], nfit, gap, sig_vec, alpha / max(len(by), 1))
            if not ok:
                names, nfit = ["drag_shape"], fits[DRAG_SHAPE.name]
    except (FitError, FloatingPointError, ValueError, np.linalg.LinAlgError):
        return None
    subs = drop_one_fits(setup, names, nfit, fits) if len(names) > 1 else {}
    return names, nfit, subs
