"""Scheme 1: Cd(M) over the whole flight together with the initial conditions (paper §3-4).

How a fit is set up and run (each choice with its reason):

* **Start from the data** (:mod:`bayesdrag.estimate.start`). The Mach span, the starting Cd(M)
  and the state at the first sample are read off the track (smoothed speed, its rate and the
  path angle), not from the round's nominal launch values or a generic curve: a round file may
  be wrong, and a shell may be nothing like a 155 mm one. A track whose path bends as if gravity
  were 32 (feet) or 10.7 (yards) units/s^2 is refused with the likely unit.
* **Default drag model: ``spline``**, a *penalised* cubic B-spline (P-spline, Eilers & Marx
  1996). With a firing table it is the table times a smooth correction
  (:class:`bayesdrag.drag.TableSpline`: the table is evaluated exactly, so a correct table costs
  nothing however steep its rise); without one, a spline in Cd itself. Knots are placed where
  the start curve (and the table) bend (:func:`bayesdrag.estimate.basis.adaptive_knots`); the
  penalty is on the second derivative of the relative correction ``Cd / base`` (base: the table,
  or the start curve), its weight chosen by maximising the Laplace-approximated marginal
  likelihood (the evidence) over :data:`SMOOTHING_GRID`, and allowed more freedom where the base
  itself bends. Why not knots added one by one by BIC: BIC's ``log N`` per knot (~9 for a
  1500-sample track) refuses corrections of a few Cramér-Rao sd, so the representation error
  stays several bounds wide where Cd bends; the penalised spline follows the bend and its bounds
  include the smoothing (the curvature of the penalised cost is the posterior sd under the
  smoothness prior, Wahba 1983, which the Bayesian layer samples too). ``edf`` is reported.
  Explicit ``knots`` give a plain (unpenalised) spline. ``poly2`` and ``poly2-split`` are the
  paper's and are kept for comparison; their misfit is reported, not hidden.
* **Continuation** (:func:`fit_scheme1`): first the initial state and one overall scale of the
  start curve (7 parameters, a well-posed problem from any sane start), then the full curve from
  there; when the Levenberg-Marquardt fit does not converge, scipy's trust-region reflective
  least squares continues from where it stopped (:meth:`OutputErrorProblem.fit` ``fallback``).
* **Launch priors**: when the track starts at t = 0 and the round gives the launch velocity and
  elevation, the muzzle at the origin, the launch speed and the elevation are Gaussian priors.
  Each is first checked against a fit without them: one that disagrees with the track by more
  than :data:`LAUNCH_CONFLICT_K` combined sd is reported and left out, not obeyed (a nominal
  muzzle velocity 15 % off; a time origin at the first radar sample instead of the launch).
  A track that starts later gets no launch priors; its state extrapolated back to t = 0 is
  compared with the round's launch values and a disagreement is reported.
* **Earth rotation** is in the model when the round gives ``[launch] latitude`` (with
  ``azimuth``), as in ``bayesdrag simulate``.
* **Noise**: the round's ``[radar] sigma`` when given for a channel, else estimated by
  relaxation.
* **Determined Mach range**: where the sd of Cd is below 1 % of Cd, inside the Mach span of the
  data, and not where the curve is clamped or held at a bound (:mod:`bayesdrag.estimate.quality`).
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from .._threads import single_blas
from ..drag import ReferenceScale, ReferenceTable, Spline, TableSpline, default_spline_knots, make_drag_model
from ..dynamics.pointmass import PointMassModel, initial_state
from ..errors import FitError, InputError
from .basis import (KNOT_TOL, NEAR_FINE, RISE_SPACING, adaptive_knots, curvature_weights, rise_regions,
                    second_difference_rows)
from .problem import OutputErrorProblem, Prior
from .start import check_gravity_units, data_start

#: relative CRB sd of Cd below which Cd counts as determined by the data
DETERMINED_REL_SD = 0.01
#: initial-condition parameters after the drag coefficients (X0, Y0, Z0, Ux0, Uy0, Uz0)
_N_IC = 6
#: Student-t degrees of freedom of the robust fit (4: heavy tails, finite variance)
ROBUST_NU = 4.0
#: reweighting passes of the robust fit
ROBUST_ITERATIONS = 6
#: a sample more than this many noise scales off the robust curve is listed as rejected
REJECT_K = 5.0
#: candidate sd of the correction's second derivative, integral (s'')^2 dM ~ 1/sd^2 [Mach^-1.5]
#: (the penalty weight is 1/sd^2); a 5 % change over 0.05 Mach needs ~20, a 1 % tilt over the
#: whole flight ~0.05
SMOOTHING_GRID = tuple(10.0 ** np.arange(-3.0, 3.01, 0.5))
#: the knots follow the start's shape to no finer than this many times its own noise
KNOT_NOISE_FACTOR = 2.0
#: the Mach span of the drag model extends the data's by this much at each end (the fitted
#: trajectory may reach a little beyond the smoothed speed's extremes)
SPAN_MARGIN = 0.02
#: a launch prior that disagrees with the track by more than this many combined sd is dropped
LAUNCH_CONFLICT_K = 4.0


def _initial_state(track, rnd):
    """State at the first sample read off the track (:func:`bayesdrag.estimate.start.data_start`)."""
    return data_start(track, rnd).state0


def _coriolis(rnd):
    L = rnd.launch
    return (L.latitude_deg, L.azimuth_deg) if L.latitude_deg is not None else None


def mach_span(track, rnd, state0=None):
    """Mach range the track flies, from its smoothed speed and height (``state0`` is ignored;
    kept for callers of the earlier simulation-based version)."""
    return data_start(track, rnd).mach_span


def launch_state_priors(L, P, heading=False, names=None):
    """Gaussian priors on the state at launch (t = 0) from a round's ``[launch]`` ``L``, for a
    parameter vector whose initial state starts at index ``P``: muzzle at the origin
    (``position_sd`` per axis), launch speed (``velocity_sd``), elevation (``elevation_sd``) and,
    with ``heading``, a heading along +x with the elevation's sd (the diagnosis); ``names``
    keeps only the priors of those names.

    The functions take one parameter vector (n,) or many (W, n): the sampler evaluates all
    walkers at once.
    """
    from .problem import Prior

    pri = [Prior(f"{n}_muzzle", (lambda th, k=k: th[..., P + k]), 0.0, L.position_sd)
           for k, n in enumerate(("X0", "Y0", "Z0"))]
    pri.append(Prior("launch_speed", lambda th: np.sqrt(th[..., P + 3] ** 2 + th[..., P + 4] ** 2
                                                        + th[..., P + 5] ** 2), L.velocity, L.velocity_sd))
    pri.append(Prior("elevation", lambda th: np.degrees(np.arctan2(th[..., P + 5], np.hypot(th[..., P + 3],
                                                                                           th[..., P + 4]))),
                     L.elevation_deg, L.elevation_sd_deg))
    if heading:
        pri.append(Prior("heading", lambda th: np.degrees(np.arctan2(th[..., P + 4], th[..., P + 3])),
                         0.0, L.elevation_sd_deg))
    if names is not None:
        pri = [p for p in pri if p.name in names]
    return tuple(pri)


def launch_priors(track, rnd, P):
    """The round's launch priors (:func:`launch_state_priors`) when the track starts at the
    muzzle (t = 0) and the launch is known, else none. They are weak against a full x, y, z, v
    track but keep a speed-only (Doppler) track's elevation where the gun put it."""
    L = rnd.launch
    if abs(float(track.t[0])) > 1e-9 or L.velocity is None or L.elevation_deg is None:
        return ()
    return launch_state_priors(L, P)


