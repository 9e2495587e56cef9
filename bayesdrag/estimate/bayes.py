"""Bayesian layer: emcee posterior of an output-error problem, seeded by its ML fit.

The posterior is the ML cost of :mod:`bayesdrag.estimate.ml` turned into a likelihood, with
the noise sd of every channel unknown, weak priors, and sampled by :mod:`emcee` with all
walkers simulated in one call of the batched point-mass kernel.

Model (written down once; ``docs/bayes.md`` has the reasons and the measurements)
--------------------------------------------------------------------------------
Parameters ``theta`` = the problem's free parameters (drag coefficients, the initial state
``X0 .. Uz0`` and any effect parameters appended after them); fixed ones stay at their values.

Likelihood
    ``gaussian`` (default): channel ``c`` has white Gaussian noise of unknown sd ``sigma_c``,
    ``p(z | theta, sigma) = prod_c prod_i N(z_ic; y_ic(theta), sigma_c^2)``, i.e. Eq. 19 with R
    unknown. With the prior ``log sigma_c ~ uniform`` the sd integrates out analytically:
    ``log p(z | theta) = -N/2 sum_c log SS_c(theta) + const`` (``SS_c`` = sum of squared
    residuals of channel c). The sampler runs on this marginal (fewer dimensions, better
    mixing, the *same* posterior of theta) and every retained draw gets its exact conditional
    ``sigma_c^2 | theta, z ~ SS_c / chi^2_N``, so the posterior still holds ``log_sigma_c``
    and is the joint posterior the lead's design asks for.

    ``student-t``: ``(z - y) / sigma_c ~ t_nu`` per sample, robust to outliers. ``log sigma_c``
    are sampled explicitly (uniform prior on ``[log(s_c/100), log(100 s_c)]``, ``s_c`` the ML
    residual rms); ``nu`` fixed (default 4) or sampled as ``log_nu`` (uniform on
    ``[log 1, log 100]``) with ``nu="sample"``.

Priors (weak; the data dominate every one of them on a radar track)
    * drag coefficients: uniform inside the drag model's bounds (``problem.lower/upper``);
      outside -> log-probability ``-inf``;
    * every other free parameter (initial state, effects): Gaussian around the ML estimate with
      sd ``IC_PRIOR_FACTOR`` (100) x its Cramér-Rao sd — proper, and 10^4 times weaker than the
      data in variance;
    * plus the problem's own priors (``problem.priors``: the round's launch priors on muzzle
      position, launch speed and elevation when the track starts at the muzzle), exactly as
      the ML fit used them;
    * noise: ``log sigma_c`` uniform (see above).

Non-physical parameters or a simulation that is not finite give ``-inf``, never an exception.

Sampling (choices measured, see ``docs/bayes.md`` and ``benchmarks/fit.py --moves``)
    * ``emcee.EnsembleSampler(vectorize=True)``: one kernel call per half-ensemble move.
    * Walkers start as draws from the Gaussian (Laplace) approximation at the ML estimate,
      ``N(theta_ml, cov)`` with ``cov`` the inverse Fisher information at the ML residual rms
      (the CRB "ball" at full scale, so the burn-in is short).
    * Moves: the independence move of :func:`independence_move` (multivariate-t proposal,
      10 dof, centred at the posterior mode with 1.1 x the Laplace covariance) 90 % plus 10 %
      of a local move (``DEMove`` with >= 2 D walkers, else random-walk Metropolis with the
      Laplace covariance). Measured on the shipped demo track (54 parameters, 300 steps, 32
      walkers): tau ~ 4-5 steps, acceptance ~ 0.4; 70 %/1.2x/5 dof gave tau 8.3; the stretch
      move and DE alone need >= 2 D = 108 walkers and gave tau of hundreds of steps on the
      ~20-parameter spline (docs/bayes.md). The mix reproduces a strongly correlated Gaussian
      target's covariance (tests/test_bayes.py) even with a deliberately mis-centred and
      mis-scaled proposal, because the independence move is an exact Metropolis-Hastings
      move (its proposal ratio enters the acceptance).
    * Run length: every ``check_every`` steps the integrated autocorrelation time tau is
      estimated (emcee, walker-averaged); the run stops when the chain is longer than
      ``TAU_FACTOR`` (50) x max tau, tau changed by < ``TAU_RTOL`` (5 %) since the last check,
      and, on the burnt-in and thinned draws, ArviZ ``r_hat < 1.01`` and bulk and tail
      ESS >= 400 for every parameter; or at ``max_steps`` (then ``converged=False`` with a
      message). Burn-in = ceil(3 max tau), thinning = max(1, floor(min tau / 2)).
    * The chain is written as it runs to an HDF5 file (:class:`ChainFile`: emcee's memory
      backend flushed every 25 steps; emcee's ``HDFBackend`` reopened the file at every step
      and cost more than the simulations); a run restarted on the same file (``resume=True``)
      continues it from its last flushed step with the stored random state, so the continued
      chain is the one an uninterrupted run would have produced.
"""
from __future__ import annotations

import hashlib
import json
import math
import time
import warnings as _warnings
from dataclasses import dataclass, field

import numpy as np
from scipy.special import gammaln

from .._threads import single_blas
from ..errors import FitError, InputError

#: prior sd of non-drag parameters in units of their Cramér-Rao sd
IC_PRIOR_FACTOR = 100.0
#: half-width of the uniform prior on log sigma, in factors of the ML residual rms
SIGMA_RANGE = 100.0
#: run until the chain is this many autocorrelation times long
TAU_FACTOR = 50.0
#: relative change of tau between checks below which it counts as stable
TAU_RTOL = 0.05
#: convergence thresholds (ArviZ)
RHAT_MAX = 1.01
ESS_MIN = 400
#: independence proposal: scale of the Laplace covariance and Student-t dof
PROPOSAL_SCALE = 1.1
PROPOSAL_DOF = 10.0
#: default weight of the independence move in the move mix (rest: DEMove or random-walk)
INDEPENDENCE_WEIGHT = 0.9
#: default number of walkers
DEFAULT_WALKERS = 16
#: bounds of log nu when the Student-t dof is sampled
LOG_NU_RANGE = (0.0, math.log(100.0))


