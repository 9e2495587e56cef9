"""How large a drag model a track can determine: counted before any fitting work, and the knots
of the default spline sized to the data.

A fit has as many unknowns as its free initial-state values plus the drag model's effective
parameters, and a track holds samples x channels values. A penalised spline's effective size is
not its coefficient count: its smoothness penalty is a pseudo-measurement on every curvature, so
the data must determine only its null space, a straight-line correction
(:func:`check_determinable`; :class:`bayesdrag.estimate.model.problem.OutputErrorProblem` counts the
same way). A track too short for the default spline but long enough for one factor on the firing
table is fitted with that factor (and says so); one too short for even that is refused, naming
the smallest model and the samples it needs.

Knots (:func:`default_knots`) follow where the data's shape and the table bend
(:func:`bayesdrag.estimate.build.basis.adaptive_knots`); a *short* track, with fewer samples than
those rules want coefficients, gets at most one coefficient per sample and no knot between two
samples the data cannot tell apart (:func:`bayesdrag.estimate.build.basis.sparse_knots`), and its bands
include how far Cd may bend between its samples (:func:`bayesdrag.estimate.cd.quality.unresolved_bend`).
"""
from __future__ import annotations

import numpy as np

from ...errors import InputError
from ...measure import gun_equivalent
from ..model.layout import ParameterLayout
from .basis import KNOT_TOL, NEAR_FINE, RISE_SPACING, adaptive_knots, coefficient_budget, rise_regions, sparse_knots
from .launch import unseen_launch_priors

__all__ = ["MIN_FIT_SAMPLES", "NARROW_SPAN_MACH", "SHAPE_SLOPE_SD", "check_determinable", "default_knots", "free_mask",
           "narrow_shape_sd", "narrow_span_model"]

#: the knots follow the start's shape to no finer than this many times its own noise
KNOT_NOISE_FACTOR = 2.0


def free_mask(P, n, chans, free_ic, drag_name, span):
    """Which of ``n`` parameters (``P`` drag coefficients, then the initial state) a Scheme 1 fit
    estimates: the initial state unless ``free_ic`` is False, no cross-range state without a
    ``y`` channel, no position without a position channel, and ``poly2-split``'s coefficients
    only on the sides of Mach 1 the data's Mach ``span`` reaches."""
    free = np.ones(n, bool)
    chans = gun_equivalent(chans)      # a radar's range, angles, range rate observe x, y, z, v
    lay = ParameterLayout(P)
    if not free_ic:
        free[lay.state] = False
    if "y" not in chans:
        free[lay.index("y")] = free[lay.index("vy")] = False
    if not any(c in chans for c in ("x", "y", "z")):
        free[lay.position] = False
    if drag_name == "poly2-split":
        lo, hi = span
        if hi < 1.0:
            free[3:6] = False
        if lo >= 1.0:
            free[0:3] = False
    return free


#: fewest samples a fit accepts: positions must bend (three points) for the drag to show
MIN_FIT_SAMPLES = 3
#: effective drag parameters of each model at its smallest: the penalised spline's penalty
#: leaves a straight-line correction (its null space) to the data; ``poly2-split`` has 3 on a
#: flight on one side of Mach 1 (6 across it: the problem itself then counts them)
_MODEL_SIZE = {"reference-scale": 1, "spline": 2, "poly2": 3, "poly2-split": 3}


def _ic_unknowns(track, rnd, chans, free_ic):
    """Initial-state values the data must determine: the free ones less those the unseen
    launch priors pin (no z: the muzzle height and the elevation are priors)."""
    free = free_mask(0, 6, chans, free_ic, "", (0.0, 0.0))
    pinned = set(unseen_launch_priors(track, rnd, chans))
    n = int(free.sum())
    n -= int("X0_muzzle" in pinned and free[0]) + int("Z0_muzzle" in pinned and free[2])
    n -= int("elevation" in pinned and bool(free[3] or free[5]))
    return max(n, 0)


def check_constant_channels(track, chans):
    """Raise :class:`InputError` when a channel of ``chans`` is constant: it says nothing of the
    flight (``y`` may be 0 throughout beside other channels, a flight in the plane of fire, not
    alone). Checked before any fitting or diagnosis work."""
    for ch in chans:
        vals = np.asarray(track.channels[ch], float)
        if vals.size and np.ptp(vals) == 0.0 and (ch != "y" or len(chans) == 1):
            raise InputError(f"{track.source or 'track'}: channel {ch} is constant ({vals[0]:g}); it carries no "
                             f"information — drop the column or fix the track")


#: a track spanning less Mach than this [-] cannot tell a slope of Cd / table from its noise and
#: its initial speed: with a table the default model is then one factor on it, whose shape the
#: pipeline checks against the flexible fit of the same track (a chronograph shot spans 0.05-0.2;
#: a chronograph session, whose shots spread in speed, fits its slope itself)
NARROW_SPAN_MACH = 0.3


#: how far Cd / table may depart from the table's shape per Mach [1/Mach] when one factor on it
#: is fitted over a narrow span: the session's shape prior (15 % of the level per 0.1 Mach). The
#: standard functions' log-ratio slopes reach 0.5 per Mach above Mach 1.3 and 1.9 below 0.8
#: (docs/measurements.md, "Where the constants come from")
SHAPE_SLOPE_SD = 1.5


