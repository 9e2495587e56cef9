"""Maximum-likelihood output-error fit (paper Eq. 19) with Cramér-Rao bounds, of an
:class:`~bayesdrag.estimate.model.problem.OutputErrorProblem`.

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
* Gauss-Newton with Levenberg-Marquardt damping, parameters kept inside their bounds (a
  parameter on its bound that the step would push out is held for that step,
  :func:`bounded_step`);
  sensitivities by central differences, all perturbed trajectories in one batched kernel call.

Convergence rules (all must hold, checked after each accepted step):
``|dJ|/J < 1e-8`` or every ``|d theta_j| < 1e-3 sd_j`` (its Cramér-Rao sd), and, when R is
estimated, every noise sd changed by < 0.1 % in the last relaxation. Failure modes are reported
in the result (``success=False`` with a message) and never passed off as an answer: more than
``max_iter`` iterations, a damping factor beyond 1e10 (no descent direction), a singular or
non-finite information matrix, an integration that produced non-finite states.

Channels with the ``ar1`` noise (white + AR(1) model error, :mod:`colored`) have their
correlation and variance fitted in the relaxation by the likelihood of the residuals. A fit
flexible enough to absorb part of a slow noise leaves residuals whose correlation is shorter
than the noise's, and the bounds that rest on it are too narrow (on an AR(1) flight with rho
0.95, 0.79 was found and the Cd bands were half what the noise gives). Once the relaxation has
converged, a fit with ``restricted=True`` (the default) therefore fits each ``ar1`` channel's
noise once more by *restricted* likelihood, with the parameters' move under the candidate noise
linearised (:meth:`OutputErrorProblem.update_noise_restricted`), holds it, and takes at most
:data:`RESTRICTED_STEPS` more steps towards the generalised least squares at that noise; the
bounds are those at it. Fits whose likelihoods are compared across models with other
parameters (the diagnosis's) keep the plain likelihood: restricted likelihoods of different
fixed effects are not comparable.

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

import math
from dataclasses import dataclass, field

import numpy as np

from .layout import ParameterLayout
from ...effects import param_unit
from ...errors import FitError, FitWarning
from .filters import autocovariance_window, convolve_same
from .noise_spread import noise_covariance

#: a fit that no step improves has converged when Gauss-Newton predicts a cost decrease below
#: this (the cost is a chi2: 1e-3 is far below what the data can tell)
STUCK_PREDICTED_DECREASE = 1e-3
#: Levenberg-Marquardt steps at most with the noise held at its restricted estimate
RESTRICTED_STEPS = 5


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
        Noise sd used at the end (estimated or fixed); the white part's sd of ``ar1`` channels.
    cost : float
        Eq. 19 at the estimate (with the final R), plus prior terms.
    converged : bool
    success : bool
    message : str
    iterations : int
    warnings : tuple of FitWarning
        What the fit says of its parameters (:class:`~bayesdrag.errors.FitWarning`: tested by
        ``kind``).
    residuals : dict channel -> (N,) ndarray
        Measured minus model.
    fitted : dict channel -> (N,) ndarray
    mach : (N,) ndarray
        Mach number along the fitted trajectory.
    history : tuple of float
        Cost after each iteration.
    n_drag, n_extra : int
        Drag coefficients (first) and extra (effect) parameters (last) in ``theta``.
    weights : (N, C) ndarray
        Per-sample weights used.
    ar : dict channel -> (rho, q)
        Model-error AR coefficient and variance ratio of the ``ar1`` channels
        (:mod:`bayesdrag.estimate.model.colored`; empty when every channel is white).
    noise_model : dict channel -> str
        ``white`` or ``ar1`` per channel.
    cov_noise : (n, n) ndarray or None
        What the ``ar1`` channels' noise uncertainty adds to ``cov``
        (:func:`~bayesdrag.estimate.model.noise_spread.noise_covariance`); None where the fit's
        noise is not of restricted likelihood or has no spread.
    noise_spread : dict channel -> float
        sd of ``log(1 - rho)`` of each ``ar1`` channel behind ``cov_noise``.
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
    ar: dict = field(default_factory=dict)
    noise_model: dict = field(default_factory=dict)
    cov_noise: np.ndarray = None
    noise_spread: dict = field(default_factory=dict)

    @property
    def params(self):
        return dict(zip(self.names, map(float, self.theta)))

    @property
    def drag_params(self):
        return self.theta[:self.n_drag]

    @property
    def state0(self):
        return self.theta[ParameterLayout(self.n_drag).state]

    @property
    def extras(self):
        """Extra (effect) parameters as a dict name -> value (empty without extras)."""
        k = ParameterLayout(self.n_drag).effects.start
        return dict(zip(self.names[k:], map(float, self.theta[k:])))

    def correlation(self):
        sd = np.sqrt(np.clip(np.diag(self.cov), 0, None))
        with np.errstate(invalid="ignore", divide="ignore"):
            c = self.cov / np.outer(sd, sd)
        return np.where(np.outer(sd, sd) > 0, c, 0.0)


def fit(problem, *, max_iter=50, tol_cost=1e-8, tol_step=1e-3, tol_sigma=1e-3, fallback=False, restricted=True):
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
    restricted : bool
        Once converged, the ``ar1`` channels' noise (and with it the bounds) of restricted
        likelihood (module docstring); the estimate stays the plain fit's. ``False`` keeps the plain likelihood: for fits whose likelihoods are
        compared across models with other parameters (the diagnosis's), as restricted
        likelihoods of different fixed effects are not comparable.
    """
    res = _fit_lm(problem, max_iter, tol_cost, tol_step, tol_sigma, restricted)
    if res.converged or not fallback or not np.all(np.isfinite(res.theta)):
        return res
    alt = fit_trust_region(problem, res.theta, res.sigma, ar=res.ar)
    if alt.converged and (alt.cost <= res.cost * (1 + 1e-9) or not res.converged):
        if len(problem.sigma_fixed) < len(problem.channels) or problem.ar_channels:
            # the noise sd was held at the LM's last estimate: one more relaxation pass
            again = _fit_lm(problem.replace(theta0=alt.theta), max_iter, tol_cost, tol_step, tol_sigma, restricted)
            if again.converged:
                return again
        return alt
    return res