def _prior_values(prior, full):
    """``prior.fn`` at every row of ``full`` (W, n): one vectorised call when the function
    accepts a 2-D array and returns one value per row (the launch priors are written so),
    otherwise row by row."""
    try:
        v = np.asarray(prior.fn(full), dtype=float)
        if v.shape == (full.shape[0],):
            return v
    except (TypeError, ValueError, IndexError):
        pass
    return np.array([prior.fn(row) for row in full], dtype=float)


def _student_t_mode(problem, theta, sigma, nu, cov, iterations=30):
    """Mode of the Student-t likelihood by iteratively reweighted Gauss-Newton (the EM
    algorithm of the t distribution: weights ``(nu + 1) / (nu + r^2 / sigma^2)``, then
    ``sigma_c^2 = mean(w r^2)``), started at the Gaussian mode.

    Returns the mode (n,), the noise sd per channel and the covariance of the free parameters
    from the expected Fisher information of the t likelihood, ``(nu + 1) / (nu + 3) S^T R^-1 S``.
    """
    idx = np.flatnonzero(problem.free)
    th = np.asarray(theta, float).copy()
    sig = np.array([sigma[c] for c in problem.channels], float)
    for _ in range(iterations):
        y, _, S = problem.sensitivities(th)
        r = problem.z - y
        if not np.all(np.isfinite(r)):
            break
        w = (nu + 1) / (nu + (r / sig) ** 2)                     # (N, C)
        sig = np.sqrt(np.mean(w * r ** 2, axis=0))
        sw = np.sqrt(w) / sig                                    # (N, C)
        A = (S * sw[..., None]).reshape(-1, idx.size)
        b = (r * sw).reshape(-1)
        pr, pJ = problem._prior_terms(th)
        if pr.size:
            A, b = np.vstack([A, pJ]), np.concatenate([b, pr])
        step = np.linalg.lstsq(A, b, rcond=None)[0]
        new = th.copy()
        new[idx] = np.clip(th[idx] + step, problem.lower[idx], problem.upper[idx])
        done = np.all(np.abs(step) < 1e-4 * np.sqrt(np.diag(cov)))
        th = new
        if done:
            break
    _, _, S = problem.sensitivities(th)
    W = (nu + 1) / (nu + 3) / sig ** 2
    A = (S * np.sqrt(W)[None, :, None]).reshape(-1, idx.size)
    M = A.T @ A
    pr, pJ = problem._prior_terms(th)
    if pr.size:
        M = M + pJ.T @ pJ
    try:
        cov_t = np.linalg.inv(M)
        cov_t = 0.5 * (cov_t + cov_t.T)
        np.linalg.cholesky(cov_t)
    except np.linalg.LinAlgError:
        cov_t = cov
    return th, dict(zip(problem.channels, map(float, sig))), cov_t


def _mode_fit(problem, ml):
    """ML fit of ``problem`` with every noise sd estimated, started at ``ml.theta``; None when
    the ML fit already estimated them all or the refit fails (then the ML estimate is used)."""
    import copy

    if not problem.sigma_fixed:
        return None
    p2 = copy.copy(problem)
    p2.sigma_fixed = {}
    p2.theta0 = np.asarray(ml.theta, float).copy()
    try:
        res = p2.fit()
    except FitError:
        return None
    return res if res.success else None


def fisher_information(problem, theta, sigma):
    """Fisher information of the free parameters at ``theta`` for noise sd ``sigma``.

    Parameters
    ----------
    problem : OutputErrorProblem
    theta : (n,) ndarray
        Full parameter vector.
    sigma : dict channel -> sd (m or m/s)

    Returns
    -------
    (n_free, n_free) ndarray
        ``S^T R^-1 S`` plus the problem's prior terms (pseudo-measurements).
    """
    _, _, S = problem.sensitivities(theta)
    W = 1.0 / np.array([sigma[c] for c in problem.channels]) ** 2
    A = (S * np.sqrt(W)[None, :, None]).reshape(-1, S.shape[-1])
    M = A.T @ A
    pr, pJ = problem._prior_terms(theta)
    if pr.size:
        M = M + pJ.T @ pJ
    return M


