"""Scheme 1: Cd(M) over the whole flight together with the initial conditions (paper §3-4).

How a fit is set up and run (each choice with its reason):

* **Start from the data** (:mod:`bayesdrag.estimate.build.start`). The Mach span, the starting Cd(M)
  and the state at the first sample are read off the track (smoothed speed, its rate and the
  path angle), not from the round's nominal launch values or a generic curve: a round file may
  be wrong, and a shell may be nothing like a 155 mm one. A track whose path bends as if gravity
  were 32 (feet) or 10.7 (yards) units/s^2 is refused with the likely unit.
* **Default drag model: ``spline``**, a *penalised* cubic B-spline (P-spline, Eilers & Marx
  1996). With a firing table it is the table times a smooth correction
  (:class:`bayesdrag.drag.TableSpline`: the table is evaluated exactly, so a correct table costs
  nothing however steep its rise); without one, a spline in Cd itself. Knots are placed where
  the start curve (and the table) bend (:func:`bayesdrag.estimate.build.basis.adaptive_knots`); the
  penalty is on the second derivative of the relative correction ``Cd / base`` (base: the table,
  or the start curve), its weight chosen by maximising the Laplace-approximated marginal
  likelihood (the evidence) over :data:`SMOOTHING_GRID`, and allowed more freedom where the base
  itself bends. A short track (8-24 samples) gets at most one coefficient per sample, and a
  track too short even for the penalty's straight-line correction gets one factor on the table
  or is refused, naming the smallest model (:mod:`bayesdrag.estimate.build.model_size`). Why not knots
  added one by one by BIC: BIC's ``log N`` per knot (~9 for a
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
  data, and not where the curve is clamped or held at a bound (:mod:`bayesdrag.estimate.cd.quality`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..._runtime.threads import single_blas
from ...drag import ReferenceScale, ReferenceTable, Spline, TableSpline, default_spline_knots, make_drag_model
from ...dynamics.pointmass import PointMassModel
from ...dynamics.trajectory import initial_state
from ...errors import FitError, InputError
from ..build.launch import checked_launch_priors, launch_state_priors, path_angle_prior, unseen_launch_priors
from ..build.model_size import NARROW_SPAN_MACH, SHAPE_SLOPE_SD, check_determinable, default_knots, free_mask, narrow_span_model
from ..model.ml import MLResult
from ..model import colored
from ..model.contamination import contamination_refit
from ..model.likelihood import LIKELIHOODS, STUDENT_T_NU
from ..model.layout import ParameterLayout
from ..model.problem import OutputErrorProblem
from ..build.sources import fit_with_sources
from ..build.smoothing import SMOOTHING_GRID, drop_coefficient_correlations, fit_penalised, penalty
from ..build.native_start import start_position, start_view
from ..build.start import DataStart, check_gravity_units, check_heights, check_launch_speed, data_start
from ...measure import gun_equivalent, site_of
from ...effects import RADAR_TIME, WIND_PROFILE

__all__ = ["Scheme1Fit", "fit_scheme1", "build_drag_model", "robust_refit", "coriolis_of", "noise_record"]

#: Student-t degrees of freedom of the robust fit
ROBUST_NU = STUDENT_T_NU
#: reweighting passes of the robust fit
ROBUST_ITERATIONS = 6
#: a sample more than this many noise scales off the robust curve is listed as rejected
REJECT_K = 5.0
#: the Mach span of the drag model extends the data's by this much at each end (the fitted
#: trajectory may reach a little beyond the smoothed speed's extremes)
SPAN_MARGIN = 0.02
#: without a measured speed, another shape replaces the start curve read off the positions when
#: its stage-A fit (initial state and one scale) costs less than this fraction of the other's: a
#: clearly better start, never a coin toss between two fair ones (:func:`_better_start_shape`)
REFERENCE_START_GAIN = 0.5


@dataclass(frozen=True, eq=False)
class Scheme1Fit:
    """A Scheme 1 maximum-likelihood fit and what it chose on the way.

    Attributes
    ----------
    ml : MLResult
        The fit: parameters, Cramér-Rao bounds, residuals, convergence.
    problem : OutputErrorProblem
        The problem as finally defined (drag model, priors including the chosen smoothness
        penalty and the launch priors kept, per-sample weights of a robust fit, noise): the
        posterior samples exactly this problem.
    start : DataStart
        What the track said before any fit (:mod:`bayesdrag.estimate.build.start`).
    smoothing : dict or None
        The penalty's choice (sd, edf, evidence over the grid, ``at_grid_end``); None for an
        unpenalised model.
    launch_check : dict
        The launch priors applied, those left out (``conflicts``, with messages) and, for a
        late track, its state extrapolated back to t = 0.
    rejected : dict or None
        Samples a Student-t fit rejected, per channel (None for a Gaussian fit).
    base : tuple or None
        ``(table, shape)`` the smoothness penalty is relative to (:func:`build_drag_model`).
    noise : dict
        The noise model: ``requested`` (auto, white, ar1), ``model`` per channel, and per
        channel the evidence for model-error noise ``lr`` (:func:`choose_noise_model`) and the
        fitted ``rho`` and ``q`` of ``ar1`` channels.
    sources : tuple
        The round's declared systematic sources fitted as nuisance parameters
        (:func:`bayesdrag.estimate.build.sources.source_extras`: stem, parameter, nominal, sd), in
        this order after the initial state; empty when none is declared.
    white_ml : MLResult or None
        With ``auto`` noise that chose ``ar1`` somewhere: the white-noise fit it started from,
        whose colored-residual (Morelli-Klein) bound is the band's model-error floor
        (:func:`model_error_floor`).
    effects : tuple of str
        Effects fitted as nuisance parameters (``--with``), their parameters after the
        initial state and before the sources.
    ml_without_effects : MLResult or None
        The fit before the effects were added (the report shows Cd with and without them).
    model_size : dict
        How the drag model's size followed the data (:func:`default_knots`): ``samples``,
        ``coefficients``, ``knot_rules``, ``short``; a short track's bands include the bends
        its samples cannot resolve (:func:`bayesdrag.estimate.cd.quality.unresolved_bend`).
    layer_placements : tuple or None
        With a ``wind_profile`` whose edges were placed: the kept placement's drag coefficients
        and those of the placements the track cannot tell from the best
        (:func:`bayesdrag.estimate.build.winds.equivalent_placements`); their Cd spread is
        model error.
    """

    ml: MLResult
    problem: OutputErrorProblem
    start: DataStart
    smoothing: dict | None
    launch_check: dict
    rejected: dict | None = None
    base: tuple | None = None
    noise: dict = field(default_factory=dict)
    sources: tuple = ()
    white_ml: MLResult | None = None
    effects: tuple = ()
    ml_without_effects: MLResult | None = None
    model_size: dict = field(default_factory=dict)
    layer_placements: tuple | None = None

    @property
    def drag_model(self):
        """The fitted drag model (:class:`~bayesdrag.drag.DragModel`)."""
        return self.problem.model.drag

    @property
    def success(self):
        return self.ml.success

    @property
    def message(self):
        return self.ml.message


def coriolis_of(rnd):
    """Coriolis geometry ``(latitude_deg, azimuth_deg)`` of a round, or None without a latitude."""
    L = rnd.launch
    return (L.latitude_deg, L.azimuth_deg) if L.latitude_deg is not None else None


def model_span(span):
    """Mach span of the drag model: the data's ``(lo, hi)``, widened by :data:`SPAN_MARGIN`."""
    lo, hi = span
    return max(lo - SPAN_MARGIN, 0.05), hi + SPAN_MARGIN


