"""The session fit: all shots of a chronograph session in one maximum-likelihood fit.

Steps (docs/radar.md, "Chronograph sessions"):

1. **Start from each shot's own data**: a straight line through its speeds gives its muzzle
   speed and its apparent deceleration, hence an apparent Cd; the curve starts at their median.
2. **Noise read off the residuals**: each shot's noise sd and its sample-to-sample correlation
   (AR(1) with a coefficient per sample spacing, ``rho ** (dt / dt_typical)``, so dropouts are
   gaps, not neighbours), and one-sided outliers (a sample farther than :data:`OUTLIER_K` robust
   sd from the fit is left out and counted), iterated with the fit :data:`NOISE_ROUNDS` times.
3. **Shot-to-shot drag scatter** ``tau``: each shot's own drag level and its sd given the shared
   curve, and the Paule-Mandel estimate (the ``tau`` at which the weighted scatter of the levels
   equals its degrees of freedom, ``S - 1``); the shots' drag offsets are random effects of that
   sd in the fit.
4. **Model size by the evidence**: the correction polynomial of order 1, 2, ... (a form factor, a
   slope, ...) with the lowest Bayesian information criterion, at most :data:`MAX_ORDER` and at
   most one coefficient per :data:`MACH_PER_COEFFICIENT` of the flown span; each coefficient
   beyond the level has the prior :data:`SHAPE_PRIOR_SD` (a departure from the reference's shape).
5. **Covariance** of the final fit (Gauss-Newton, the random-effect and time-origin priors
   included); the band of a row uses Student's t with ``S - 1`` degrees of freedom.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from math import comb

import numpy as np

from ...errors import FitError
from .model import Layout, SessionModel, Shot

__all__ = ["SessionFit", "fit_session", "OUTLIER_K", "T0_SD", "MAX_ORDER", "MACH_PER_COEFFICIENT", "NOISE_ROUNDS"]

#: a sample farther than this many robust sd (1.4826 MAD of the shot's residuals) from the fit
#: is an outlier: left out, counted in ``shots[].outliers``
OUTLIER_K = 4.0
#: a-priori sd of a shot's time origin [s]: the device's clock starts at its trigger, within
#: about a millisecond of the bullet leaving the muzzle
T0_SD = 1e-3
#: the most correction coefficients (a form factor, slope, curvature, cubic)
MAX_ORDER = 4
#: at most one correction coefficient per this span of Mach flown [-]: a shot spans 0.05-0.15
MACH_PER_COEFFICIENT = 0.04
#: rounds of (fit, noise and outliers from its residuals)
NOISE_ROUNDS = 3
#: the smallest drag scatter held in the fit [-]: tau = 0 exactly would make the offsets fixed
TAU_FLOOR = 1e-4
#: the prior sd of each shot's drag offset when its own level is measured [-]: no constraint
LOOSE_TAU = 10.0
#: the drag scatter a first fit assumes before the data give theirs [-]
TAU_START = 0.05
#: the fit stops when a step moves every parameter by less than this fraction of its sd
STEP_TOL = 1e-4
#: most Levenberg-Marquardt steps of one fit
MAX_ITER = 50
#: the smallest correction level (the form factor against the reference) a fit may reach [-]
C0_MIN = 1e-3
#: farthest a time origin may lie before the device's trigger [s] (50 times its prior sd)
T0_BOUND = 0.05
#: largest |q| = |y_d^2 - d^2| [m^2]: a device 3 m from the line of fire
Q_BOUND = 9.0
#: prior sd of each correction coefficient beyond the level, relative to the level [-]: the
#: reference's shape is the projectile's to within this per half span of the flown Mach (a
#: bullet's supersonic Cd departs from G1 or G7 by a few per cent over 0.2 Mach); strong data
#: overcome it, a near-muzzle misfit inside one shot's track does not bend the curve through it
SHAPE_PRIOR_SD = 0.15
#: the largest SNR slope (``beta``) the noise model takes
SNR_BETA_MAX = 2.0
#: a sample's SNR scale is held within this range (a fade or a glint is not the law's)
SNR_SCALE_RANGE = (0.02, 50.0)
#: finite-difference steps: curve coefficient, q [m^2], v0 [m/s], t0 [s], delta
_STEP = {"c": 1e-6, "q": 1e-4, "v0": 1e-4, "t0": 1e-7, "delta": 1e-6}


@dataclass(frozen=True)
class SessionFit:
    """What the session fit found (values, no presentation).

    Attributes
    ----------
    theta : ndarray
        The parameters (:class:`~bayesdrag.campaign.session.model.Layout`).
    cov : ndarray
        Their covariance (Gauss-Newton, priors included).
    layout : Layout
    model : SessionModel
    shots : tuple of Shot
        The shots fitted (those skipped are not here).
    sigma, rho : ndarray, shape (S,)
        Each shot's noise sd [m/s] at its median SNR and AR(1) coefficient per typical spacing.
    scale : tuple of ndarray
        Each sample's noise sd relative to its shot's ``sigma`` (from its SNR, :func:`snr_scale`).
    snr_beta : float
        The session's SNR slope (:func:`snr_slope`).
    keep : tuple of ndarray of bool
        Each shot's samples used (False: an outlier).
    tau : float
        The shot-to-shot drag scatter (relative sd).
    dof : int
        Degrees of freedom of the band (``S - 1``).
    chi2 : float
        Whitened residuals' sum of squares (data only).
    n_data : int
        Samples used.
    bic : dict
        ``{order: BIC}`` of the orders tried.
    residuals : tuple of ndarray
        Each shot's residual [m/s] (reported minus model), outliers included.
    mach : tuple of ndarray
        Each shot's flight Mach at its samples.
    levels : ndarray, shape (S,)
        Each shot's own drag level relative to the curve (1 + its offset), from the fit that
        gave ``tau``; ``level_sd`` its sd.
    """

    theta: np.ndarray = field(repr=False)
    cov: np.ndarray = field(repr=False)
    layout: Layout
    model: SessionModel = field(repr=False)
    shots: tuple = field(repr=False)
    sigma: np.ndarray = field(repr=False)
    rho: np.ndarray = field(repr=False)
    keep: tuple = field(repr=False)
    tau: float
    dof: int
    chi2: float
    n_data: int
    bic: dict
    residuals: tuple = field(repr=False)
    mach: tuple = field(repr=False)
    levels: np.ndarray = field(repr=False)
    level_sd: np.ndarray = field(repr=False)
    q_prior: tuple | None = None
    scale: tuple = field(default=(), repr=False)
    snr_beta: float = 0.0

    @property
    def order(self) -> int:
        """Number of correction coefficients chosen."""
        return self.layout.K

    def sd(self):
        """The parameters' sd."""
        return np.sqrt(np.clip(np.diag(self.cov), 0.0, None))