class LogPosterior:
    """Vectorised log-posterior of an :class:`~bayesdrag.estimate.ml.OutputErrorProblem`.

    Parameters
    ----------
    problem : OutputErrorProblem
    ml : MLResult
        The ML fit of ``problem`` (centre of the priors of non-drag parameters and of the
        proposal).
    likelihood : {"gaussian", "student-t"}
    nu : float or "sample"
        Student-t degrees of freedom (fixed) or ``"sample"``; ignored for ``gaussian``.

    Calling it with ``X`` of shape (W, D) returns an array (W, 1 + C): column 0 the
    log-posterior (``-inf`` where non-physical or not finite), columns 1.. the residual sum of
    squares per channel (emcee blobs, used for the noise draws).
    """

    def __init__(self, problem, ml, likelihood="gaussian", nu=4.0):
        if likelihood not in ("gaussian", "student-t"):
            raise InputError(f"likelihood {likelihood!r} is not known (allowed: gaussian, student-t)")
        self.problem = problem
        self.ml = ml
        self.likelihood = likelihood
        self.sample_nu = likelihood == "student-t" and nu == "sample"
        if likelihood == "student-t" and not self.sample_nu:
            nu = float(nu)
            if not nu > 0:
                raise InputError(f"Student-t degrees of freedom must be > 0, got {nu}")
        self.nu = nu if likelihood == "student-t" else None
        self.idx = np.flatnonzero(problem.free)
        self.theta_ml = np.asarray(ml.theta, float).copy()
        self.channels = tuple(problem.channels)
        self.C = len(self.channels)
        self.N = problem.z.shape[0]
        self.P = problem.P
        names = [problem.names[j] for j in self.idx]
        # The ML fit may have held the noise sd at the round's values; the posterior's mode is
        # the ML estimate with the noise sd estimated (relaxation). Refit from the ML estimate
        # (a few iterations) so the proposal and the walkers start at the right place.
        self.mode_fit = _mode_fit(problem, ml)
        mode = self.mode_fit.theta if self.mode_fit is not None else self.theta_ml
        self.mode = mode
        res = self.mode_fit.residuals if self.mode_fit is not None else ml.residuals
        self.rms = {c: max(float(np.sqrt(np.mean(res[c] ** 2))), 1e-9) for c in self.channels}
        self.log_sigma_lo = np.array([math.log(self.rms[c] / SIGMA_RANGE) for c in self.channels])
        self.log_sigma_hi = np.array([math.log(self.rms[c] * SIGMA_RANGE) for c in self.channels])
        self.n_theta = self.idx.size
        if likelihood == "student-t":
            names += [f"log_sigma_{c}" for c in self.channels]
            if self.sample_nu:
                names.append("log_nu")
        self.names = tuple(names)
        self.ndim = len(names)
        self.lower = problem.lower[self.idx]
        self.upper = problem.upper[self.idx]
        # Laplace approximation at the ML estimate with the residual rms as noise sd
        M = fisher_information(problem, mode, self.rms)
        try:
            cov = np.linalg.inv(M)
            cov = 0.5 * (cov + cov.T)
            np.linalg.cholesky(cov)
        except np.linalg.LinAlgError as exc:
            raise FitError("the information matrix at the ML estimate is singular: the posterior "
                           "cannot be approximated to start the sampler (a parameter is not "
                           "identifiable from this track)") from exc
        self.crb_rms = np.sqrt(np.diag(cov))
        self.gauss_sd = np.where(self.idx < self.P, np.inf, IC_PRIOR_FACTOR * self.crb_rms)
        t_sigma = None
        if likelihood == "student-t":
            # the Gaussian fit is pulled by outliers: start from the Student-t mode (IRLS)
            nu0 = 4.0 if self.sample_nu else float(nu)
            mode, t_sigma, cov = _student_t_mode(problem, mode, self.rms, nu0, cov)
            self.mode = mode
        mean = mode[self.idx]
        if likelihood == "student-t":
            mean = np.concatenate([mean, np.log([t_sigma[c] for c in self.channels])])
            sd_ls = np.full(self.C, math.sqrt((nu0 + 3.0) / (2.0 * nu0 * self.N)))
            extra = [sd_ls]
            if self.sample_nu:
                mean = np.append(mean, math.log(4.0))
                extra.append([0.5])
            d = self.ndim
            full = np.zeros((d, d))
            full[:self.n_theta, :self.n_theta] = cov
            full[self.n_theta:, self.n_theta:] = np.diag(np.concatenate(extra) ** 2)
            cov = full
        self.laplace_mean = mean
        self.laplace_cov = cov
        self._split_priors(np.sqrt(np.diag(cov))[:self.n_theta])

    def _split_priors(self, scale):
        """Sort the problem's priors into linear ones (evaluated as one matrix product: the
        launch position and spline smoothness priors) and the rest (evaluated per walker).
        Linearity is checked numerically at random points a few Laplace sd from the mode."""
        lin, G, c, self._nonlin = [], [], [], []
        base = self.laplace_mean[:self.n_theta]
        rng = np.random.default_rng(0)
        for p in self.problem.priors:
            try:
                f0 = float(p.fn(self.full_theta(base[None])[0]))
                g = np.empty(self.n_theta)
                for j in range(self.n_theta):
                    e = base.copy()
                    e[j] += scale[j]
                    g[j] = (float(p.fn(self.full_theta(e[None])[0])) - f0) / scale[j]
                ok = True
                for _ in range(2):
                    d = 3 * scale * rng.standard_normal(self.n_theta)
                    v = float(p.fn(self.full_theta((base + d)[None])[0]))
                    ok &= abs(v - (f0 + g @ d)) <= 1e-9 * (abs(v) + abs(g @ d) + p.sd)
            except Exception:
                ok = False
            if ok:
                lin.append(p)
                G.append(g)
                c.append(f0 - g @ base)
            else:
                self._nonlin.append(p)
        self._lin_G = np.array(G).reshape(len(G), self.n_theta)
        self._lin_c = np.array(c)
        self._lin_mean = np.array([p.mean for p in lin])
        self._lin_sd = np.array([p.sd for p in lin])

    # ------------------------------------------------------------------------------------
    def full_theta(self, X):
        """Full parameter vectors (W, n) from sampled coordinates (W, D)."""
        X = np.atleast_2d(X)
        th = np.repeat(self.theta_ml[None], X.shape[0], axis=0)
        th[:, self.idx] = X[:, :self.n_theta]
        return th

    def log_prior(self, X):
        """Log prior (W,) of coordinates (W, D); ``-inf`` outside the support."""
        X = np.atleast_2d(X)
        T = X[:, :self.n_theta]
        ok = np.all((T >= self.lower) & (T <= self.upper), axis=1) & np.all(np.isfinite(X), axis=1)
        lp = np.zeros(X.shape[0])
        g = np.isfinite(self.gauss_sd)
        if g.any():
            dz = (T[:, g] - self.theta_ml[self.idx][g]) / self.gauss_sd[g]
            lp -= 0.5 * np.sum(dz ** 2, axis=1)
        if self.likelihood == "student-t":
            ls = X[:, self.n_theta:self.n_theta + self.C]
            ok &= np.all((ls >= self.log_sigma_lo) & (ls <= self.log_sigma_hi), axis=1)
            if self.sample_nu:
                ln = X[:, -1]
                ok &= (ln >= LOG_NU_RANGE[0]) & (ln <= LOG_NU_RANGE[1])
        if self.problem.priors and ok.any():
            T_ok = T[ok]
            acc = np.zeros(T_ok.shape[0])
            if self._lin_G.size:
                z = (T_ok @ self._lin_G.T + self._lin_c - self._lin_mean) / self._lin_sd
                acc -= 0.5 * np.sum(z ** 2, axis=1)
            if self._nonlin:
                full = self.full_theta(X[ok])
                with np.errstate(all="ignore"):
                    for p in self._nonlin:
                        v = _prior_values(p, full)
                        acc -= 0.5 * ((v - p.mean) / p.sd) ** 2
            lp[ok] += acc
        lp[~ok] = -np.inf
        return lp

    def __call__(self, X):
        X = np.atleast_2d(np.asarray(X, float))
        W = X.shape[0]
        out = np.full((W, 1 + self.C), -np.inf)
        out[:, 1:] = np.nan
        lp = self.log_prior(X)
        ok = np.isfinite(lp)
        if not ok.any():
            return out
        with np.errstate(all="ignore"):
            try:
                y, _ = self.problem.predict(self.full_theta(X[ok]))
            except (FloatingPointError, ValueError, ZeroDivisionError):
                return out
            r = self.problem.z[None] - y                      # (w, N, C)
            finite = np.all(np.isfinite(r), axis=(1, 2))
            r = np.where(finite[:, None, None], r, 0.0)
            ss = np.sum(r ** 2, axis=1)                       # (w, C)
            if self.likelihood == "gaussian":
                ll = -0.5 * self.N * np.sum(np.log(np.maximum(ss, 1e-300)), axis=1)
            else:
                ls = X[ok, self.n_theta:self.n_theta + self.C]      # (w, C)
                nu = np.exp(X[ok, -1]) if self.sample_nu else np.full(ok.sum(), float(self.nu))
                s = np.exp(ls)
                u = r / s[:, None, :]
                nuc = nu[:, None, None]
                ll = np.sum(-0.5 * (nuc + 1) * np.log1p(u ** 2 / nuc), axis=(1, 2))
                ll += self.N * self.C * (gammaln((nu + 1) / 2) - gammaln(nu / 2) - 0.5 * np.log(nu * np.pi))
                ll -= self.N * np.sum(ls, axis=1)
        total = lp[ok] + ll
        total[~finite | ~np.isfinite(total)] = -np.inf
        out[ok, 0] = total
        out[ok, 1:] = np.where(finite[:, None], ss, np.nan)
        return out

    def sigma_draws(self, X, ss, rng):
        """Noise sd draws (W, C) for coordinates X (W, D) with residual sums ``ss`` (W, C).

        Gaussian: the exact conditional ``sigma_c^2 = SS_c / chi^2_N``; Student-t: the sampled
        ``exp(log_sigma_c)``."""
        if self.likelihood == "gaussian":
            return np.sqrt(ss / rng.chisquare(self.N, size=ss.shape))
        return np.exp(X[:, self.n_theta:self.n_theta + self.C])


