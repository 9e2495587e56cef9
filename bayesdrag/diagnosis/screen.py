"""The score-test screen: whether adding an effect to a fit *could* pass the conditional test of
forward selection, judged at the fit's optimum without refitting.

At the optimum of the smaller fit the track's sensitivities (to the fitted parameters and to the
effect's, at its "no effect" value) and the whitened residuals are known. One Gauss-Newton step
from there predicts the chi2 drop of the joint fit, ``g' M^-1 g`` (``g`` the gradient of the
cost, ``M`` the Gauss-Newton information, prior rows included): the score (Lagrange-multiplier)
statistic of the effect. The joint fit is made only when that prediction, with a safety factor for
the model's curvature, could reach the smallest drop :func:`~bayesdrag.diagnosis.selection.admits`
can accept; the other candidates are dismissed unfitted. Whatever the screen dismisses, the
selection would have rejected: the verdict is the one without the screen (the suites measure it;
docs/measurements.md has the figures).

A decaying yaw (``yaw_drag``) is never screened: at zero amplitude its decay rate is invisible
(Davies' problem), so a score at one decay rate says nothing of the drop at the rate its fit finds.
"""
from __future__ import annotations

import numpy as np

from ..effects import YAW_DRAG
from ..errors import FitError
from .setup import effect_problem

__all__ = ["predicted_drop", "smallest_admitted_drop", "could_be_admitted", "SCREEN_SAFETY"]

#: the predicted drop is multiplied by this before it is compared with the smallest admissible
#: one: a one-step prediction of a nonlinear effect can fall short of the drop its fit reaches
#: (the screen must never dismiss what the fit would admit; dismissing less costs time only)
SCREEN_SAFETY = 4.0
#: the colored inflation a test divides by is at least this (statistics.colored_inflation's floor)
_INFLATION_FLOOR = 0.05
#: outputs of the joint problem at the effect's "no effect" value that differ from the smaller
#: fit's by more than this many noise sd: that null is not the smaller model, no screen [-]
_NULL_MISMATCH_SD = 1e-3


def predicted_drop(setup, small_effects, small_fit, e):
    """One Gauss-Newton step's chi2 drop of adding effect ``e`` to ``small_fit``.

    Parameters
    ----------
    setup : Setup
    small_effects : sequence of Effect
        The effects of the smaller fit, in its parameter order.
    small_fit : (MLResult, OutputErrorProblem, (N, C) array)
        The smaller fit at its optimum.
    e : Effect

    Returns
    -------
    float or None
        ``g' M^-1 g`` [chi2] at the smaller fit's optimum with ``e`` at its "no effect" value;
        None when it cannot be formed (the joint model at the null is not the smaller fit's, a
        trajectory is not finite) and for a decaying yaw (module docstring): the caller fits.
    """
    if e.name == YAW_DRAG.name:
        return None
    res, _, y_small = small_fit
    sig_vec = np.array([res.sigma[c] for c in setup.channels])
    null = np.array([p.start for p in e.params], float)
    try:
        prob = effect_problem(setup, list(small_effects) + [e], np.concatenate([res.theta, null]))
        theta = prob.theta0
        y, _, S = prob.sensitivities(theta)
    except (FitError, FloatingPointError, ValueError, np.linalg.LinAlgError):
        return None
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(S))):
        return None
    mismatch = np.nanmax(np.abs(y - y_small) * (setup.weights > 0) / sig_vec[None, :])
    if not mismatch <= _NULL_MISMATCH_SD:
        return None
    resid = prob.z - y
    A = prob.weighted(S, res.sigma, res.ar).reshape(-1, S.shape[-1])
    rw = prob.weighted(resid, res.sigma, res.ar).reshape(-1)
    pr, pJ = prob.prior_terms(theta)
    if pr.size:
        A, rw = np.vstack([A, pJ]), np.concatenate([rw, pr])
    g = A.T @ rw
    try:
        d = float(g @ np.linalg.lstsq(A.T @ A, g, rcond=None)[0])
    except np.linalg.LinAlgError:
        return None
    return d if np.isfinite(d) else None


def smallest_admitted_drop(setup, small_fit, gap, threshold_value, second_share, left_share):
    """The smallest conditional chi2 drop :func:`~bayesdrag.diagnosis.selection.admits` can
    accept from ``small_fit`` [chi2]: above the threshold times the lowest colored inflation,
    and at least ``second_share`` of the gap or ``left_share`` of what is left (selection's
    ``MIN_SECOND_SHARE`` and ``MIN_LEFT_SHARE``; the rule's noise condition on what is left is
    taken as met: it reads the joint fit)."""
    from .setup import noise_floor

    res = small_fit[0]
    left = float(res.cost) - noise_floor(setup, res)
    # the what-is-left rule is taken as open whatever the joint fit's noise sd turns out
    share = min(second_share * gap, left_share * max(left, 0.0))
    return max(_INFLATION_FLOOR * threshold_value, share)


def could_be_admitted(setup, small_effects, small_fit, e, needed, single_drop):
    """False only when ``e`` cannot bring the drop ``needed`` (:func:`smallest_admitted_drop`)
    by either sign: its predicted drop at the smaller fit's optimum times :data:`SCREEN_SAFETY`
    falls short, *and* so does its drop when fitted alone (``single_drop``, from the baseline).
    The score is local: beside a wind profile whose cross winds took up a 6-DOF shell's spin
    drift, ``lift`` predicted 0.8 and its joint fit, reaching another optimum where the winds
    give the drift back, dropped 487; alone it had dropped thousands. True when the prediction
    cannot be formed (the candidate is fitted)."""
    if single_drop is None or not single_drop < needed:
        return True
    d = predicted_drop(setup, small_effects, small_fit, e)
    return d is None or SCREEN_SAFETY * d >= needed
