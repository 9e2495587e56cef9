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
2. **Baseline** = the round's reference drag (or, without one, a spline Cd as nuisance) in the
   round's atmosphere, without Earth rotation and without any effect, with the initial state as
   nuisance parameters. When the round gives launch velocity and elevation the state is the one
   *at launch, t = 0*, with Gaussian priors: muzzle at the origin (``position_sd``), launch speed
   (``velocity_sd``), elevation (``elevation_sd``) and heading along the firing azimuth
   (sd = ``elevation_sd``: the gun is laid in deflection as carefully as in elevation). So a
   track whose start is inconsistent with the muzzle at t = 0 costs prior misfit (a late radar
   clock is a symptom, not absorbed). Without launch data the state is at the first sample and
   ``radar_time`` is not identifiable.
3. **Gap** = chi2 (noise-weighted residuals plus prior misfit) minus its noise-only expectation
   (number of weighted samples + priors - free parameters); ``shrink`` = fraction of it an
   effect removes, clipped to [0, 1].
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
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2 as _chi2

from ._threads import single_blas
from .effects import EFFECTS, EffectContext, effect_fn, extra_params, static_model
from .errors import FitError
from .estimate.problem import OutputErrorProblem
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

    @property
    def P(self):
        return self.model.drag.n_params


def _launch_priors(L, P):
    """Priors on the state at launch (t = 0): muzzle at the origin, speed, elevation, heading."""
    from .estimate.launch import launch_state_priors

    return launch_state_priors(L, P, heading=True)


def make_setup(track, rnd, sigma=None, channels=None):
    """Baseline problem definition for a track and a round (see the module docstring)."""
    from .drag import make_drag_model
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
    launch_known = L.velocity is not None and L.elevation_deg is not None
    if launch_known:
        t_ic = 0.0
        s0 = initial_state(L.velocity, L.elevation_deg)
    else:
        t_ic = float(track.t[0])
        s0 = data_start(track, rnd).state0
        notes.append("no [launch] velocity/elevation: initial state fitted at the first sample without "
                     "priors; a late radar clock (radar_time) cannot be told from a later start")
    ref = rnd.reference_drag
    if ref is not None:
        drag = ref
        dparams = np.zeros(0)
    else:
        lo, hi = data_start(track, rnd).mach_span
        drag = make_drag_model("spline", mach_range=(lo, hi))
        dparams = drag.initial_params(None)
        notes.append("no reference drag in the round: the diagnosis works relative to a fitted Cd "
                     "(spline as nuisance); effects that only rescale drag are not identifiable")
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
                 ctx, ref is not None, launch_known, notes)


def _extra_free(setup, name):
    """Is an effect parameter estimable from the channels? Without a ``y`` channel the cross
    wind has no lateral signature left (only its small share of the airspeed), so ``wind.wy``
    is held at 0 and wind is judged by its along-range component."""
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
    return OutputErrorProblem(model, setup.track, theta0, free=free, sigma=setup.sigma,
                              priors=setup.priors, channels=setup.channels, extras=ex, effect_fn=fn,
                              t_ic=setup.t_ic, weights=setup.weights)


def _fit(setup, effects, theta_start, max_iter=40):
    prob = _problem(setup, effects, theta_start)
    res = prob.fit(max_iter=max_iter)
    y = np.stack([res.fitted[c] for c in setup.channels], axis=-1)
    return res, prob, y


