"""Maximum-likelihood output-error fit (paper Eq. 19) with Cramér-Rao bounds.

The estimator follows the output-error method of flight-test system identification (NASA
SIDPAC ``oe.m``; Jategaonkar, *Flight Vehicle System Identification*, ch. 4):

* parameters ``theta`` = drag-model coefficients + initial state ``X0, Y0, Z0, Ux0, Uy0, Uz0``
  at the first sample time (each free or fixed);
* outputs = the channels the track has (any subset of x, y, z, v);
* cost (Eq. 19) ``J = sum_i (z_i - y_i(theta))^T R^-1 (z_i - y_i(theta))`` with ``R`` diagonal
  (one noise variance per channel), either fixed (the round's ``[radar] sigma``) or estimated
  by *relaxation*: alternate a Gauss-Newton step in ``theta`` at fixed R with
  ``R = diag(mean residual^2)`` at fixed theta;
* optional Gaussian priors enter as pseudo-measurements (extra weighted residuals);
* Gauss-Newton with Levenberg-Marquardt damping, parameters kept inside their bounds;
  sensitivities by central differences, all perturbed trajectories in one batched kernel call.

Convergence rules (all must hold, checked after each accepted step):
``|dJ|/J < 1e-8`` or every ``|d theta_j| < 1e-3 sd_j`` (its Cramér-Rao sd), and, when R is
estimated, every noise sd changed by < 0.1 % in the last relaxation. Failure modes are reported
in the result (``success=False`` with a message) and never passed off as an answer: more than
``max_iter`` iterations, a damping factor beyond 1e10 (no descent direction), a singular or
non-finite information matrix, an integration that produced non-finite states.

Extra parameters (the diagnosis' unmodelled effects, :mod:`bayesdrag.effects`) may be appended
after the initial state: ``theta = [drag (P), state (6), extras (E)]``. Each :class:`ExtraParam`
has a name, start value, bounds and finite-difference step; an ``effect_fn`` maps the extra
values of a batch (B, E) to :class:`SimInputs` (kernel override columns, per-trajectory
atmospheres, a radar clock offset ``dt``: the model is evaluated at ``t + dt``). Without extras
the layout and behaviour are unchanged.

Optional per-sample weights (N, C) in [0, 1] multiply ``R^-1`` sample by sample: 0 removes a
sample (a flagged gross outlier) from the cost, the sensitivities, the bounds and the residual
autocorrelation.

Cramér-Rao bounds: ``cov = M^-1`` with ``M = S^T R^-1 S`` (``S`` = output sensitivities).
Colored-residual correction (Morelli & Klein, J. Aircraft 34(6), 1997):
``cov_c = M^-1 [sum_ij S_i^T R^-1 Rvv(i-j) R^-1 S_j] M^-1`` with ``Rvv`` the residual
autocorrelation per channel, summed to the lag where it first drops below its noise level.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.signal import fftconvolve

from ..errors import FitError, InputError
from ..track import CHANNELS

IC_NAMES = ("X0", "Y0", "Z0", "Ux0", "Uy0", "Uz0")
_CH_INDEX = {"x": 0, "y": 1, "z": 2}

#: finite-difference steps for the initial state (m, m/s): small against radar noise, large
#: against the kernel's rounding
IC_STEPS = (0.01, 0.01, 0.01, 0.001, 0.001, 0.001)

#: a fit that no step improves has converged when Gauss-Newton predicts a cost decrease below
#: this (the cost is a chi2: 1e-3 is far below what the data can tell)
STUCK_PREDICTED_DECREASE = 1e-3

#: longest backward extrapolation from the initial state for a shifted radar clock [s]
MAX_BACKWARD = 0.25


@dataclass(frozen=True)
class ExtraParam:
    """An extra (effect) parameter appended after the initial state.

    Attributes
    ----------
    name : str
    start : float
        Starting value (usually the "no effect" value).
    lower, upper : float
        Bounds the fit keeps the parameter inside.
    step : float
        Central finite-difference step for the sensitivities (in the parameter's unit).
    """

    name: str
    start: float
    lower: float = -np.inf
    upper: float = np.inf
    step: float = 1e-3


@dataclass(frozen=True, eq=False)
class SimInputs:
    """What a batch of extra-parameter values does to the simulation.

    Attributes
    ----------
    overrides : dict kernel column -> (B,) array
        Per-trajectory kernel parameters (``dynamics._kernel.P_*``).
    atmospheres : list of Atmosphere (length B) or None
    time_shift : (B,) array or None, s
        Radar clock offset: the model is evaluated at ``track.t + time_shift``.
    """

    overrides: dict = field(default_factory=dict)
    atmospheres: list | None = None
    time_shift: np.ndarray | None = None


@dataclass(frozen=True)
class Prior:
    """Gaussian prior on a function of the parameters, ``f(theta) ~ N(mean, sd^2)``.

    ``fn`` maps the full parameter vector (P + 6,) to a float; ``name`` labels it. ``row``, when
    given, says the prior is linear: ``fn(theta) = row @ theta`` with ``row`` of the full
    parameter length, so its Jacobian needs no finite differences (the spline smoothness penalty
    has ~45 such priors).
    """

    name: str
    fn: object
    mean: float
    sd: float
    row: object = None


@dataclass(frozen=True, eq=False)
class MLResult:
    """Outcome of an output-error fit.

    Attributes
    ----------
    names : tuple of str
        All parameter names (drag coefficients then initial state).
    theta : (n,) ndarray
        Estimates of all parameters (fixed ones at their given values).
    free : (n,) bool ndarray
    crb : (n,) ndarray
        Cramér-Rao sd (0 for fixed parameters).
    crb_colored : (n,) ndarray
        Colored-residual-corrected sd (Morelli & Klein).
    cov, cov_colored : (n, n) ndarray
        Covariances (zero rows/columns for fixed parameters).
    sigma : dict channel -> float
        Noise sd used at the end (estimated or fixed).
    cost : float
        Eq. 19 at the estimate (with the final R), plus prior terms.
    converged : bool
    success : bool
    message : str
    iterations : int
    warnings : tuple of str
    residuals : dict channel -> (N,) ndarray
        Measured minus model.
    fitted : dict channel -> (N,) ndarray
    mach : (N,) ndarray
        Mach number along the fitted trajectory.
    history : tuple of float
        Cost after each iteration.
    """

    names: tuple
    theta: np.ndarray
    free: np.ndarray
    crb: np.ndarray
    crb_colored: np.ndarray
    cov: np.ndarray
    cov_colored: np.ndarray
    sigma: dict
    cost: float
    converged: bool
    success: bool
    message: str
    iterations: int
    warnings: tuple = ()
    residuals: dict = field(default_factory=dict)
    fitted: dict = field(default_factory=dict)
    mach: np.ndarray = None
    history: tuple = ()
    n_drag: int = 0
    n_extra: int = 0
    weights: np.ndarray = None

    @property
    def params(self):
        return dict(zip(self.names, map(float, self.theta)))

    @property
    def drag_params(self):
        return self.theta[:self.n_drag]

    @property
    def state0(self):
        return self.theta[self.n_drag:self.n_drag + 6]

    @property
    def extras(self):
        """Extra (effect) parameters as a dict name -> value (empty without extras)."""
        k = self.n_drag + 6
        return dict(zip(self.names[k:], map(float, self.theta[k:])))

    def correlation(self):
        sd = np.sqrt(np.clip(np.diag(self.cov), 0, None))
        with np.errstate(invalid="ignore", divide="ignore"):
            c = self.cov / np.outer(sd, sd)
        return np.where(np.outer(sd, sd) > 0, c, 0.0)


def _outputs(traj_state, channels):
    """Model outputs (B, N, C) for channels from states (B, N, 6)."""
    out = np.empty(traj_state.shape[:-1] + (len(channels),))
    for j, c in enumerate(channels):
        if c == "v":
            vx, vy, vz = traj_state[..., 3], traj_state[..., 4], traj_state[..., 5]
            out[..., j] = np.sqrt(vx * vx + vy * vy + vz * vz)
        else:
            out[..., j] = traj_state[..., _CH_INDEX[c]]
    return out


class OutputErrorProblem:
    """An output-error fit of one track with one point-mass model.

    Parameters
    ----------
    model : PointMassModel
        Its ``drag`` is the model whose coefficients are estimated.
    track : RadarTrack
    theta0 : (P + 6,) array
        Starting values: drag coefficients, then the state at ``track.t[0]``.
    free : (P + 6,) bool array, optional
        Which parameters are estimated (default all).
    sigma : dict channel -> sd, optional
        Fixed noise sd; channels missing here have their sd estimated by relaxation.
    priors : sequence of Prior, optional
    channels : sequence of str, optional
        Channels to fit (default: all the track has).
    extras : sequence of ExtraParam, optional
        Effect parameters appended after the initial state (``theta0`` then has P + 6 + E
        entries; their start values are taken from ``theta0``).
    effect_fn : callable, optional
        ``effect_fn(E)`` with ``E`` (B, n_extras) returns :class:`SimInputs`; required with extras.
    t_ic : float, optional, s
        Time of the initial state (default ``track.t[0]``; the diagnosis uses 0 = launch).
    weights : (N, C) array, optional
        Per-sample weights in [0, 1] on ``R^-1`` (0 drops a sample).
    """

    def __init__(self, model, track, theta0, free=None, sigma=None, priors=(), channels=None,
                 extras=(), effect_fn=None, t_ic=None, weights=None):
        self.model = model
        self.track = track
        self.channels = tuple(channels) if channels is not None else track.names
        for c in self.channels:
            if c not in CHANNELS or track.channels.get(c) is None:
                raise InputError(f"{track.source}: channel {c!r} is not in the track (has {', '.join(track.names)})")
        self.P = model.drag.n_params
        self.extras = tuple(extras)
        self.E = len(self.extras)
        if self.E and effect_fn is None:
            raise ValueError("extra parameters need an effect_fn mapping them to the simulation")
        self.effect_fn = effect_fn
        self.t_ic = float(track.t[0]) if t_ic is None else float(t_ic)
        self.names = tuple(model.drag.param_names) + IC_NAMES + tuple(e.name for e in self.extras)
        n = self.P + 6 + self.E
        self.theta0 = np.asarray(theta0, dtype=float).copy()
        if self.theta0.shape != (n,):
            raise ValueError(f"theta0 must have {n} entries, got {self.theta0.shape}")
        self.free = np.ones(n, bool) if free is None else np.asarray(free, bool).copy()
        self.sigma_fixed = {c: float(s) for c, s in (sigma or {}).items() if c in self.channels}
        self.priors = tuple(priors)
        self.z = np.stack([track.channels[c] for c in self.channels], axis=-1)  # (N, C)
        if weights is None:
            self.weights = np.ones_like(self.z)
        else:
            self.weights = np.asarray(weights, dtype=float)
            if self.weights.shape != self.z.shape or np.any(self.weights < 0) or np.any(self.weights > 1):
                raise ValueError(f"weights must be (N, C) = {self.z.shape} in [0, 1]")
        n_free = int(self.free.sum())
        if self.z.shape[0] * len(self.channels) <= n_free:
            raise InputError(f"{track.source}: {self.z.shape[0]} samples x {len(self.channels)} channels "
                             f"are too few for {n_free} free parameters")
        for j, c in enumerate(self.channels):
            if np.ptp(self.z[:, j]) == 0.0 and c != "y":
                raise InputError(f"{track.source}: channel {c} is constant ({self.z[0, j]}); "
                                 f"it carries no information — drop the column or fix the track")
        lb, ub = model.drag.bounds
        big = np.full(6, np.inf)
        self.lower = np.concatenate([lb, -big, [e.lower for e in self.extras]])
        self.upper = np.concatenate([ub, big, [e.upper for e in self.extras]])
        self.steps = np.concatenate([np.maximum(1e-6, 1e-5 * np.abs(self.theta0[:self.P]) + 1e-7),
                                     IC_STEPS, [e.step for e in self.extras]])

    # ----------------------------------------------------------------------------------------
    def predict(self, thetas):
        """Model outputs (B, N, C) and Mach (B, N) for parameter sets (B, P + 6)."""
        thetas = np.atleast_2d(thetas)
        P = self.P
        if not self.E:
            tr = self.model.simulate_batch(thetas[:, :P], thetas[:, P:P + 6], self.track.t,
                                           t_start=self.t_ic)
            return _outputs(tr.state, self.channels), tr.mach
        B = thetas.shape[0]
        inp = self.effect_fn(thetas[:, P + 6:])
        shift = np.zeros(B) if inp.time_shift is None else np.asarray(inp.time_shift, float)
        y = np.full((B, self.track.n, len(self.channels)), np.nan)
        mach = np.full((B, self.track.n), np.nan)
        # one kernel call per distinct clock offset (a finite-difference batch has at most 3)
        for s in np.unique(shift):
            g = np.flatnonzero(shift == s)
            t_out = self.track.t + s
            if t_out[0] < self.t_ic - MAX_BACKWARD:
                continue  # too far before the initial state: left NaN, the fit rejects the step
            ov = {k: np.asarray(v, float)[g] for k, v in inp.overrides.items()}
            atm = None if inp.atmospheres is None else [inp.atmospheres[i] for i in g]
            state, m = self._simulate_shifted(thetas[g], t_out, ov, atm)
            y[g] = _outputs(state, self.channels)
            mach[g] = m
        return y, mach

    def _simulate_shifted(self, th, t_out, ov, atm):
        """States (G, N, 6) and Mach (G, N) at ``t_out``; samples before the initial state (an
        early radar clock) are extrapolated backwards to second order from it."""
        P = self.P
        pre = t_out < self.t_ic - 1e-12
        if not pre.any():
            tr = self.model.simulate_batch(th[:, :P], th[:, P:P + 6], t_out, t_start=self.t_ic,
                                           overrides=ov, atmospheres=atm)
            return tr.state, tr.mach
        hh = 1e-3
        t_post = t_out[~pre]
        extra = [t for t in (self.t_ic, self.t_ic + hh) if not np.any(np.abs(t_post - t) < 1e-9)]
        t_req = np.sort(np.concatenate([extra, t_post]))
        tr = self.model.simulate_batch(th[:, :P], th[:, P:P + 6], t_req, t_start=self.t_ic,
                                       overrides=ov, atmospheres=atm)
        st = tr.state
        i1 = int(np.argmin(np.abs(t_req - (self.t_ic + hh))))
        a0 = (st[:, i1, 3:] - st[:, 0, 3:]) / (t_req[i1] - t_req[0])
        tau = (t_out[pre] - self.t_ic)[None, :, None]
        pos = st[:, :1, :3] + st[:, :1, 3:] * tau + 0.5 * a0[:, None, :] * tau**2
        vel = st[:, :1, 3:] + a0[:, None, :] * tau
        post = np.searchsorted(t_req, t_post - 1e-9)
        state = np.concatenate([np.concatenate([pos, vel], axis=-1), st[:, post]], axis=1)
        mach = np.concatenate([np.repeat(tr.mach[:, :1], int(pre.sum()), axis=1), tr.mach[:, post]], axis=1)
        return state, mach

    def sensitivities(self, theta):
        """Outputs at theta (N, C) and d outputs / d theta_free (N, C, n_free) by central
        differences, all trajectories in one batch."""
        idx = np.flatnonzero(self.free)
        h = self.steps[idx]
        batch = np.repeat(theta[None], 1 + 2 * idx.size, axis=0)
        for k, j in enumerate(idx):
            batch[1 + 2 * k, j] += h[k]
            batch[2 + 2 * k, j] -= h[k]
        if idx.size:
            y, _ = self.predict(batch[1:])
            S = (y[0::2] - y[1::2]) / (2 * h[:, None, None])  # (n_free, N, C)
        else:
            S = np.zeros((0, self.z.shape[0], self.z.shape[1]))
        # the outputs at theta itself come from a one-trajectory call, the same code path as the
        # trial steps of the fit (a batch runs the SIMD lanes, a single trajectory the scalar
        # code; they agree to ~1e-9 m, but at the optimum that is the whole cost change and a
        # mixed comparison would make every step look uphill)
        y0, mach0 = self.predict(theta[None])
        return y0[0], mach0[0], np.moveaxis(S, 0, -1)

    def _prior_terms(self, theta):
        """Weighted prior residuals (K,) and their Jacobian (K, n_free)."""
        if not self.priors:
            return np.zeros(0), np.zeros((0, int(self.free.sum())))
        idx = np.flatnonzero(self.free)
        r = np.array([(p.mean - p.fn(theta)) / p.sd for p in self.priors])
        J = np.zeros((len(self.priors), idx.size))
        lin = np.array([p.row is not None for p in self.priors])
        if lin.any():
            rows = np.array([np.asarray(p.row, float) for p in self.priors if p.row is not None])
            sds = np.array([p.sd for p in self.priors if p.row is not None])
            J[lin] = rows[:, idx] / sds[:, None]
        other = [k for k, p in enumerate(self.priors) if p.row is None]
        if other:
            for k, j in enumerate(idx):
                tp, tm = theta.copy(), theta.copy()
                tp[j] += self.steps[j]
                tm[j] -= self.steps[j]
                J[other, k] = [(self.priors[i].fn(tp) - self.priors[i].fn(tm)) / (2 * self.steps[j] * self.priors[i].sd)
                               for i in other]
        return r, J

    # ----------------------------------------------------------------------------------------
    def fit(self, max_iter=50, tol_cost=1e-8, tol_step=1e-3, tol_sigma=1e-3, fallback=False):
        """Run Gauss-Newton / Levenberg-Marquardt with R relaxation. Returns :class:`MLResult`.

        Parameters
        ----------
        max_iter : int
        tol_cost, tol_step, tol_sigma : float
            Convergence rules (module docstring).
        fallback : bool
            When Levenberg-Marquardt ends without converging, continue from where it stopped with
            scipy's trust-region reflective least squares (:meth:`fit_trust_region`) at the
            noise sd reached, and keep whichever result converged with the lower cost.
        """
        res = self._fit_lm(max_iter, tol_cost, tol_step, tol_sigma)
        if res.converged or not fallback or not np.all(np.isfinite(res.theta)):
            return res
        alt = self.fit_trust_region(res.theta, res.sigma)
        if alt.converged and (alt.cost <= res.cost * (1 + 1e-9) or not res.converged):
            if len(self.sigma_fixed) < len(self.channels):
                # the noise sd was held at the LM's last estimate: one more relaxation pass
                theta0 = self.theta0
                self.theta0 = alt.theta.copy()
                try:
                    again = self._fit_lm(max_iter, tol_cost, tol_step, tol_sigma)
                finally:
                    self.theta0 = theta0
                if again.converged:
                    return again
            return alt
        return res

    def fit_trust_region(self, theta, sigma, max_nfev=200):
        """Minimise the cost at fixed noise sd ``sigma`` with scipy's ``least_squares``
        (trust-region reflective, bounds respected, our central-difference Jacobian), from
        ``theta``. Returns :class:`MLResult`; ``converged`` when scipy reports success."""
        from scipy.optimize import least_squares

        idx = np.flatnonzero(self.free)
        sig_vec = np.array([sigma[c] for c in self.channels])
        sw = np.sqrt(self.weights / sig_vec[None, :] ** 2)
        base = np.asarray(theta, float).copy()
        cache = {}

        def full(x):
            th = base.copy()
            th[idx] = x
            return th

        def fun_jac(x):
            key = x.tobytes()
            if key not in cache:
                th = full(x)
                y, _, S = self.sensitivities(th)
                r = ((self.z - y) * sw).reshape(-1)
                J = -(S * sw[:, :, None]).reshape(-1, idx.size)
                pr, pJ = self._prior_terms(th)
                if pr.size:
                    r = np.concatenate([r, pr])
                    J = np.vstack([J, -pJ])
                if not np.all(np.isfinite(r)):
                    r = np.full_like(r, 1e10)
                    J = np.zeros_like(J)
                cache.clear()
                cache[key] = (r, J)
            return cache[key]

        lo = np.where(np.isfinite(self.lower[idx]), self.lower[idx], -np.inf)
        hi = np.where(np.isfinite(self.upper[idx]), self.upper[idx], np.inf)
        x0 = np.clip(base[idx], np.nextafter(lo, np.inf), np.nextafter(hi, -np.inf))
        try:
            sol = least_squares(lambda x: fun_jac(x)[0], x0, jac=lambda x: fun_jac(x)[1],
                                bounds=(lo, hi), method="trf", x_scale="jac", max_nfev=max_nfev,
                                ftol=1e-10, xtol=1e-10, gtol=1e-10)
        except (ValueError, np.linalg.LinAlgError) as exc:
            th = full(x0)
            y, mach, S = self.sensitivities(th)
            return self._finish(th, y, mach, S, self.z - y, dict(sigma), self._cost(self.z - y, sigma, th),
                                False, f"trust-region fallback failed: {exc}", 0, [])
        th = full(sol.x)
        y, mach, S = self.sensitivities(th)
        resid = self.z - y
        cost = self._cost(resid, sigma, th)
        ok = bool(sol.success and np.all(np.isfinite(y)))
        msg = (f"converged (trust-region fallback: {sol.message})" if ok
               else f"not converged (trust-region fallback: {sol.message})")
        return self._finish(th, y, mach, S, resid, dict(sigma), cost, ok, msg, int(sol.nfev), [cost])

    def _fit_lm(self, max_iter, tol_cost, tol_step, tol_sigma):
        theta = np.clip(self.theta0, self.lower, self.upper)
        idx = np.flatnonzero(self.free)
        C = len(self.channels)
        y, mach, S = self.sensitivities(theta)
        if not np.all(np.isfinite(y)):
            raise FitError("the model trajectory at the starting values is not finite: check the "
                           "drag starting values and the launch conditions")
        resid = self.z - y
        sigma = self._update_sigma(resid, None)
        lam = 1e-3
        history = []
        converged = False
        message = ""
        it = 0
        cost = self._cost(resid, sigma, theta)
        for it in range(1, max_iter + 1):
            W = 1.0 / np.array([sigma[c] for c in self.channels]) ** 2  # (C,)
            sw = np.sqrt(W[None, :] * self.weights)  # (N, C)
            Sw = S * sw[:, :, None]
            A = Sw.reshape(-1, idx.size)
            rw = (resid * sw).reshape(-1)
            pr, pJ = self._prior_terms(theta)
            A = np.vstack([A, pJ]) if pr.size else A
            rw = np.concatenate([rw, pr]) if pr.size else rw
            M = A.T @ A
            g = A.T @ rw
            if not np.all(np.isfinite(M)):
                raise FitError("the information matrix is not finite (sensitivities blew up); "
                               "the trajectory may leave the drag model's Mach span")
            D = np.diag(np.diag(M)).copy()
            D[D == 0] = 1.0
            accepted = False
            while lam < 1e10:
                try:
                    step = np.linalg.solve(M + lam * D, g)
                except np.linalg.LinAlgError:
                    lam *= 10
                    continue
                trial = theta.copy()
                trial[idx] = np.clip(theta[idx] + step, self.lower[idx], self.upper[idx])
                yt, _ = self.predict(trial)
                if not np.all(np.isfinite(yt)):
                    lam *= 10
                    continue
                rt = self.z - yt[0]
                ct = self._cost(rt, sigma, trial)
                if ct <= cost:
                    accepted = True
                    break
                lam *= 10
            if not accepted:
                # no step reduces the cost: at the minimum when the Gauss-Newton decrease the
                # model predicts is negligible against one unit of chi2 (the cost's scale)
                try:
                    pred = float(g @ np.linalg.lstsq(M, g, rcond=None)[0])
                except np.linalg.LinAlgError:
                    pred = np.inf
                if pred < STUCK_PREDICTED_DECREASE:
                    converged = True
                    message = (f"converged: no step reduces the cost and the predicted decrease "
                               f"{pred:.2g} is negligible (< {STUCK_PREDICTED_DECREASE:g} chi2)")
                else:
                    message = (f"no step reduces the cost (damping above 1e10) although a decrease "
                               f"of {pred:.3g} is predicted: the fit is stuck")
                break
            lam = max(lam / 10, 1e-9)
            dtheta = trial[idx] - theta[idx]
            theta = trial
            y, mach, S = self.sensitivities(theta)
            resid = self.z - y
            new_sigma = self._update_sigma(resid, sigma)
            dsig = max(abs(new_sigma[c] / sigma[c] - 1) for c in self.channels)
            sigma = new_sigma
            new_cost = self._cost(resid, sigma, theta)
            history.append(new_cost)
            try:
                sd = np.sqrt(np.diag(np.linalg.inv(M)))
            except np.linalg.LinAlgError:
                sd = np.full(idx.size, np.inf)
            small_step = np.all(np.abs(dtheta) < tol_step * sd)
            small_cost = abs(cost - ct) <= tol_cost * max(cost, 1e-300)
            cost = new_cost
            if (small_step or small_cost) and dsig < tol_sigma:
                converged = True
                message = ("converged: " + ("parameter steps < 1e-3 CRB sd" if small_step else
                                            "relative cost change < 1e-8") +
                           (", noise sd change < 0.1 %" if len(self.sigma_fixed) < C else ""))
                break
        else:
            message = f"not converged after {max_iter} iterations"
        return self._finish(theta, y, mach, S, resid, sigma, cost, converged, message, it, history)

    def _update_sigma(self, resid, old):
        sig = {}
        for j, c in enumerate(self.channels):
            if c in self.sigma_fixed:
                sig[c] = self.sigma_fixed[c]
            else:
                w = self.weights[:, j]
                sig[c] = max(float(np.sqrt(np.sum(w * resid[:, j] ** 2) / max(np.sum(w), 1.0))), 1e-9)
        return sig

    def _cost(self, resid, sigma, theta):
        W = 1.0 / np.array([sigma[c] for c in self.channels]) ** 2
        J = float(np.sum(resid**2 * W[None, :] * self.weights))
        if self.priors:
            J += float(sum(((p.mean - p.fn(theta)) / p.sd) ** 2 for p in self.priors))
        return J

    def _finish(self, theta, y, mach, S, resid, sigma, cost, converged, message, it, history):
        idx = np.flatnonzero(self.free)
        n = theta.size
        W = 1.0 / np.array([sigma[c] for c in self.channels]) ** 2
        A = (S * np.sqrt(W[None, :] * self.weights)[:, :, None]).reshape(-1, idx.size)
        pr, pJ = self._prior_terms(theta)
        M = A.T @ A + (pJ.T @ pJ if pr.size else 0.0)
        warnings = []
        dg = np.diag(M).copy()
        blind = [self.names[j] for j, d in zip(idx, dg) if not d > 0]
        if blind:
            warnings.append(f"the track carries no information on {', '.join(blind)} (zero sensitivity): "
                            f"fix {'it' if len(blind) == 1 else 'them'} or add the channel that sees "
                            f"{'it' if len(blind) == 1 else 'them'}")
        if not np.all(np.isfinite(M)):
            cond = np.inf
        else:
            sc = 1.0 / np.sqrt(np.where(dg > 0, dg, 1.0))
            try:
                cond = float(np.linalg.cond(M * np.outer(sc, sc)))
            except np.linalg.LinAlgError:
                cond = np.inf
        if not np.isfinite(cond) or cond > 1e12:
            warnings.append(f"information matrix is ill-conditioned (condition number of the scaled "
                            f"matrix {cond:.2g}): some parameters are not identifiable from this track")
        try:
            Minv = np.linalg.inv(M) if np.all(np.isfinite(M)) and not blind else np.full_like(M, np.nan)
        except np.linalg.LinAlgError:
            Minv = np.full_like(M, np.nan)
        if not np.all(np.isfinite(Minv)):
            Minv = np.full_like(M, np.nan)
            warnings.append("information matrix is singular: no Cramér-Rao bounds")
        # colored-residual correction (Morelli & Klein 1997)
        D = np.zeros_like(M)
        Sw = S * (W[None, :] * self.weights)[:, :, None]  # R^-1 S, (N, C, nf)
        N = resid.shape[0]
        for j in range(len(self.channels)):
            wj = self.weights[:, j] > 0
            e = np.where(wj, resid[:, j] - resid[wj, j].mean(), 0.0)
            r = np.correlate(e, e, mode="full")[N - 1:] / N
            limit = 2.0 / np.sqrt(N) * r[0]
            below = np.flatnonzero(r < limit)
            kmax = int(below[0]) if below.size else N // 4
            kmax = min(kmax, N // 4)
            s = np.ascontiguousarray(Sw[:, j, :])
            D += r[0] * s.T @ s
            if kmax > 0:
                # sum_k r_k (s[:-k]' s[k:] + its transpose) = s' (T s), T the Toeplitz matrix of
                # r_1..r_kmax: one FFT convolution instead of kmax matrix products
                ker = np.concatenate([r[kmax:0:-1], [0.0], r[1:kmax + 1]])
                D += s.T @ fftconvolve(s, ker[:, None], mode="same", axes=0)
        cov_c = Minv @ (D + (pJ.T @ pJ if pr.size else 0.0)) @ Minv
        cov = np.zeros((n, n))
        covc = np.zeros((n, n))
        cov[np.ix_(idx, idx)] = Minv
        covc[np.ix_(idx, idx)] = cov_c
        crb = np.sqrt(np.clip(np.diag(cov), 0, None))
        crbc = np.sqrt(np.clip(np.diag(covc), 0, None))
        # identifiability warnings
        for j in idx:
            name = self.names[j]
            span = self.upper[j] - self.lower[j]
            if np.isfinite(span) and (theta[j] - self.lower[j] < 1e-6 * span or self.upper[j] - theta[j] < 1e-6 * span):
                warnings.append(f"parameter {name} = {theta[j]:.6g} is at its bound "
                                f"[{self.lower[j]:.4g}, {self.upper[j]:.4g}]")
            if j < self.P and crb[j] > abs(theta[j]) and theta[j] != 0:
                warnings.append(f"parameter {name}: Cramér-Rao sd {crb[j]:.3g} exceeds its value {theta[j]:.3g}")
        corr = cov / np.where(np.outer(crb, crb) > 0, np.outer(crb, crb), 1.0)
        iu = np.triu_indices(n, 1)
        strong = [(self.names[a], self.names[b], corr[a, b]) for a, b in zip(*iu)
                  if abs(corr[a, b]) > 0.98]
        for a, b, c in strong[:5]:
            warnings.append(f"parameters {a} and {b} are strongly correlated (rho = {c:+.3f})")
        success = bool(np.all(np.isfinite(theta)) and np.all(np.isfinite(crb)) and converged)
        fitted = {c: y[:, j] for j, c in enumerate(self.channels)}
        resids = {c: resid[:, j] for j, c in enumerate(self.channels)}
        return MLResult(self.names, theta, self.free.copy(), crb, crbc, cov, covc, sigma, cost,
                        converged, success, message, it, tuple(warnings), resids, fitted, mach,
                        tuple(history), self.P, self.E, self.weights)
