"""The diagnosis' baseline problem and its fits (steps 1-3 of :mod:`bayesdrag.diagnosis`).

:func:`make_setup` reads the noise and the gross outliers off the track
(:func:`bayesdrag.estimate.model.noise.noise_and_outliers`), chooses the baseline drag (the round's
table, or the nuisance spline of a Scheme 1 fit, :func:`nuisance_drag`) and the initial state
with its launch priors, and returns a :class:`Setup` that every later fit shares.
:func:`fit_effects` fits the baseline plus any list of effects by maximum likelihood;
:func:`noise_floor` is the noise-only expectation of a fit's cost, with the effective number of
parameters of a penalised nuisance spline (:func:`edf`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..effects import cross_range_effects, EffectContext, drag_shape_free, drag_shape_model, effect_fn, extra_params, static_model
from ..estimate.build.winds import layer_free
from ..effects.wind_layers import wind_profile_free
from .winds import rw_information, rw_priors
from ..errors import FitError
from ..estimate.model.noise import OUTLIER_K, noise_and_outliers
from ..estimate.model.problem import OutputErrorProblem, Prior
from ..estimate.model.layout import ParameterLayout
from ..measure import gun_equivalent, site_of
from ..track import NATIVE_CHANNELS
from ..effects import DRAG_SHAPE, RADAR_POSITION, WIND_PROFILE

__all__ = ["Setup", "make_setup", "nuisance_drag", "flown_mach_span", "drag_shape_for", "launch_priors",
           "extra_free", "k_free", "fit_starts", "effect_problem", "fit_effects", "n_weighted", "edf",
           "noise_floor", "track_chi2", "report_params", "gun_path",
           "unseen_effects", "held_params"]

#: half-width [samples] of the central difference that reads the speed off the positions
SPEED_HALF_WINDOW = 5
#: starting yaw amplitude k delta0^2 of a yaw_drag fit (delta0 = 0.045 rad)
YAW_AMP_START = 0.02
#: Levenberg-Marquardt iterations of a fit with drag_shape before scipy's trust-region
#: reflective method takes over (``OutputErrorProblem.fit(fallback=True)``): where the fit
#: converges it does so in 5-10; one that does not is a fit whose effects fight over the same
#: drag change (docs/measurements.md, "Where the constants come from")
DRAG_SHAPE_MAX_ITER = 12
#: ... and the trust region's function evaluations (each a sensitivity batch); a fit that needs
#: more is one whose effects fight over the same drag change (yaw drag beside the shape)
DRAG_SHAPE_TRF_NFEV = 15


@dataclass
class Setup:
    """Everything the baseline and candidate fits share."""

    model: object
    track: object
    rnd: object
    channels: tuple
    theta0: np.ndarray
    free: np.ndarray
    priors: tuple
    t_ic: float
    sigma: dict
    sigma_source: dict
    weights: np.ndarray
    outliers: np.ndarray
    ctx: EffectContext
    has_reference: bool
    launch_known: bool
    notes: list = field(default_factory=list)
    #: smoothness pseudo-priors of the nuisance spline (no reference drag), rows of length P + 6
    smooth: tuple = ()
    #: their information sum_k r_k r_k' / sd_k^2 on the drag coefficients (P, P), or None
    pen: np.ndarray | None = None
    #: how the nuisance drag was made (no reference drag), for the output
    nuisance: dict | None = None
    #: where the radar stands (:class:`bayesdrag.measure.RadarSite`): native channels are seen from there
    site: object = None
    #: the baseline's path in the gun's frame (N, 3) [m] of a track without x and z channels
    #: (radar-native): wind layers and the apex are read off it (:func:`gun_path`)
    path: np.ndarray | None = None
    #: the baseline's nuisance basis (:func:`bayesdrag.diagnosis.signatures.nuisance_basis`),
    #: with the bytes of the parameters it was made at
    basis: tuple | None = None

    @property
    def seen_as(self):
        """The gun-frame channels the track's channels observe (a radar's range, angles and range
        rate stand for x, y, z, v: :func:`bayesdrag.measure.gun_equivalent`)."""
        return gun_equivalent(self.channels)

    @property
    def P(self):
        return self.model.drag.n_params


def launch_priors(L, P):
    """Priors on the state at launch (t = 0): muzzle at the origin, speed, elevation, heading.

    Parameters
    ----------
    L : Launch
    P : int
        Number of drag coefficients before the initial state in the parameter vector.

    Returns
    -------
    tuple of Prior
    """
    from ..estimate.build.launch import launch_state_priors

    return launch_state_priors(L, P, heading=True)


def nuisance_drag(track, rnd, channels, sigma, t_ic):
    """The nuisance drag of a round without a firing table, from a Scheme 1 fit of the track.

    :func:`bayesdrag.estimate.scheme1.fit.fit_scheme1` (``drag="spline"``) reads the Mach span, a
    start Cd(M) and the state off the track, places the spline's knots where the data's shape
    bends and chooses the smoothness penalty by its evidence. The diagnosis takes from it only
    what a baseline needs to be the *same* model as the Cd fit a user would make: the drag
    model (its knots), the smoothness penalty at the chosen sd (as linear pseudo-priors) and the
    fitted coefficients and state as the starting point. Its own conventions stay: the state at
    ``t_ic`` (launch, with the round's launch priors, when the launch is known), its noise sd and
    its outlier weights, no Earth rotation; its baseline refits all of it.

    Parameters
    ----------
    track : RadarTrack
    rnd : Round
        Without ``reference_drag``.
    channels : tuple of str
    sigma : dict
        Noise sd per channel (the diagnosis' own, given or estimated).
    t_ic : float [s]
        Time of the diagnosis' initial state.

    Returns
    -------
    dict with ``model`` (DragModel), ``params`` (P,), ``state`` ((6,) at ``t_ic`` or None when
    it could not be carried there), ``smooth`` (tuple of Prior), ``sd`` and ``info`` (for the
    output) and ``notes`` (list of str).

    Raises
    ------
    FitError
        The Scheme 1 fit gave no finite estimate.
    """
    from ..dynamics.pointmass import PointMassModel
    from ..estimate.scheme1.fit import fit_scheme1
    from ..estimate.build.smoothing import SMOOTHING_GRID, smoothness_priors

    # the whole track: samples the diagnosis weights out as gross outliers are kept here (the
    # local-cubic rule also flags the first samples of a shell that decelerates fast, and leaving
    # them out would cut the drag model's Mach span short of the launch); the diagnosis' own fits
    # weight them out
    tr = track
    f1 = fit_scheme1(tr, rnd, drag="spline", channels=channels, sigma=sigma)
    res = f1.ml
    if not np.all(np.isfinite(res.theta)):
        raise FitError(f"{track.source or 'track'}: no reference drag, and the Scheme 1 fit that supplies the "
                       f"diagnosis' nuisance Cd gave no finite estimate ({res.message})")
    dm = f1.drag_model
    notes = []
    sm = f1.smoothing
    base = f1.base
    if sm:
        sd = float(sm["sd"])
    else:  # no smoothing gave a converged Scheme 1 fit: the grid's middle
        sd = float(SMOOTHING_GRID[len(SMOOTHING_GRID) // 2])
        notes.append(f"the Scheme 1 fit behind the nuisance Cd chose no smoothing ({res.message}); "
                     f"its penalty is held at sd {sd:g}")
    smooth = smoothness_priors(dm, base, sd) if base is not None else ()
    state = res.state0.copy()
    t1 = float(tr.t[0])
    if abs(t1 - t_ic) > 1e-9:
        back = PointMassModel(rnd.projectile.mass, rnd.projectile.diameter, dm, rnd.atmosphere).state_at(
            res.drag_params, state, t1, t_ic)
        state = back if back is not None and np.all(np.isfinite(back)) else None
    for c in (f1.launch_check or {}).get("conflicts", []):
        if not c.get("secondary"):
            notes.append(f"Scheme 1 (nuisance Cd): {c['message']}; the diagnosis keeps the round's launch "
                         f"priors, so this misfit is part of the gap")
    info = {"model": "penalised spline (Scheme 1 fit of this track)", "coefficients": int(dm.n_params),
            "knots": [round(float(k), 4) for k in dm.knots], "smoothing_sd": sd,
            "edf_drag": (sm or {}).get("edf_drag"), "scheme1_converged": bool(res.converged)}
    return {"model": dm, "params": res.drag_params.copy(), "state": state, "smooth": tuple(smooth), "sd": sd,
            "info": info, "notes": notes}


def flown_mach_span(setup, mach_model):
    """Mach range the shell flies at the track's samples, read off the data.

    The speed is the ``v`` channel, else the central difference of the positions over
    ``2 SPEED_HALF_WINDOW`` samples; the speed of sound is the round's atmosphere at the
    measured height (``z``), else at the gun. Outliers are left out. Not the baseline's Mach: a
    baseline flown with a table of another shell can have its speed far off (a sphere with a G1
    table "flies" at Mach 0.3-0.7 when the track says 0.2-1.7). The model's Mach is the fallback
    when the data give no speed.

    Parameters
    ----------
    setup : Setup
    mach_model : (N,) Mach numbers of the baseline (the fallback)

    A radar's own channels are read in the gun's frame first, as the fit's start reads them
    (:func:`bayesdrag.estimate.build.native_start.start_view`: positions from range and angles,
    a speed from the range rate through the nominal flight's line of sight).

    Returns
    -------
    (float, float) or None when neither gives a finite range.
    """
    track, ch = setup.track, setup.channels
    ok = setup.weights.min(axis=1) > 0
    if _native_view_needed(ch):
        from ..estimate.build.native_start import start_view

        track = start_view(track.with_channels(ch) if set(ch) != set(track.names) else track, setup.rnd, setup.site)
        ch, ok = track.names, np.ones(track.n, bool)
    t = np.asarray(track.t, float)
    if "v" in ch:
        # every sample: a gross speed outlier (15 noise sd, ~1 % of the speed at most) barely
        # moves the span, while the local-cubic outlier rule flags the first samples of a shell
        # that decelerates fast (a sphere: 9 samples), and they hold the highest Mach
        speed = np.asarray(track.channels["v"], float)
        ok = np.ones(t.size, bool)
    elif any(c in ch for c in ("x", "y", "z")) and t.size > 2 * SPEED_HALF_WINDOW + 1:
        h = SPEED_HALF_WINDOW
        comp = [np.asarray(track.channels[c], float) for c in ("x", "y", "z") if c in ch]
        speed = np.full(t.size, np.nan)
        d = np.sqrt(sum((p[2 * h:] - p[:-2 * h]) ** 2 for p in comp)) / (t[2 * h:] - t[:-2 * h])
        speed[h:-h] = d
    else:
        speed = np.full(t.size, np.nan)
    # without a height channel the air at the gun (the model's Mach span covers the rest)
    z = np.asarray(track.channels["z"], float) if "z" in ch else np.zeros(t.size)
    a = setup.rnd.atmosphere.at_height(np.clip(z, -400.0, 20000.0)).speed_of_sound
    m = np.where(ok, speed / a, np.nan)
    if not np.any(np.isfinite(m)):
        m = np.asarray(mach_model, float)
    if not np.any(np.isfinite(m)):
        return None
    lo, hi = float(np.nanmin(m)), float(np.nanmax(m))
    return (lo, hi) if hi > lo else None


def _native_view_needed(channels):
    """Whether channels hold a radar's own ones without the gun-frame speed or positions that
    the data's Mach span is read from."""
    return any(c in NATIVE_CHANNELS for c in channels) and "v" not in channels and not (
        "x" in channels and "z" in channels)


def gun_path(setup, theta):
    """The path (N, 3) [m] in the gun's frame that parameters ``theta`` (drag and initial state,
    no effects) fly at the track's samples: where a radar-native track's shell is, for the wind
    layers and the apex."""
    lay = ParameterLayout(setup.P)
    th = np.asarray(theta, float)[:lay.size]
    tr = setup.model.simulate_batch(th[None, lay.drag], th[None, lay.state], setup.track.t, t_start=setup.t_ic)
    return np.asarray(tr.state[0, :, :3], float)


def drag_shape_for(setup, base_theta, span):
    """The ``drag_shape`` drag of this track: knots over the flown Mach ``span``
    (:func:`bayesdrag.effects.drag_shape_model`) and offsets that make every shape function move
    the track orthogonally to a constant drag factor once the initial state (with the launch
    priors) has taken its share (:func:`bayesdrag.effects.level_free_offsets`), at the baseline.
    So ``drag_shape`` is the part of a table error that ``drag_scale`` cannot mimic, and the two
    compose into a whole smooth correction of the table."""
    from ..effects import level_free_offsets

    ref = setup.rnd.reference_drag
    ds0 = drag_shape_model(ref, span)
    P, Pk = setup.P, ds0.n_params
    th = np.concatenate([[1.0], np.zeros(Pk - 1), base_theta[ParameterLayout(P).state]])
    free = np.concatenate([np.ones(Pk, bool), setup.free[ParameterLayout(P).state]])
    pri = launch_priors(setup.rnd.launch, Pk) if setup.launch_known else ()
    prob = OutputErrorProblem(setup.model.with_(drag=ds0), setup.track, th, free=free, sigma=setup.sigma,
                              priors=pri, channels=setup.channels, t_ic=setup.t_ic, weights=setup.weights,
                              site=setup.site)
    _, _, S = prob.sensitivities(th)
    sw = np.sqrt(setup.weights) / np.array([setup.sigma[c] for c in setup.channels])[None, :]
    A = (S * sw[:, :, None]).reshape(-1, S.shape[-1])
    _, pJ = prob.prior_terms(th)
    if pJ.shape[0]:
        A = np.vstack([A, pJ])
    off = level_free_offsets(ds0, A[:, :Pk], A[:, Pk:])
    return drag_shape_model(ref, span, tuple(off))


def _penalty_information(smooth, P):
    """Information ``sum r r' / sd^2`` (P, P) of linear priors on the drag coefficients."""
    if not smooth:
        return None
    R = np.array([np.asarray(p.row, float)[:P] / p.sd for p in smooth])
    return R.T @ R


def make_setup(track, rnd, *, sigma=None, channels=None):
    """The baseline problem of a track and a round (steps 1-2 of :mod:`bayesdrag.diagnosis`).

    Parameters
    ----------
    track : RadarTrack
    rnd : Round
    sigma : dict, optional
        Noise sd per channel [m, m/s]; default the round's ``[radar] sigma``, estimated from the
        track's high-frequency content where that gives none.
    channels : sequence of str, optional
        Channels used (default all of the track's).

    Returns
    -------
    Setup
        Model, parameters (drag coefficients, then the initial state at ``t_ic``) with which of
        them are free, launch priors, noise sd and its source, outlier weights, the effect
        context and notes for the output.

    Raises
    ------
    FitError
        No reference drag and the Scheme 1 fit behind the nuisance Cd failed.
    """
    from ..dynamics.pointmass import PointMassModel
    from ..dynamics.trajectory import initial_state

    chans = tuple(channels) if channels is not None else tuple(track.names)
    L = rnd.launch
    notes = []
    sig_given = dict(rnd.radar.sigma) if sigma is None else dict(sigma)
    sig, source, outl = noise_and_outliers(track, chans, sig_given)
    if any(v == "estimated" for v in source.values()):
        notes.append("noise sd estimated from the track's high-frequency content for "
                     + ", ".join(c for c in chans if source[c] == "estimated")
                     + " (no [radar] sigma); strongly correlated noise makes this estimate low")
    weights = (~outl).astype(float)
    if outl.any():
        notes.append(f"{int(outl.any(axis=1).sum())} samples have gross outliers (> {OUTLIER_K:g} robust sd "
                     f"from a local smoother) and are left out")
    site = site_of(rnd, chans)
    seen_as = gun_equivalent(chans)      # a radar's range, angles, range rate observe x, y, z, v
    if "y" not in seen_as:
        what = ("no y channel" if not any(c in NATIVE_CHANNELS for c in chans)
                else f"the radar's channels ({', '.join(chans)}) see no cross-range position")
        notes.append(f"{what}: the cross wind wy is held at 0 (not identifiable) and lift/Coriolis "
                     f"drift cannot be seen")
    seen = track.with_channels(chans) if set(chans) != set(track.names) else track
    launch_known = L.velocity is not None and L.elevation_deg is not None
    t_ic = 0.0 if launch_known else float(track.t[0])
    if not launch_known:
        notes.append("no [launch] velocity/elevation: initial state fitted at the first sample without "
                     "priors; a late radar clock (radar_time) cannot be told from a later start")
    ref = rnd.reference_drag
    smooth, nuis, s0 = (), None, None
    if ref is not None:
        drag = ref
        dparams = np.zeros(0)
    else:
        nuis = nuisance_drag(seen, rnd, chans, sig, t_ic)
        drag, dparams, smooth, s0 = nuis["model"], nuis["params"], nuis["smooth"], nuis["state"]
        notes.append(f"no reference drag in the round: the diagnosis works relative to a fitted Cd, the "
                     f"penalised spline of a Scheme 1 fit of this track ({drag.n_params} coefficients, "
                     f"smoothness sd {nuis['sd']:g}); effects that only rescale or reshape drag are not "
                     f"identifiable")
        notes += nuis["notes"]
    if s0 is None:
        s0 = initial_state(L.velocity, L.elevation_deg) if launch_known else _data_state(seen, rnd, site, t_ic)
    model = PointMassModel(rnd.projectile.mass, rnd.projectile.diameter, drag, rnd.atmosphere)
    P = drag.n_params
    theta0 = np.concatenate([dparams, s0])
    free = np.ones(theta0.size, bool)
    if "y" not in seen_as:
        free[ParameterLayout(P).index("y")] = free[ParameterLayout(P).index("vy")] = False
    if not any(c in seen_as for c in ("x", "y", "z")):
        free[ParameterLayout(P).position] = False
    priors = launch_priors(L, P) if launch_known else ()
    ctx = EffectContext(atmosphere=rnd.atmosphere, latitude_deg=L.latitude_deg,
                        azimuth_deg=L.azimuth_deg, v0=L.velocity)
    return Setup(model, track, rnd, chans, theta0, free, priors, t_ic, sig, source, weights, outl,
                 ctx, ref is not None, launch_known, notes, smooth=tuple(smooth),
                 pen=_penalty_information(smooth, P), nuisance=None if nuis is None else nuis["info"], site=site)


def _data_state(seen, rnd, site, t0):
    """The initial state at the first sample read off the data, as the fit's start reads it (a
    radar's own channels through :func:`bayesdrag.estimate.build.native_start.start_view`; a
    range rate without positions flown out from the muzzle)."""
    from ..estimate.build.native_start import start_position, start_view
    from ..estimate.build.start import data_start

    s0 = data_start(start_view(seen, rnd, site), rnd).state0
    if not any(c in gun_equivalent(seen.names) for c in ("x", "y", "z")):
        s0 = s0.copy()
        s0[:3] = start_position(s0, t0, seen.names)[:3]
    return s0


def extra_free(setup, name):
    """Is an effect parameter estimable from the channels? Without a ``y`` channel the cross
    wind has no lateral signature left (only its small share of the airspeed), so ``wind.wy``
    is held at 0 and wind is judged by its along-range component (``wind_profile``'s ``wy_k``
    too). ``wind_profile`` uses as many layers as its context's layers have; ``drag_shape`` as many
    coefficients as its knots over the flown span give (:func:`bayesdrag.effects.drag_shape_knots`);
    the rest are held at 0."""
    if name.startswith("drag_shape.s"):
        return drag_shape_free(setup.ctx, int(name.rsplit("s", 1)[1]) - 1)
    if name.startswith("wind_profile."):
        return layer_free(setup.ctx.wind_layers, name, setup.seen_as)
    if name.startswith("radar_position."):
        return name.rsplit(".", 1)[1] in setup.ctx.radar_axes
    return not (name == "wind.wy" and "y" not in setup.seen_as)


#: effects whose signature at their null value is all cross-range: without a channel that sees
#: the shell's sideways position they cannot be fitted (the lift's vertical part is even in its
#: factor, so at factor 0 it has no gradient either)
CROSS_RANGE_EFFECTS = cross_range_effects()


def unseen_effects(setup, candidates=None):
    """Effects the radar's own channels cannot see, with the reason (name -> str): on a track of
    radar-native channels without a cross-range view (a Doppler radar's range rate alone), the
    effects whose signature is a sideways drift (:data:`CROSS_RANGE_EFFECTS`). They are reported
    as not identifiable rather than fitted. Empty for gun-frame channels (their screening by
    signature, :func:`bayesdrag.diagnosis.signatures.signatures`, stands as it is)."""
    if not any(c in NATIVE_CHANNELS for c in setup.channels) or "y" in setup.seen_as:
        return {}
    names = list(candidates) if candidates is not None else list(CROSS_RANGE_EFFECTS)
    return {n: (f"not identifiable from this track (the radar's channels ({', '.join(setup.channels)}) see no "
                f"cross-range position, and its signature is a sideways drift)")
            for n in CROSS_RANGE_EFFECTS if n in names}


def held_params(setup, e):
    """An effect's parameters held at their null value on this track because the channels cannot
    see them (``wind.wy`` without a cross-range view), with the reason; {} for gun-frame tracks
    (whose reports keep the held value with a note)."""
    if not any(c in NATIVE_CHANNELS for c in setup.channels):
        return {}
    if e.name == RADAR_POSITION.name:
        return {a: f"held at 0, not identifiable: the radar's channels ({', '.join(setup.channels)}) see no shift "
                   f"of the site along {a} apart from a shift of the flight"
                for a in "xyz" if a not in setup.ctx.radar_axes}
    held = [p.name for p in e.params if p.name.startswith("wy") and not extra_free(setup, f"{e.name}.{p.name}")
            and (e.name != WIND_PROFILE.name or wind_profile_free(setup.ctx, p.name))]
    why = f"held at 0, not identifiable: the radar's channels ({', '.join(setup.channels)}) see no cross-range position"
    return {n: why for n in held}


def k_free(setup, e):
    """Number of parameters of effect ``e`` fitted on this track (:func:`extra_free`)."""
    return sum(extra_free(setup, f"{e.name}.{p.name}") for p in e.params)


def fit_starts(e):
    """Starting values of an effect's parameters: its null value, except the yaw amplitude,
    started slightly positive so that the decay rate has a gradient (at zero amplitude the
    decay is invisible and Gauss-Newton would stop at once)."""
    return [YAW_AMP_START if p.name == "yaw_amp" else p.start for p in e.params]


def effect_problem(setup, effects, theta_start):
    """The output-error problem of the baseline plus ``effects``.

    Parameters
    ----------
    setup : Setup
    effects : sequence of Effect
        Their parameters are appended after the initial state, in this order.
    theta_start : array
        Starting parameters: ``(P + 6,)`` (the effects then start at :func:`fit_starts`) or the
        full vector with the effects' parameters.

    Returns
    -------
    OutputErrorProblem
        With ``effect_names``, the effects' names in the order of the parameters.
    """
    eff = [e for e in effects if e.k]
    model = static_model(setup.model, effects, setup.ctx)
    ex = extra_params(eff)
    theta0 = np.concatenate([theta_start, [s for e in eff for s in fit_starts(e)]]) \
        if len(theta_start) == setup.theta0.size else np.asarray(theta_start, float)
    free = np.concatenate([setup.free, [extra_free(setup, p.name) for p in ex]])
    fn = effect_fn(eff, setup.ctx, setup.theta0[setup.P:]) if eff else None
    # wind_profile's neighbouring layers tied by a random walk (diagnosis.winds)
    walk = rw_priors([""] * setup.theta0.size + [p.name for p in ex], free)
    prob = OutputErrorProblem(model, setup.track, theta0, free=free, sigma=setup.sigma,
                              priors=setup.priors + _padded(setup.smooth, len(ex)) + walk, channels=setup.channels,
                              extras=ex, effect_fn=fn, t_ic=setup.t_ic, weights=setup.weights,
                              effect_names=tuple(e.name for e in effects), site=setup.site)
    return prob


def _padded(priors, n_extra):
    """Linear priors on the drag coefficients with their rows extended by ``n_extra`` zeros
    (the effect parameters after the initial state)."""
    if not n_extra:
        return tuple(priors)
    return tuple(Prior(p.name, p.fn, p.mean, p.sd, row=np.concatenate([np.asarray(p.row, float), np.zeros(n_extra)]))
                 for p in priors)


def fit_effects(setup, effects, theta_start, max_iter=40):
    """Maximum-likelihood fit of the baseline plus ``effects`` (with the initial state and, without
    a reference drag, the nuisance spline). A fit with ``drag_shape`` hands over from
    Levenberg-Marquardt to scipy's trust region after ``DRAG_SHAPE_MAX_ITER`` iterations.

    Parameters
    ----------
    setup : Setup
    effects : sequence of Effect
    theta_start : array
        As for :func:`effect_problem`.
    max_iter : int
        Gauss-Newton iterations at most.

    Returns
    -------
    (MLResult, OutputErrorProblem, (N, C) array)
        The fit, its problem and the fitted outputs per channel [m, m/s].
    """
    prob = effect_problem(setup, effects, theta_start)
    # plain noise likelihood: the diagnosis compares these fits' likelihoods across effects,
    # and restricted likelihoods of models with other parameters are not comparable
    if not any(e.name == DRAG_SHAPE.name for e in effects):
        res = prob.fit(max_iter=max_iter, restricted=False)
    else:
        res = prob.fit(max_iter=min(max_iter, DRAG_SHAPE_MAX_ITER), restricted=False)
        if not res.converged and np.all(np.isfinite(res.theta)):
            alt = prob.fit_trust_region(res.theta, res.sigma, max_nfev=DRAG_SHAPE_TRF_NFEV)
            if np.all(np.isfinite(alt.theta)) and alt.cost <= res.cost:
                res = alt
    y = np.stack([res.fitted[c] for c in setup.channels], axis=-1)
    return res, prob, y


def n_weighted(setup):
    """Number of weighted data values (samples times channels, gross outliers out)."""
    return float(setup.weights.sum())


def edf(setup, res):
    """Effective number of fitted parameters of a fit: the free ones, less what the smoothness
    penalty of the nuisance spline takes, ``n_free - tr(cov Lambda)`` (Lambda the penalty's
    information on the drag coefficients; Hastie & Tibshirani's trace of the hat matrix)."""
    n_free = float(res.free.sum())
    walk = rw_information(res.names, res.free)
    if walk.any():  # wind_profile's random walk takes its share of the layers, as a penalty does
        tw = float(np.trace(res.cov @ walk))
        n_free -= tw if np.isfinite(tw) else 0.0
    if setup.pen is None:
        return n_free
    P = setup.P
    tr = float(np.trace(res.cov[:P, :P] @ setup.pen))
    return n_free - tr if np.isfinite(tr) else n_free - len(setup.smooth)


def noise_floor(setup, res):
    """Noise-only expectation of a fit's cost: weighted samples + launch priors - effective
    parameters (:func:`edf`). With a penalised nuisance spline the penalty's rows are not
    observations of a random quantity (a smooth truth has zero second differences), so they add
    nothing and shrink the parameter count instead: E[cost] = n - tr(H) for a penalised linear
    fit whose truth the penalty does not bias."""
    return n_weighted(setup) + len(setup.priors) - edf(setup, res)


def track_chi2(setup, res):
    """A fit's cost without its prior terms (launch priors, smoothness penalty): the track's own
    noise-weighted residuals."""
    th = res.theta
    pri = sum(((p.mean - p.fn(th)) / p.sd) ** 2 for p in setup.priors + setup.smooth
              + rw_priors(list(res.names), res.free))
    return float(res.cost) - float(pri)


def report_params(setup, e, vals, cov=None):
    """An effect's reported parameters (``cov`` None) or their sd: the reported names (docs/diagnosis.md); for
    ``drag_shape`` only the coefficients this track uses, for ``wind_profile`` only its layers."""
    out = e.report_params(vals) if cov is None else e.report_sd(vals, cov)
    if e.name == DRAG_SHAPE.name:
        out = {k: v for k, v in out.items() if extra_free(setup, f"drag_shape.{k}")}
    if e.name == WIND_PROFILE.name:  # the layers this track uses (a held wy without a y channel is 0)
        out = {k: v for k, v in out.items() if wind_profile_free(setup.ctx, k)}
    return out