def model_span(span):
    """Mach span of the drag model: the data's ``(lo, hi)``, widened by :data:`SPAN_MARGIN`."""
    lo, hi = span
    return max(lo - SPAN_MARGIN, 0.05), hi + SPAN_MARGIN


def build_drag_model(drag, reference, start, knots=None, penalise=True, span=None):
    """The drag model of a Scheme 1 fit and the base curve its smoothness penalty is relative to.

    Parameters
    ----------
    drag : str
        ``spline`` (default), ``poly2``, ``poly2-split`` or ``reference-scale``.
    reference : ReferenceTable or None
        The round's firing table.
    start : DataStart
    knots : sequence of float, optional
        Explicit knots: a plain spline in Cd (unpenalised).
    penalise : bool
        False: a plain spline on :func:`bayesdrag.drag.default_spline_knots` (the sparse knots
        of the unpenalised model, kept to show why the default is penalised).
    span : (float, float), optional
        Mach span of the data (default: the start's).

    Returns
    -------
    (DragModel, base) where ``base`` is None for an unpenalised model, else ``(table, shape)``:
    the table the correction multiplies (None without one: the penalty is then on Cd's own
    curvature) and the data's smoothed shape (where the drag bends).
    """
    lo, hi = model_span(start.mach_span if span is None else span)
    if drag != "spline":
        try:
            return make_drag_model(drag, reference=reference, mach_range=(lo, hi)), None
        except ValueError as exc:
            raise InputError(str(exc)) from None
    if knots is not None or not penalise:
        try:
            k = default_spline_knots(lo, hi) if knots is None else tuple(float(v) for v in knots)
            return Spline(tuple(k)), None
        except ValueError as exc:
            raise InputError(str(exc)) from None
    shape = start.shape_curve
    # the knots follow the shape to KNOT_TOL, but not into wiggles the start's noise left
    tol = max(KNOT_TOL, KNOT_NOISE_FACTOR * start.shape_noise)
    if reference is not None:
        ratio = lambda m: shape(m) / reference.value(m)  # noqa: E731
        regions = [(a, b, NEAR_FINE) for a, b in rise_regions(lo, hi, reference.value)]
        k = adaptive_knots(lo, hi, [ratio], tol=tol, regions=regions)
        dm = TableSpline(reference, tuple(k))
        base = (reference.value, shape)
    else:
        regions = [(a, b, RISE_SPACING) for a, b in rise_regions(lo, hi, shape)]
        k = adaptive_knots(lo, hi, [shape], tol=tol, regions=regions)
        dm = Spline(tuple(k))
        base = (None, shape)
    return dm, base