def build_drag_model(drag, reference, start, knots=None, penalise=True, span=None, info=None):
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
    info : dict, optional
        Receives the record of the model's size (:func:`default_knots`; also for the other
        models: whether the track is short).

    Returns
    -------
    (DragModel, base) where ``base`` is None for an unpenalised model, else ``(table, shape)``:
    the table the correction multiplies (None without one: the penalty is then on Cd's own
    curvature) and the data's smoothed shape (where the drag bends).
    """
    lo, hi = model_span(start.mach_span if span is None else span)
    k, record = default_knots(reference, start, lo, hi)
    if info is not None:
        info.clear()
        info.update(record)
    if drag != "spline":
        try:
            dm = make_drag_model(drag, reference=reference, mach_range=(lo, hi))
        except ValueError as exc:
            raise InputError(str(exc)) from None
        if info is not None:
            info["coefficients"] = dm.n_params
        return dm, None
    if knots is not None or not penalise:
        try:
            k = default_spline_knots(lo, hi) if knots is None else tuple(float(v) for v in knots)
            dm = Spline(tuple(k))
        except ValueError as exc:
            raise InputError(str(exc)) from None
        if info is not None:
            info["coefficients"] = dm.n_params
        return dm, None
    shape = start.shape_curve
    if reference is not None:
        return TableSpline(reference, tuple(k)), (reference.value, shape)
    return Spline(tuple(k)), (None, shape)


def fit_scheme1(track, rnd, *, drag="spline", channels=None, sigma=None, free_ic=True, knots=None,
                penalise=True, likelihood="gaussian", nu=ROBUST_NU, start=None, noise_model="white", with_effects=(),
                progress=None, wind_layers=None, span_rule=True):
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
    noise_model : {"white", "ar1", "auto"}
        ``ar1``: every channel has white noise plus an AR(1) model-error process
        (:mod:`bayesdrag.estimate.model.colored`); ``auto``: the channels whose white-noise residuals
        show one (:func:`choose_noise_model`). A Student-t fit stays white.
    with_effects : sequence of str
        Effects of :mod:`bayesdrag.effects` fitted with Cd as nuisance parameters (checked by
        :func:`bayesdrag.estimate.build.sources.plan_effects`).
    progress : callable, optional
        ``progress(step)`` receives a short description of each step as the fit reaches it
        (the command prints them when the fit is slow).
    wind_layers : WindLayers or str, optional
        The layers of a ``wind_profile`` in ``with_effects``, or the axis to lay them on (the
        diagnosis's); default: laid over the fitted flight on the better axis
        (:func:`bayesdrag.estimate.build.sources.fit_with_sources`).
    span_rule : bool
        The model-size rule by Mach span (:func:`~bayesdrag.estimate.build.model_size.narrow_span_model`).

    Returns
    -------
    Scheme1Fit
    """
    with single_blas():   # the kernel's threads use the cores, not BLAS's
        if likelihood not in LIKELIHOODS:
            raise InputError(f"likelihood {likelihood!r} is not allowed; use gaussian or student-t")
        chans = tuple(channels) if channels is not None else track.names
        smaller = check_determinable(track, rnd, chans, free_ic, drag, knots)
        check_heights(track, rnd)
        drag = smaller or drag
        site = site_of(rnd, chans)
        seen = track.with_channels(chans) if set(chans) != set(track.names) else track
        own_start = start is None           # a start passed in (a refit's) has its shape chosen already
        if own_start:
            start = data_start(start_view(seen, rnd, site), rnd)
        check_gravity_units(start.kinematics, track.source, channels=chans)
        check_launch_speed(track, rnd, chans)
        drag = (narrow := narrow_span_model(start.mach_span, span_rule and rnd.reference_drag is not None, drag, knots)) or drag
        L, t0, s0 = rnd.launch, float(track.t[0]), start.state0
        if not free_ic and abs(t0) < 1e-9 and L.velocity is not None and L.elevation_deg is not None:
            s0 = initial_state(L.velocity, L.elevation_deg)
        sig = dict(rnd.radar.sigma) if sigma is None else dict(sigma)
        seen_as = gun_equivalent(chans)      # what a radar's own channels observe in the gun's frame
        if not any(c in seen_as for c in ("x", "y", "z")):
            s0 = s0.copy()
            s0[:3] = 0.0 if abs(t0) < 1e-9 else start_position(s0, t0, chans)[:3]
        # launch values no channel sees (no z: muzzle height, elevation) are priors; the rest is checked first
        unseen = unseen_launch_priors(track, rnd, chans)
        if unseen and abs(t0) < 1e-9 and "z" not in seen_as:
            s0 = s0.copy()
            s0[2] = 0.0
        # stage A: the initial state and one scale of the start curve; its trajectory also gives the
        # Mach span better than the smoothed speed, whose ends are the least certain part of it
        table = ReferenceTable(tuple(start.mach), tuple(start.cd), source="start curve from the track")
        base_model = PointMassModel(rnd.projectile.mass, rnd.projectile.diameter, ReferenceScale(table),
                                    rnd.atmosphere, coriolis=coriolis_of(rnd))
        ic_free = free_mask(0, 6, chans, free_ic, "", (0, 0))
        say = progress if progress is not None else (lambda step: None)
        say("the initial state and one scale of the drag read off the track")
        a_pri = _unseen_priors(track, rnd, chans, unseen, 1, False)
        # no speed measured: a poor start curve lets the initial position wander, so it is held at the
        # track's own start until the whole curve has its shape (:func:`_better_start_shape`)
        anchored = own_start and free_ic and "v" not in seen_as and any(c in seen_as for c in ("x", "y", "z"))
        held = ic_free & np.array([not anchored] * 3 + [True] * 3)
        start, shape, (state, scale, span_a, _) = _better_start_shape(
            start, rnd, lambda model: _stage_scale(model, track, s0, held, sig, chans, likelihood, a_pri, site=site),
            base_model, others=anchored)
        span = start.mach_span if span_a is None else (min(start.mach_span[0], span_a[0]),
                                                       max(start.mach_span[1], span_a[1]))
        size = {}
        dm, base = build_drag_model(drag, rnd.reference_drag, start, knots, penalise, span=span, info=size)
        P = dm.n_params
        fixed_pri = _unseen_priors(track, rnd, chans, unseen, P, _angle_held(narrow, span))
        free_b = free_mask(P, ParameterLayout(P).size, chans, free_ic, dm.name, span)
        prob, pen = _curve_problem(base_model, dm, base, track, lambda m: scale * shape(m),
                                   state if free_ic else s0, free_b, sig, chans, likelihood, fixed_pri, site)
        # stage B: the full curve without the checked launch priors, then check them against it
        say(f"the whole curve ({P} drag coefficients)")
        if anchored:    # the curve takes its shape with the initial position held, then all is free
            first = _curve_problem(base_model, dm, base, track, lambda m: scale * shape(m), state,
                                   _position_held(free_b, P), sig, chans, likelihood, fixed_pri, site)[0].fit(fallback=True)
            prob = prob.replace(theta0=first.theta) if np.all(np.isfinite(first.theta)) else prob
        res_b = prob.fit(fallback=True)
        if res_b.success or np.all(np.isfinite(res_b.theta)):
            prob = prob.replace(theta0=res_b.theta)
        wider = _wider_span(dm, res_b, span)
        if wider is not None and knots is None:
            # the fitted flight reaches beyond the model's Mach span (the smoothed speed's ends
            # were low): rebuild the model over the flight's span and refit from this curve
            span = wider
            cur = (dm, res_b.drag_params.copy())
            dm, base = build_drag_model(drag, rnd.reference_drag, start, knots, penalise, span=span, info=size)
            P = dm.n_params
            fixed_pri = _unseen_priors(track, rnd, chans, unseen, P, _angle_held(narrow, span))
            prob, pen = _curve_problem(base_model, dm, base, track, lambda m: np.clip(cur[0].cd(cur[1], m), 1e-3, None),
                                       res_b.state0, free_mask(P, ParameterLayout(P).size, chans, free_ic, dm.name, span), sig, chans,
                                       likelihood, fixed_pri, site)
            say(f"the whole curve over the flight's Mach span ({P} drag coefficients)")
            res_b = prob.fit(fallback=True)
            if np.all(np.isfinite(res_b.theta)):
                prob = prob.replace(theta0=res_b.theta)
        model = prob.model
        say("checking the round's launch values against the track")
        clock = RADAR_TIME.name in with_effects or rnd.systematics.time_offset is not None
        used, check = checked_launch_priors(track, rnd, model, res_b, P, skip=unseen, start=start, sigma=sig,
                                            clock_fitted=clock)
        used = fixed_pri + tuple(used)
        if unseen:
            check["applied"] = list(unseen) + check["applied"]
            check["unchecked"] = list(unseen)
        smoothing = rejected = None
        if pen is not None:
            prob, res, smoothing = fit_penalised(prob, used, P, pen, progress=say)
        else:
            prob = prob.replace(priors=used)
            res = prob.fit(fallback=True) if used else res_b
        prob, res, smoothing, noise, rejected, white_ml, sources, fitted_effects, before, placements = noise_and_effects(
            prob, res, smoothing, rnd, likelihood, noise_model, sig, nu, with_effects, wind_layers, say)
        if pen is not None:
            res = drop_coefficient_correlations(res, P)
        _size_note(size, track, chans, smaller, narrow, start.mach_span)
        return Scheme1Fit(res, prob, start, smoothing, check, rejected, base, noise, sources, white_ml, fitted_effects,
                          before if fitted_effects else None, size, placements)