def independence_move(mean, cov, dof=PROPOSAL_DOF, scale=PROPOSAL_SCALE):
    """An ``emcee.moves.MHMove`` drawing independent multivariate-t proposals.

    Parameters
    ----------
    mean : (D,) ndarray
    cov : (D, D) ndarray
        Covariance the proposal's scale matrix is built from (``scale**2 * cov``).
    dof : float
        Student-t degrees of freedom of the proposal (heavier tails than the target keep the
        importance ratio bounded).
    scale : float

    Returns
    -------
    emcee.moves.MHMove
    """
    import emcee

    mean = np.asarray(mean, float)
    L = np.linalg.cholesky(scale ** 2 * np.asarray(cov, float))
    D = mean.size

    def logq(x):
        z = np.linalg.solve(L, (x - mean).T).T
        return -0.5 * (dof + D) * np.log1p(np.sum(z ** 2, axis=1) / dof)

    def proposal(coords, random):
        W = coords.shape[0]
        g = random.randn(W, D)
        chi = random.chisquare(dof, size=W)
        new = mean + (g @ L.T) * np.sqrt(dof / chi)[:, None]
        return new, logq(coords) - logq(new)

    move = emcee.moves.MHMove(proposal, ndim=D)
    move.description = f"independence (multivariate t, {dof:g} dof, {scale:g} x Laplace covariance)"
    return move


def make_moves(kind, post, nwalkers=None, weight=None, scale=None, dof=None):
    """Move mix by name.

    ``auto``: the independence move (weight ``weight``) plus, for the rest, ``DEMove`` when
    there are at least 2 D walkers (emcee's red-blue moves need them), else a random-walk
    Metropolis move (``GaussianMove``) with the Laplace covariance scaled by 2.38^2 / D;
    ``de``: DE 80 % + DE snooker 20 % (emcee's recommendation); ``stretch``: emcee's default.
    """
    import emcee

    if kind == "auto":
        w = INDEPENDENCE_WEIGHT if weight is None else weight
        ind = independence_move(post.laplace_mean, post.laplace_cov, dof=dof or PROPOSAL_DOF,
                                scale=scale or PROPOSAL_SCALE)
        if w >= 1:
            return [(ind, 1.0)]
        if nwalkers is not None and nwalkers >= 2 * post.ndim:
            other = emcee.moves.DEMove()
        else:
            other = emcee.moves.GaussianMove(post.laplace_cov * 2.38 ** 2 / post.ndim)
        return [(ind, w), (other, 1 - w)]
    if kind == "de":
        return [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]
    if kind == "stretch":
        return [(emcee.moves.StretchMove(), 1.0)]
    raise InputError(f"moves {kind!r} not known (allowed: auto, de, stretch)")


@dataclass(frozen=True, eq=False)
class BayesResult:
    """Outcome of :func:`sample_posterior`.

    Attributes
    ----------
    names : tuple of str
        Sampled parameter names plus ``log_sigma_<c>`` (and ``log_nu``) in the draws.
    draws : (chains, draws, K) ndarray
        Burnt-in, thinned draws; walkers are the chains. The last columns are the noise
        ``log_sigma_<c>`` (Gaussian: exact conditional draws).
    lp : (chains, draws) ndarray
        Log posterior of each draw (sampled coordinates).
    thetas : (chains, draws, n) ndarray
        Full parameter vectors (fixed parameters included), for predictions.
    tau : (D,) ndarray
        Integrated autocorrelation time per sampled coordinate [steps].
    steps, burn, thin, nwalkers : int
    acceptance : float
        Mean acceptance fraction.
    converged : bool
    message : str
    summary : pandas.DataFrame
        ArviZ summary of ``draws`` (mean, sd, hdi, r_hat, ess_bulk, ess_tail).
    elapsed : float
        Wall-clock seconds of sampling (this call).
    moves : str
    warnings : tuple of str
    resumed_from : int
        Steps already in the chain file when this call started (0: a fresh chain).
    tau_history : tuple of (steps, max tau)
    chain : (steps, walkers, D) ndarray
        The whole chain of the sampled coordinates, burn-in included (for trace plots).
    """

    names: tuple
    draws: np.ndarray
    lp: np.ndarray
    thetas: np.ndarray
    tau: np.ndarray
    steps: int
    burn: int
    thin: int
    nwalkers: int
    acceptance: float
    converged: bool
    message: str
    summary: object
    elapsed: float
    moves: str
    likelihood: str
    warnings: tuple = ()
    resumed_from: int = 0
    tau_history: tuple = field(default_factory=tuple)
    chain: np.ndarray = None

    @property
    def r_hat(self):
        return dict(zip(self.summary.index, self.summary["r_hat"].astype(float)))

    @property
    def ess_bulk(self):
        return dict(zip(self.summary.index, self.summary["ess_bulk"].astype(float)))

    @property
    def ess_tail(self):
        return dict(zip(self.summary.index, self.summary["ess_tail"].astype(float)))


