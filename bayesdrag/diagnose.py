"""The sim-to-real gap diagnosis: where the nominal simulation misses a track, which unmodelled
effect explains it, how large the effect is, how much of the gap it removes, and what it would
have done to a fitted Cd (issue 6, DESIGN.md ``diagnosis.json``). Pure functions, no I/O;
:mod:`bayesdrag.diagnose_report` writes the files.

Method (each decision with its reason; docs/diagnosis.md has the long form):

1. **Noise and outliers from the data, not from the fit.** Per channel the residual about a
   local cubic (Savitzky-Golay, 11 samples, never across a dropout or gap) measures the
   high-frequency content. Samples further
   than ``OUTLIER_K`` robust sd from it are flagged as gross outliers and get weight 0 in every
   fit (listed in the output). The noise sd is the round's ``[radar] sigma`` when given;
   otherwise the robust sd of that local residual corrected for the smoother. The baseline
   residuals are never used for sigma: a misfit would inflate it and hide the gap. Limitation:
   strongly correlated (AR(1)) noise has little high-frequency content, so an estimated sigma is
   then too small; the significance rule below is invariant to that scale (it uses the residual
   autocovariance measured against the assumed sigma), but ``chi2_per_sample`` and the gap are
   inflated — the output says which sigma was estimated.
2. **Baseline** = the round's reference drag (or, without one, a fitted Cd as nuisance: the
   penalised spline of a Scheme 1 fit of the same track and channels, :func:`nuisance_drag`,
   with its smoothness penalty at the evidence-chosen sd as linear pseudo-priors; the Scheme 1
   fit supplies only the drag model, the penalty and the starting coefficients and state) in the
   round's atmosphere, without Earth rotation and without any effect, with the initial state as
   nuisance parameters. When the round gives launch velocity and elevation the state is the one
   *at launch, t = 0*, with Gaussian priors: muzzle at the origin (``position_sd``), launch speed
   (``velocity_sd``), elevation (``elevation_sd``) and heading along the firing azimuth
   (sd = ``elevation_sd``: the gun is laid in deflection as carefully as in elevation). So a
   track whose start is inconsistent with the muzzle at t = 0 costs prior misfit (a late radar
   clock is a symptom, not absorbed). Without launch data the state is at the first sample and
   ``radar_time`` is not identifiable.
3. **Gap** = chi2 (noise-weighted residuals plus prior misfit) minus its noise-only expectation
   (number of weighted samples + launch priors - effective parameters: the free ones less what
   the nuisance spline's penalty takes, :func:`_edf`); ``shrink`` = fraction of it an effect
   removes, clipped to [0, 1].
4. **Which**: every candidate is fitted by ML with its parameters and the initial state.
   Significance: the chi2 drop ``d`` is divided by the colored-noise inflation
   ``g' Rvv g / g' R g`` of the fitted output change ``g`` (residual autocovariance measured on
   the candidate's own residuals, summed to the lag where it drops below its noise level, as in
   Morelli & Klein's colored-residual CRB). Under AR(1) noise with rho = 0.95 this inflation is
   ~30, and it also absorbs a wrong assumed sigma. The statistic is compared with the chi2
   quantile of the effect's number of parameters at ``ALPHA / K`` (Bonferroni over the K
   candidates tested). Ranking by chi2 drop (= 2 delta log-likelihood); exact ties keep the
   library order.
5. **Confounding**: two effects are ``confounded_with`` each other when their signatures (output
   sensitivities with the initial state and drag nuisance projected out) span nearly the same
   direction (canonical correlation >= ``CONFOUND_CORR``: density vs drag_scale is exactly 1),
   or when both are significant and the data prefer one over the other by less than the 95 %
   point of chi2(1) in colored units.
6. **Forward selection**: the best significant effect enters the verdict; the others are refitted
   together with the selected ones and enter when their conditional chi2 drop is significant
   (same rule, K = remaining candidates) and removes at least ``MIN_SECOND_SHARE`` of the
   baseline gap (a practical-size rule: a model mismatch that no effect describes leaves
   correlated residuals that a second effect would always nibble at). Forward selection is also
   started from up to two runners-up that explain most of the gap alone; between the resulting
   explanations parsimony wins unless the larger is significantly better (:func:`_better`).
   The verdict is ordered by what each member explains alone. Without a ``y`` channel the cross
   wind is held at 0 (:func:`_extra_free`); a candidate whose fit fails is skipped with the
   reason.
7. **Where**: normalised baseline residuals smoothed over ~1 % of the flight; segments where the
   smoothed residual exceeds the noise sd (merged over short breaks), by channel, with time,
   Mach range, phase (ascent, apex = within 10 % of the flight time of the summit, descent) and
   share of the systematic residual energy.
8. **Cd shift**: the output change an effect causes, refitted by a Scheme 1 spline Cd plus the
   initial state (linearised), shows what a Cd fit that ignored the effect would have absorbed.
9. **Materiality** (DESIGN.md): a detected effect is material when ignoring it would shift a
   fitted Cd by more than ``material_cd_shift`` (0.1 %) anywhere in the flown Mach range or move
   the track's last sample by more than ``material_end_sd`` (3) noise sd; both figures of a
   detected effect come from the detected effects' joint fit (:func:`effect_change`). The
   verdict lists the material ones; ``immaterial`` the detectable but immaterial ones.
10. **A table of another shell** is ``drag_shape`` (the table times a correction that
    ``drag_scale`` cannot mimic) with its level as ``drag_scale`` or its twin ``density``; when
    it is detected, every other effect is judged against a fitted Cd, as without a table
    (:func:`_beside_a_wrong_table`): no finite correction makes a wrong table a reference a
    weather effect could be measured against.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2 as _chi2

from ._threads import single_blas
from .effects import (EFFECTS, EffectContext, drag_shape_free, drag_shape_model, effect_fn, extra_params,
                      static_model)
from .errors import FitError
from .estimate.problem import OutputErrorProblem, Prior
from .estimate.noise import HF_ORDER, HF_WINDOW, OUTLIER_K, _robust_sd, hf_residual, hf_residual_t, noise_and_outliers  # noqa: F401

#: overall false-alarm rate of the verdict on a track the nominal model explains
ALPHA = 0.05
#: fewest samples a diagnosis accepts: the initial state (6) and an effect (<= 2 parameters)
#: need more data values than that with room for a test; a Doppler report every 100 yd (16
#: samples of x and v) qualifies. Without [radar] sigma the noise estimate needs more (see
#: :func:`estimate_noise`), which is checked there.
MIN_DIAGNOSIS_SAMPLES = 12
#: canonical correlation of two effects' signatures above which the data cannot separate them
CONFOUND_CORR = 0.995
#: a second (third) effect must remove at least this fraction of the baseline gap ...
MIN_SECOND_SHARE = 0.02
#: ... or at least this fraction of what the effects already selected leave: a mismatch no
#: effect describes leaves residuals a wrong effect only nibbles at (removing a small part),
#: while a second real effect explains most of what is left -- e.g. the spin drift (lift) of
#: a shell fired into a head wind, 0.2 % of that gap (6-DOF validation case)
MIN_LEFT_SHARE = 0.8
#: ... which counts only when what is left stands out of the noise: above this many sd of the
#: noise-only chi2 (with the residuals' own autocorrelation, :func:`chi2_noise_sd`)
LEFT_NOISE_K = 5.0
#: projected-signature norm fraction below which an effect is unidentifiable (absorbed by the
#: initial state and, without reference drag, the fitted Cd)
IDENTIFIABLE_FRACTION = 0.02
#: parameters of two verdict effects correlated beyond this in the joint fit are reported
JOINT_CORR_WARN = 0.9
#: largest number of effects forward selection puts in the verdict
MAX_VERDICT = 3
#: the runner-up starts a second forward selection when it removes this much of the gap alone
LOOKAHEAD_SHRINK = 0.5
#: forward selection is started from at most this many of the best single candidates
LOOKAHEAD_STARTS = 3
#: forward selection tries at most this many further candidates per step (best single first)
FORWARD_MAX_CANDIDATES = 7
#: starting yaw amplitude k delta0^2 of a yaw_drag fit (delta0 = 0.045 rad)
YAW_AMP_START = 0.02
#: Bonferroni factor for the unidentified yaw decay rate under the null (see :func:`threshold`)
YAW_DECAY_MULTIPLICITY = 5
#: the Cd shift is computed for the verdict and this many best-ranked candidates
CD_SHIFT_TOP = 2
#: apex phase: within this fraction of the flight time of the summit
APEX_FRACTION = 0.1
#: Levenberg-Marquardt iterations of a fit with drag_shape before scipy's trust-region
#: reflective method takes over (``OutputErrorProblem.fit(fallback=True)``): with a coefficient
#: against its bound the clipped LM steps crawl (a table of another shell: chi2 2.7e5 after 60
#: iterations where the trust region reaches 1.5e4 in 9 evaluations); where the fit converges it
#: does so in 5-10
DRAG_SHAPE_MAX_ITER = 12
#: ... and the trust region's function evaluations (each a sensitivity batch); a fit that needs
#: more is one whose effects fight over the same drag change (yaw drag beside the shape)
DRAG_SHAPE_TRF_NFEV = 15
#: materiality (DESIGN.md): an effect is material when ignoring it would shift a fitted Cd by
#: more than this (relative, 0.001 = 0.1 %) anywhere in the flown Mach range ...
MATERIAL_CD_SHIFT = 0.001
#: ... or move the track at its last sample by more than this many noise sd (any channel)
MATERIAL_END_SD = 3.0


# ----------------------------------------------------------------------------------------------
# noise, outliers, autocorrelation
def autocovariance(resid, weights, max_lag=None):
    """Autocovariance per channel of weighted residuals, truncated where it first drops below
    its noise level ``2 r0 / sqrt(N)`` (as the Morelli-Klein correction in ml.py).

    Parameters
    ----------
    resid : (N, C) array
    weights : (N, C) array (0 = excluded sample)

    Returns
    -------
    list of (L_c,) arrays r_c(0..L_c)
    """
    N, C = resid.shape
    out = []
    for j in range(C):
        w = weights[:, j] > 0
        e = np.where(w, resid[:, j] - (resid[w, j].mean() if w.any() else 0.0), 0.0)
        r = np.correlate(e, e, mode="full")[N - 1:] / max(w.sum(), 1)
        lim = 2.0 / math.sqrt(N) * r[0]
        below = np.flatnonzero(r < lim)
        kmax = int(below[0]) if below.size else N // 4
        kmax = min(kmax, N // 4, max_lag or N)
        out.append(r[:kmax + 1])
    return out


def chi2_noise_sd(acov, sigma_vec, weights):
    """Standard deviation of the noise-only chi2 of a fit whose residuals have the
    autocovariance ``acov``: ``sqrt(sum_c 2 n_c sum_k (r_c(k) / sigma_c^2)^2)`` over lags
    -L..L (Gaussian noise; sqrt(2 n) when white at the assumed sigma, ~4.4 times that for
    AR(1) noise with rho = 0.95)."""
    v = 0.0
    for j, r in enumerate(acov):
        n = float(np.count_nonzero(weights[:, j]))
        rr = np.asarray(r, dtype=float) / sigma_vec[j] ** 2
        v += 2.0 * n * (rr[0] ** 2 + 2.0 * float(np.sum(rr[1:] ** 2)))
    return math.sqrt(max(v, 0.0))


def _left_share_ok(setup, res, d, left, sig_vec):
    """The what-is-left rule of forward selection: the addition removes ``MIN_LEFT_SHARE`` of
    what the smaller set leaves, and that is ``LEFT_NOISE_K`` noise sd above the noise floor.
    ``res`` is the fit *with* the addition: its residuals measure the noise's correlation (those
    of the smaller set would count the very misfit in question as correlated noise)."""
    if d < MIN_LEFT_SHARE * left:
        return False
    resid = np.stack([res.residuals[c] for c in setup.channels], axis=-1)
    return left > LEFT_NOISE_K * chi2_noise_sd(autocovariance(resid, setup.weights), sig_vec, setup.weights)


def colored_inflation(g, acov, sigma_vec, weights):
    """Variance inflation ``g' Rvv g / g' R g`` of a weighted output change under the measured
    residual autocovariance (1 for white noise at the assumed sigma).

    Parameters
    ----------
    g : (N, C) array
        Output change (model units).
    acov : list of arrays (from :func:`autocovariance`)
    sigma_vec : (C,) assumed noise sd
    weights : (N, C)
    """
    gw = g * weights / sigma_vec[None, :] ** 2  # R^-1 g
    num = 0.0
    den = float(np.sum(g * gw))
    for j, r in enumerate(acov):
        s = gw[:, j]
        num += r[0] * float(s @ s)
        for k in range(1, len(r)):
            num += 2.0 * r[k] * float(s[:-k] @ s[k:])
    if den <= 0:
        return 1.0
    return max(num / den, 0.05)


# ----------------------------------------------------------------------------------------------
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

    @property
    def P(self):
        return self.model.drag.n_params


def _launch_priors(L, P):
    """Priors on the state at launch (t = 0): muzzle at the origin, speed, elevation, heading."""
    from .estimate.launch import launch_state_priors

    return launch_state_priors(L, P, heading=True)


def nuisance_drag(track, rnd, channels, sigma, t_ic):
    """The nuisance drag of a round without a firing table, from a Scheme 1 fit of the track.

    :func:`bayesdrag.estimate.scheme1.fit_scheme1` (``drag="spline"``) reads the Mach span, a
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
    from .dynamics.pointmass import PointMassModel
    from .estimate.scheme1 import fit_scheme1
    from .estimate.smoothing import SMOOTHING_GRID, smoothness_priors

    # the whole track: samples the diagnosis weights out as gross outliers are kept here (the
    # local-cubic rule also flags the first samples of a shell that decelerates fast -- 9-12
    # speed samples of a sphere or a bullet -- and leaving them out cut the drag model's Mach
    # span short of the launch, so the held-flat spline put a 10 % "wind" into a G1 bullet's
    # track); the diagnosis' own fits weight them out
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