def _robust_sd(r):
    r = np.asarray(r, float)
    if r.size < 2:
        return np.nan
    return 1.4826 * float(np.median(np.abs(r - np.median(r))))


def _start_shot(shot):
    """(muzzle speed [m/s], deceleration [m/s^2], robust sd [m/s]) from a line through the speeds."""
    A = np.vstack([np.ones_like(shot.t), shot.t]).T
    coef = np.linalg.lstsq(A, shot.v, rcond=None)[0]
    r = shot.v - A @ coef
    for _ in range(2):     # a second line without the points far off the first
        s = max(_robust_sd(r), 1e-3)
        ok = np.abs(r) < 4 * s
        if ok.sum() >= 2:
            coef = np.linalg.lstsq(A[ok], shot.v[ok], rcond=None)[0]
            r = shot.v - A @ coef
    return float(coef[0]), float(-coef[1]), max(_robust_sd(r), 1e-3)


def _phi(t, keep, rho):
    """AR(1) coefficient between each kept sample and the previous kept one (0 at the first)."""
    tk = t[keep]
    if tk.size < 2:
        return np.zeros(tk.size)
    dt = np.diff(tk)
    dt0 = float(np.median(dt))
    phi = np.zeros(tk.size)
    phi[1:] = np.sign(rho) * np.abs(rho) ** (dt / dt0)
    return phi