class ChainFile:
    """The chain on disk, written in blocks: an emcee memory ``Backend`` whose new steps are
    appended to an HDF5 file every ``flush_every`` steps (and at every convergence check).

    emcee's own ``HDFBackend`` opens and closes the file at every step, which cost ~18 ms per
    step on the demo track (more than the 16 simulations of the step); writing blocks of 25
    steps costs ~1 ms per block. A kill loses at most the unflushed block; the file stores the
    random state of its last step, so a resumed run reproduces the uninterrupted chain exactly.

    Layout (group ``mcmc``): datasets ``chain`` (steps, walkers, D), ``log_prob`` (steps,
    walkers), ``blobs`` (steps, walkers, C), ``accepted`` (walkers,); attributes
    ``iteration``, ``random_state`` (pickled), ``bayesdrag_fingerprint``.
    """

    def __init__(self, path, flush_every=25):
        self.path = str(path)
        self.flush_every = int(flush_every)

    def exists(self):
        import h5py

        try:
            with h5py.File(self.path, "r") as f:
                return "mcmc" in f and int(f["mcmc"].attrs.get("iteration", 0)) > 0
        except (OSError, KeyError):
            return False

    def fingerprint(self):
        import h5py

        with h5py.File(self.path, "r") as f:
            v = f["mcmc"].attrs.get("bayesdrag_fingerprint", "")
        return v.decode() if isinstance(v, bytes) else str(v)

    def new_backend(self, nwalkers, ndim, fingerprint):
        """A fresh memory backend; the file is (re)created empty."""
        import h5py

        with h5py.File(self.path, "w") as f:
            g = f.create_group("mcmc")
            g.attrs["iteration"] = 0
            g.attrs["bayesdrag_fingerprint"] = fingerprint
        return _BufferedBackend(self, nwalkers, ndim, flushed=0)

    def load_backend(self):
        """A memory backend holding the stored chain (for ``resume``)."""
        import pickle

        import h5py

        with h5py.File(self.path, "r") as f:
            g = f["mcmc"]
            n = int(g.attrs["iteration"])
            chain = g["chain"][:n]
            lp = g["log_prob"][:n]
            blobs = g["blobs"][:n] if "blobs" in g else None
            acc = g["accepted"][:]
            rs = pickle.loads(bytes(g.attrs["random_state"].tobytes()))
        b = _BufferedBackend(self, chain.shape[1], chain.shape[2], flushed=n)
        b.chain, b.log_prob, b.blobs, b.accepted = chain, lp, blobs, acc
        b.iteration, b.random_state = n, rs
        return b


def _make_buffered_backend():
    import emcee

    class Buffered(emcee.backends.Backend):
        def __init__(self, file, nwalkers, ndim, flushed):
            super().__init__()
            self.reset(nwalkers, ndim)
            self.file = file
            self.flushed = flushed

        def save_step(self, state, accepted):
            super().save_step(state, accepted)
            if self.iteration - self.flushed >= self.file.flush_every:
                self.flush()

        def flush(self):
            import pickle

            import h5py

            n0, n1 = self.flushed, self.iteration
            if n1 <= n0:
                return
            with h5py.File(self.file.path, "a") as f:
                g = f["mcmc"]
                W, D = self.nwalkers, self.ndim
                if "chain" not in g:
                    g.create_dataset("chain", (0, W, D), maxshape=(None, W, D), dtype="f8", chunks=(32, W, D))
                    g.create_dataset("log_prob", (0, W), maxshape=(None, W), dtype="f8", chunks=(32, W))
                    if self.blobs is not None:
                        C = self.blobs.shape[2] if self.blobs.ndim == 3 else 1
                        g.create_dataset("blobs", (0, W, C), maxshape=(None, W, C), dtype="f8", chunks=(32, W, C))
                for name, arr in (("chain", self.chain), ("log_prob", self.log_prob), ("blobs", self.blobs)):
                    if arr is None or name not in g:
                        continue
                    g[name].resize(n1, axis=0)
                    g[name][n0:n1] = np.asarray(arr[n0:n1], float).reshape((n1 - n0,) + g[name].shape[1:])
                if "accepted" in g:
                    del g["accepted"]
                g.create_dataset("accepted", data=np.asarray(self.accepted, float))
                g.attrs["random_state"] = np.void(pickle.dumps(self.random_state))
                g.attrs["iteration"] = n1
            self.flushed = n1

    return Buffered


def _BufferedBackend(file, nwalkers, ndim, flushed):
    global _BUFFERED
    if _BUFFERED is None:
        _BUFFERED = _make_buffered_backend()
    return _BUFFERED(file, nwalkers, ndim, flushed)


_BUFFERED = None