def fit_trust_region(problem, theta, sigma, max_nfev=200, ar=None):
    """Minimise the cost at fixed noise sd ``sigma`` (and model-error parameters ``ar``) with scipy's
    ``least_squares`` (trust-region reflective, bounds respected, our central-difference
    Jacobian), from ``theta``. Returns :class:`MLResult`; ``converged`` when scipy reports
    success."""
    from scipy.optimize import least_squares

    idx = np.flatnonzero(problem.free)
    ar = dict(ar or {})
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
            y, _, S = problem.sensitivities(th)
            r = problem.weighted(problem.z - y, sigma, ar).reshape(-1)
            J = -problem.weighted(S, sigma, ar).reshape(-1, idx.size)
            pr, pJ = problem.prior_terms(th)
            if pr.size:
                r = np.concatenate([r, pr])
                J = np.vstack([J, -pJ])
            if not np.all(np.isfinite(r)):
                r = np.full_like(r, 1e10)
                J = np.zeros_like(J)
            cache.clear()
            cache[key] = (r, J)
        return cache[key]

    lo = np.where(np.isfinite(problem.lower[idx]), problem.lower[idx], -np.inf)
    hi = np.where(np.isfinite(problem.upper[idx]), problem.upper[idx], np.inf)
    x0 = np.clip(base[idx], np.nextafter(lo, np.inf), np.nextafter(hi, -np.inf))
    try:
        sol = least_squares(lambda x: fun_jac(x)[0], x0, jac=lambda x: fun_jac(x)[1],
                            bounds=(lo, hi), method="trf", x_scale="jac", max_nfev=max_nfev,
                            ftol=1e-10, xtol=1e-10, gtol=1e-10)
    except (ValueError, np.linalg.LinAlgError) as exc:
        th = full(x0)
        y, mach, S = problem.sensitivities(th)
        return _finish(problem, th, y, mach, S, problem.z - y, dict(sigma), ar,
                       problem.cost(problem.z - y, sigma, th, ar), False, f"trust-region fallback failed: {exc}", 0, [])
    th = full(sol.x)
    y, mach, S = problem.sensitivities(th)
    resid = problem.z - y
    cost = problem.cost(resid, sigma, th, ar)
    ok = bool(sol.success and np.all(np.isfinite(y)))
    msg = (f"converged (trust-region fallback: {sol.message})" if ok
           else f"not converged (trust-region fallback: {sol.message})")
    return _finish(problem, th, y, mach, S, resid, dict(sigma), ar, cost, ok, msg, int(sol.nfev), [cost])