def _whiten(e, phi):
    """AR(1) innovations of ``e`` (along axis 0), unit variance if ``e`` has unit variance."""
    out = np.array(e, float, copy=True)
    out[1:] = (e[1:] - phi[1:, None] * e[:-1] if e.ndim == 2 else e[1:] - phi[1:] * e[:-1])
    scale = np.sqrt(1.0 - phi ** 2)
    scale[0] = 1.0
    return out / (scale[:, None] if e.ndim == 2 else scale)


class _Problem:
    """The residual vector and its Jacobian for one layout, noise and prior set."""

    def __init__(self, model, shots, layout, sigma, rho, keep, tau, q_prior, scale=None, shape_sd=None):
        self.model, self.shots, self.layout = model, shots, layout
        # prior sd of the correction's coefficients beyond the level [Cd units per half span]
        self.shape_sd = shape_sd
        self.sigma, self.keep, self.tau, self.q_prior = sigma, keep, tau, q_prior
        # each sample's noise sd [m/s]: the shot's level times the sample's SNR scale
        self.sd = [sg * (np.ones(s.n) if scale is None else sc)
                   for s, sg, sc in zip(shots, sigma, scale if scale is not None else [None] * len(shots))]
        self.phi = [_phi(s.t, k, r) for s, k, r in zip(shots, keep, rho)]

    def _data_part(self, pred):
        out = []
        for i, (s, p) in enumerate(zip(self.shots, pred)):
            k = self.keep[i]
            out.append(_whiten((s.v[k] - p[k]) / self.sd[i][k], self.phi[i]))
        return np.concatenate(out)

    def _prior_part(self, theta):
        L = self.layout
        parts = [L.t0(theta) / T0_SD, L.delta(theta) / max(self.tau, TAU_FLOOR)]
        if self.shape_sd and L.K > 1:
            parts.append(np.asarray(theta[1: L.K]) / self.shape_sd)
        if L.fit_q and self.q_prior is not None:
            parts.append(np.atleast_1d((L.q(theta, 0.0) - self.q_prior[0]) / self.q_prior[1]))
        return np.concatenate(parts)

    def residual(self, theta):
        pred, _ = self.model.predict(theta, self.layout, self.shots)
        return np.concatenate([self._data_part(pred), self._prior_part(theta)])

    def jacobian(self, theta):
        """d residual / d theta by forward differences; a per-shot block is perturbed for all
        shots at once (each shot's prediction depends only on its own entries)."""
        L = self.layout
        base, _ = self.model.predict(theta, L, self.shots)
        cols = []           # (column indices, per-shot derivative of the prediction)

        def diff(idx, h):
            th = np.array(theta, float)
            th[idx] += h
            pred, _ = self.model.predict(th, L, self.shots)
            return [(p - b) / h for p, b in zip(pred, base)]

        for k in range(L.K):
            cols.append(("shared", k, diff(k, _STEP["c"])))
        if L.fit_q:
            cols.append(("shared", L.K, diff(L.K, _STEP["q"])))
        for name in ("v0", "t0", "delta"):
            sl = L.block(name)
            cols.append(("block", sl, diff(np.arange(sl.start, sl.stop), _STEP[name])))
        rows = []
        for i, s in enumerate(self.shots):
            k = self.keep[i]
            Ji = np.zeros((int(k.sum()), L.size))
            for kind, where, d in cols:
                j = where if kind == "shared" else where.start + i
                Ji[:, j] = -d[i][k] / self.sd[i][k]
            rows.append(_whiten(Ji, self.phi[i]))
        n_shape = L.K - 1 if self.shape_sd else 0
        Jp = np.zeros((L.S * 2 + n_shape + int(L.fit_q and self.q_prior is not None), L.size))
        shots = np.arange(L.S)
        Jp[shots, L.block("t0").start + shots] = 1.0 / T0_SD
        Jp[L.S + shots, L.block("delta").start + shots] = 1.0 / max(self.tau, TAU_FLOOR)
        if n_shape:
            Jp[2 * L.S + np.arange(n_shape), 1 + np.arange(n_shape)] = 1.0 / self.shape_sd
        if L.fit_q and self.q_prior is not None:
            Jp[-1, L.K] = 1.0 / self.q_prior[1]
        return np.vstack(rows + [Jp])