def _angle_held(narrow, span):
    """Whether a speed-only track's path angle is held by its prior: over a narrow Mach ``span``
    (or where the narrow-span rule chose the model), where the drag level is all that is fitted.
    Over a wider span the angle stays free as it was: held, it left the fit of a chronograph track
    with one-sided outliers at a worse optimum of its site (docs/radar.md, "One-sided outliers")."""
    return narrow is not None or float(span[1]) - float(span[0]) < NARROW_SPAN_MACH


def _unseen_priors(track, rnd, chans, unseen, P, angle_held):
    """The priors on launch values the channels cannot see: the round's (:func:`unseen_launch_priors`)
    and, when ``angle_held`` (:func:`_angle_held`; not in stage A, before the span is known), a
    speed-only track's path angle (:func:`path_angle_prior`)."""
    return ((launch_state_priors(rnd.launch, P, names=unseen) if unseen else ())
            + (path_angle_prior(track, rnd, chans, P) if angle_held else ()))


def _size_note(size, track, chans, smaller, narrow, span):
    """Say in ``size`` (``ml.model_size``) why the default spline gave way to one factor on the table."""
    if smaller is not None:
        size["note"] = (f"{track.n} samples x {len(chans)} channels are too few for the default spline: Cd is the "
                        f"firing table times one fitted factor (reference-scale)")
    elif narrow is not None:
        size["narrow_span"] = [float(f"{v:.6g}") for v in span]
        size["note"] = (f"the track spans Mach {span[0]:.3f}-{span[1]:.3f}, narrower than {NARROW_SPAN_MACH:g}: too "
                        f"little to tell a slope of Cd from the noise, so Cd is the firing table times one fitted "
                        f"factor (reference-scale), its band leaning {SHAPE_SLOPE_SD:g} per Mach from the middle "
                        f"for the table's shape; a series of shots fitted as one session also fits the slope")


