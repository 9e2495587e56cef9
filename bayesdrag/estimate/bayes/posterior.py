"""The log posterior of an output-error problem, seeded by its ML fit.

The posterior is the ML cost of :mod:`bayesdrag.estimate.model.ml` turned into a likelihood, with the
noise sd of every channel unknown and weak priors; :class:`LogPosterior` evaluates it for many
parameter sets in one call of the batched point-mass kernel (what emcee's vectorised ensemble
needs). Sampling it is :mod:`bayesdrag.estimate.bayes.sampler`'s job; ``docs/bayes.md`` has the
reasons and the measurements.

Model
-----
Parameters ``theta`` = the problem's free parameters (drag coefficients, the initial state
``X0 .. Uz0`` and any effect parameters appended after them); fixed ones stay at their values.

Likelihood
    ``gaussian`` (default): channel ``c`` has white Gaussian noise of unknown sd ``sigma_c``,
    ``p(z | theta, sigma) = prod_c prod_i N(z_ic; y_ic(theta), sigma_c^2)``, i.e. Eq. 19 with R
    unknown. With the prior ``log sigma_c ~ uniform`` the sd integrates out analytically:
    ``log p(z | theta) = -N/2 sum_c log SS_c(theta) + const`` (``SS_c`` = sum of squared
    residuals of channel c). The sampler runs on this marginal (fewer dimensions, better
    mixing, the *same* posterior of theta) and every retained draw gets its exact conditional
    ``sigma_c^2 | theta, z ~ SS_c / chi^2_N`` (:meth:`LogPosterior.sigma_draws`), so the
    posterior still holds ``log_sigma_c`` and is the joint posterior.

    Channels with ``ar1`` noise (:mod:`bayesdrag.estimate.model.colored`: white noise plus an AR(1)
    model-error process of coefficient ``rho_c`` and variance ``q_c sigma_c^2``) enter through
    their Kalman innovations: ``-1/2 sum log F_i - N/2 log SS_c``, ``SS_c`` the whitened sum of
    squares, the white sd marginalised the same way and drawn as ``SS_c / chi^2_N``. Their
    ``rho_c`` and ``q_c`` are held at their ML values by default (an empirical-Bayes plug-in).
    With ``sample_ar=True`` ``log_1m_rho_c = log(1 - rho_c)`` and ``log_q_c`` are sampled with
    uniform priors on :data:`colored.LOG_1M_RHO_RANGE` and :data:`colored.LOG_Q_RANGE`. Why not
    by default: the drift's correlation time and variance scale the information of every drag
    coefficient, a funnel that the independence proposal cannot follow (acceptance and tau:
    docs/measurements.md, "AR(1) parameters sampled"). The plug-in converges; what the correlation
    time's uncertainty would add is covered by the model-error floor of ``auto``
    (:func:`bayesdrag.estimate.cd.table.model_error_floor`).

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
      position, launch speed and elevation when the track starts at the muzzle; the P-spline's
      smoothness pseudo-priors), exactly as the ML fit used them;
    * noise: ``log sigma_c`` uniform (see above).

Non-physical parameters or a simulation that is not finite give ``-inf``, never an exception.

Laplace approximation
    The ML fit may hold the noise sd at the round's values; the posterior's mode is the ML
    estimate with every noise sd estimated (a short refit, :func:`mode_fit`), or for the
    Student-t likelihood the t mode (:func:`student_t_mode`). ``N(mode, inverse Fisher
    information at the residual rms)`` (:func:`fisher_information`) centres the proposal of
    :mod:`bayesdrag.estimate.bayes.moves` and the walkers' start (:meth:`LogPosterior.initial_walkers`).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.special import gammaln

from ...errors import FitError, InputError
from ..model import colored
from ..model.likelihood import LIKELIHOODS, STUDENT_T_NU
from .coords import drift_coordinates

#: prior sd of non-drag parameters in units of their Cramér-Rao sd
IC_PRIOR_FACTOR = 100.0
#: half-width of the uniform prior on log sigma, in factors of the ML residual rms
SIGMA_RANGE = 100.0
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


def student_t_mode(problem, theta, sigma, nu, cov, *, iterations=30):
    """Mode of the Student-t likelihood by iteratively reweighted Gauss-Newton (the EM
    algorithm of the t distribution: weights ``(nu + 1) / (nu + r^2 / sigma^2)``, then
    ``sigma_c^2 = mean(w r^2)``), started at the Gaussian mode.

    Parameters
    ----------
    problem : OutputErrorProblem
    theta : (n,) ndarray
        Full parameter vector to start from (the Gaussian mode).
    sigma : dict channel -> float
        Starting noise scale per channel [m or m/s].
    nu : float
        Degrees of freedom of the t distribution (> 0).
    cov : (n_free, n_free) ndarray
        Gaussian Laplace covariance: sets the step size that counts as converged (1e-4 sd) and
        is returned when the t information matrix is singular.
    iterations : int, keyword-only
        Maximum reweighting iterations.

    Returns
    -------
    mode : (n,) ndarray
        Full parameter vector at the t mode.
    sigma : dict channel -> float
        t scale per channel [m or m/s].
    cov : (n_free, n_free) ndarray
        Covariance of the free parameters from the expected Fisher information of the t
        likelihood, ``(nu + 1) / (nu + 3) S^T R^-1 S`` (plus the prior terms).
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
        pr, pJ = problem.prior_terms(th)
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
    pr, pJ = problem.prior_terms(th)
    if pr.size:
        M = M + pJ.T @ pJ
    try:
        cov_t = np.linalg.inv(M)
        cov_t = 0.5 * (cov_t + cov_t.T)
        np.linalg.cholesky(cov_t)
    except np.linalg.LinAlgError:
        cov_t = cov
    return th, dict(zip(problem.channels, map(float, sig))), cov_t