def _bounds(problem):
    """Where the parameters may go: a time origin before the shot's first sample and at most
    :data:`T0_BOUND` before the trigger; a positive muzzle speed; ``q`` within :data:`Q_BOUND`."""
    L = problem.layout
    lo, hi = np.full(L.size, -np.inf), np.full(L.size, np.inf)
    lo[0] = C0_MIN       # a drag level: positive
    if L.fit_q:
        lo[L.K], hi[L.K] = -Q_BOUND, Q_BOUND
    lo[L.block("v0")] = 1.0
    lo[L.block("t0")] = -T0_BOUND
    hi[L.block("t0")] = [float(s.t[0]) - 1e-5 for s in problem.shots]
    lo[L.block("delta")] = -0.9
    return lo, hi


def _solve(problem, theta0, max_iter=MAX_ITER, fixed=()):
    """Levenberg-Marquardt on the normal equations, each step projected into the bounds
    (:func:`_bounds`); stops when a step moves every parameter by less than
    :data:`STEP_TOL` of its sd. The problem is small (a few dozen parameters), so the
    normal equations are solved directly: no SVD of the Jacobian per step. Parameters at the
    indices ``fixed`` are held."""
    fixed = np.asarray(fixed, int)
    lo, hi = _bounds(problem)
    fin_lo, fin_hi = np.isfinite(lo), np.isfinite(hi)
    theta = np.array(theta0, float)
    theta[fin_lo] = np.maximum(theta[fin_lo], lo[fin_lo] + 1e-7 * (np.abs(lo[fin_lo]) + 1))
    theta[fin_hi] = np.minimum(theta[fin_hi], hi[fin_hi] - 1e-7 * (np.abs(hi[fin_hi]) + 1))
    r = problem.residual(theta)
    cost = float(r @ r)
    lam = 1e-3
    for _ in range(max_iter):
        J = problem.jacobian(theta)
        A, g = J.T @ J, J.T @ r
        if fixed.size:
            A[fixed, :], A[:, fixed], g[fixed] = 0.0, 0.0, 0.0
            A[fixed, fixed] = 1.0
        d = np.maximum(np.diag(A), 1e-300)
        accepted = False
        for _ in range(12):
            try:
                step = -np.linalg.solve(A + lam * np.diag(d), g)
            except np.linalg.LinAlgError:
                lam *= 10
                continue
            new = np.clip(theta + step, lo, hi)
            try:
                r_new = problem.residual(new)
                c_new = float(r_new @ r_new)
            except ValueError:      # a trial step that stops a shot within its track: no step
                c_new = np.inf
            if np.isfinite(c_new) and c_new <= cost:
                accepted = True
                break
            lam *= 10
        if not accepted:
            break
        moved = np.abs(new - theta) * np.sqrt(d)
        theta, r, cost = new, r_new, c_new
        lam = max(lam / 10, 1e-9)
        if np.max(moved) < STEP_TOL:
            break
    return theta


def _theta_with_order(theta, old, new):
    """Parameters of a layout of another order: the common coefficients kept, new ones 0."""
    out = np.zeros(new.size)
    k = min(old.K, new.K)
    out[:k] = theta[:k]
    out[new.K: new.n_shared] = theta[old.K: old.n_shared]
    out[new.n_shared:] = theta[old.n_shared:]
    return out