def noise_and_effects(prob, res, smoothing, rnd, likelihood, noise_model, sig, nu, with_effects, wind_layers, say):
    """The noise model (robust reweighting or white / AR(1)) and stage C, the declared sources and
    ``--with`` effects (:func:`fit_with_sources`), in that order -- except a wind profile, which is
    model, not noise: fitted before the noise model is chosen (model-error noise chosen first took
    the wind's signature, and the layers stayed at zero).

    Returns
    -------
    (prob, res, smoothing, noise, rejected, white_ml, sources, fitted_effects, before, placements)
    """
    rejected = white_ml = placements = None
    sources, fitted_effects = (), ()
    winds_first = (WIND_PROFILE.name in with_effects or rnd.systematics.wind_profile is not None) \
        and likelihood != "student-t"
    before = res
    if winds_first:
        say("the declared systematic sources and effects")
        prob, res, sources, fitted_effects, placements = fit_with_sources(prob, res, rnd, with_effects,
                                                                             wind_layers)
    if likelihood == "student-t":
        say("reweighting outliers (Student-t)")
        prob, res, rejected = robust_refit(prob, res, sigma=sig, nu=nu)
        noise = {"requested": noise_model, "model": dict(prob.noise_model),
                 "note": "a Student-t fit keeps white noise"} if noise_model != "white" else {}
    else:
        # one-sided (skewed) outliers, where the residuals show them: reweighted by the
        # contamination model, white noise kept (AR(1) needs unit weights)
        prob, res, contamination = contamination_refit(prob, res)
        white = res
        say("the noise model")
        if contamination["engaged"]:
            noise = {"requested": noise_model, "model": dict(prob.noise_model)}
            if noise_model != "white":
                noise["note"] = "one-sided outliers reweighted (skewed contamination model): white noise kept"
        else:
            prob, res, smoothing, noise = colored_refit(prob, res, smoothing, noise_model)
        noise["contamination"] = contamination
        if noise_model == "auto" and "ar1" in noise.get("model", {}).values():
            white_ml = white
    if not winds_first:
        before = res
        if with_effects or rnd.systematics.declared():
            say("the declared systematic sources and effects")
        prob, res, sources, fitted_effects, placements = fit_with_sources(prob, res, rnd, with_effects,
                                                                             wind_layers)
    return prob, res, smoothing, noise, rejected, white_ml, sources, fitted_effects, before, placements