def bounded_step(A, g, at_lo, at_hi):
    """The damped Gauss-Newton step ``A^-1 g`` with the parameters that sit at a bound and that
    it would push beyond it held where they are: a binding set found by the sign of the descent
    direction, then by the reduced step, one round at a time (a projected-Newton step in
    Bertsekas' manner, not the exact bound-constrained subproblem; every such step descends, and
    a held parameter whose descent points inwards is released at the next iteration).

    Clipping such a parameter after the step, with the other components still computed as if it
    moved, gives a step that raises the cost; the damping then grows until the steps are tiny, and
    a fit whose optimum lies on a bound (a density ratio at its lowest beside a table of another
    shell) crept towards it for its whole iteration budget.

    Parameters
    ----------
    A : (n, n) array
        The damped information ``M + lambda D``.
    g : (n,) array
        The cost's descent direction ``S' R^-1 r``.
    at_lo, at_hi : (n,) bool arrays
        Parameters at their lower and upper bound.

    Returns
    -------
    (n,) array
        The step; exactly ``np.linalg.solve(A, g)`` when neither the descent direction nor that
        step pushes a parameter on a bound out (a fit that never touches a bound is unchanged).

    Raises
    ------
    numpy.linalg.LinAlgError
        A singular (reduced) system.
    """
    # first the bounds the descent direction itself points out of (the active set's Lagrange
    # condition), then any the step of the others still pushes out
    held = _held(g, at_lo, at_hi)
    while True:
        if not held.any():
            step = np.linalg.solve(A, g)
        else:
            keep = ~held
            step = np.zeros(g.size)
            if keep.any():
                step[keep] = np.linalg.solve(A[np.ix_(keep, keep)], g[keep])
        out = ((at_lo & (step < 0)) | (at_hi & (step > 0))) & ~held
        if not out.any():
            return step
        held |= out


def _held(g, at_lo, at_hi):
    """The parameters on a bound that the descent direction ``g`` points out of (boolean mask):
    no decrease is to be had by moving them."""
    return (at_lo & (g < 0)) | (at_hi & (g > 0))


def _fit_lm(problem, max_iter, tol_cost, tol_step, tol_sigma, restricted):
    theta = np.clip(problem.theta0, problem.lower, problem.upper)
    idx = np.flatnonzero(problem.free)
    C = len(problem.channels)
    y, mach, S = problem.sensitivities(theta)
    if not np.all(np.isfinite(y)):
        raise FitError("the model trajectory at the starting values is not finite: check the "
                       "drag starting values and the launch conditions")
    resid = problem.z - y
    sigma, ar = problem.update_noise(resid, None, None)
    lam = 1e-3
    history = []
    converged = False
    message = ""
    it = 0
    held = None         # the iteration at which the noise was set to its restricted estimate
    cost = problem.cost(resid, sigma, theta, ar)
    for it in range(1, max_iter + 1):
        A = problem.weighted(S, sigma, ar).reshape(-1, idx.size)
        rw = problem.weighted(resid, sigma, ar).reshape(-1)
        pr, pJ = problem.prior_terms(theta)
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
        at_lo = theta[idx] <= problem.lower[idx]
        at_hi = theta[idx] >= problem.upper[idx]
        while lam < 1e10:
            try:
                step = bounded_step(M + lam * D, g, at_lo, at_hi)
            except np.linalg.LinAlgError:
                lam *= 10
                continue
            if not step.any() and (at_lo.any() or at_hi.any()):
                break   # every parameter held on its bound: no step can lower the cost
            trial = theta.copy()
            trial[idx] = np.clip(theta[idx] + step, problem.lower[idx], problem.upper[idx])
            yt, _ = problem.predict(trial)
            if not np.all(np.isfinite(yt)):
                lam *= 10
                continue
            rt = problem.z - yt[0]
            ct = problem.cost(rt, sigma, trial, ar)
            if ct <= cost:
                accepted = True
                break
            lam *= 10
        if not accepted:
            # no step reduces the cost: at the minimum when the Gauss-Newton decrease the
            # model predicts is negligible against one unit of chi2 (the cost's scale)
            try:
                keep = ~_held(g, at_lo, at_hi)
                pred = float(g[keep] @ np.linalg.lstsq(M[np.ix_(keep, keep)], g[keep], rcond=None)[0])
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
        y, mach, S = problem.sensitivities(theta)
        resid = problem.z - y
        new_sigma, new_ar = (sigma, ar) if held is not None else problem.update_noise(resid, sigma, ar)
        dsig = max(abs(new_sigma[c] / sigma[c] - 1) for c in problem.channels)
        # model-error parameters (log correlation time and log variance) to 1 % : their effect
        # on the estimate and the bounds is second order, and their optimiser's tolerance is 1e-3
        dsig = max([dsig] + [0.1 * max(abs(math.log((1.0 - new_ar[c][0]) / (1.0 - ar.get(c, (0.0, 0.0))[0]))),
                                 abs(math.log((new_ar[c][1] + 1e-6) / (ar.get(c, (0.0, 0.0))[1] + 1e-6))))
                             for c in new_ar])
        sigma, ar = new_sigma, new_ar
        new_cost = problem.cost(resid, sigma, theta, ar)
        history.append(new_cost)
        try:
            # a near-singular information gives negative round-off variances: NaN, so the step
            # test fails there as it did, without numpy's warning on the user's console
            var = np.diag(np.linalg.inv(M))
            sd = np.where(var >= 0, np.sqrt(np.abs(var)), np.nan)
        except np.linalg.LinAlgError:
            sd = np.full(idx.size, np.inf)
        small_step = np.all(np.abs(dtheta) < tol_step * sd)
        small_cost = abs(cost - ct) <= tol_cost * max(cost, 1e-300)
        cost = new_cost
        if (small_step or small_cost) and dsig < tol_sigma and restricted and ar and held is None:
            # converged with the noise of the residuals' likelihood: the noise of restricted
            # likelihood, which the fit's own absorption of slow noise does not bias, with the
            # parameters' move under it linearised (Problem.update_noise_restricted), then held
            # while the parameters take their generalised least squares at it
            held = it
            sigma, ar = problem.update_noise_restricted(resid, sigma, ar, S, problem.prior_terms(theta))
            cost = problem.cost(resid, sigma, theta, ar)
            continue
        if held is not None and it - held >= RESTRICTED_STEPS:
            # on a flat valley the steps creep (0.01-0.1 sd each for tens of iterations): the
            # first steps make the move, the rest stays inside the band
            converged = True
            message = f"converged: noise of restricted likelihood held for {RESTRICTED_STEPS} steps"
            break
        if (small_step or small_cost) and dsig < tol_sigma:
            converged = True
            message = ("converged: " + ("parameter steps < 1e-3 CRB sd" if small_step else
                                        "relative cost change < 1e-8") +
                       (", noise sd change < 0.1 %" if len(problem.sigma_fixed) < C or ar else "") +
                       (", noise of restricted likelihood" if held is not None else ""))
            break
    else:
        message = f"not converged after {max_iter} iterations"
    return _finish(problem, theta, y, mach, S, resid, sigma, ar, cost, converged, message, it, history,
                   spread=held is not None)