def snr_slope(shots, pred, keep):
    """How the noise grows as the echo weakens: ``beta`` in ``sd ~ 10 ** (-beta * snr_dB / 20)``,
    fitted to the log of the absolute residuals with an intercept per shot (0 without SNR).

    A chronograph's speed noise grows from a tenth of a m/s near the muzzle to metres per second
    at its reach as the echo weakens; ``beta = 1`` is the Cramér-Rao law of a tone's frequency
    (:mod:`bayesdrag.measure.sample_noise`); real tracks show about 0.7."""
    xs, ys = [], []
    for s, p, k in zip(shots, pred, keep):
        if s.snr is None or k.sum() < 5:
            continue
        snr = np.asarray(s.snr, float)[k]
        r = np.abs(s.v - p)[k]
        ok = np.isfinite(snr) & (snr != 0) & (r > 0)
        if ok.sum() < 5:
            continue
        xs.append(snr[ok] - np.median(snr[ok]))
        y = np.log(r[ok])
        ys.append(y - np.mean(y))
    if not xs:
        return 0.0
    x, y = np.concatenate(xs), np.concatenate(ys)
    if np.sum(x * x) <= 0:
        return 0.0
    b = float(np.sum(x * y) / np.sum(x * x))
    return float(np.clip(-b * 20.0 / np.log(10.0), 0.0, SNR_BETA_MAX))


def snr_scale(shot, beta):
    """Each sample's noise sd relative to the shot's median sample (1 without SNR)."""
    if shot.snr is None or beta == 0.0:
        return np.ones(shot.n)
    snr = np.asarray(shot.snr, float)
    known = np.isfinite(snr) & (snr != 0)
    med = float(np.median(snr[known])) if known.any() else 0.0
    sc = np.where(known, 10.0 ** (-beta * (snr - med) / 20.0), 1.0)
    return np.clip(sc, SNR_SCALE_RANGE[0], SNR_SCALE_RANGE[1])


def _noise(shots, pred, keep_prev):
    """Each shot's (sd level, AR(1) coefficient, samples kept, per-sample scale) from its
    residuals, and the session's SNR slope."""
    beta = snr_slope(shots, pred, keep_prev)
    sig, rho, keep, scales = [], [], [], []
    for s, p, kp in zip(shots, pred, keep_prev):
        sc = snr_scale(s, beta)
        r = (s.v - p) / sc
        rs = _robust_sd(r[kp])
        k = np.abs(r - np.median(r[kp])) <= OUTLIER_K * max(rs, 1e-6)
        if k.sum() < 4:     # too few left: keep them all rather than fit nothing
            k = np.ones_like(k)
        rk = r[k] - np.mean(r[k])
        sd = float(np.sqrt(np.sum(rk ** 2) / max(rk.size - 2, 1)))
        tk = s.t[k]
        near = np.diff(tk) <= 1.5 * np.median(np.diff(tk)) if tk.size > 2 else np.zeros(0, bool)
        if near.sum() >= 3:
            a, b = rk[:-1][near], rk[1:][near]
            rr = float(np.sum(a * b) / max(np.sqrt(np.sum(a * a) * np.sum(b * b)), 1e-300))
        else:
            rr = 0.0
        sig.append(max(sd, 1e-3))
        rho.append(float(np.clip(rr, 0.0, 0.95)))
        keep.append(k)
        scales.append(sc)
    return np.asarray(sig), np.asarray(rho), keep, scales, beta


def _levels(problem, theta):
    """Each shot's drag level ``1 + delta_i`` and its sd given the shared curve (its own data,
    its muzzle speed and time origin profiled out)."""
    L = problem.layout
    J = problem.jacobian(theta)
    n_rows = [int(k.sum()) for k in problem.keep]
    start = np.concatenate([[0], np.cumsum(n_rows)])
    sd = np.empty(L.S)
    for i in range(L.S):
        cols = [L.block("v0").start + i, L.block("t0").start + i, L.block("delta").start + i]
        Ji = J[start[i]: start[i + 1]][:, cols]
        info = Ji.T @ Ji + np.diag([0.0, 1.0 / T0_SD ** 2, 0.0])
        try:
            sd[i] = np.sqrt(max(np.linalg.inv(info)[2, 2], 0.0))
        except np.linalg.LinAlgError:
            sd[i] = np.inf
    return 1.0 + L.delta(theta), sd