def _free_mask(P, n, chans, free_ic, drag_name, span):
    free = np.ones(n, bool)
    if not free_ic:
        free[P:P + 6] = False
    if "y" not in chans:
        free[P + 1] = free[P + 4] = False
    if not any(c in chans for c in ("x", "y", "z")):
        free[P:P + 3] = False
    if drag_name == "poly2-split":
        lo, hi = span
        if hi < 1.0:
            free[3:6] = False
        if lo >= 1.0:
            free[0:3] = False
    return free


@single_blas
def fit_scheme1(track, rnd, drag="spline", channels=None, sigma=None, free_ic=True, knots=None,
                penalise=True, likelihood="gaussian", nu=ROBUST_NU, start=None):
    """Scheme 1 ML fit of one track.

    Parameters
    ----------
    track : RadarTrack
    rnd : Round
    drag : str
        Drag model name: ``spline`` (default), ``poly2``, ``poly2-split``, ``reference-scale``.
    channels : sequence of str, optional
    sigma : dict, optional
        Fixed noise sd per channel (default: the round's ``[radar] sigma``).
    free_ic : bool
        Estimate the initial conditions (paper Fig. 3c) or keep them at their starting values
        (Fig. 3b: the round's launch values for a track from t = 0, else the data's).
    knots : sequence of float, optional
        Spline knots: a plain (unpenalised) spline on these knots.
    penalise : bool
        ``False`` with ``knots=None``: a plain spline on
        :func:`bayesdrag.drag.default_spline_knots`.
    likelihood : {"gaussian", "student-t"}
        ``student-t``: a robust fit for tracks with gross outliers, see :func:`robust_refit`.
    nu : float
        Degrees of freedom of the Student-t likelihood.
    start : DataStart, optional
        A start already read off this track.

    Returns
    -------
    (MLResult, OutputErrorProblem)
        The problem carries ``smoothing`` (dict or None), ``start`` (DataStart), ``launch_check``
        (dict: the priors used, those left out and why) and ``base`` (the penalty's base curve).
    """
    if likelihood not in ("gaussian", "student-t"):
        raise InputError(f"likelihood {likelihood!r} is not allowed; use gaussian or student-t")
    chans = tuple(channels) if channels is not None else track.names
    seen = track.with_channels(chans) if set(chans) != set(track.names) else track
    if start is None:
        start = data_start(seen, rnd)
    check_gravity_units(start.kinematics, track.source)
    L = rnd.launch
    t0 = float(track.t[0])
    s0 = start.state0
    if not free_ic and abs(t0) < 1e-9 and L.velocity is not None and L.elevation_deg is not None:
        s0 = initial_state(L.velocity, L.elevation_deg)
    sig = dict(rnd.radar.sigma) if sigma is None else dict(sigma)
    if not any(c in chans for c in ("x", "y", "z")):
        s0 = s0.copy()
        s0[:3] = 0.0 if abs(t0) < 1e-9 else s0[:3]
    # launch values the channels cannot see (no z: the muzzle height and the elevation) are
    # priors from the start; the others are checked against the track first
    unseen = _unseen_launch_priors(track, rnd, chans)
    if unseen and abs(t0) < 1e-9 and "z" not in chans:
        s0 = s0.copy()
        s0[2] = 0.0
    # stage A: the initial state and one scale of the start curve; its trajectory also gives the
    # Mach span better than the smoothed speed, whose ends are the least certain part of it
    table = ReferenceTable(tuple(start.mach), tuple(start.cd), source="start curve from the track")
    base_model = PointMassModel(rnd.projectile.mass, rnd.projectile.diameter, ReferenceScale(table),
                                rnd.atmosphere, coriolis=_coriolis(rnd))
    ic_free = _free_mask(0, 6, chans, free_ic, "", (0, 0))
    state, scale, span_a = _stage_scale(base_model, track, s0, ic_free, sig, chans, likelihood,
                                        launch_state_priors(L, 1, names=unseen) if unseen else ())
    span = start.mach_span if span_a is None else (min(start.mach_span[0], span_a[0]),
                                                   max(start.mach_span[1], span_a[1]))
    dm, base = build_drag_model(drag, rnd.reference_drag, start, knots, penalise, span=span)
    model = base_model.with_(drag=dm)
    P = dm.n_params
    free = _free_mask(P, P + 6, chans, free_ic, dm.name, span)
    m = np.linspace(*dm.fit_range, 200)
    theta0 = np.concatenate([dm.params_for(m, scale * start.curve(m)), state])
    if not free_ic:
        theta0[P:] = s0
    fixed_pri = launch_state_priors(L, P, names=unseen) if unseen else ()
    prob = OutputErrorProblem(model, track, theta0, free=free, sigma=sig, channels=chans, priors=fixed_pri)
    if likelihood == "student-t":
        # start from a fit whose noise sd is estimated (relaxation inflates it over the
        # outliers instead of bending the curve to them), then reweight
        prob.sigma_fixed = {}
    prob.start = start
    prob.base = base
    pen = None
    if base is not None:
        pen = _penalty(dm, base)
        prob.priors = fixed_pri + pen(SMOOTHING_GRID[len(SMOOTHING_GRID) // 2])[0]
    # stage B: the full curve without the checked launch priors, then check them against it
    res_b = prob.fit(fallback=True)
    if res_b.success or np.all(np.isfinite(res_b.theta)):
        prob.theta0 = res_b.theta.copy()
    wider = _wider_span(dm, res_b, span)
    if wider is not None and knots is None:
        # the fitted flight reaches beyond the model's Mach span (the smoothed speed's ends
        # were low): rebuild the model over the flight's span and refit from this curve
        span = wider
        cur = (dm, res_b.drag_params.copy())
        dm, base = build_drag_model(drag, rnd.reference_drag, start, knots, penalise, span=span)
        model = base_model.with_(drag=dm)
        P = dm.n_params
        free = _free_mask(P, P + 6, chans, free_ic, dm.name, span)
        m = np.linspace(*dm.fit_range, 200)
        theta0 = np.concatenate([dm.params_for(m, np.clip(cur[0].cd(cur[1], m), 1e-3, None)), res_b.state0])
        fixed_pri = launch_state_priors(L, P, names=unseen) if unseen else ()
        prob = OutputErrorProblem(model, track, theta0, free=free, sigma=sig, channels=chans, priors=fixed_pri)
        if likelihood == "student-t":
            prob.sigma_fixed = {}
        prob.start = start
        prob.base = base
        pen = _penalty(dm, base) if base is not None else None
        if pen is not None:
            prob.priors = fixed_pri + pen(SMOOTHING_GRID[len(SMOOTHING_GRID) // 2])[0]
        res_b = prob.fit(fallback=True)
        if np.all(np.isfinite(res_b.theta)):
            prob.theta0 = res_b.theta.copy()
    used, check = _checked_launch_priors(track, rnd, model, res_b, P, skip=unseen)
    used = fixed_pri + tuple(used)
    if unseen:
        check["applied"] = list(unseen) + check["applied"]
        check["unchecked"] = list(unseen)
    prob.launch_check = check
    if pen is not None:
        res, prob = _fit_penalised(prob, used, P, pen)
    else:
        prob.smoothing = None
        prob.priors = tuple(used)
        res = prob.fit(fallback=True) if used else res_b
    if likelihood == "student-t":
        res = robust_refit(prob, res, sigma=sig, nu=nu)
    if pen is not None:
        res = _drop_coefficient_correlations(res, P)
    return res, prob


def _wider_span(dm, res, span):
    """The Mach span of a fitted flight when it reaches beyond ``dm``'s span by more than half
    the margin (where a spline is held flat), else None."""
    k = getattr(dm, "knots", None)
    if k is None or res.mach is None or not np.any(np.isfinite(res.mach)):
        return None
    lo, hi = float(np.nanmin(res.mach)), float(np.nanmax(res.mach))
    if lo >= k[0] + 0.5 * SPAN_MARGIN and hi <= k[-1] - 0.5 * SPAN_MARGIN:
        return None
    return min(span[0], lo), max(span[1], hi)


def _unseen_launch_priors(track, rnd, chans):
    """Names of the launch priors on quantities the channels do not observe (no ``z``: the
    muzzle height and the elevation; no ``x``: the muzzle's downrange position): the data
    cannot check them, so they are applied as given. Empty when no launch priors apply."""
    L = rnd.launch
    if abs(float(track.t[0])) > 1e-9 or L.velocity is None or L.elevation_deg is None:
        return ()
    out = []
    if "x" not in chans:
        out.append("X0_muzzle")
    if "z" not in chans:
        out += ["Z0_muzzle", "elevation"]
    return tuple(out)


def _stage_scale(model, track, s0, free_state, sig, chans, likelihood, priors=()):
    """Fit the initial state and one scale factor of the start curve (7 parameters; ``model``'s
    drag is the start curve as a :class:`ReferenceScale`).

    Returns the fitted state (6,), the scale and the Mach range of the fitted trajectory; on
    failure the start's own state, 1 and None."""
    free = np.concatenate([[True], free_state])
    prob = OutputErrorProblem(model, track, np.concatenate([[1.0], s0]), free=free,
                              sigma={} if likelihood == "student-t" else sig, channels=chans,
                              priors=priors)
    try:
        res = prob.fit(max_iter=30)
    except FitError:
        return s0, 1.0, None
    if not np.all(np.isfinite(res.theta)):
        return s0, 1.0, None
    mach = res.mach[np.isfinite(res.mach)]
    span = (float(mach.min()), float(mach.max())) if mach.size else None
    return res.theta[1:], float(res.theta[0]), span


def _prior_value_sd(prior, theta, cov, steps):
    """A prior's function at theta and its sd under ``cov`` (delta method)."""
    v = float(prior.fn(theta))
    g = np.zeros(theta.size)
    for j in np.flatnonzero((np.diag(cov) > 0) & (np.asarray(steps) > 0)):
        tp, tm = theta.copy(), theta.copy()
        tp[j] += steps[j]
        tm[j] -= steps[j]
        g[j] = (float(prior.fn(tp)) - float(prior.fn(tm))) / (2 * steps[j])
    return v, float(np.sqrt(max(g @ cov @ g, 0.0)))


def _checked_launch_priors(track, rnd, model, res, P, skip=()):
    """The round's launch priors (except those named in ``skip``) that agree with a fit made
    without them.

    Returns (priors to use, check dict for result.json)."""
    L = rnd.launch
    t0 = float(track.t[0])
    check = {"applied": [], "conflicts": [], "extrapolated": None}
    if L.velocity is None or L.elevation_deg is None:
        check["note"] = "no [launch] velocity and elevation: no launch priors"
        return (), check
    if abs(t0) > 1e-9:
        check["note"] = (f"the track starts at t = {t0:g} s: the state is fitted at its first sample "
                         f"without launch priors")
        back = model.state_at(res.drag_params, res.state0, t0, 0.0) if np.all(np.isfinite(res.theta)) else None
        if back is not None:
            v = float(np.linalg.norm(back[3:]))
            el = math.degrees(math.atan2(back[5], math.hypot(back[3], back[4])))
            check["extrapolated"] = {"t": 0.0, "velocity": v, "elevation": el,
                                     "position": [float(x) for x in back[:3]]}
            # the extrapolation is only as good as the Cd it assumes above the data's Mach:
            # a generous sd (1 % of the speed) on top of the round's
            sd_v = math.hypot(L.velocity_sd, 0.01 * v)
            if abs(v - L.velocity) > LAUNCH_CONFLICT_K * sd_v:
                check["conflicts"].append({
                    "prior": "launch_speed", "round": L.velocity, "track": v, "sd": sd_v,
                    "message": f"the track extrapolated back to t = 0 left the muzzle at {v:.1f} m/s; "
                               f"the round says {L.velocity:g} +- {L.velocity_sd:g} m/s"})
        return (), check
    cands = [p for p in launch_state_priors(L, P) if p.name not in skip]
    cov = res.cov_colored if np.all(np.isfinite(res.cov_colored)) else res.cov
    vals = {}
    for p in cands:
        v, sd_fit = _prior_value_sd(p, res.theta, cov, np.r_[np.zeros(P), [0.01] * 3, [0.001] * 3])
        vals[p.name] = (v, sd_fit)
    muzzle = [n for n in ("X0_muzzle", "Y0_muzzle", "Z0_muzzle") if n in vals]
    r0 = math.sqrt(sum(vals[n][0] ** 2 for n in muzzle))
    pos_conflict = any(abs(vals[n][0]) > LAUNCH_CONFLICT_K * math.hypot(L.position_sd, vals[n][1])
                       for n in muzzle if vals[n][1] > 0 or True)
    used = []
    for p in cands:
        v, sd_fit = vals[p.name]
        sd = math.hypot(p.sd, sd_fit)
        z = (v - p.mean) / sd if sd > 0 else 0.0
        if pos_conflict or abs(z) > LAUNCH_CONFLICT_K:
            unit = {"launch_speed": "m/s", "elevation": "deg"}.get(p.name, "m")
            msg = (f"the round's {p.name.replace('_', ' ')} {p.mean:g} +- {p.sd:g} {unit} disagrees with the "
                   f"track ({v:.4g} {unit}, {z:+.1f} sd): left out of the fit")
            if pos_conflict and p.name in muzzle:
                speed = float(np.linalg.norm(res.state0[3:]))
                msg = (f"the first sample is {r0:.1f} m from the muzzle at t = {t0:g} s: the track's time origin "
                       f"is not the launch (it looks about {r0 / max(speed, 1.0):.2f} s late); launch priors "
                       f"left out; shift t so that t = 0 is the launch to use them")
            entry = {"prior": p.name, "round": p.mean, "track": v, "sd": sd, "z": z, "message": msg}
            if pos_conflict and p.name not in muzzle:
                # left out with the muzzle position (the launch values hold at the launch, which
                # is not at t = 0): not a finding of its own, one line says it
                entry["message"] = f"left out with the muzzle position (time origin): {msg}"
                entry["secondary"] = True
            check["conflicts"].append(entry)
        else:
            used.append(p)
            check["applied"].append(p.name)
    # one message for the time origin is enough
    if pos_conflict:
        first = next(c for c in check["conflicts"] if c["prior"] in muzzle)
        check["conflicts"] = [first] + [c for c in check["conflicts"] if c["prior"] not in muzzle]
        check["time_origin_offset"] = r0 / max(float(np.linalg.norm(res.state0[3:])), 1.0)
    return tuple(used), check


def _drop_coefficient_correlations(res, P):
    """Neighbouring coefficients of a penalised spline are strongly correlated by design; only
    correlations that involve an initial condition (e.g. Cd at the top Mach vs Ux0) are news."""
    drag_names = set(res.names[:P])
    kept = tuple(w for w in res.warnings
                 if not (w.startswith("parameters ") and "strongly correlated" in w
                         and set(w.split()[1:4:2]) <= drag_names))
    return replace(res, warnings=kept)


def robust_refit(prob, res, sigma=None, nu=ROBUST_NU, iterations=ROBUST_ITERATIONS):
    """Student-t maximum likelihood by iteratively reweighted least squares.

    The t likelihood's EM weights ``w = (nu + 1) / (nu + r^2 / s^2)`` (``s`` the noise scale:
    the round's sigma when given, else a robust estimate, 1.4826 x the median absolute residual)
    are divided by their maximum ``(nu + 1) / nu`` so they lie in [0, 1] (the problem's per-sample
    weights; this rescales the noise by a constant) and the fit is repeated from the previous
    estimate with the same priors (and smoothing weight) a few times. Samples more than
    :data:`REJECT_K` scales from the curve end with a weight below 0.15: they are listed as
    rejected in ``prob.rejected`` (channel -> sample indices).

    Returns the final MLResult; ``prob.weights`` keeps the weights.
    """
    chans = prob.channels
    for _ in range(iterations):
        r = np.stack([res.residuals[c] for c in chans], axis=-1)
        scale = np.empty(len(chans))
        for j, c in enumerate(chans):
            if sigma and c in sigma:
                scale[j] = float(sigma[c])
            else:
                scale[j] = max(1.4826 * float(np.median(np.abs(r[:, j] - np.median(r[:, j])))), 1e-9)
        w = (nu + 1.0) / (nu + (r / scale) ** 2) * nu / (nu + 1.0)
        prob.weights = np.clip(w, 0.0, 1.0)
        prob.sigma_fixed = {c: float(scale[j] * np.sqrt(nu / (nu + 1.0))) for j, c in enumerate(chans)}
        prob.theta0 = res.theta.copy()
        new = prob.fit()
        if not np.all(np.isfinite(new.theta)):
            break
        step = np.abs(new.theta - res.theta)[res.free]
        res = new
        if np.all(step <= 1e-3 * np.where(res.crb[res.free] > 0, res.crb[res.free], np.inf)):
            break
    r = np.stack([res.residuals[c] for c in chans], axis=-1)
    prob.rejected = {c: [int(i) for i in np.flatnonzero(np.abs(r[:, j]) > REJECT_K * scale[j])]
                     for j, c in enumerate(chans)}
    return res


def _penalty(dm, base):
    """A function ``sd -> (priors, D, sds)``: the smoothness pseudo-priors of
    :mod:`bayesdrag.estimate.basis` on the relative correction of ``dm``.

    With a table (:class:`TableSpline`) the coefficients *are* the correction; without one the
    penalty is on Cd's own second derivative over its typical level (the median of the data's
    shape): a wiggly start must not become the prior's mean. The weights allow more bending
    where the table or the data's shape bend.
    """
    table, shape = base
    knots = np.asarray(dm.knots)
    D = second_difference_rows(knots)
    if table is not None:
        w = curvature_weights(knots, table, shape)
        level = 1.0
    else:
        w = curvature_weights(knots, shape)
        level = float(np.median(shape(np.linspace(knots[0], knots[-1], 200))))
    Dc = D / level
    P = dm.n_params

    def priors(sd):
        sds = sd * w
        return tuple(Prior(f"smooth{i}", (lambda th, d=d: th[..., :P] @ d), 0.0, float(sds[i]),
                           row=np.concatenate([d, np.zeros(_N_IC)]))
                     for i, d in enumerate(Dc)), Dc, sds

    return priors


def smoothness_priors(dm, base, sd):
    """The smoothness pseudo-priors of a penalised Scheme 1 drag model at penalty sd ``sd``
    (``prob.smoothing["sd"]`` of a fit): a tuple of linear :class:`Prior` on the drag
    coefficients (the first ``dm.n_params`` parameters). ``base`` is ``prob.base`` of the fit."""
    return _penalty(dm, base)(sd)[0]


def _fit_penalised(prob, base_priors, P, penalty):
    """Choose the penalty by the Laplace evidence and return the fit at the best one.

    ``sd`` is walked uphill in the Laplace evidence over :data:`SMOOTHING_GRID` from its middle;
    every fit starts from the previous one. When the best value is at an end of the grid the
    smoothing record says so (``at_grid_end``): at the stiff end the data ask for no more than
    a linear (in knot position) correction of the base curve, which with a table means the
    table's shape fits; at the flexible end the penalty no longer smooths. The choice is
    recorded in ``prob.smoothing``.
    """
    grid = SMOOTHING_GRID
    cache = {}
    state = {"theta": prob.theta0.copy()}

    def evaluate(i):
        if i in cache:
            return cache[i][0]
        pen, D, sds = penalty(grid[i])
        prob.priors = tuple(base_priors) + pen
        prob.theta0 = state["theta"]
        res = prob.fit(fallback=True)
        idx = np.flatnonzero(res.free)
        ok = np.all(np.isfinite(res.theta)) and np.all(np.isfinite(res.cov))
        sign, logdet_cov = np.linalg.slogdet(res.cov[np.ix_(idx, idx)]) if ok else (0, 0.0)
        if sign <= 0:
            cache[i] = (-np.inf, res, prob.priors, np.nan)
            return -np.inf
        # log evidence (+ const): -1/2 chi2_penalised - 1/2 log|F| + 1/2 log|Lambda D'D|_+
        ev = -0.5 * res.cost + 0.5 * logdet_cov - float(np.sum(np.log(sds)))
        edf = float(idx.size - np.trace(res.cov[:P, :P] @ (D.T @ (D / sds[:, None] ** 2))))
        if not res.converged:
            ev = -np.inf
        cache[i] = (float(ev), res, prob.priors, edf)
        if res.converged:
            state["theta"] = res.theta.copy()
        return float(ev)

    i = len(grid) // 2
    best = evaluate(i)
    for step in (1, -1):
        moved = False
        while 0 <= i + step < len(grid):
            ev = evaluate(i + step)
            if not ev > best:
                break
            i, best, moved = i + step, ev, True
        if moved:
            break
    if not np.isfinite(best):
        # no smoothing gave a converged fit: the best finite-evidence or the last tried
        finite = [k for k, v in cache.items() if v[1].success]
        if finite:
            i = max(finite, key=lambda k: cache[k][0] if np.isfinite(cache[k][0]) else -1e300)
    ev, res, pri, edf = cache[i]
    if not res.success and not any(v[1].success for v in cache.values()):
        prob.priors = pri
        prob.smoothing = None
        return res, prob
    prob.priors = pri
    table = [{"sd": float(grid[k]), "log_evidence": v[0], "edf": v[3], "converged": v[1].converged}
             for k, v in sorted(cache.items())]
    n_ic = int(res.free[P:].sum())
    end = "stiff" if i == 0 else ("flexible" if i == len(grid) - 1 else None)
    prob.smoothing = {"method": "P-spline: integral of the relative correction's second derivative squared, "
                                "weighted by the base curve's curvature; Laplace evidence",
                      "base": "table" if isinstance(prob.model.drag, TableSpline) else "start curve from the track",
                      "sd": float(grid[i]), "edf": edf, "edf_drag": edf - n_ic,
                      "at_grid_end": end, "fits": len(cache), "grid": table}
    return res, prob


#: largest Mach step of the result's ``cd`` grid (the kernel's Mach grid: a steep drag rise is
#: ~0.1 Mach wide and a table interpolated through the rows must follow it)
CD_GRID_STEP = 0.01
#: fewest rows of the result's ``cd`` grid
CD_GRID_MIN_ROWS = 81


def cd_grid(mach_min, mach_max):
    """The result's Mach grid over [mach_min, mach_max]: uniform, at least
    :data:`CD_GRID_MIN_ROWS` rows, no step above :data:`CD_GRID_STEP`, rounded to 1e-4."""
    n = max(CD_GRID_MIN_ROWS, int(math.ceil((mach_max - mach_min) / CD_GRID_STEP - 1e-9)) + 1)
    return np.round(np.linspace(mach_min, mach_max, n), 4)


def cd_table(result, drag_model, mach, reference=None):
    """Cd(M) rows for result.json: ML value, CRB sd (delta method), reference."""
    P = drag_model.n_params
    B = drag_model.jacobian(mach)
    cd = drag_model.cd(result.drag_params, mach)
    var = np.einsum("ij,jk,ik->i", B, result.cov[:P, :P], B)
    varc = np.einsum("ij,jk,ik->i", B, result.cov_colored[:P, :P], B)
    rows = []
    for i, m in enumerate(mach):
        rows.append({"mach": round(float(m), 4), "ml": float(cd[i]), "crb_sd": float(np.sqrt(max(var[i], 0))),
                     "crb_sd_colored": float(np.sqrt(max(varc[i], 0))),
                     "reference": float(reference.value(m)) if reference is not None else None})
    return rows


def determined_range(rows):
    """Mach interval spanned by the rows marked ``determined`` (:mod:`bayesdrag.estimate.quality`;
    holes inside it are listed in ``ml.quality.undetermined``), or, for rows not yet assessed,
    where the CRB relative sd of Cd is below :data:`DETERMINED_REL_SD`."""
    if rows and "determined" in rows[0]:
        ok = [r["mach"] for r in rows if r["determined"]]
    else:
        ok = [r["mach"] for r in rows if r["ml"] > 0 and r["crb_sd"] / r["ml"] < DETERMINED_REL_SD]
    return (min(ok), max(ok)) if ok else None