def narrow_shape_sd(span, grid, ml):
    """The shape error [Cd] of one factor on the table at each row (Mach ``grid``, Cd ``ml``):
    :data:`SHAPE_SLOPE_SD` times the distance from the middle of the data's Mach ``span``, so
    the middle is the factor's own and the ends carry how far the shape may lean."""
    mid = 0.5 * (float(span[0]) + float(span[1]))
    return SHAPE_SLOPE_SD * np.abs(np.asarray(grid, float) - mid) * np.abs(np.asarray(ml, float))


def narrow_span_model(span, table, drag, knots):
    """The model-size rule by Mach span: ``"reference-scale"`` when the default spline was asked
    (``drag == "spline"``, no explicit ``knots``), the round has a ``table`` and the data's Mach
    ``span`` (lo, hi) is narrower than :data:`NARROW_SPAN_MACH`, else None."""
    if drag != "spline" or knots is not None or not table:
        return None
    return "reference-scale" if float(span[1]) - float(span[0]) < NARROW_SPAN_MACH else None


def check_determinable(track, rnd, chans, free_ic=True, drag="spline", knots=None):
    """Can this track determine the drag model asked for, or at least the smallest one?

    Counted before any fitting work: no channel may be constant (it says nothing), and the
    track's values (samples x channels) must outnumber
    the unknowns: the initial-state values (:func:`_ic_unknowns`) plus the model's effective
    drag parameters (:data:`_MODEL_SIZE`: a penalised spline counts its penalty's null space,
    however many coefficients it has; explicit knots count every coefficient). The smallest
    model is one factor on the firing table (``reference-scale``), or without a table the
    penalised spline at its stiffest (a straight-line correction of the drag curve read off the
    track).

    Returns
    -------
    str or None
        ``"reference-scale"`` when the default spline is too large for the track but the
        table's one factor is not (the fit then uses it and says so), else None.

    Raises
    ------
    InputError
        When even the smallest model is not determined, naming it and the samples it needs; or
        when an explicitly chosen model is too large, naming the smallest that is not.
    """
    n, c = int(track.n), len(chans)
    check_constant_channels(track, chans)
    if drag == "reference-scale" and rnd.reference_drag is None:
        # refused here, before the start is read off the track (it was found after seconds of fitting)
        raise InputError("drag model 'reference-scale' needs a reference drag table: set [projectile] "
                         "reference_drag in the round file")
    ic = _ic_unknowns(track, rnd, chans, free_ic)
    table = rnd.reference_drag is not None
    small = ("reference-scale", "one factor on the firing table") if table else (
        "spline", "the default spline at its stiffest: a straight-line correction of the drag curve read off the track")
    k_small = _MODEL_SIZE[small[0]] + ic
    src = track.source or "track"
    if n < MIN_FIT_SAMPLES or n * c <= k_small:
        need = max(MIN_FIT_SAMPLES, k_small // c + 1)
        raise InputError(
            f"{src}: {n} samples x {c} channel{'s' if c > 1 else ''} ({','.join(chans)}) are too few to determine Cd: "
            f"even the smallest drag model, {small[1]}, has {k_small} unknowns with the {ic} initial-state values "
            f"the data must give; it needs at least {need} samples of these channels (or more channels, or "
            f"--fix-ic to take the initial state from the round)")
    if knots is not None:
        k_req = len(tuple(knots)) + 2 + ic
    else:
        k_req = _MODEL_SIZE.get(drag, 0) + ic
    if n * c > k_req:
        return None
    if drag == "spline" and knots is None and table:
        return "reference-scale"
    what = f"--drag {drag}" + (f" with {len(tuple(knots))} knots" if knots is not None else "")
    raise InputError(
        f"{src}: {n} samples x {c} channel{'s' if c > 1 else ''} are too few for {what} ({k_req} unknowns with "
        f"the {ic} initial-state values); the smallest model this track determines is {small[1]}"
        + (" (--drag reference-scale)" if table else " (the default --drag spline)"))


def default_knots(reference, start, lo, hi):
    """Knots of the default (penalised) spline over [lo, hi] and the record of the model's size.

    The knots follow where the start's shape (and the table) bend
    (:func:`bayesdrag.estimate.build.basis.adaptive_knots`), to :data:`KNOT_TOL` but not into wiggles
    the start's noise left. A short track, with fewer samples than those rules want
    coefficients, gets at most one coefficient per sample, and no knot between two samples
    that the data cannot tell apart (:func:`bayesdrag.estimate.build.basis.sparse_knots`): the
    model's size follows the data.

    Returns
    -------
    (knots, dict)
        The dict (``ml.model_size`` of result.json): ``samples``, ``coefficients``,
        ``knot_rules`` (coefficients the rules alone want), ``short`` (bool) and, for a short
        track, ``mach_step`` (median Mach step between samples).
    """
    shape = start.shape_curve
    tol = max(KNOT_TOL, KNOT_NOISE_FACTOR * start.shape_noise)
    if reference is not None:
        shapes = [lambda m: shape(m) / reference.value(m)]
        regions = [(a, b, NEAR_FINE) for a, b in rise_regions(lo, hi, reference.value)]
    else:
        shapes = [shape]
        regions = [(a, b, RISE_SPACING) for a, b in rise_regions(lo, hi, shape)]
    k = adaptive_knots(lo, hi, shapes, tol=tol, regions=regions)
    n = int(start.kinematics.t.size)
    budget = coefficient_budget(n)
    record = {"samples": n, "knot_rules": int(k.size + 2), "short": bool(k.size + 2 > n)}
    if k.size + 2 > budget:
        k = sparse_knots(lo, hi, shapes, budget, start.track_mach, tol=tol, regions=regions)
    if record["short"]:
        record["mach_step"] = float(start.mach_step)
    record["coefficients"] = int(k.size + 2)
    return k, record