def paule_mandel(y, s, max_iter=100):
    """The between-shot sd ``tau`` at which ``sum w (y - ybar_w)^2 = n - 1``, ``w = 1/(s^2 + tau^2)``.

    Parameters
    ----------
    y : ndarray, shape (n,)
        The shots' levels.
    s : ndarray, shape (n,)
        Their sd.

    Returns
    -------
    float
        ``tau`` >= 0 (0 when the levels scatter no more than their sd say).
    """
    y, s = np.asarray(y, float), np.asarray(s, float)
    ok = np.isfinite(y) & np.isfinite(s) & (s > 0)
    y, s = y[ok], s[ok]
    n = y.size
    if n < 2:
        return 0.0

    def excess(t2):
        w = 1.0 / (s ** 2 + t2)
        yb = np.sum(w * y) / np.sum(w)
        return float(np.sum(w * (y - yb) ** 2) - (n - 1))

    if excess(0.0) <= 0:
        return 0.0
    lo, hi = 0.0, float(np.var(y)) * 4 + 1e-12
    while excess(hi) > 0:
        hi *= 4
    for _ in range(max_iter):
        mid = 0.5 * (lo + hi)
        if excess(mid) > 0:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-14:
            break
    return float(np.sqrt(0.5 * (lo + hi)))


def _max_order(mach_span):
    return int(max(1, min(MAX_ORDER, 1 + np.floor(mach_span / MACH_PER_COEFFICIENT))))