def mode_fit(problem, ml):
    """ML fit of ``problem`` with every noise sd estimated, started at ``ml.theta``.

    Parameters
    ----------
    problem : OutputErrorProblem
    ml : MLResult
        Its fit (possibly with noise sd held at the round's values).

    Returns
    -------
    MLResult or None
        None when the ML fit already estimated every noise sd or the refit fails (the ML
        estimate is then the mode). An ``ar1`` channel's noise is estimated whether its sd is
        held or not (:meth:`~bayesdrag.estimate.model.problem.OutputErrorProblem.update_noise`),
        so a fit that holds only such channels' sd has estimated every one: a refit only
        walked away under the plain noise and back under the restricted one (docs/bayes.md).
    """
    if not set(problem.sigma_fixed) - set(problem.ar_channels):
        return None
    p2 = problem.replace(sigma_fixed={}, theta0=ml.theta)
    try:
        res = p2.fit()
    except FitError:
        return None
    return res if res.success else None


def fisher_information(problem, theta, sigma, ar=None):
    """Fisher information of the free parameters at ``theta`` for noise sd ``sigma``.

    Parameters
    ----------
    problem : OutputErrorProblem
    theta : (n,) ndarray
        Full parameter vector.
    sigma : dict channel -> float
        Noise sd per channel [m for x, y, z; m/s for v] (the white part of ``ar1`` channels).
    ar : dict channel -> (rho, q), optional
        Model-error noise of the ``ar1`` channels (their sensitivities are whitened).

    Returns
    -------
    (n_free, n_free) ndarray
        ``S^T R^-1 S`` plus the problem's prior terms (pseudo-measurements).
    """
    _, _, S = problem.sensitivities(theta)
    W = 1.0 / np.array([sigma[c] for c in problem.channels]) ** 2
    A = (problem.whiten(problem.standardized(S), ar) * np.sqrt(W)[None, :, None]).reshape(-1, S.shape[-1])
    M = A.T @ A
    pr, pJ = problem.prior_terms(theta)
    if pr.size:
        M = M + pJ.T @ pJ
    return M