def _angle_scale(name):
    """(factor, unit) a parameter is shown in: an angle in degrees, as the round gives angles
    (``azimuth_bias.bias`` is fitted in radians); other parameters as fitted, no unit."""
    return (180.0 / math.pi, " deg") if param_unit(name) == "rad" else (1.0, "")


def _finish(problem, theta, y, mach, S, resid, sigma, ar, cost, converged, message, it, history, spread=False):
    idx = np.flatnonzero(problem.free)
    n = theta.size
    Sw_all = problem.weighted(S, sigma, ar)                        # (N, C, nf): whitened / sigma
    A = Sw_all.reshape(-1, idx.size)
    pr, pJ = problem.prior_terms(theta)
    M = A.T @ A + (pJ.T @ pJ if pr.size else 0.0)
    warnings = []
    dg = np.diag(M).copy()
    blind = [problem.names[j] for j, d in zip(idx, dg) if not d > 0]
    if blind:
        warnings.append(FitWarning("no_information",
                                   f"the track carries no information on {', '.join(blind)} (zero sensitivity): "
                                   f"fix {'it' if len(blind) == 1 else 'them'} or add the channel that sees "
                                   f"{'it' if len(blind) == 1 else 'them'}", tuple(blind)))
    if not np.all(np.isfinite(M)):
        cond = np.inf
    else:
        sc = 1.0 / np.sqrt(np.where(dg > 0, dg, 1.0))
        try:
            cond = float(np.linalg.cond(M * np.outer(sc, sc)))
        except np.linalg.LinAlgError:
            cond = np.inf
    if not np.isfinite(cond) or cond > 1e12:
        warnings.append(FitWarning("ill_conditioned", f"information matrix is ill-conditioned (condition number of "
                                   f"the scaled matrix {cond:.2g}): some parameters are not identifiable from this "
                                   f"track"))
    try:
        Minv = np.linalg.inv(M) if np.all(np.isfinite(M)) and not blind else np.full_like(M, np.nan)
    except np.linalg.LinAlgError:
        Minv = np.full_like(M, np.nan)
    if not np.all(np.isfinite(Minv)):
        Minv = np.full_like(M, np.nan)
        warnings.append(FitWarning("singular_information", "information matrix is singular: no Cramér-Rao bounds"))
    # colored-residual correction (Morelli & Klein 1997), on the whitened residuals and
    # sensitivities (for white channels the residuals and R^-1 S themselves)
    D = np.zeros_like(M)
    sig_vec = np.array([sigma[c] for c in problem.channels])
    Sw = Sw_all * np.sqrt(problem.weights)[:, :, None] / sig_vec[None, :, None]  # R^-1 S (whitened)
    resid_w = problem.whiten(problem.standardized(resid), ar)
    N = resid.shape[0]
    for j in range(len(problem.channels)):
        wj = problem.weights[:, j] > 0
        e = np.where(wj, resid_w[:, j] - resid_w[wj, j].mean(), 0.0)
        r = autocovariance_window(e, N, N // 4)
        kmax = r.size - 1
        s = np.ascontiguousarray(Sw[:, j, :])
        D += r[0] * s.T @ s
        if kmax > 0:
            # sum_k r_k (s[:-k]' s[k:] + its transpose) = s' (T s), T the Toeplitz matrix of
            # r_1..r_kmax: one FFT convolution instead of kmax matrix products
            ker = np.concatenate([r[kmax:0:-1], [0.0], r[1:kmax + 1]])
            D += s.T @ convolve_same(s, ker)
    cov_c = Minv @ (D + (pJ.T @ pJ if pr.size else 0.0)) @ Minv
    cov = np.zeros((n, n))
    covc = np.zeros((n, n))
    cov[np.ix_(idx, idx)] = Minv
    covc[np.ix_(idx, idx)] = cov_c
    cov_noise, noise_spread = None, {}
    if spread:
        # the restricted noise's own uncertainty, averaged into the estimate's error (noise_spread)
        inc, noise_spread = noise_covariance(problem, S, resid, sigma, ar, Minv, (pr, pJ) if pr.size else None,
                                             Sw=Sw_all)
        if inc is not None:
            cov_noise = np.zeros((n, n))
            cov_noise[np.ix_(idx, idx)] = inc
    crb = np.sqrt(np.clip(np.diag(cov), 0, None))
    crbc = np.sqrt(np.clip(np.diag(covc), 0, None))
    # identifiability warnings
    for j in idx:
        name = problem.names[j]
        span = problem.upper[j] - problem.lower[j]
        if np.isfinite(span) and (theta[j] - problem.lower[j] < 1e-6 * span or problem.upper[j] - theta[j] < 1e-6 * span):
            k, u = _angle_scale(name)
            warnings.append(FitWarning("at_bound", f"parameter {name} = {theta[j] * k:.6g}{u} is at its bound "
                                                   f"[{problem.lower[j] * k:.4g}, {problem.upper[j] * k:.4g}]{u}",
                                       (name,)))
        if j < problem.P and crb[j] > abs(theta[j]) and theta[j] != 0:
            k, u = _angle_scale(name)
            warnings.append(FitWarning("sd_exceeds_value", f"parameter {name}: Cramér-Rao sd {crb[j] * k:.3g}{u} "
                                                           f"exceeds its value {theta[j] * k:.3g}{u}", (name,)))
    corr = cov / np.where(np.outer(crb, crb) > 0, np.outer(crb, crb), 1.0)
    iu = np.triu_indices(n, 1)
    hit = np.flatnonzero(np.abs(corr[iu]) > 0.98)[:5]      # in the order of the pairs, as listed below
    strong = [(problem.names[a], problem.names[b], corr[a, b]) for a, b in zip(iu[0][hit], iu[1][hit])]
    for a, b, c in strong[:5]:
        warnings.append(FitWarning("correlated", f"parameters {a} and {b} are strongly correlated (rho = {c:+.3f})",
                                   (a, b)))
    success = bool(np.all(np.isfinite(theta)) and np.all(np.isfinite(crb)) and converged)
    fitted = {c: y[:, j] for j, c in enumerate(problem.channels)}
    resids = {c: resid[:, j] for j, c in enumerate(problem.channels)}
    return MLResult(problem.names, theta, problem.free.copy(), crb, crbc, cov, covc, sigma, cost,
                    converged, success, message, it, tuple(warnings), resids, fitted, mach,
                    tuple(history), problem.P, problem.E, problem.weights,
                    {c: (float(v[0]), float(v[1])) for c, v in (ar or {}).items()}, dict(problem.noise_model),
                    cov_noise, noise_spread)