def fit_session(shots, model, *, fit_q=True, q_prior=None, orders=None, log=None):
    """Fit every shot of a session at once (module docstring).

    Parameters
    ----------
    shots : sequence of Shot
        At least two shots of at least :data:`MIN_SAMPLES` samples each.
    model : SessionModel
        The shared physics; its ``mach_center`` and ``mach_half`` are replaced by the session's.
    fit_q : bool
        Estimate ``q`` (the device's site as a range rate sees it); else hold ``model.q_fixed``.
    q_prior : (float, float) or None
        Mean and sd [m^2] of ``q`` when it is fitted with a prior (the round's offset and its sd).
    orders : sequence of int, optional
        The correction orders to try (default 1 .. the span's maximum).
    log : callable, optional
        ``log(str)`` for progress lines.

    Returns
    -------
    SessionFit

    Raises
    ------
    FitError
        Fewer than two shots, or no fit converged.
    """
    shots = tuple(shots)
    S = len(shots)
    if S < 2:
        raise FitError(f"a session needs at least 2 shots to fit, got {S}")
    starts = [_start_shot(s) for s in shots]
    v_mean = np.array([np.mean(s.v) for s in shots])
    n = np.array([s.n for s in shots], float)
    m_mean = v_mean / model.sound_speed
    cd_app = np.array([st[1] for st in starts]) / (model.k_air * v_mean ** 2)
    m_lo = min(float(np.min(s.v)) for s in shots) / model.sound_speed
    m_hi = max(float(np.max(s.v)) for s in shots) / model.sound_speed
    span = max(m_hi - m_lo, 1e-3)
    model = replace(model, mach_center=float(np.sum(n * m_mean) / np.sum(n)), mach_half=max(0.5 * span, 0.02))
    c0 = float(np.median(cd_app / model.reference(m_mean)))
    if not np.isfinite(c0) or c0 <= 0:
        c0 = 1.0
    K0 = min(2, _max_order(span))
    layout = Layout(K0, S, fit_q)
    theta = np.zeros(layout.size)
    theta[0] = c0
    if fit_q:
        theta[layout.K] = q_prior[0] if q_prior is not None else model.q_fixed
    theta[layout.block("v0")] = [st[0] for st in starts]
    keep = [np.ones(s.n, bool) for s in shots]
    sigma = np.array([st[2] for st in starts])
    rho = np.zeros(S)
    scale, beta = None, 0.0
    shape_sd = SHAPE_PRIOR_SD * c0
    tau = TAU_START
    for rnd in range(NOISE_ROUNDS):
        prob = _Problem(model, shots, layout, sigma, rho, keep, tau, q_prior, scale, shape_sd)
        theta = _solve(prob, theta)
        pred, mach = model.predict(theta, layout, shots)
        sigma, rho, keep, scale, beta = _noise(shots, pred, keep)
        if log:
            log(f"session: noise round {rnd + 1}: median sd {np.median(sigma):.3g} m/s, rho {np.median(rho):.2f}")
    # the information-weighted Mach: the shots' Mach weighted by their samples over their noise
    w = np.concatenate([np.full(int(k.sum()), 1.0 / s ** 2) for k, s in zip(keep, sigma)])
    mk = np.concatenate([m[k] for m, k in zip(mach, keep)])
    mc = float(np.sum(w * mk) / np.sum(w))
    span = float(mk.max() - mk.min())
    theta = _recentre(theta, layout, model, mc, max(0.5 * span, 0.02))
    model = replace(model, mach_center=mc, mach_half=max(0.5 * span, 0.02))
    # drag scatter across shots
    # each shot's own level: its offset free (a flat prior) with the curve held
    loose = _Problem(model, shots, layout, sigma, rho, keep, LOOSE_TAU, q_prior, scale, shape_sd)
    theta_loose = _solve(loose, theta, fixed=np.arange(layout.n_shared))
    levels, level_sd = _levels(loose, theta_loose)
    tau = paule_mandel(levels, level_sd)
    # model order by the evidence
    # the slope is always a parameter where the span allows one (its prior keeps it honest): a
    # fixed reference shape would claim the edge rows to the level's band when the bullet's shape
    # is not the reference's; the evidence decides among the higher orders
    orders = (list(orders) if orders is not None
              else list(range(min(2, _max_order(span)), _max_order(span) + 1)))
    fits, bic = {}, {}
    for K in orders:
        lay = Layout(K, S, fit_q)
        th = _solve(_Problem(model, shots, lay, sigma, rho, keep, tau, q_prior, scale, shape_sd), _theta_with_order(theta, layout, lay))
        r = _Problem(model, shots, lay, sigma, rho, keep, tau, q_prior, scale, shape_sd).residual(th)
        n_data = int(sum(int(k.sum()) for k in keep))
        bic[K] = float(np.sum(r ** 2) + K * np.log(n_data))
        fits[K] = (lay, th)
        if log:
            log(f"session: order {K}: BIC {bic[K]:.1f}")
    K = min(bic, key=bic.get)
    layout, theta = fits[K]
    prob = _Problem(model, shots, layout, sigma, rho, keep, tau, q_prior, scale, shape_sd)
    J = prob.jacobian(theta)
    try:
        cov = np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError as exc:
        raise FitError(f"session fit: the information matrix is singular ({exc})") from None
    pred, mach = model.predict(theta, layout, shots)
    r_all = prob._data_part(pred)
    n_data = int(sum(int(k.sum()) for k in keep))
    return SessionFit(theta=theta, cov=cov, layout=layout, model=model, shots=shots, sigma=sigma, rho=rho,
                      keep=tuple(keep), tau=float(tau), dof=S - 1, chi2=float(np.sum(r_all ** 2)), n_data=n_data,
                      bic=bic, residuals=tuple(s.v - p for s, p in zip(shots, pred)), mach=tuple(mach),
                      levels=levels, level_sd=level_sd, q_prior=q_prior,
                      scale=tuple(scale) if scale is not None else tuple(np.ones(x.n) for x in shots), snr_beta=beta)


def _recentre(theta, layout, model, mc, half):
    """Coefficients of the same correction polynomial about a new centre ``mc`` and half span ``half``."""
    K = layout.K
    a, b = half / model.mach_half, (mc - model.mach_center) / model.mach_half
    c = np.asarray(theta[:K], float)
    new = np.zeros(K)
    for k in range(K):          # c_k (a u' + b)^k expanded in u'
        for j in range(k + 1):
            new[j] += c[k] * comb(k, j) * a ** j * b ** (k - j)
    out = np.array(theta, float)
    out[:K] = new
    return out