def _n_obs(setup):
    return float(setup.weights.sum())


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
def cd_shift(setup, theta_eff, effects, y_eff, base_theta, n_mach=9):
    """Cd change a Scheme 1 spline fit would absorb had ``effects`` been ignored (linearised).

    The output change the effect causes at the fitted state, ``dy = y(effect) - y(no effect)``,
    is least-squares fitted (noise-weighted) by spline-Cd and initial-state sensitivities;
    ``dCd(M) = B(M) d beta``.

    Returns
    -------
    dict with ``mach`` (list), ``cd_relative`` (list, dCd / Cd), ``max_abs_relative``.
    """
    from .drag import make_drag_model
    from .dynamics.pointmass import PointMassModel

    P = setup.P
    s0 = theta_eff[P:P + 6]
    prob_no = _problem(setup, [], np.concatenate([theta_eff[:P], s0]))
    y_no, mach_no = prob_no.predict(np.concatenate([theta_eff[:P], s0])[None])
    dy = y_eff - y_no[0]
    m = mach_no[0][np.isfinite(mach_no[0])]
    lo, hi = float(m.min()), float(m.max())
    spl = make_drag_model("spline", mach_range=(lo, hi))
    ref = setup.rnd.reference_drag
    if ref is not None:
        beta = spl.initial_params(ref)
    else:
        beta = theta_eff[:P] if P == spl.n_params else spl.initial_params(None)
    model = PointMassModel(setup.model.mass, setup.model.diameter, spl, setup.model.atmosphere)
    th = np.concatenate([beta, s0])
    free = np.concatenate([np.ones(spl.n_params, bool), setup.free[P:P + 6]])
    pri = _launch_priors(setup.rnd.launch, spl.n_params) if setup.launch_known else ()
    prob = OutputErrorProblem(model, setup.track, th, free=free, sigma=setup.sigma, priors=pri,
                              channels=setup.channels, t_ic=setup.t_ic, weights=setup.weights)
    _, _, S = prob.sensitivities(th)
    sw = np.sqrt(setup.weights) / np.array([setup.sigma[c] for c in setup.channels])[None, :]
    A = (S * sw[:, :, None]).reshape(-1, S.shape[-1])
    b = (dy * sw).reshape(-1)
    # the Scheme 1 fit keeps its launch priors: the effect cannot hide in the initial state
    _, pJ = prob.prior_terms(th)
    if pJ.shape[0]:
        A = np.vstack([A, pJ])
        b = np.concatenate([b, np.zeros(pJ.shape[0])])
    d, *_ = np.linalg.lstsq(A, b, rcond=None)
    grid = np.linspace(lo, hi, n_mach)
    cd0 = spl.cd(beta, grid)
    dcd = spl.jacobian(grid) @ d[:spl.n_params]
    rel = dcd / cd0
    return {"mach": [round(float(v), 3) for v in grid], "cd_relative": [float(v) for v in rel],
            "max_abs_relative": float(np.max(np.abs(rel)))}


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
def diagnose(track, rnd, candidates=None, sigma=None, channels=None, alpha=ALPHA, cd_shifts=True):
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
        Compute the Cd shift of the significant effects (one extra sensitivity batch each).

    Returns
    -------
    Diagnosis
    """
    setup = make_setup(track, rnd, sigma, channels)
    chans = setup.channels
    sig_vec = np.array([setup.sigma[c] for c in chans])
    W = setup.weights / sig_vec[None, :] ** 2
    base, base_prob, y_base = _fit(setup, [], setup.theta0)
    if not np.all(np.isfinite(y_base)):
        raise FitError("the nominal simulation of the round does not reach the track's times")
    base_theta = base.theta.copy()
    n_obs = _n_obs(setup)
    n_free0 = int(base.free.sum())
    floor0 = n_obs + len(setup.priors) - n_free0
    chi2_base = float(base.cost)
    gap = max(chi2_base - floor0, 0.0)
    resid_base = np.stack([base.residuals[c] for c in chans], axis=-1)
    prior_terms = {p.name: float((p.mean - p.fn(base_theta)) / p.sd) for p in setup.priors}
    prior_chi2 = float(sum(v * v for v in prior_terms.values()))

    # candidates
    names = list(candidates) if candidates is not None else list(EFFECTS)
    skipped = {}
    if setup.ctx.latitude_deg is None and "coriolis" in names:
        skipped["coriolis"] = "the round gives no [launch] latitude: Earth rotation cannot be formed"
    if not setup.launch_known and "radar_time" in names:
        skipped["radar_time"] = "no [launch] velocity/elevation: a clock offset is a later start of the same trajectory"
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
        rows.append(_candidate_row(e, res, y, y_base, chi2_base, gap, setup, W, alpha, K))
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

    # forward selection, with a look-ahead from the runner-up when it is a real alternative
    verdict, selected_fit = [], None
    if rows and rows[0]["significant"]:
        starts = [rows[0]]
        for r in rows[1:LOOKAHEAD_STARTS]:
            twin = any(r["signature_corr"].get(x["name"], 0) >= CONFOUND_CORR
                       or x["signature_corr"].get(r["name"], 0) >= CONFOUND_CORR for x in starts)
            if r["significant"] and r["shrink"] >= LOOKAHEAD_SHRINK and not twin:
                starts.append(r)
        best = None
        for r0 in starts:
            v, f = _forward(setup, rows, r0, fits[r0["name"]], gap, sig_vec, alpha)
            if best is None or _better(setup, (v, f), best, sig_vec, alpha, gap, K):
                best = (v, f)
        verdict, selected_fit, drop_one = _backward(setup, best[0], best[1], fits, gap, sig_vec, alpha, K)
        # the verdict is ordered by what each effect explains alone (its single chi2 drop), and
        # the effects list is "best first": the verdict, then the rest
        rank = {r["name"]: i for i, r in enumerate(rows)}
        verdict = sorted(verdict, key=rank.get)
        order = {n: i for i, n in enumerate(verdict)}
        rows.sort(key=lambda r: (order.get(r["name"], len(order)),))
    # Cd shifts
    if cd_shifts:
        for i, r in enumerate(rows):  # the verdict and the best few (each costs a batch)
            if r["name"] in verdict or i < CD_SHIFT_TOP:
                try:
                    res, prob, y = fits[r["name"]]
                    r["cd_shift"] = cd_shift(setup, res.theta, [EFFECTS[r["name"]]], y, base_theta)
                except Exception as exc:  # noqa: BLE001 - a report item, never the verdict
                    r["cd_shift"] = {"error": f"{type(exc).__name__}: {exc}"}
    joint = None
    if len(verdict) > 1:
        res, _, y = selected_fit
        joint = {"effects": list(verdict), "params": {k: float(v) for k, v in res.extras.items()},
                 "shrink": float(np.clip((chi2_base - res.cost) / gap, 0, 1)) if gap > 0 else 0.0,
                 "shrink_given_others": _conditional_shrinks(setup, res, drop_one)}
        # parameters of different effects that the joint fit can hardly tell apart: their values
        # then rest on the shapes of the models (e.g. a cross wind against the spin drift of a
        # shell whose lift differs from the generic Mach shape) more than on the data
        k0 = res.theta.size - len(joint["params"])
        names = list(joint["params"])
        with np.errstate(invalid="ignore", divide="ignore"):
            corr = res.correlation()[k0:, k0:]
        joint["sd"] = {n: float(v) for n, v in zip(names, np.sqrt(np.clip(np.diag(res.cov_colored)[k0:], 0, None)))}
        joint["strongly_correlated"] = [
            {"params": [names[i], names[j]], "corr": float(corr[i, j])}
            for i in range(len(names)) for j in range(i + 1, len(names))
            if names[i].split(".")[0] != names[j].split(".")[0] and abs(corr[i, j]) >= JOINT_CORR_WARN]
        # each verdict member's parameters and sd in the joint fit (its single fit may have
        # taken up another member's signature, e.g. a cross wind for the spin drift)
        for r in rows:
            if r["name"] in verdict:
                e = EFFECTS[r["name"]]
                idx = [names.index(f"{e.name}.{p.name}") for p in e.params]
                vals = np.array([joint["params"][names[i]] for i in idx])
                cov_e = res.cov_colored[np.ix_([k0 + i for i in idx], [k0 + i for i in idx])]
                r["params_joint"] = e.report_params(vals) if e.k else {}
                r["sd_joint"] = e.report_sd(vals, cov_e) if e.k else {}
                r["shrink_given_others"] = joint["shrink_given_others"].get(r["name"])
    best_name = rows[0]["name"] if rows else None
    y_best = fits[best_name][2] if best_name else None
    if len(verdict) > 1:  # "after" = the verdict's joint fit
        best_name, y_best = " + ".join(verdict), selected_fit[2]
    resid_best = (np.stack([track.channels[c] for c in chans], axis=-1) - y_best) if y_best is not None else None
    mach = np.asarray(base.mach, float)
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
            "initial_state": {n: float(v) for n, v in zip(base.names[setup.P:], base_theta[setup.P:])},
            "ic_time": setup.t_ic, "converged": bool(base.converged), "message": base.message,
        },
        "where": where,
        "effects": rows,
        "verdict": verdict,
        "joint": joint,
        "skipped": skipped,
        "outliers": {c: [int(i) for i in np.flatnonzero(setup.outliers[:, j])] for j, c in enumerate(chans)},
        "tests": {"alpha": alpha, "candidates": K, "per_test_alpha": alpha / K,
                  "rule": "chi2 drop / colored inflation > chi2_k quantile at alpha/K"},
        "notes": setup.notes,
        "reference_drag": setup.has_reference,
    }
    return Diagnosis(summary, np.asarray(track.t), chans, dict(setup.sigma), resid_base, resid_best,
                     mach, setup.weights, best_name)


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
        left = float(small[0].cost) - (_n_obs(setup) + len(setup.priors) - int(small[0].free.sum()))
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
        if r is first or set(r["confounded_with"]) & set(verdict):
            continue
        if any(r["name"] in x["confounded_with"] for x in remaining):
            continue
        remaining.append(r)
    remaining = remaining[:FORWARD_MAX_CANDIDATES]
    floor_n = _n_obs(setup) + len(setup.priors)
    while remaining and len(verdict) < MAX_VERDICT:
        sel_res = selected_fit[0]
        # what is left above the noise floor (an addition must remove a share of the gap or of this)
        left = float(sel_res.cost) - (floor_n - int(sel_res.free.sum()))
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
        remaining = [r for r in remaining if r["name"] != best_add[0]
                     and not set(r["confounded_with"]) & set(verdict)]
    return verdict, selected_fit


def _admits(setup, e, small, big, gap, sig_vec, a):
    """Would effect ``e`` be admitted to the explanation ``small`` to give ``big``? (fits as
    (res, prob, y)). Its conditional chi2 drop ``d`` must be significant at level ``a`` in
    colored units (inflation from the residuals of ``big``) and remove ``MIN_SECOND_SHARE`` of
    the gap or, by :func:`_left_share_ok`, most of what ``small`` leaves. Returns (ok, d)."""
    (sres, _, sy), (bres, _, by) = small, big
    d = float(sres.cost - bres.cost)
    resid = np.stack([bres.residuals[c] for c in setup.channels], axis=-1)
    infl = colored_inflation(by - sy, autocovariance(resid, setup.weights), sig_vec, setup.weights)
    left = float(sres.cost) - (_n_obs(setup) + len(setup.priors) - int(sres.free.sum()))
    ok = (d / infl > threshold(e, a, k_free(setup, e))
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
    floor_n = _n_obs(setup) + len(setup.priors)
    out = {}
    for n, (res_o, _, _) in subs.items():
        left = float(res_o.cost) - (floor_n - int(res_o.free.sum()))
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


def _candidate_row(e, res, y, y_base, chi2_base, gap, setup, W, alpha, K):
    chans = setup.channels
    sig_vec = np.array([setup.sigma[c] for c in chans])
    d = float(chi2_base - res.cost)
    resid = np.stack([res.residuals[c] for c in chans], axis=-1)
    acov = autocovariance(resid, setup.weights)
    infl = colored_inflation(y - y_base, acov, sig_vec, setup.weights)
    stat = d / infl
    thr = threshold(e, alpha / K, k_free(setup, e))
    n_obs = _n_obs(setup)
    vals = res.theta[-e.k:] if e.k else np.zeros(0)
    idx = slice(res.theta.size - e.k, res.theta.size)
    cov = res.cov[idx, idx] if e.k else np.zeros((0, 0))
    covc = res.cov_colored[idx, idx] if e.k else np.zeros((0, 0))
    floor_e = n_obs + len(setup.priors) - int(res.free.sum())
    remaining = max(float(res.cost) - floor_e, 0.0)
    noise_sd = chi2_noise_sd(acov, sig_vec, setup.weights)
    physical = True
    if e.name == "yaw_drag" and vals[0] < 0:
        physical = False
    sd_c = e.report_sd(vals, covc) if e.k else {}
    # inflate the white sd by the colored factor where the Morelli-Klein bound is smaller
    row = {
        "name": e.name,
        "params": e.report_params(vals) if e.k else {},
        "sd": sd_c,
        "sd_white": e.report_sd(vals, cov) if e.k else {},
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
        "units": dict(zip(e.report_params(vals).keys(), e.units)) if e.k else {},
    }
    if not res.success:
        row["message"] = res.message
    return row