def _fingerprint(post, nwalkers, moves, seed):
    """Hash of everything that defines a chain, stored in the HDF file to refuse resuming a
    different problem."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(post.problem.z).tobytes())
    h.update(np.ascontiguousarray(post.problem.track.t).tobytes())
    h.update(np.round(post.laplace_mean, 9).tobytes())
    h.update(json.dumps([list(post.names), post.likelihood, str(post.nu), nwalkers, moves,
                         seed]).encode())
    return h.hexdigest()[:16]


def _summary(draws, names):
    """ArviZ convergence summary of draws (chains, draws, K): mean, sd, 5/50/95 % quantiles,
    ``r_hat`` (rank-normalised split R-hat), ``ess_bulk``, ``ess_tail``, ``mcse_mean``.

    (``az.summary`` computes the same diagnostics plus HDIs but takes seconds on 50+
    parameters; the diagnostics here are ArviZ's own functions.)"""
    import arviz as az
    import pandas as pd

    with _warnings.catch_warnings():
        _warnings.simplefilter("ignore")
        ds = az.convert_to_dataset({"p": draws}, dims={"p": ["k"]})
        rhat = az.rhat(ds)["p"].values
        eb = az.ess(ds, method="bulk")["p"].values
        et = az.ess(ds, method="tail")["p"].values
        mcse = az.mcse(ds, method="mean")["p"].values
    flat = draws.reshape(-1, draws.shape[-1])
    q = np.quantile(flat, [0.05, 0.5, 0.95], axis=0)
    return pd.DataFrame({"mean": flat.mean(0), "sd": flat.std(0, ddof=1), "q05": q[0], "q50": q[1],
                         "q95": q[2], "mcse_mean": mcse, "ess_bulk": eb, "ess_tail": et, "r_hat": rhat},
                        index=list(names))


def split_rank_rhat(draws):
    """Rank-normalised split R-hat (Vehtari et al. 2021), max of bulk and folded, per parameter.

    A fast numpy version of ``arviz.rhat`` for the in-run convergence checks (the reported
    values come from ArviZ; tests check the two agree).

    Parameters
    ----------
    draws : (chains, draws, K) ndarray

    Returns
    -------
    (K,) ndarray
    """
    from scipy.special import ndtri
    from scipy.stats import rankdata

    W, S, K = draws.shape
    h = S // 2
    x = np.concatenate([draws[:, :h], draws[:, S - h:]], axis=0)  # (2W, h, K)

    def rhat(y):
        n = y.shape[0] * y.shape[1]
        r = rankdata(y.reshape(n, K), axis=0, method="average").reshape(y.shape)
        z = ndtri((r - 0.375) / (n + 0.25))
        cm = z.mean(axis=1)
        B = h * cm.var(axis=0, ddof=1)
        Wv = z.var(axis=1, ddof=1).mean(axis=0)
        return np.sqrt(((h - 1) / h * Wv + B / h) / Wv)

    folded = np.abs(x - np.median(x.reshape(-1, K), axis=0))
    return np.maximum(rhat(x), rhat(folded))


def _tau(chain, c=5):
    """Walker-averaged integrated autocorrelation time per coordinate: emcee's estimator
    (``emcee.autocorr.integrated_time(chain, c=5, tol=0)``: FFT autocorrelation per walker,
    averaged over walkers, Sokal's automatic window), computed for all walkers and coordinates in
    one FFT instead of one call per walker and coordinate (the sampler checks it every 25 steps).

    Parameters
    ----------
    chain : (n_steps, n_walkers, n_dim) array

    Returns
    -------
    (n_dim,) array of tau [steps]
    """
    x = np.asarray(chain, dtype=float)
    n = x.shape[0]
    n2 = 1 << int(np.ceil(np.log2(max(n, 1))))
    f = np.fft.rfft(x - x.mean(axis=0), n=2 * n2, axis=0)
    acf = np.fft.irfft(f * np.conjugate(f), n=2 * n2, axis=0)[:n]
    with np.errstate(invalid="ignore", divide="ignore"):
        acf = acf / acf[0]
    acf = np.nan_to_num(acf).mean(axis=1)                       # (n, n_dim)
    taus = 2.0 * np.cumsum(acf, axis=0) - 1.0
    m = np.arange(n)[:, None] < c * taus
    window = np.where(m.all(axis=0), n - 1, np.argmin(m, axis=0))
    return taus[window, np.arange(taus.shape[1])]


@single_blas
def sample_posterior(post, nwalkers=None, max_steps=20000, check_every=None, seed=None,
                     moves="auto", backend_path=None, resume=False, progress=False,
                     log=None, min_steps=100, move_options=None):
    """Sample ``post`` with emcee until converged (see module docstring) or ``max_steps``.

    Parameters
    ----------
    post : LogPosterior
    nwalkers : int, optional
        Default :data:`DEFAULT_WALKERS` (16). The stopping rule counts steps (50 tau, and
        r_hat < 1.01 needs some 100 effective draws per walker), so the cost grows with the
        walkers; the independence move needs no minimum number, and 16 walkers give a total
        ESS well above 400 at the stop. (32 walkers on the demo track: 625 steps, 20 000
        simulations; 16 walkers: see docs/bayes.md.)
    max_steps : int
        Hard limit of ensemble steps (the chain's total length, resumed part included).
    check_every : int, optional
        Steps between convergence checks (default 25).
    seed : int, optional
        Seeds the walkers' start and emcee's random state.
    moves : {"auto", "de", "stretch"}
    backend_path : path, optional
        HDF5 file the chain is written to as it runs (:class:`ChainFile`; ``None``: memory
        only).
    resume : bool
        Continue the chain in ``backend_path`` (it must have been made by the same problem and
        settings); without it an existing chain there is started afresh.
    progress : bool
        Show a tqdm progress bar.
    log : callable, optional
        Called with one-line status messages at each convergence check.
    min_steps : int
        Never stop before this many steps.

    Returns
    -------
    BayesResult
    """
    import emcee

    D = post.ndim
    if nwalkers is None:
        nwalkers = DEFAULT_WALKERS
    nwalkers = int(nwalkers) + int(nwalkers) % 2
    if nwalkers < 2 * D and moves != "auto":
        raise InputError(f"--walkers {nwalkers}: ensemble moves need at least 2 x {D} walkers")
    if nwalkers < 8:
        raise InputError(f"--walkers {nwalkers}: at least 8 walkers are needed")
    check_every = int(check_every or 25)
    fp = _fingerprint(post, nwalkers, moves, seed)
    backend = None
    resumed = 0
    if backend_path is not None:
        cf = ChainFile(backend_path, flush_every=check_every)
        if resume and cf.exists():
            old = cf.fingerprint()
            if old != fp:
                raise InputError(f"{backend_path}: the stored chain was made with other inputs or "
                                 f"settings (fingerprint {old or 'none'} != {fp}); remove it or rerun "
                                 f"without --resume")
            backend = cf.load_backend()
            if backend.nwalkers != nwalkers or backend.ndim != D:
                raise InputError(f"{backend_path}: the stored chain has {backend.nwalkers} walkers x "
                                 f"{backend.ndim} parameters, this run {nwalkers} x {D}")
            resumed = backend.iteration
        else:
            backend = cf.new_backend(nwalkers, D, fp)
    rs = np.random.RandomState(np.random.SeedSequence(seed).generate_state(1)[0] if seed is not None else None)
    sampler = emcee.EnsembleSampler(nwalkers, D, post, moves=make_moves(moves, post, nwalkers, **(move_options or {})),
                                    vectorize=True,
                                    backend=backend, blobs_dtype=float)
    if resumed:
        state = None
    else:
        sampler.random_state = rs.get_state()
        rng = np.random.default_rng(seed)
        p0 = _initial_walkers(post, nwalkers, rng)
        state = emcee.State(p0, random_state=rs.get_state())
    t0 = time.perf_counter()
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=max_steps, initial=resumed, desc="mcmc", unit="step", leave=False)
    old_tau = None
    converged = False
    message = ""
    tau = np.full(D, np.nan)
    tau_hist = []
    summary = None
    done = resumed
    try:
        while done < max_steps:
            n = min(check_every, max_steps - done) if done >= min_steps else max(min_steps - done, 1)
            n = min(n, max_steps - done)
            sampler.run_mcmc(state, n, progress=False, skip_initial_state_check=True)
            state = None
            done = sampler.iteration
            if backend is not None:
                backend.flush()
            if bar is not None:
                bar.update(n)
            if done < min_steps:
                continue
            chain = sampler.get_chain()
            tau = _tau(chain)
            tmax = float(np.max(tau))
            tau_hist.append((done, tmax))
            stable = old_tau is not None and np.all(np.abs(tau - old_tau) < TAU_RTOL * old_tau)
            old_tau = tau
            long_enough = done >= TAU_FACTOR * tmax
            msg = f"mcmc: {done} steps, tau max {tmax:.1f}, acceptance {np.mean(sampler.acceptance_fraction):.2f}"
            if long_enough and stable and np.isfinite(tmax):
                draws, burn, thin = _retained(sampler, tau)
                fast_r = float(np.max(split_rank_rhat(draws)))
                ess_est = nwalkers * (done - burn) / tmax
                msg += f", r_hat max {fast_r:.4f}, ESS ~{ess_est:.0f}"
                if fast_r < RHAT_MAX and ess_est >= ESS_MIN:
                    # the reported diagnostics are ArviZ's: confirm with them before stopping
                    summary = _summary(draws, post.names[:post.ndim])
                    worst_r = float(summary["r_hat"].max())
                    min_ess = float(min(summary["ess_bulk"].min(), summary["ess_tail"].min()))
                    if worst_r < RHAT_MAX and min_ess >= ESS_MIN:
                        converged = True
                        message = (f"converged: {done} steps >= {TAU_FACTOR:g} tau (max {tmax:.1f}), "
                                   f"ArviZ r_hat max {worst_r:.4f}, ESS min {min_ess:.0f}")
                        if log:
                            log(msg)
                        break
            if log:
                log(msg)
    finally:
        if bar is not None:
            bar.close()
    elapsed = time.perf_counter() - t0
    if not converged:
        message = (f"not converged after {done} steps (max_steps): tau max {np.nanmax(tau):.1f} "
                   f"needs {TAU_FACTOR:g} tau; the draws are reported but check the diagnostics")
    return _collect(post, sampler, tau, converged, message, elapsed, moves, nwalkers, seed,
                    resumed, tuple(tau_hist))