class LogPosterior:
    """Vectorised log-posterior of an :class:`~bayesdrag.estimate.model.problem.OutputErrorProblem`.

    Parameters
    ----------
    problem : OutputErrorProblem
    ml : MLResult
        The ML fit of ``problem`` (centre of the priors of non-drag parameters and of the
        proposal).
    likelihood : {"gaussian", "student-t"}, keyword-only
    nu : float or "sample", keyword-only
        Student-t degrees of freedom (fixed) or ``"sample"``; ignored for ``gaussian``.

    Attributes
    ----------
    names : tuple of str
        The D sampled coordinates: the free parameters' names, then (Student-t) ``log_sigma_<c>``
        and, with ``nu="sample"``, ``log_nu``.
    ndim : int
        D.
    n_theta : int
        Free parameters among them (the first ``n_theta`` coordinates).
    channels : tuple of str
        The C fitted channels; ``N`` samples per channel, ``P`` drag coefficients.
    theta_ml : (n,) ndarray
        Full ML parameter vector (fixed parameters keep these values).
    mode : (n,) ndarray
        Full parameter vector at the posterior's mode (Laplace centre).
    rms : dict channel -> float
        Residual rms at the mode [m or m/s].
    laplace_mean : (D,) ndarray
    laplace_cov : (D, D) ndarray
        Gaussian (Laplace) approximation of the posterior of the sampled coordinates.

    Notes
    -----
    Calling it with ``X`` of shape (W, D) returns an array (W, 1 + C): column 0 the
    log-posterior (``-inf`` where non-physical or not finite), columns 1.. the residual sum of
    squares per channel [m^2 or m^2/s^2] (emcee blobs, used for the noise draws).
    """

    def __init__(self, problem, ml, *, likelihood="gaussian", nu=STUDENT_T_NU, sample_ar=False):
        if likelihood not in LIKELIHOODS:
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
        self.mode_fit = mode_fit(problem, ml)
        mode = self.mode_fit.theta if self.mode_fit is not None else self.theta_ml
        self.mode = mode
        src = self.mode_fit if self.mode_fit is not None else ml
        res = src.residuals
        self.rms = {c: max(float(np.sqrt(np.mean(res[c] ** 2))), 1e-9) for c in self.channels}
        # model-error noise: the sampled log(1 - rho), log q per ar1 channel (Gaussian only)
        self.ar_channels = tuple(problem.ar_channels) if likelihood == "gaussian" else ()
        # residuals over a noise scale of ones are the residuals (the division is skipped)
        self._unit_scale = bool(np.all(problem.noise_scale == 1.0))
        # every channel AR(1): the plain sums of squares would all be replaced by whitened ones
        self._all_ar = len(self.ar_channels) == self.C
        self.ar_ml = {c: tuple(src.ar.get(c, (0.0, 0.0))) for c in self.ar_channels}
        #: sampled model-error coordinates (else held at their ML values)
        self.ar_sampled = tuple(self.ar_channels) if sample_ar else ()
        self.white_sd = {c: (src.sigma[c] if c in self.ar_channels else self.rms[c]) for c in self.channels}
        self.log_sigma_lo = np.array([math.log(self.rms[c] / SIGMA_RANGE) for c in self.channels])
        self.log_sigma_hi = np.array([math.log(self.rms[c] * SIGMA_RANGE) for c in self.channels])
        self.n_theta = self.idx.size
        names += [f"{k}_{c}" for c in self.ar_sampled for k in ("log_1m_rho", "log_q")]
        if likelihood == "student-t":
            names += [f"log_sigma_{c}" for c in self.channels]
            if self.sample_nu:
                names.append("log_nu")
        self.names = tuple(names)
        self.ndim = len(names)
        self.lower = problem.lower[self.idx]
        self.upper = problem.upper[self.idx]
        # Laplace approximation at the ML estimate with the residual rms as noise sd
        M = fisher_information(problem, mode, self.white_sd, self.ar_ml)
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
            mode, t_sigma, cov = student_t_mode(problem, mode, self.rms, nu0, cov)
            self.mode = mode
        mean = mode[self.idx]
        if self.ar_sampled:
            ar_mean, ar_cov = self._ar_laplace(res)
            mean = np.concatenate([mean, ar_mean])
            full = np.zeros((mean.size, mean.size))
            full[:self.n_theta, :self.n_theta] = cov
            full[self.n_theta:, self.n_theta:] = ar_cov
            cov = full
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
        # priors split in the free parameters' own space (linear ones stay one matrix product)
        self.coords = None
        self._split_priors(mean[:self.n_theta], np.sqrt(np.diag(cov))[:self.n_theta])
        # sample the spline in coordinates where the air and shell sources decouple (coords.py)
        nominal = {p.name: p.mean for p in problem.priors}
        self.coords = drift_coordinates(problem, self.idx, self.mode, mass=nominal.get("mass_sd"),
                                        diameter=nominal.get("diameter_sd"))
        if self.coords is not None:
            n = self.n_theta
            x0 = self.coords.from_theta(mean[:n])[0]
            Ji = np.linalg.inv(self.coords.jacobian(x0))
            mean = mean.copy()
            mean[:n] = x0
            cov = cov.copy()
            cov[:n, :] = Ji @ cov[:n, :]
            cov[:, :n] = cov[:, :n] @ Ji.T
            cov = 0.5 * (cov + cov.T)
        self.laplace_mean = mean
        self.laplace_cov = cov

    def _ar_laplace(self, res):
        """Centre and block-diagonal covariance of the sampled ``log_1m_rho``, ``log_q`` from
        the profile likelihood of the mode's residuals (a 2 x 2 finite-difference Hessian per
        channel: the two are strongly correlated, their product ~ the drift's innovation
        variance being what a track determines; sd clipped to [0.02, 3])."""
        lo = np.array([colored.LOG_1M_RHO_RANGE[0], colored.LOG_Q_RANGE[0]])
        hi = np.array([colored.LOG_1M_RHO_RANGE[1], colored.LOG_Q_RANGE[1]])
        k = len(self.ar_sampled)
        mean = np.zeros(2 * k)
        cov = np.zeros((2 * k, 2 * k))
        for n, c in enumerate(self.ar_sampled):
            rho, q = self.ar_ml[c]
            x0 = np.clip([math.log(max(1.0 - rho, 1e-12)), math.log(max(q, 1e-12))], lo + 0.2, hi - 0.2)
            e = np.asarray(res[c], float)

            def ll(x, e=e):
                return colored.profile_loglik(e, 1.0 - math.exp(x[0]), math.exp(x[1]), self.problem.dt_ratio)
            h = 0.1
            H = np.empty((2, 2))
            for i in range(2):
                for j in range(2):
                    ei, ej = np.eye(2)[i] * h, np.eye(2)[j] * h
                    H[i, j] = (ll(x0 + ei + ej) - ll(x0 + ei - ej) - ll(x0 - ei + ej) + ll(x0 - ei - ej)) / (4 * h * h)
            try:
                C = np.linalg.inv(-H)
                np.linalg.cholesky(C)
            except np.linalg.LinAlgError:
                C = np.diag([0.25, 0.25])
            sd = np.sqrt(np.diag(C))
            f = np.clip(sd, 0.02, 3.0) / sd
            C = C * f[:, None] * f[None, :]
            mean[2 * n:2 * n + 2] = x0
            cov[2 * n:2 * n + 2, 2 * n:2 * n + 2] = C
        return mean, cov

    def _split_priors(self, base, scale):
        """Sort the problem's priors into linear ones (evaluated as one matrix product: the
        launch position and spline smoothness priors) and the rest (evaluated per walker).
        Linearity in the free parameters is checked numerically at random points a few Laplace
        sd ``scale`` from ``base``."""
        lin, G, c, self._nonlin = [], [], [], []
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
    def free_theta(self, X):
        """Free parameters (W, n_theta) of sampled coordinates (W, D) (the coordinate map of
        :mod:`~bayesdrag.estimate.bayes.coords` undone where it is used)."""
        X = np.atleast_2d(X)
        T = X[:, :self.n_theta]
        return T if self.coords is None else self.coords.to_theta(T)

    def full_theta(self, X):
        """Full parameter vectors (W, n) from sampled coordinates (W, D) (fixed parameters at
        their ML values)."""
        X = np.atleast_2d(X)
        th = np.repeat(self.theta_ml[None], X.shape[0], axis=0)
        th[:, self.idx] = self.free_theta(X)
        return th

    def reported(self, X):
        """Sampled coordinates (W, D) with the free parameters mapped back to their own
        units (what draws, summaries and files report)."""
        X = np.array(np.atleast_2d(X), float)
        if self.coords is not None:
            X[:, :self.n_theta] = self.coords.to_theta(X[:, :self.n_theta])
        return X

    def log_prior(self, X):
        """Log prior (W,) of coordinates (W, D); ``-inf`` outside the support."""
        X = np.atleast_2d(X)
        with np.errstate(all="ignore"):
            T = self.free_theta(X)
        ok = np.all((T >= self.lower) & (T <= self.upper), axis=1) & np.all(np.isfinite(X), axis=1)
        lp = np.zeros(X.shape[0])
        if self.coords is not None:
            with np.errstate(all="ignore"):
                lp += self.coords.log_jacobian(X[:, :self.n_theta])
            ok &= np.isfinite(lp)
        g = np.isfinite(self.gauss_sd)
        if g.any():
            dz = (T[:, g] - self.theta_ml[self.idx][g]) / self.gauss_sd[g]
            lp -= 0.5 * np.sum(dz ** 2, axis=1)
        if self.ar_sampled:
            A = X[:, self.n_theta:self.n_theta + 2 * len(self.ar_sampled)]
            ok &= np.all((A[:, 0::2] >= colored.LOG_1M_RHO_RANGE[0]) & (A[:, 0::2] <= colored.LOG_1M_RHO_RANGE[1])
                         & (A[:, 1::2] >= colored.LOG_Q_RANGE[0]) & (A[:, 1::2] <= colored.LOG_Q_RANGE[1]), axis=1)
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
        """Log posterior and blobs of coordinates ``X``.

        Parameters
        ----------
        X : (W, D) array_like
            Sampled coordinates, one row per walker.

        Returns
        -------
        (W, 1 + C) ndarray
            Column 0: log posterior (``-inf`` where non-physical or not finite, never an
            exception); columns 1..C: residual sum of squares per channel [m^2 or m^2/s^2]
            (NaN where column 0 is ``-inf``).
        """
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
            r = self.problem.z[None] - y
            if not self._unit_scale:
                r = r / self.problem.noise_scale[None]        # (w, N, C), per-sample sd out
            finite = np.all(np.isfinite(r), axis=(1, 2))
            if not finite.all():
                r = np.where(finite[:, None, None], r, 0.0)
            ss = np.empty((r.shape[0], self.C)) if self._all_ar else np.sum(r ** 2, axis=1)      # (w, C)
            if self.likelihood == "gaussian":
                ll = np.zeros(ss.shape[0])
                for c in self.ar_channels:
                    j = self.channels.index(c)
                    if c in self.ar_sampled:
                        k = self.ar_sampled.index(c)
                        a = X[ok, self.n_theta + 2 * k:self.n_theta + 2 * k + 2]
                        rho, q = 1.0 - np.exp(a[:, 0]), np.exp(a[:, 1])
                    else:
                        rho, q = self.ar_ml[c]
                    ss[:, j], ld = colored.whitened_ss(r[:, :, j], rho, q, self.problem.dt_ratio)
                    ll -= 0.5 * ld
                ll -= 0.5 * self.N * np.sum(np.log(np.maximum(ss, 1e-300)), axis=1)
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

    def sigma_draws(self, X, ss, *, rng):
        """Noise sd draws for sampled coordinates.

        Parameters
        ----------
        X : (W, D) ndarray
            Sampled coordinates.
        ss : (W, C) ndarray
            Their residual sums of squares per channel (the blobs) [m^2 or m^2/s^2].
        rng : numpy.random.Generator, keyword-only
            Consumed for the Gaussian likelihood's chi-square draws.

        Returns
        -------
        (W, C) ndarray
            Noise sd per channel [m or m/s]: Gaussian, the exact conditional
            ``sigma_c^2 = SS_c / chi^2_N``; Student-t, the sampled ``exp(log_sigma_c)``.
        """
        if self.likelihood == "gaussian":
            return np.sqrt(ss / rng.chisquare(self.N, size=ss.shape))
        return np.exp(X[:, self.n_theta:self.n_theta + self.C])

    def initial_walkers(self, nwalkers, *, rng):
        """Start positions: draws from the Laplace approximation; walkers whose log posterior
        is ``-inf`` are redrawn closer to its centre (0.5, 0.25, 0.1, 0.01 of its scale, then at
        the centre).

        Parameters
        ----------
        nwalkers : int
            W.
        rng : numpy.random.Generator, keyword-only

        Returns
        -------
        (W, D) ndarray

        Raises
        ------
        FitError
            When the log posterior is ``-inf`` even at the Laplace centre.
        """
        L = np.linalg.cholesky(self.laplace_cov)
        p0 = self.laplace_mean + rng.standard_normal((nwalkers, self.ndim)) @ L.T
        for shrink in (0.5, 0.25, 0.1, 0.01, 0.0):
            bad = ~np.isfinite(self(p0)[:, 0])
            if not bad.any():
                return p0
            p0[bad] = self.laplace_mean + shrink * rng.standard_normal((bad.sum(), self.ndim)) @ L.T
        if not np.all(np.isfinite(self(p0)[:, 0])):
            raise FitError("the posterior is -inf at the ML estimate: the ML fit and the priors disagree")
        return p0