#: half-width [samples] of the central difference that reads the speed off the positions
SPEED_HALF_WINDOW = 5


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

    Returns
    -------
    (float, float) or None when neither gives a finite range.
    """
    ch = setup.channels
    ok = setup.weights.min(axis=1) > 0
    t = np.asarray(setup.track.t, float)
    if "v" in ch:
        # every sample: a gross speed outlier (15 noise sd, ~1 % of the speed at most) barely
        # moves the span, while the local-cubic outlier rule flags the first samples of a shell
        # that decelerates fast (a sphere: 9 samples), and they hold the highest Mach
        speed = np.asarray(setup.track.channels["v"], float)
        ok = np.ones(t.size, bool)
    elif any(c in ch for c in ("x", "y", "z")) and t.size > 2 * SPEED_HALF_WINDOW + 1:
        h = SPEED_HALF_WINDOW
        comp = [np.asarray(setup.track.channels[c], float) for c in ("x", "y", "z") if c in ch]
        speed = np.full(t.size, np.nan)
        d = np.sqrt(sum((p[2 * h:] - p[:-2 * h]) ** 2 for p in comp)) / (t[2 * h:] - t[:-2 * h])
        speed[h:-h] = d
    else:
        speed = np.full(t.size, np.nan)
    # without a height channel the air at the gun (the model's Mach span covers the rest)
    z = np.asarray(setup.track.channels["z"], float) if "z" in ch else np.zeros(t.size)
    a = setup.rnd.atmosphere.at_height(np.clip(z, -400.0, 20000.0)).speed_of_sound
    m = np.where(ok, speed / a, np.nan)
    if not np.any(np.isfinite(m)):
        m = np.asarray(mach_model, float)
    if not np.any(np.isfinite(m)):
        return None
    lo, hi = float(np.nanmin(m)), float(np.nanmax(m))
    return (lo, hi) if hi > lo else None


def drag_shape_for(setup, base_theta, span):
    """The ``drag_shape`` drag of this track: knots over the flown Mach ``span``
    (:func:`bayesdrag.effects.drag_shape_model`) and offsets that make every shape function move
    the track orthogonally to a constant drag factor once the initial state (with the launch
    priors) has taken its share (:func:`bayesdrag.effects.level_free_offsets`), at the baseline.
    So ``drag_shape`` is the part of a table error that ``drag_scale`` cannot mimic, and the two
    compose into a whole smooth correction of the table."""
    from .effects import level_free_offsets

    ref = setup.rnd.reference_drag
    ds0 = drag_shape_model(ref, span)
    P, Pk = setup.P, ds0.n_params
    th = np.concatenate([[1.0], np.zeros(Pk - 1), base_theta[P:P + 6]])
    free = np.concatenate([np.ones(Pk, bool), setup.free[P:P + 6]])
    pri = _launch_priors(setup.rnd.launch, Pk) if setup.launch_known else ()
    prob = OutputErrorProblem(setup.model.with_(drag=ds0), setup.track, th, free=free, sigma=setup.sigma,
                              priors=pri, channels=setup.channels, t_ic=setup.t_ic, weights=setup.weights)
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


def make_setup(track, rnd, sigma=None, channels=None):
    """Baseline problem definition for a track and a round (see the module docstring)."""
    from .dynamics.pointmass import PointMassModel
    from .dynamics.trajectory import initial_state
    from .estimate.start import data_start

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
    if "y" not in chans:
        notes.append("no y channel: the cross wind wy is held at 0 (not identifiable) and lift/Coriolis "
                     "drift cannot be seen")
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
        s0 = initial_state(L.velocity, L.elevation_deg) if launch_known else data_start(seen, rnd).state0
    model = PointMassModel(rnd.projectile.mass, rnd.projectile.diameter, drag, rnd.atmosphere)
    P = drag.n_params
    theta0 = np.concatenate([dparams, s0])
    free = np.ones(theta0.size, bool)
    if "y" not in chans:
        free[P + 1] = free[P + 4] = False
    if not any(c in chans for c in ("x", "y", "z")):
        free[P:P + 3] = False
    priors = _launch_priors(L, P) if launch_known else ()
    ctx = EffectContext(atmosphere=rnd.atmosphere, latitude_deg=L.latitude_deg,
                        azimuth_deg=L.azimuth_deg, v0=L.velocity)
    return Setup(model, track, rnd, chans, theta0, free, priors, t_ic, sig, source, weights, outl,
                 ctx, ref is not None, launch_known, notes, smooth=tuple(smooth),
                 pen=_penalty_information(smooth, P), nuisance=None if nuis is None else nuis["info"])


def _extra_free(setup, name):
    """Is an effect parameter estimable from the channels? Without a ``y`` channel the cross
    wind has no lateral signature left (only its small share of the airspeed), so ``wind.wy``
    is held at 0 and wind is judged by its along-range component. ``drag_shape`` uses as many
    coefficients as its knots over the flown span give (:func:`bayesdrag.effects.drag_shape_knots`);
    the rest are held at 0."""
    if name.startswith("drag_shape.s"):
        return drag_shape_free(setup.ctx, int(name.rsplit("s", 1)[1]) - 1)
    return not (name == "wind.wy" and "y" not in setup.channels)


def k_free(setup, e):
    """Number of parameters of effect ``e`` fitted on this track."""
    return sum(_extra_free(setup, f"{e.name}.{p.name}") for p in e.params)


def _fit_starts(e):
    """Starting values of an effect's parameters: its null value, except the yaw amplitude,
    started slightly positive so that the decay rate has a gradient (at zero amplitude the
    decay is invisible and Gauss-Newton would stop at once)."""
    return [YAW_AMP_START if p.name == "yaw_amp" else p.start for p in e.params]


def _problem(setup, effects, theta_start):
    """OutputErrorProblem of the baseline plus ``effects`` (parameters appended)."""
    eff = [e for e in effects if e.k]
    model = static_model(setup.model, effects, setup.ctx)
    ex = extra_params(eff)
    theta0 = np.concatenate([theta_start, [s for e in eff for s in _fit_starts(e)]]) \
        if len(theta_start) == setup.theta0.size else np.asarray(theta_start, float)
    free = np.concatenate([setup.free, [_extra_free(setup, p.name) for p in ex]])
    fn = effect_fn(eff, setup.ctx, setup.theta0[setup.P:]) if eff else None
    prob = OutputErrorProblem(model, setup.track, theta0, free=free, sigma=setup.sigma,
                              priors=setup.priors + _padded(setup.smooth, len(ex)), channels=setup.channels,
                              extras=ex, effect_fn=fn, t_ic=setup.t_ic, weights=setup.weights)
    prob.diag_effects = tuple(e.name for e in effects)  # in the order of the fit's parameters
    return prob


def _padded(priors, n_extra):
    """Linear priors on the drag coefficients with their rows extended by ``n_extra`` zeros
    (the effect parameters after the initial state)."""
    if not n_extra:
        return tuple(priors)
    return tuple(Prior(p.name, p.fn, p.mean, p.sd, row=np.concatenate([np.asarray(p.row, float), np.zeros(n_extra)]))
                 for p in priors)


def _fit(setup, effects, theta_start, max_iter=40):
    prob = _problem(setup, effects, theta_start)
    if not any(e.name == "drag_shape" for e in effects):
        res = prob.fit(max_iter=max_iter)
    else:
        res = prob.fit(max_iter=min(max_iter, DRAG_SHAPE_MAX_ITER))
        if not res.converged and np.all(np.isfinite(res.theta)):
            alt = prob.fit_trust_region(res.theta, res.sigma, max_nfev=DRAG_SHAPE_TRF_NFEV)
            if np.all(np.isfinite(alt.theta)) and alt.cost <= res.cost:
                res = alt
    y = np.stack([res.fitted[c] for c in setup.channels], axis=-1)
    return res, prob, y


def _n_obs(setup):
    return float(setup.weights.sum())


def _edf(setup, res):
    """Effective number of fitted parameters of a fit: the free ones, less what the smoothness
    penalty of the nuisance spline takes, ``n_free - tr(cov Lambda)`` (Lambda the penalty's
    information on the drag coefficients; Hastie & Tibshirani's trace of the hat matrix)."""
    n_free = float(res.free.sum())
    if setup.pen is None:
        return n_free
    P = setup.P
    tr = float(np.trace(res.cov[:P, :P] @ setup.pen))
    return n_free - tr if np.isfinite(tr) else n_free - len(setup.smooth)


def _floor(setup, res):
    """Noise-only expectation of a fit's cost: weighted samples + launch priors - effective
    parameters (:func:`_edf`). With a penalised nuisance spline the penalty's rows are not
    observations of a random quantity (a smooth truth has zero second differences), so they add
    nothing and shrink the parameter count instead: E[cost] = n - tr(H) for a penalised linear
    fit whose truth the penalty does not bias."""
    return _n_obs(setup) + len(setup.priors) - _edf(setup, res)


# ----------------------------------------------------------------------------------------------
def signatures(setup, base_theta, effects):
    """Effect signatures at the baseline with the nuisance parameters projected out.

    Returns
    -------
    dict name -> (Q (n, r) orthonormal basis of the projected signature or None, fraction of the
    signature norm left after projection)
    """
    sw = np.sqrt(setup.weights / np.array([setup.sigma[c] for c in setup.channels])[None, :] ** 2)
    prob0 = _problem(setup, [], base_theta)
    y0, _, S0 = prob0.sensitivities(base_theta)
    A = (S0 * sw[:, :, None]).reshape(-1, S0.shape[-1])
    # the launch priors are pseudo-measurements: appending their Jacobian makes the projection
    # below the Schur complement (information left for the effect after the nuisance)
    _, pJ = prob0.prior_terms(base_theta)
    n_pr = pJ.shape[0]
    A = np.vstack([A, pJ]) if n_pr else A
    Qn, _ = np.linalg.qr(A)
    out = {}
    for e in effects:
        if e.k == 0:
            prob = _problem(setup, [e], base_theta)
            y1, _ = prob.predict(base_theta[None])
            cols = ((y1[0] - y0) * sw).reshape(-1, 1)
        else:
            prob = _problem(setup, [e], base_theta)
            th = prob.theta0.copy()
            if e.name == "yaw_drag":
                th[-2] = 0.05  # the decay column is flat at zero amplitude: evaluate at a small one
            if e.name == "lift":
                # the vertical part of the lift is even in the factor (flat at 0): the signature
                # of a typical right-hand-spin shell's lift, at factor 1
                th[-1] = 1.0
            _, _, S = prob.sensitivities(th)
            kf = k_free(setup, e)
            cols = (S[:, :, -kf:] * sw[:, :, None]).reshape(-1, kf)
        cols = np.vstack([cols, np.zeros((n_pr, cols.shape[1]))]) if n_pr else cols
        norms = np.linalg.norm(cols, axis=0)
        keep = norms > 0
        if not keep.any():
            out[e.name] = (None, 0.0)
            continue
        cols = cols[:, keep] / norms[keep]
        proj = cols - Qn @ (Qn.T @ cols)
        frac = float(np.max(np.linalg.norm(proj, axis=0)))
        pn = np.linalg.norm(proj, axis=0)
        if frac < 1e-12:
            out[e.name] = (None, frac)
            continue
        Q, _ = np.linalg.qr(proj[:, pn > 1e-12 * pn.max()])
        out[e.name] = (Q, frac)
    return out


def canonical_corr(Qa, Qb):
    """Largest canonical correlation between two orthonormal bases (1 = same direction)."""
    if Qa is None or Qb is None:
        return 0.0
    return float(np.linalg.svd(Qa.T @ Qb, compute_uv=False).max())


# ----------------------------------------------------------------------------------------------
def _phase(t, t_apex, t_end, t0):
    span = max(t_end - t0, 1e-9)
    if abs(t - t_apex) <= APEX_FRACTION * span:
        return "apex"
    return "ascent" if t < t_apex else "descent"


def where_segments(t, resid_norm, weights, mach, z_model, channels, window=None):
    """Segments where the systematic (smoothed) normalised residual exceeds the noise sd.

    Parameters
    ----------
    t : (N,) s; resid_norm : (N, C) residual / sigma; weights : (N, C); mach : (N,);
    z_model : (N,) model height (for the apex); channels : tuple of str

    Returns
    -------
    list of dicts (channel, t_start, t_end, mach_min, mach_max, phase, phases, share,
    peak_sigma), sorted by share.
    """
    N, C = resid_norm.shape
    w = window or max(9, int(round(N / 100)) | 1)
    k = np.ones(w)
    smooth = np.zeros_like(resid_norm)
    for j in range(C):
        r = np.where(weights[:, j] > 0, resid_norm[:, j], 0.0)
        num = np.convolve(r, k, mode="same")
        den = np.convolve((weights[:, j] > 0).astype(float), k, mode="same")
        smooth[:, j] = num / np.maximum(den, 1)
    energy = smooth ** 2
    total = float(energy.sum())
    t_apex = float(t[int(np.argmax(z_model))]) if z_model is not None else float(t[N // 2])
    segs = []
    if total <= 0:
        return segs
    for j, c in enumerate(channels):
        on = np.abs(smooth[:, j]) > 1.0
        # close short breaks, drop short runs
        idx = np.flatnonzero(on)
        if idx.size == 0:
            continue
        runs = np.split(idx, np.flatnonzero(np.diff(idx) > w) + 1)
        for run in runs:
            a, b = int(run[0]), int(run[-1])
            if b - a + 1 < max(3, w // 2):
                continue
            sl = slice(a, b + 1)
            share = float(energy[sl, j].sum() / total)
            ph_t = [_phase(tt, t_apex, t[-1], t[0]) for tt in t[sl]]
            phases = [p for p in ("ascent", "apex", "descent") if p in ph_t]
            e_by = {p: float(energy[sl, j][np.array(ph_t) == p].sum()) for p in phases}
            m = mach[sl]
            m = m[np.isfinite(m)]
            segs.append({"channel": c, "t_start": float(t[a]), "t_end": float(t[b]),
                         "mach_min": float(m.min()) if m.size else None,
                         "mach_max": float(m.max()) if m.size else None,
                         "phase": max(e_by, key=e_by.get), "phases": phases, "share": share,
                         "peak_sigma": float(np.max(np.abs(smooth[sl, j])))})
    segs.sort(key=lambda s: -s["share"])
    return segs


# ----------------------------------------------------------------------------------------------
def effect_change(setup, fit, name):
    """The output change effect ``name`` causes in a fit: the fit's outputs minus those of the
    same model and parameters with that effect switched off (the others kept).

    Parameters
    ----------
    setup : Setup
    fit : (MLResult, OutputErrorProblem, (N, C) outputs)
        A fit with ``name`` among its effects (a single-effect fit or a verdict's joint fit).
    name : str

    Returns
    -------
    dy : (N, C) array, model units
    mach : (N,) Mach along the trajectory without the effect
    """
    res, prob, y = fit
    effs = [EFFECTS[n] for n in prob.diag_effects]
    k0 = setup.P + 6
    keep, j = [res.theta[:k0]], k0
    for e in effs:
        if e.k and e.name != name:
            keep.append(res.theta[j:j + e.k])
        j += e.k
    th = np.concatenate(keep)
    others = [e for e in effs if e.name != name]
    y_o, mach_o = _problem(setup, others, th).predict(th[None])
    return y - y_o[0], mach_o[0]


def end_shift(setup, dy):
    """How far an output change moves the track at its end, in noise sd.

    Parameters
    ----------
    setup : Setup
    dy : (N, C) array
        Output change (model units) from :func:`effect_change`.

    Returns
    -------
    dict with ``per_channel`` (channel -> |dy| / sigma at the channel's last weighted sample) and
    ``max_sd``: the length of that end displacement in noise units, ``sqrt(sum_c (dy_c /
    sigma_c)^2)`` (with x, y, z at 1 m noise: how many metres the end point moves). A clock 10 ms
    late moves a 15-deg shell's end 2.7 m along x and 1.5 m in z: 3.1 sd.
    """
    out = {}
    for j, c in enumerate(setup.channels):
        w = np.flatnonzero(setup.weights[:, j] > 0)
        if w.size:
            out[c] = float(dy[w[-1], j] / setup.sigma[c])
    norm = math.sqrt(sum(v * v for v in out.values()))
    return {"per_channel": {c: abs(v) for c, v in out.items()}, "max_sd": norm}


def cd_shift(setup, theta_eff, dy, mach, n_mach=9):
    """Cd change a Scheme 1 fit would absorb had an effect been ignored (linearised).

    The output change the effect causes, ``dy`` (:func:`effect_change`), is least-squares fitted
    (noise-weighted, zero-weight samples out) by Cd and initial-state sensitivities at the fitted
    state, with the launch priors as pseudo-measurements (the effect cannot hide in the initial
    state); ``dCd(M) = B(M) d beta``. The Cd model is the Scheme 1 one: with a reference table the
    table times a cubic-spline correction on :func:`bayesdrag.drag.default_spline_knots` (a
    constant or smooth change of the table costs nothing, and relative shifts read straight off
    the correction); without one the diagnosis' nuisance spline at its fitted coefficients with
    its smoothness penalty (the penalised refit is what the Scheme 1 fit would do).

    Parameters
    ----------
    setup : Setup
    theta_eff : (P + 6 + ...) array
        The fit's parameters (drag coefficients and the initial state are used).
    dy : (N, C) array
    mach : (N,) Mach along the trajectory (its finite range is the flown range)

    Returns
    -------
    dict with ``mach`` (list), ``cd_relative`` (list, dCd / Cd), ``max_abs_relative``.
    """
    from .drag import TableSpline, default_spline_knots

    P = setup.P
    s0 = theta_eff[P:P + 6]
    m = np.asarray(mach, float)
    m = m[np.isfinite(m)]
    lo, hi = float(m.min()), float(m.max())
    if hi - lo < 0.02:  # a (nearly) constant-Mach flight: a 0.02 span around it
        lo, hi = lo - 0.01, hi + 0.01
    ref = setup.rnd.reference_drag
    if ref is not None:
        dm = TableSpline(ref, tuple(default_spline_knots(lo, hi)))
        beta = dm.initial_params()
        model = setup.model.with_(drag=dm)
        pri = _launch_priors(setup.rnd.launch, dm.n_params) if setup.launch_known else ()
    else:
        dm, beta, model = setup.model.drag, theta_eff[:P], setup.model
        pri = setup.priors + setup.smooth
    Pn = dm.n_params
    th = np.concatenate([beta, s0])
    free = np.concatenate([np.ones(Pn, bool), setup.free[P:P + 6]])
    prob = OutputErrorProblem(model, setup.track, th, free=free, sigma=setup.sigma, priors=pri,
                              channels=setup.channels, t_ic=setup.t_ic, weights=setup.weights)
    _, _, S = prob.sensitivities(th)
    sw = np.sqrt(setup.weights) / np.array([setup.sigma[c] for c in setup.channels])[None, :]
    A = (S * sw[:, :, None]).reshape(-1, S.shape[-1])
    b = (dy * sw).reshape(-1)
    # the Scheme 1 fit keeps its launch priors (and, without a table, its smoothness penalty):
    # linearised about the fit, they enter as pseudo-measurements of a zero change
    _, pJ = prob.prior_terms(th)
    if pJ.shape[0]:
        A = np.vstack([A, pJ])
        b = np.concatenate([b, np.zeros(pJ.shape[0])])
    d, *_ = np.linalg.lstsq(A, b, rcond=None)
    grid = np.linspace(lo, hi, n_mach)
    cd0 = dm.cd(beta, grid)
    rel = (dm.jacobian(grid) @ d[:Pn]) / cd0
    return {"mach": [round(float(v), 3) for v in grid], "cd_relative": [float(v) for v in rel],
            "max_abs_relative": float(np.max(np.abs(rel)))}


def materiality(cd_shift_max, end_shift_sd, cd_tol=MATERIAL_CD_SHIFT, end_tol=MATERIAL_END_SD):
    """Is an effect material (DESIGN.md)? Ignoring it would shift a fitted Cd by more than
    ``cd_tol`` (relative) anywhere in the flown range, or move the track's end by more than
    ``end_tol`` noise sd.

    Parameters
    ----------
    cd_shift_max : float or None
        Largest |dCd / Cd| (:func:`cd_shift`); None when not computed: an unknown Cd shift
        counts as material (a detected effect is never called immaterial on half the evidence).
    end_shift_sd : float
        :func:`end_shift` ``max_sd``.
    cd_tol, end_tol : float

    Returns
    -------
    (bool, str) : material, and the reason in words.
    """
    cd_txt = ("Cd shift not computed" if cd_shift_max is None else
              f"Cd shift {100 * cd_shift_max:.3g} % ({'>' if cd_shift_max > cd_tol else '<='} {100 * cd_tol:g} %)")
    end_txt = f"end of track moved {end_shift_sd:.3g} noise sd ({'>' if end_shift_sd > end_tol else '<='} {end_tol:g})"
    material = cd_shift_max is None or cd_shift_max > cd_tol or end_shift_sd > end_tol
    return bool(material), f"{'material' if material else 'immaterial'}: {cd_txt}, {end_txt}"


# ----------------------------------------------------------------------------------------------
@dataclass
class Diagnosis:
    """Result of :func:`diagnose`: ``summary`` is diagnosis.json; the arrays feed the figures."""

    summary: dict
    t: np.ndarray
    channels: tuple
    sigma: dict
    resid_base: np.ndarray
    resid_best: np.ndarray | None
    mach: np.ndarray
    weights: np.ndarray
    best: str | None


def _effect_order(name):
    return list(EFFECTS).index(name)


@single_blas
def diagnose(track, rnd, candidates=None, sigma=None, channels=None, alpha=ALPHA, cd_shifts=True,
             material_cd_shift=MATERIAL_CD_SHIFT, material_end_sd=MATERIAL_END_SD):
    """Diagnose the gap between a radar track and the nominal simulation of its round.

    Parameters
    ----------
    track : RadarTrack
    rnd : Round
    candidates : sequence of str, optional
        Effect names to test (default: the whole library that the round makes testable).
    sigma : dict, optional
        Noise sd per channel (default the round's ``[radar] sigma``, else estimated).
    channels : sequence of str, optional
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
        ``summary["verdict"]`` lists the detected effects that are material, best first;
        ``summary["immaterial"]`` those detected but immaterial.
    """
    if not (material_cd_shift >= 0 and material_end_sd >= 0):
        raise ValueError(f"materiality thresholds must be >= 0, got material_cd_shift={material_cd_shift!r}, "
                         f"material_end_sd={material_end_sd!r}")
    setup = make_setup(track, rnd, sigma, channels)
    chans = setup.channels
    sig_vec = np.array([setup.sigma[c] for c in chans])
    W = setup.weights / sig_vec[None, :] ** 2
    base, base_prob, y_base = _fit(setup, [], setup.theta0)
    if not np.all(np.isfinite(y_base)):
        raise FitError("the nominal simulation of the round does not reach the track's times")
    base_theta = base.theta.copy()
    n_obs = _n_obs(setup)
    floor0 = _floor(setup, base)
    chi2_base = float(base.cost)
    gap = max(chi2_base - floor0, 0.0)
    resid_base = np.stack([base.residuals[c] for c in chans], axis=-1)
    prior_terms = {p.name: float((p.mean - p.fn(base_theta)) / p.sd) for p in setup.priors}
    prior_chi2 = float(sum(v * v for v in prior_terms.values()))
    mach = np.asarray(base.mach, float)
    span = flown_mach_span(setup, mach)

    # candidates
    names = list(candidates) if candidates is not None else list(EFFECTS)
    skipped = {}
    if setup.ctx.latitude_deg is None and "coriolis" in names:
        skipped["coriolis"] = "the round gives no [launch] latitude: Earth rotation cannot be formed"
    if not setup.launch_known and "radar_time" in names:
        skipped["radar_time"] = "no [launch] velocity/elevation: a clock offset is a later start of the same trajectory"
    if "drag_shape" in names:
        if not setup.has_reference:
            skipped["drag_shape"] = ("no reference drag: the fitted nuisance Cd already has any shape, so a "
                                     "shape error of a table cannot be asked")
        elif span is None or not span[1] > span[0]:
            skipped["drag_shape"] = "the nominal trajectory gives no Mach span to shape the table over"
        else:
            from dataclasses import replace

            setup.ctx = replace(setup.ctx, drag_shape=drag_shape_for(setup, base_theta, span))
    effs = [EFFECTS[n] for n in names if n not in skipped]
    sigs = signatures(setup, base_theta, effs)
    for e in list(effs):
        Q, frac = sigs[e.name]
        if Q is None or frac < IDENTIFIABLE_FRACTION:
            why = ("absorbed by the fitted Cd and the initial state" if not setup.has_reference
                   else "absorbed by the initial state")
            skipped[e.name] = f"not identifiable from this track ({why}; {frac:.3g} of its signature left)"
            effs.remove(e)
    K = max(len(effs), 1)

    rows = []
    fits = {}
    for e in effs:
        try:
            res, prob, y = _fit(setup, [e], base_theta)
            if not np.all(np.isfinite(y)):
                raise FloatingPointError("non-finite trajectory at the estimate")
        except (FitError, FloatingPointError, ValueError, np.linalg.LinAlgError) as exc:
            # one candidate failing is a finding about that candidate, not the end of the diagnosis
            skipped[e.name] = f"its fit failed ({type(exc).__name__}: {exc})"
            continue
        fits[e.name] = (res, prob, y)
        rows.append(_candidate_row(e, res, y, y_base, chi2_base, gap, setup, W, alpha, K, base))
    # best first: significant effects before the rest (a non-physical or non-converged fit, e.g. a
    # yaw_drag at a negative amplitude, may drop chi2 the most yet cannot be the answer), then by
    # chi2 drop
    rows.sort(key=lambda r: (not r["significant"], -round(r["delta_chi2"], 6 if r["delta_chi2"] < 1e3 else 3),
                             _effect_order(r["name"])))
    # confounding
    for a in rows:
        a["confounded_with"] = []
    for i, a in enumerate(rows):
        for b in rows[i + 1:]:
            cc = canonical_corr(sigs[a["name"]][0], sigs[b["name"]][0])
            a.setdefault("_corr", {})[b["name"]] = cc
            close = (a["significant"] and b["significant"]
                     and abs(a["delta_chi2"] - b["delta_chi2"]) / max(a["inflation"], b["inflation"])
                     < _chi2.ppf(0.95, 1))
            # near-collinear signatures confound two effects only if the part one does not share
            # with the other is too small to detect at the size the data give it: (1 - cc^2) of
            # the smaller chi2 drop, in colored units (a wind and Coriolis share 99.7 % of their
            # signature, yet with a large gap the rest is plain; density/drag_scale share all)
            unshared = (1.0 - cc * cc) * max(min(a["delta_chi2"], b["delta_chi2"]), 0.0) / max(
                a["inflation"], b["inflation"])
            if (cc >= CONFOUND_CORR and unshared < _chi2.ppf(1 - alpha / K, 1)) or close:
                a["confounded_with"].append(b["name"])
                b["confounded_with"].append(a["name"])
    for r in rows:
        corr = r.pop("_corr", {})
        r["signature_corr"] = {k: round(v, 4) for k, v in corr.items()}

    # forward selection, with a look-ahead from the runners-up when they are real alternatives
    found, selected_fit, drop_one, wrong_table = [], None, {}, None
    if rows and rows[0]["significant"]:
        starts = [rows[0]]
        for r in rows[1:LOOKAHEAD_STARTS]:
            # drag_shape is no start of its own: never kept out of forward selection
            # (:func:`_blocked`), it enters wherever it adds what the others cannot
            if (r["significant"] and r["shrink"] >= LOOKAHEAD_SHRINK and r["name"] != "drag_shape"
                    and not any(_twins(setup, r, x) for x in starts)):
                starts.append(r)
        best = None
        for r0 in starts:
            v, f = _forward(setup, rows, r0, fits[r0["name"]], gap, sig_vec, alpha)
            if best is None or _better(setup, (v, f), best, sig_vec, alpha, gap, K):
                best = (v, f)
        found, selected_fit, drop_one = _backward(setup, best[0], best[1], fits, gap, sig_vec, alpha, K)
        if "drag_shape" in found and set(found) - set(DRAG_EFFECTS):
            found, selected_fit, drop_one, wrong_table = _beside_a_wrong_table(
                setup, rows, found, selected_fit, drop_one, fits, gap, sig_vec, alpha,
                dict(cd_shifts=cd_shifts, material_cd_shift=material_cd_shift, material_end_sd=material_end_sd))
        # ordered by what each effect explains alone (its single chi2 drop)
        rank = {r["name"]: i for i, r in enumerate(rows)}
        found = sorted(found, key=rank.get)
    by_name = {r["name"]: r for r in rows}

    # the joint fit of the detected effects: every figure of a detected effect comes from it
    joint = None
    if len(found) > 1:
        res, _, y = selected_fit
        joint = {"effects": list(found), "params": {k: float(v) for k, v in res.extras.items()},
                 "shrink": float(np.clip((chi2_base - res.cost) / gap, 0, 1)) if gap > 0 else 0.0,
                 "shrink_given_others": _conditional_shrinks(setup, res, drop_one)}
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
            r["params_joint"] = _report_params(setup, e, vals) if e.k else {}
            r["sd_joint"] = _report_params(setup, e, vals, cov_e) if e.k else {}
            r["shrink_given_others"] = joint["shrink_given_others"].get(n)

    # what ignoring each effect would do (detected effects: in their joint fit), and materiality
    for i, r in enumerate(rows):
        n = r["name"]
        fit = selected_fit if (n in found and len(found) > 1) else fits[n]
        r["impact_from"] = "joint fit" if (n in found and len(found) > 1) else "fitted alone"
        try:
            dy, mach_o = effect_change(setup, fit, n)
            es = end_shift(setup, dy)
        except (FitError, FloatingPointError, ValueError, np.linalg.LinAlgError) as exc:
            dy, es = None, None
            r["end_shift"] = {"error": f"{type(exc).__name__}: {exc}"}
        if es is not None:
            r["end_shift"] = es
        r["end_shift_sd"] = None if es is None else es["max_sd"]
        r["cd_shift_max"] = None
        if cd_shifts and dy is not None and (n in found or r["significant"] or i < CD_SHIFT_TOP):
            try:
                r["cd_shift"] = cd_shift(setup, fit[0].theta, dy, mach_o)
                r["cd_shift_max"] = r["cd_shift"]["max_abs_relative"]
            except Exception as exc:  # noqa: BLE001 - a report item, never the verdict
                r["cd_shift"] = {"error": f"{type(exc).__name__}: {exc}"}
        if (r["significant"] or n in found) and r["end_shift_sd"] is not None:
            r["material"], r["materiality"] = materiality(r["cd_shift_max"], r["end_shift_sd"],
                                                          material_cd_shift, material_end_sd)
        else:
            r["material"] = False
            r["materiality"] = ("not detected: its test statistic is below the threshold" if not r["significant"]
                                else "impact not computed: " + r["end_shift"].get("error", ""))
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
                rows[k] = dict(sub[r["name"]], detected=True, judged_against="fitted Cd (the table has another "
                                                                             "shell's shape)")
        verdict += wrong_table["verdict"]
        immaterial += wrong_table["immaterial"]
        found = found + moved
        setup.notes.append("the firing table has another shell's shape (drag_shape): the other effects were "
                           "judged against a fitted Cd, as without a table"
                           + (f" ({', '.join(moved)} found there)" if moved else " (none found)"))
    # the effects list is "best first": the verdict, the detected but immaterial, then the rest
    order = {n: k for k, n in enumerate(verdict + immaterial)}
    rows.sort(key=lambda r: (order.get(r["name"], len(order)),))

    best_name = rows[0]["name"] if rows else None
    y_best = fits[best_name][2] if best_name else None
    if len(found) > 1:  # "after" = the detected effects' joint fit
        best_name, y_best = " + ".join(found), selected_fit[2]
    elif found:
        best_name, y_best = found[0], fits[found[0]][2]
    resid_best = (np.stack([track.channels[c] for c in chans], axis=-1) - y_best) if y_best is not None else None
    rn = resid_base / sig_vec[None, :]
    z_model = y_base[:, chans.index("z")] if "z" in chans else None
    where = where_segments(track.t, rn, setup.weights, mach, z_model, chans)
    if prior_chi2 > 0 and gap > 0:
        where.append({"channel": "launch", "t_start": 0.0, "t_end": float(track.t[0]),
                      "mach_min": None, "mach_max": None, "phase": "launch", "phases": ["launch"],
                      "share": float(min(prior_chi2 / max(chi2_base - floor0 + prior_chi2, 1e-9), 1.0)),
                      "peak_sigma": float(max(abs(v) for v in prior_terms.values())),
                      "prior_misfit_sd": prior_terms})
        # channel shares are of the systematic residual energy; rescale them to the part of the
        # gap that is not launch-prior misfit so that all shares add up to at most 1
        launch_share = where[-1]["share"]
        for w in where[:-1]:
            w["share"] *= 1.0 - launch_share
        where.sort(key=lambda w: -w["share"])
    for r in rows:
        r.pop("inflation_raw", None)
    summary = {
        "baseline": {
            "rms": {c: float(np.sqrt(np.sum(setup.weights[:, j] * resid_base[:, j] ** 2)
                                     / max(setup.weights[:, j].sum(), 1))) for j, c in enumerate(chans)},
            "chi2_per_sample": float(chi2_base / max(n_obs, 1)),
            "chi2": chi2_base, "chi2_noise_floor": float(floor0), "gap": float(gap),
            # sd of chi2 under white noise: a gap or a remaining gap of this order is noise, and
            # shrink cannot be resolved better than gap_noise_sd / gap
            "gap_noise_sd": float(math.sqrt(2.0 * max(floor0, 1.0))),
            "prior_misfit_sd": prior_terms, "n_samples": int(track.n), "n_weighted": n_obs,
            "sigma": {c: float(setup.sigma[c]) for c in chans}, "sigma_source": setup.sigma_source,
            "drag": "reference" if setup.has_reference else "fitted spline (no reference drag)",
            "nuisance_drag": setup.nuisance,
            "edf": float(_edf(setup, base)),
            "initial_state": {n: float(v) for n, v in zip(base.names[setup.P:], base_theta[setup.P:])},
            "ic_time": setup.t_ic, "converged": bool(base.converged), "message": base.message,
        },
        "where": where,
        "effects": rows,
        "verdict": verdict,
        "immaterial": immaterial,
        "joint": joint,
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
    return Diagnosis(summary, np.asarray(track.t), chans, dict(setup.sigma), resid_base, resid_best,
                     mach, setup.weights, best_name)


#: the effects that are a drag (table) error or cannot be told from one: a table of another
#: shell is described by these; anything else beside it is judged against a fitted Cd
DRAG_EFFECTS = ("density", "drag_scale", "drag_shape")


def _beside_a_wrong_table(setup, rows, found, fit, drop_one, fits, gap, sig_vec, alpha, opts):
    """When ``drag_shape`` is detected the table is of another shell, and no finite shape
    correction makes it a good reference: on a precise track what the correction leaves is
    still far above the noise, and a weather effect that changes the drag along the flight (a
    head wind changes the air speed, a temperature the Mach number) removes part of it -- a
    55 m/s head wind beside the shape of a G7 table flown by a G1 bullet. So the explanation
    keeps the drag: ``drag_scale`` (the level, when it is admitted beside the shape) and
    ``drag_shape`` in their joint fit, and every other effect is judged as a round without a
    table is: by a diagnosis against a fitted Cd (the Scheme 1 spline), which sees a wind by
    what it does to the path, not to the drag.

    The level is the twin the selection found (``density`` or ``drag_scale``; DESIGN.md: a
    table error is named ``drag_scale`` when the implied air is outside the round's stated
    atmosphere, and a round that states none bounds it only by ``density``'s physical range), or
    else the better ranked of the two, kept when :func:`_admits` admits it beside the shape.

    Returns (drag effects, their joint fit, its drop-one fits, that diagnosis' summary)."""
    from dataclasses import replace

    by = {r["name"]: r for r in rows}
    level = [n for n in found if n in ("density", "drag_scale")]
    if not level:
        level = [r["name"] for r in rows if r["name"] in ("density", "drag_scale")][:1]
    names = level[:1] + ["drag_shape"]
    res = fit[0]
    k0 = setup.P + 6
    vals = dict(zip(res.names[k0:], res.theta[k0:]))
    start = [res.theta[:k0]]
    for n in names:
        e = EFFECTS[n]
        start.append([vals.get(f"{n}.{p.name}", s0) for p, s0 in zip(e.params, _fit_starts(e))])
    try:
        nfit = _fit(setup, [EFFECTS[n] for n in names], np.concatenate(start))
        if len(names) == 2 and names[0] not in found and "drag_shape" in fits:
            ok, _ = _admits(setup, EFFECTS[names[0]], fits["drag_shape"], nfit, gap, sig_vec, alpha / max(len(by), 1))
            if not ok:
                names, nfit = ["drag_shape"], fits["drag_shape"]
    except (FitError, FloatingPointError, ValueError, np.linalg.LinAlgError):
        return found, fit, drop_one, None
    subs = _drop_one_fits(setup, names, nfit, fits) if len(names) > 1 else {}
    rnd = setup.rnd
    no_table = replace(rnd, projectile=replace(rnd.projectile, reference_drag=None))
    sub = diagnose(setup.track, no_table, candidates=[n for n in EFFECTS if n not in DRAG_EFFECTS],
                   sigma=dict(setup.sigma), channels=setup.channels, alpha=alpha, **opts)
    return names, nfit, subs, sub.summary


def _twins(setup, a, b):
    """Two candidate rows are structural twins when their projected signatures span the same
    direction (canonical correlation >= CONFOUND_CORR) *and* they have as many parameters:
    their fits are then the same fit (density and drag_scale), and forward selection need not
    start from both. A smaller effect inside a larger one's span (temperature inside what
    drag_shape and a scale can do on a flat flight) is no twin: parsimony must weigh the two."""
    cc = max(a["signature_corr"].get(b["name"], 0.0), b["signature_corr"].get(a["name"], 0.0))
    return cc >= CONFOUND_CORR and k_free(setup, EFFECTS[a["name"]]) == k_free(setup, EFFECTS[b["name"]])


def _report_params(setup, e, vals, cov=None):
    """An effect's reported parameters (``cov`` None) or their sd: DESIGN.md names; for
    ``drag_shape`` only the coefficients this track uses."""
    out = e.report_params(vals) if cov is None else e.report_sd(vals, cov)
    if e.name == "drag_shape":
        out = {k: v for k, v in out.items() if _extra_free(setup, f"drag_shape.{k}")}
    return out


def _track_chi2(setup, res):
    """A fit's cost without its prior terms (launch priors, smoothness penalty): the track's own
    noise-weighted residuals."""
    th = res.theta
    pri = sum(((p.mean - p.fn(th)) / p.sd) ** 2 for p in setup.priors + setup.smooth)
    return float(res.cost) - float(pri)


def _test_drop(setup, e, d, small_res, big_res):
    """The chi2 drop a test uses. ``drag_shape`` is a hypothesis about the drag curve, so its
    evidence must be in the track: its drop counts only as far as the track's residuals fall
    (a round whose launch velocity is 15 % off leaves a launch-prior misfit that a correction
    bending the drag to nothing in the first tenths of a second, at the end of the span no speed
    sample pins, can trade against -- a sphere with its right table was named ``drag_shape``).
    Other effects keep the whole drop (``radar_time`` is *meant* to explain a start that misses
    the muzzle)."""
    if e.name != "drag_shape":
        return d
    return min(d, _track_chi2(setup, small_res) - _track_chi2(setup, big_res))


def _test_inflation(e, infl):
    """The colored inflation a test divides by. ``drag_shape``, the library's most flexible
    effect (up to 8 coefficients), gets no credit for an inflation below 1: white noise at the
    right sigma scatters the measured inflation by ~10 % either way, and below 1 it would lift
    an 8-dof chi2 of pure noise over its threshold (a null track did: chi2 drop 19.5 < 19.7,
    divided by 0.85). It must be significant in plain chi2 units too."""
    return max(infl, 1.0) if e.name == "drag_shape" else infl


def threshold(e, a, k=None):
    """Critical value of the colored chi2-drop statistic of effect ``e`` at level ``a``.

    chi2 quantile with the effect's number of parameters; for ``yaw_drag`` the decay rate is
    not identified when the amplitude is zero (Davies' problem: the fit maximises over it, which
    inflates the statistic under the null), so its amplitude is tested with 1 degree of freedom
    at ``a / YAW_DECAY_MULTIPLICITY`` (as if that many separate decay rates were tried)."""
    if e.name == "yaw_drag":
        return float(_chi2.ppf(1 - a / YAW_DECAY_MULTIPLICITY, 1))
    return float(_chi2.ppf(1 - a, max(e.k if k is None else k, 1)))


def _better(setup, new, old, sig_vec, alpha, gap, K):
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
    big_wins = d / infl > _chi2.ppf(1 - alpha / K, abs(kn - ko))
    if nested:  # the bigger set adds effects to the smaller: the forward-selection rule applies
        left = float(small[0].cost) - _floor(setup, small[0])
        big_wins = big_wins and (d >= MIN_SECOND_SHARE * gap or _left_share_ok(setup, big[0], d, left, sig_vec))
    return big_wins if kn > ko else not big_wins


def _forward(setup, rows, first, first_fit, gap, sig_vec, alpha):
    """Forward selection starting from ``first``: add the candidate that :func:`_admits`
    (Bonferroni over the remaining) with the largest conditional chi2 drop, up to
    ``MAX_VERDICT`` effects."""
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
        left = float(sel_res.cost) - _floor(setup, sel_res)
        if left <= 0:
            break
        sel_effs = [EFFECTS[n] for n in verdict]
        best_add = None
        Kr = len(remaining)
        for r in remaining:
            e = EFFECTS[r["name"]]
            start = np.concatenate([sel_res.theta, _fit_starts(e)])
            try:
                res, prob, y = _fit(setup, sel_effs + [e], start)
            except (FitError, FloatingPointError, ValueError, np.linalg.LinAlgError):
                continue
            if not np.all(np.isfinite(y)) or (e.name == "yaw_drag" and res.theta[-2] < 0):
                continue  # a failed or unphysical (negative yaw amplitude) joint fit
            ok, d = _admits(setup, e, selected_fit, (res, prob, y), gap, sig_vec, alpha / Kr)
            if ok and (best_add is None or d > best_add[1]):
                best_add = (r["name"], d, (res, prob, y))
        if best_add is None:
            break
        verdict.append(best_add[0])
        selected_fit = best_add[2]
        remaining = [r for r in remaining if r["name"] != best_add[0] and not _blocked(r, verdict)]
    return verdict, selected_fit


def _blocked(r, names):
    """Is candidate row ``r`` kept out of forward selection by one of ``names`` (confounded with
    it: a structural twin, or as well supported)? ``drag_shape`` never is: its span *contains*
    the drag-like effects it is confounded with (a yaw drag is a shape change early in the
    flight), so after one of them it can still add what they cannot, and the conditional test
    decides."""
    return r["name"] != "drag_shape" and bool(set(r["confounded_with"]) & set(names))


def _admits(setup, e, small, big, gap, sig_vec, a):
    """Would effect ``e`` be admitted to the explanation ``small`` to give ``big``? (fits as
    (res, prob, y)). Its conditional chi2 drop ``d`` must be significant at level ``a`` in
    colored units (inflation from the residuals of ``big``) and remove ``MIN_SECOND_SHARE`` of
    the gap or, by :func:`_left_share_ok`, most of what ``small`` leaves. Returns (ok, d)."""
    (sres, _, sy), (bres, _, by) = small, big
    d = float(sres.cost - bres.cost)
    resid = np.stack([bres.residuals[c] for c in setup.channels], axis=-1)
    infl = colored_inflation(by - sy, autocovariance(resid, setup.weights), sig_vec, setup.weights)
    left = float(sres.cost) - _floor(setup, sres)
    ok = (_test_drop(setup, e, d, sres, bres) / _test_inflation(e, infl) > threshold(e, a, k_free(setup, e))
          and (d >= MIN_SECOND_SHARE * gap or _left_share_ok(setup, bres, d, left, sig_vec)))
    return ok, d


def _drop_one_fits(setup, verdict, fit, fits):
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
            out[n] = _fit(setup, effs, np.concatenate([res.theta[:setup.P + 6]] + [_fit_starts(e) for e in effs]))
        except (FitError, FloatingPointError, ValueError, np.linalg.LinAlgError):
            continue
    return out


def _conditional_shrinks(setup, joint_res, subs):
    """For each member of a multi-effect verdict, the fraction of the gap left by the *other*
    members that it removes: ``(cost(others) - cost(all)) / (cost(others) - noise floor)``.
    This is "how far the gap shrinks once that effect is added" when the track carries more
    than one effect (e.g. a 6-DOF shell's spin drift besides a withheld clock offset).
    ``subs``: the verdict's drop-one fits (:func:`_drop_one_fits`)."""
    out = {}
    for n, (res_o, _, _) in subs.items():
        left = float(res_o.cost) - _floor(setup, res_o)
        out[n] = float(np.clip((res_o.cost - joint_res.cost) / left, 0.0, 1.0)) if left > 0 else 0.0
    return out


def _backward(setup, verdict, fit, fits, gap, sig_vec, alpha, K):
    """Backward elimination after forward selection: drop a member that would not be admitted
    to the verdict without it (:func:`_admits`, as in :func:`_forward`), the least useful first,
    and refit. A flexible effect chosen first because it mimics two real ones at once (a head
    wind for a density change, its cross wind for the spin drift) is thus removed once both have
    entered. Returns (verdict, fit, drop-one fits of that verdict)."""
    verdict = list(verdict)
    while True:
        subs = _drop_one_fits(setup, verdict, fit, fits) if len(verdict) > 1 else {}
        worst = None
        for n, sub in subs.items():
            keep, d = _admits(setup, EFFECTS[n], sub, fit, gap, sig_vec, alpha / K)
            if not keep and (worst is None or d < worst[1]):
                worst = (n, d, sub)
        if worst is None:
            return verdict, fit, subs
        verdict, fit = [m for m in verdict if m != worst[0]], worst[2]


def _candidate_row(e, res, y, y_base, chi2_base, gap, setup, W, alpha, K, base_res):
    chans = setup.channels
    sig_vec = np.array([setup.sigma[c] for c in chans])
    d = float(chi2_base - res.cost)
    resid = np.stack([res.residuals[c] for c in chans], axis=-1)
    acov = autocovariance(resid, setup.weights)
    infl = colored_inflation(y - y_base, acov, sig_vec, setup.weights)
    stat = _test_drop(setup, e, d, base_res, res) / _test_inflation(e, infl)
    thr = threshold(e, alpha / K, k_free(setup, e))
    n_obs = _n_obs(setup)
    vals = res.theta[-e.k:] if e.k else np.zeros(0)
    idx = slice(res.theta.size - e.k, res.theta.size)
    cov = res.cov[idx, idx] if e.k else np.zeros((0, 0))
    covc = res.cov_colored[idx, idx] if e.k else np.zeros((0, 0))
    floor_e = _floor(setup, res)
    remaining = max(float(res.cost) - floor_e, 0.0)
    noise_sd = chi2_noise_sd(acov, sig_vec, setup.weights)
    physical = True
    if e.name == "yaw_drag" and vals[0] < 0:
        physical = False
    sd_c = _report_params(setup, e, vals, covc) if e.k else {}
    # inflate the white sd by the colored factor where the Morelli-Klein bound is smaller
    row = {
        "name": e.name,
        "params": _report_params(setup, e, vals) if e.k else {},
        "sd": sd_c,
        "sd_white": _report_params(setup, e, vals, cov) if e.k else {},
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
        "units": dict(zip(_report_params(setup, e, vals).keys(), e.units)) if e.k else {},
    }
    if e.name == "drag_shape" and setup.ctx.drag_shape is not None:
        ds = setup.ctx.drag_shape
        grid = np.linspace(ds.knots[0], ds.knots[-1], 9)
        row["shape"] = {"knots": [round(float(k), 3) for k in ds.knots], "mach": [round(float(m), 3) for m in grid],
                        "cd_relative": [float(v) for v in ds.correction(vals[:ds.n_shape], grid)]}
    if not res.success:
        row["message"] = res.message
    return row