def _curve_problem(base_model, dm, base, track, cd_start, state, free, sig, chans, likelihood, fixed_pri, site=None):
    """The problem of the whole curve (stage B): drag model ``dm`` started at ``cd_start(M)``
    and the initial ``state``, with the launch priors ``fixed_pri`` and, for a penalised model,
    the smoothness rows at the middle of the smoothing grid. The rows are part of the problem
    from its start: they count as the pseudo-measurements they are when the problem checks that
    the data can determine it. A Student-t fit starts with its noise sd estimated (relaxation
    inflates it over the outliers instead of bending the curve to them), then reweights.

    Returns
    -------
    (OutputErrorProblem, penalty or None)
    """
    m = np.linspace(*dm.fit_range, 200)
    theta0 = np.concatenate([dm.params_for(m, cd_start(m)), state])
    pen = penalty(dm, base) if base is not None else None
    pen0 = pen(SMOOTHING_GRID[len(SMOOTHING_GRID) // 2])[0] if pen is not None else ()
    prob = OutputErrorProblem(base_model.with_(drag=dm), track, theta0, free=free, sigma=sig, channels=chans,
                              priors=tuple(fixed_pri) + pen0, site=site)
    if likelihood == "student-t":
        prob = prob.replace(sigma_fixed={})
    return prob, pen


def choose_noise_model(prob, res, requested):
    """Noise model per channel from the white-noise fit's residuals.

    ``auto`` gives a channel ``ar1`` noise when the likelihood ratio of white + AR(1)
    model-error noise against white noise exceeds :data:`colored.LR_THRESHOLD` (chi-square(2)
    at 0.999): residuals that model error has made correlated switch, a white channel almost
    never does (and then with a small ``q``, i.e. nearly the same bounds).

    Returns
    -------
    (dict channel -> str, dict channel -> float)
        The models and the likelihood-ratio statistics.
    """
    if requested not in ("white", "ar1", "auto"):
        raise InputError(f"noise model {requested!r} is not known (allowed: auto, white, ar1)")
    lr = {}
    for c in prob.channels:
        e = np.asarray(res.residuals[c], float)
        lr[c] = float(colored.fit_noise(e, prob.dt_ratio)[3]) if requested == "auto" else float("nan")
    if requested == "auto":
        return {c: "ar1" if lr[c] > colored.LR_THRESHOLD else "white" for c in prob.channels}, lr
    return {c: requested for c in prob.channels}, lr


def colored_refit(prob, res, smoothing, requested):
    """Refit with the chosen noise model, at the smoothing the white-noise fit chose.

    Why the smoothing is not chosen again: under ``ar1`` noise a slow model-error process and a
    smooth correction of Cd compete for the same low-frequency residual, and the evidence then
    explains it with noise: on the shipped 6-DOF demo it went to the stiff end of the grid and
    the band covered the table at 54 % of the Mach grid, against 75 % at the white fit's choice.

    Returns
    -------
    (OutputErrorProblem, MLResult, dict or None, dict)
        The problem with the chosen noise models (started at the white fit), the fit, its
        smoothing record and the noise record of :class:`Scheme1Fit`.
    """
    if requested == "white":
        return prob, res, smoothing, {"requested": "white", "model": dict(prob.noise_model)}
    models, lr = choose_noise_model(prob, res, requested)
    noise = {"requested": requested, "model": models,
             "lr": {c: (None if not np.isfinite(v) else round(v, 2)) for c, v in lr.items()}}
    if "ar1" not in models.values():
        return prob, res, smoothing, noise
    colored_prob = prob.replace(noise_model=models, theta0=res.theta)
    new = colored_prob.fit(fallback=True)
    if not new.success:
        # keep the white fit, say so: its bounds ignore the correlation
        prob = prob.replace(theta0=res.theta)
        noise["model"] = dict(prob.noise_model)
        noise["note"] = f"the fit with model-error noise failed ({new.message}); white noise kept"
        return prob, res, smoothing, noise
    noise["ar"] = {c: {"rho": v[0], "q": v[1]} for c, v in new.ar.items()}
    return colored_prob, new, smoothing, noise


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


def _position_held(free, P):
    """``free`` with the initial position held (``P`` drag coefficients first)."""
    out = np.array(free, bool, copy=True)
    out[ParameterLayout(P).position] = False
    return out


def _better_start_shape(start, rnd, stage_a, base_model, others=True):
    """Stage A of a track without a measured speed: the start curve's shape, and the initial
    velocity and one scale with the initial position held at the track's own start.

    Without a speed the start curve is the positions differentiated twice; from a radar's angles
    at ranges of km (0.03 deg is 5 m at 10 km) its shape can be off by a factor of 2. Fitted
    with the position free, the wrong shape is traded against the initial state (hundreds of
    metres off the muzzle), from where the whole curve's fit does not return. So the position is
    held, and the shapes are compared by that fit's cost: the curve read off the positions, the
    round's reference drag and a flat Cd at the read curve's median (each scaled; one fit of 4
    parameters each). Another shape is kept only when it costs less than
    :data:`REFERENCE_START_GAIN` of the read curve's.

    Parameters
    ----------
    start : DataStart
    rnd : Round
    stage_a : callable ``stage_a(model) -> tuple``
        :func:`_stage_scale` with a model flying another drag (the position held).
    base_model : PointMassModel
        Flies the start curve (as a :class:`ReferenceScale`).
    others : bool
        Compare the other shapes (False: stage A of the start curve alone, as with a speed).

    Returns
    -------
    (DataStart, callable, tuple)
        The start (its notes saying which shape starts the curve; the curve read off the
        positions stays the smoothing's base), the shape kept ``shape(mach) -> Cd`` and its
        stage-A result.
    """
    fitted = stage_a(base_model)
    shapes = []
    if not others:
        return start, start.curve, fitted
    if rnd.reference_drag is not None:
        shapes.append(("the round's reference drag", np.asarray(rnd.reference_drag.value(start.mach), float)))
    shapes.append(("a flat Cd at the read curve's median", np.full(start.cd.shape, float(np.median(start.cd)))))
    best = (fitted[3], start, start.curve, fitted)
    for what, cd in shapes:
        table = ReferenceTable(tuple(start.mach), tuple(cd), source=what)
        got = stage_a(base_model.with_(drag=ReferenceScale(table)))
        if got[3] < REFERENCE_START_GAIN * fitted[3] and got[3] < best[0]:
            note = (f"the whole curve's fit starts from {what}, scaled: it fitted the track better than the curve "
                    f"read off the positions (no speed measured)")
            best = (got[3], replace(start, notes=tuple(start.notes) + (note,)),
                    lambda m, g=np.asarray(start.mach, float), c=cd: np.interp(np.asarray(m, float), g, c), got)
    return best[1:]


def _stage_scale(model, track, s0, free_state, sig, chans, likelihood, priors=(), site=None):
    """Fit the initial state and one scale factor of the start curve (7 parameters; ``model``'s
    drag is the start curve as a :class:`ReferenceScale`).

    Returns the fitted state (6,), the scale, the Mach range of the fitted trajectory and the
    fit's cost; on failure the start's own state, 1, None and inf."""
    free = np.concatenate([[True], free_state])
    prob = OutputErrorProblem(model, track, np.concatenate([[1.0], s0]), free=free,
                              sigma={} if likelihood == "student-t" else sig, channels=chans,
                              priors=priors, site=site)
    try:
        res = prob.fit(max_iter=30)
    except FitError:
        return s0, 1.0, None, np.inf
    if not np.all(np.isfinite(res.theta)):
        return s0, 1.0, None, np.inf
    mach = res.mach[np.isfinite(res.mach)]
    span = (float(mach.min()), float(mach.max())) if mach.size else None
    return res.theta[1:], float(res.theta[0]), span, float(res.cost)


def robust_refit(prob, res, *, sigma=None, nu=ROBUST_NU, iterations=ROBUST_ITERATIONS):
    """Student-t maximum likelihood by iteratively reweighted least squares.

    The t likelihood's EM weights ``w = (nu + 1) / (nu + r^2 / s^2)`` (``s`` the noise scale:
    the round's sigma when given, else a robust estimate, 1.4826 x the median absolute residual)
    are divided by their maximum ``(nu + 1) / nu`` so they lie in [0, 1] (the problem's per-sample
    weights; this rescales the noise by a constant) and the fit is repeated from the previous
    estimate with the same priors (and smoothing weight) a few times. Samples more than
    :data:`REJECT_K` scales from the curve end with a weight below 0.15: they are listed as
    rejected (channel -> sample indices).

    Returns
    -------
    (OutputErrorProblem, MLResult, dict)
        The reweighted problem (the final ``weights`` and ``sigma_fixed``: the posterior samples
        it), the final fit and the rejected samples per channel.
    """
    chans = prob.channels
    for _ in range(iterations):
        r = np.stack([res.residuals[c] for c in chans], axis=-1) / prob.noise_scale   # per-sample sd out
        scale = np.empty(len(chans))
        for j, c in enumerate(chans):
            if sigma and c in sigma:
                scale[j] = float(sigma[c])
            else:
                scale[j] = max(1.4826 * float(np.median(np.abs(r[:, j] - np.median(r[:, j])))), 1e-9)
        w = (nu + 1.0) / (nu + (r / scale) ** 2) * nu / (nu + 1.0)
        prob = prob.replace(weights=np.clip(w, 0.0, 1.0), theta0=res.theta,
                            sigma_fixed={c: float(scale[j] * np.sqrt(nu / (nu + 1.0))) for j, c in enumerate(chans)})
        new = prob.fit()
        if not np.all(np.isfinite(new.theta)):
            break
        step = np.abs(new.theta - res.theta)[res.free]
        res = new
        if np.all(step <= 1e-3 * np.where(res.crb[res.free] > 0, res.crb[res.free], np.inf)):
            break
    r = np.stack([res.residuals[c] for c in chans], axis=-1) / prob.noise_scale
    rejected = {c: [int(i) for i in np.flatnonzero(np.abs(r[:, j]) > REJECT_K * scale[j])]
                for j, c in enumerate(chans)}
    return prob, res, rejected


def noise_record(noise, res):
    """``ml.noise`` of the final fit: the noise choice's record with the AR(1) parameters the
    final fit holds (a fit with effects after the noise choice moves them) and ``sd``, each
    channel's total noise sd, white sd times ``sqrt(1 + q)`` on an ``ar1`` channel, and each
    ``ar1`` channel's ``sd_log_1m_rho`` where the fit's bands average over its correlation
    (:mod:`bayesdrag.estimate.model.noise_spread`).

    Why ``sd``: ``ml.sigma`` is the *white* part only; where the fit puts nearly all the scatter
    in the AR(1) part (its split from the white part is not determined when rho is near 0) that
    part reads 1e-4 m beside residuals of 1 m, and a reader takes it for the channel's noise.
    """
    out = dict(noise)
    ar = {c: v for c, v in (res.ar or {}).items() if res.noise_model.get(c) == "ar1"}
    if ar:
        out["ar"] = {c: {"rho": float(v[0]), "q": float(v[1])} for c, v in ar.items()}
        for c, sd in (getattr(res, "noise_spread", None) or {}).items():
            if c in out["ar"]:
                # how far the restricted likelihood leaves rho open (the bands average over it)
                out["ar"][c]["sd_log_1m_rho"] = float(sd)
    out["sd"] = {c: float(s * math.sqrt(1.0 + ar[c][1])) if c in ar else float(s) for c, s in res.sigma.items()}
    return out