def _initial_walkers(post, nwalkers, rng):
    """Draws from the Laplace approximation, clipped into the support; walkers whose
    log-probability is -inf are redrawn closer to the ML estimate."""
    L = np.linalg.cholesky(post.laplace_cov)
    p0 = post.laplace_mean + rng.standard_normal((nwalkers, post.ndim)) @ L.T
    for shrink in (0.5, 0.25, 0.1, 0.01, 0.0):
        lp = post(p0)[:, 0]
        bad = ~np.isfinite(lp)
        if not bad.any():
            return p0
        p0[bad] = post.laplace_mean + shrink * rng.standard_normal((bad.sum(), post.ndim)) @ L.T
    if not np.all(np.isfinite(post(p0)[:, 0])):
        raise FitError("the posterior is -inf at the ML estimate: the ML fit and the priors disagree")
    return p0


def _retained(sampler, tau):
    tmax = float(np.max(tau))
    burn = int(math.ceil(3 * tmax))
    thin = max(1, int(np.min(tau) // 2))
    draws = np.swapaxes(sampler.get_chain(discard=burn, thin=thin), 0, 1)  # (walkers, draws, D)
    return draws, burn, thin


def _collect(post, sampler, tau, converged, message, elapsed, moves, nwalkers, seed, resumed, tau_hist):
    rng = np.random.default_rng(None if seed is None else seed + 1)
    if not np.all(np.isfinite(tau)):
        tau = _tau(sampler.get_chain())
    draws, burn, thin = _retained(sampler, tau)
    if draws.shape[1] < 4:  # very short (max_steps tiny): keep the second half
        burn = sampler.iteration // 2
        thin = 1
        draws = np.swapaxes(sampler.get_chain(discard=burn), 0, 1)
    lp = np.swapaxes(sampler.get_log_prob(discard=burn, thin=thin), 0, 1)
    blobs = np.swapaxes(sampler.get_blobs(discard=burn, thin=thin), 0, 1)  # (W, S, C)
    W, S, D = draws.shape
    flat = draws.reshape(-1, D)
    ss = blobs.reshape(-1, post.C)
    sig = post.sigma_draws(flat, ss, rng)
    if post.likelihood == "gaussian":
        full = np.concatenate([draws, np.log(sig).reshape(W, S, post.C)], axis=-1)
        names = post.names + tuple(f"log_sigma_{c}" for c in post.channels)
    else:
        full = draws
        names = post.names
    thetas = post.full_theta(flat).reshape(W, S, -1)
    summary = _summary(full, names)
    warns = []
    if not converged:
        warns.append(message)
    bad_r = [n for n, r in zip(summary.index, summary["r_hat"]) if not r < RHAT_MAX]
    if bad_r:
        warns.append(f"r_hat >= {RHAT_MAX} for {', '.join(bad_r[:6])}")
    acc = float(np.mean(sampler.acceptance_fraction))
    if acc < 0.1:
        warns.append(f"mean acceptance {acc:.3f} is very low: the chain barely moves"
                     + (" (the posterior is far from its Gaussian approximation, e.g. a poorly "
                        "identified drag model; try --moves de)" if moves == "auto" else ""))
    return BayesResult(names, full, lp, thetas, np.asarray(tau), int(sampler.iteration), burn, thin, W,
                       acc, converged, message, summary, elapsed, _moves_text(moves), post.likelihood,
                       tuple(warns), resumed, tau_hist, sampler.get_chain())


def _moves_text(kind):
    return {"auto": f"independence t-proposal ({PROPOSAL_DOF:g} dof, {PROPOSAL_SCALE:g} x Laplace cov) "
                     f"{INDEPENDENCE_WEIGHT:.0%} + DE/random-walk {1 - INDEPENDENCE_WEIGHT:.0%}",
            "de": "DEMove 80 % + DESnookerMove 20 %", "stretch": "StretchMove"}.get(kind, kind)


# ---------------------------------------------------------------------------------------------
def cd_draws(result, drag_model, mach, n_drag):
    """Cd on a Mach grid for every retained draw: (chains, draws, M)."""
    B = drag_model.jacobian(np.asarray(mach, float))  # (M, P)
    return np.einsum("wsp,mp->wsm", result.thetas[..., :n_drag], B)


def cd_posterior_rows(rows, cd):
    """Add the posterior part to ``cd_table`` rows.

    Parameters
    ----------
    rows : list of dict
        From :func:`bayesdrag.estimate.scheme1.cd_table` (keys mach, ml, crb_sd, ...).
    cd : (chains, draws, M) ndarray
        Posterior draws of Cd at the rows' Mach numbers.

    Returns
    -------
    list of dict
        Each row with ``mean``, ``sd``, ``q05``, ``q25``, ``q50``, ``q75``, ``q95`` and
        ``sd_over_crb`` (posterior sd / Cramér-Rao sd; None where the CRB sd is 0).
    """
    flat = cd.reshape(-1, cd.shape[-1])
    q = np.quantile(flat, [0.05, 0.25, 0.5, 0.75, 0.95], axis=0)
    mean = flat.mean(axis=0)
    sd = flat.std(axis=0, ddof=1)
    out = []
    for i, r in enumerate(rows):
        r = dict(r)
        r.update(mean=float(mean[i]), sd=float(sd[i]), q05=float(q[0, i]), q25=float(q[1, i]),
                 q50=float(q[2, i]), q75=float(q[3, i]), q95=float(q[4, i]),
                 sd_over_crb=float(sd[i] / r["crb_sd"]) if r.get("crb_sd") else None)
        out.append(r)
    return out


def to_inference_data(result, post, mach, cd, reference=None, n_ppc_per_chain=5, seed=None):
    """ArviZ InferenceData of a Bayesian fit.

    Groups: ``posterior`` (sampled parameters and ``log_sigma_<c>``), ``sample_stats``
    (``lp``), ``observed_data`` (the track's channels against time), ``constant_data`` (time,
    Mach grid, ML estimate and Cramér-Rao sd, fixed parameters, reference Cd),
    ``posterior_predictive`` (``cd`` on the Mach grid and the track channels with noise, at
    ``n_ppc_per_chain`` evenly spaced draws of every chain).
    """
    import arviz as az

    W, S, K = result.draws.shape
    posterior = {n: result.draws[..., k] for k, n in enumerate(result.names)}
    k = max(1, min(n_ppc_per_chain, S))
    pick = np.unique(np.linspace(0, S - 1, k).round().astype(int))
    th = result.thetas[:, pick].reshape(-1, result.thetas.shape[-1])
    y, _ = post.problem.predict(th)
    rng = np.random.default_rng(seed)
    sig_cols = [result.names.index(f"log_sigma_{c}") for c in post.channels]
    sig = np.exp(result.draws[:, pick][..., sig_cols]).reshape(-1, post.C)
    if post.likelihood == "gaussian":
        noise = rng.standard_normal(y.shape) * sig[:, None, :]
    else:
        nu = np.exp(result.draws[:, pick][..., -1]).reshape(-1) if post.sample_nu else np.full(y.shape[0], post.nu)
        noise = rng.standard_t(nu[:, None, None], size=y.shape) * sig[:, None, :]
    yy = (y + noise).reshape(W, pick.size, y.shape[1], post.C).astype(np.float32)
    ppc = {"cd": cd[:, pick].astype(np.float64)}
    for j, c in enumerate(post.channels):
        ppc[c] = yy[..., j]
    pp_idx = {"cd": ["mach"], **{c: ["time"] for c in post.channels}}
    t = post.problem.track.t
    obs = {c: post.problem.z[:, j] for j, c in enumerate(post.channels)}
    crb_ml = dict(zip(post.ml.names, post.ml.crb))
    const = {"t": t, "mach_grid": np.asarray(mach, float),
             "ml_estimate": np.array([post.ml.params[n] for n in post.names[:post.n_theta]]),
             "crb_sd": np.array([crb_ml[n] for n in post.names[:post.n_theta]]),
             "fixed_values": np.array([post.theta_ml[j] for j in range(post.theta_ml.size)
                                       if not post.problem.free[j]] or [np.nan])}
    if reference is not None:
        const["reference_cd"] = np.asarray(reference.value(np.asarray(mach, float)), float)
    with _warnings.catch_warnings():
        _warnings.simplefilter("ignore")
        idata_pp = az.from_dict(
            posterior_predictive=ppc, coords={"mach": np.asarray(mach, float), "time": t},
            dims=pp_idx)
        idata = az.from_dict(
            posterior=posterior, sample_stats={"lp": result.lp},
            observed_data=obs, constant_data=const,
            coords={"time": t, "mach": np.asarray(mach, float), "theta": list(post.names[:post.n_theta]),
                    "fixed": [n for j, n in enumerate(post.problem.names) if not post.problem.free[j]] or ["none"]},
            dims={**{c: ["time"] for c in post.channels}, "t": ["time"], "mach_grid": ["mach"],
                  "reference_cd": ["mach"], "ml_estimate": ["theta"], "crb_sd": ["theta"],
                  "fixed_values": ["fixed"]},
            attrs={"likelihood": result.likelihood, "moves": result.moves, "steps": result.steps,
                   "burn": result.burn, "thin": result.thin, "converged": int(result.converged),
                   "message": result.message, "inference_library": "emcee"})
    # the posterior predictive draws are a subset of the posterior draws: their draw
    # coordinate holds the posterior draw indices they belong to
    idata.add_groups({"posterior_predictive": idata_pp.posterior_predictive.assign_coords(draw=pick)})
    return idata
