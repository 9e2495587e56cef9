"""emcee moves for the posterior of a radar track: the independence move and the move mix.

The posterior of a radar track is close to Gaussian and its Laplace covariance is known
(:class:`~bayesdrag.estimate.bayes.posterior.LogPosterior`), so a proposal that jumps anywhere in it
mixes in a few steps regardless of the dimension and the correlations. The default mix
(``"auto"``) is the independence move of :func:`independence_move` (a mixture of a Gaussian with
the Laplace covariance, 90 %, and a multivariate t, 10 dof, 1.1 x, 10 %, centred at the
posterior mode) 90 % plus 10 % of a local move (``DEMove`` with >= 2 D walkers, else random-walk
Metropolis with the Laplace covariance). The stretch move and DE alone need >= 2 D walkers and
mix over hundreds of steps on a spline posterior; the Gaussian component keeps the acceptance up
on posteriors with declared air sources (the figures behind each weight: docs/measurements.md,
"Sampler moves", and docs/bayes.md). The mix reproduces a strongly correlated
Gaussian target's covariance (``tests/integration/test_bayes.py``) even with a deliberately
mis-centred and mis-scaled proposal, because the independence move is an exact
Metropolis-Hastings move (its proposal ratio enters the acceptance).
"""
from __future__ import annotations

import emcee
import numpy as np
from scipy.special import gammaln

from ...errors import InputError

#: independence proposal, t component: scale of the Laplace covariance and Student-t dof
PROPOSAL_SCALE = 1.1
PROPOSAL_DOF = 10.0
#: independence proposal, Gaussian component: weight and scale (docs/measurements.md)
GAUSS_WEIGHT = 0.9
GAUSS_SCALE = 1.0
#: default weight of the independence move in the move mix (rest: DEMove or random-walk)
INDEPENDENCE_WEIGHT = 0.9
#: move mixes known by name
MOVE_KINDS = ("auto", "de", "stretch")


def independence_move(mean, cov, *, dof=PROPOSAL_DOF, scale=PROPOSAL_SCALE, gauss_weight=GAUSS_WEIGHT,
                      gauss_scale=GAUSS_SCALE):
    """An ``emcee.moves.MHMove`` drawing independent proposals from a Gaussian / Student-t mixture.

    The proposal does not depend on the walker's position; the Metropolis-Hastings ratio
    includes ``q(old) / q(new)``, so the move leaves any target invariant and a proposal far
    from the target costs efficiency, not correctness. The mixture is a Gaussian (weight
    ``gauss_weight``, scale ``gauss_scale``) and a multivariate t (the rest, ``dof``, ``scale``):
    in tens of dimensions a t proposal alone wastes most draws on radii the target never reaches
    (acceptance 0.41 on an exactly Gaussian 57-dimensional target against 0.71 for a Gaussian),
    while its heavy tails keep the importance ratio bounded where the target has heavier tails
    than its Laplace approximation (any ``gauss_weight < 1`` bounds it by ``1 / (1 - gauss_weight)``
    times the t's bound).

    Parameters
    ----------
    mean : (D,) array_like
        Centre of the proposal, in the sampled coordinates' units.
    cov : (D, D) array_like
        Covariance the proposal's scale matrices are built from (``scale**2 * cov``).
    dof : float, keyword-only
        Student-t degrees of freedom of the t component.
    scale : float, keyword-only
        Factor on the standard deviations of ``cov`` for the t component.
    gauss_weight : float, keyword-only
        Probability of the Gaussian component, in [0, 1) (0: the t alone).
    gauss_scale : float, keyword-only
        Factor on the standard deviations of ``cov`` for the Gaussian component.

    Returns
    -------
    emcee.moves.MHMove
        Draws with the sampler's own random state (so a stored chain resumes exactly).
    """
    if not 0.0 <= gauss_weight < 1.0:
        raise InputError(f"gauss_weight must be in [0, 1), got {gauss_weight}")
    mean = np.asarray(mean, float)
    L = np.linalg.cholesky(np.asarray(cov, float))
    D = mean.size
    # log normalising constants of the two components over the common whitened coordinates
    log_t = (gammaln((dof + D) / 2) - gammaln(dof / 2) - 0.5 * D * np.log(dof * np.pi)
             - D * np.log(scale) + np.log1p(-gauss_weight))
    log_g = (-0.5 * D * np.log(2 * np.pi) - D * np.log(gauss_scale) + np.log(gauss_weight)
             if gauss_weight > 0 else -np.inf)

    def logq(x):
        u2 = np.sum(np.linalg.solve(L, (x - mean).T) ** 2, axis=0)
        lt = log_t - 0.5 * (dof + D) * np.log1p(u2 / (dof * scale * scale))
        lg = log_g - 0.5 * u2 / (gauss_scale * gauss_scale)
        return np.logaddexp(lt, lg)

    def proposal(coords, random):
        W = coords.shape[0]
        g = random.randn(W, D)
        chi = random.chisquare(dof, size=W)
        use_g = random.rand(W) < gauss_weight
        radial = np.where(use_g, gauss_scale, scale * np.sqrt(dof / chi))
        new = mean + (g @ L.T) * radial[:, None]
        return new, logq(coords) - logq(new)

    move = emcee.moves.MHMove(proposal, ndim=D)
    move.description = (f"independence ({gauss_weight:.0%} Gaussian {gauss_scale:g} x, "
                        f"{1 - gauss_weight:.0%} multivariate t {dof:g} dof {scale:g} x Laplace covariance)")
    return move


def random_walk_move(cov):
    """An ``emcee.moves.MHMove``: random-walk Metropolis with Gaussian steps ``N(0, cov)``, each
    walker its own step.

    The Cholesky factor of ``cov`` is computed once here, so a proposal costs one (W, D) x
    (D, D) product (emcee's ``GaussianMove`` draws with ``multivariate_normal``, an SVD of the
    covariance at every proposal, and moves every walker by the same step). The step is
    symmetric, so the acceptance is the target ratio and the move leaves any target invariant.

    Parameters
    ----------
    cov : (D, D) array_like
        Covariance of the step, in the sampled coordinates' units (positive definite).

    Returns
    -------
    emcee.moves.MHMove
        Draws with the sampler's own random state (so a stored chain resumes exactly).
    """
    L = np.linalg.cholesky(np.asarray(cov, float))
    D = L.shape[0]

    def proposal(coords, random):
        W = coords.shape[0]
        return coords + random.randn(W, D) @ L.T, np.zeros(W)

    move = emcee.moves.MHMove(proposal, ndim=D)
    move.description = "random-walk Metropolis (Gaussian, precomputed Cholesky factor)"
    return move


def make_moves(kind, post, *, nwalkers=None, weight=None, scale=None, dof=None):
    """Move mix by name.

    Parameters
    ----------
    kind : {"auto", "de", "stretch"}
        ``auto``: the independence move (weight ``weight``) plus, for the rest, ``DEMove`` when
        there are at least 2 D walkers (emcee's red-blue moves need them), else a random-walk
        Metropolis move (:func:`random_walk_move`) with the Laplace covariance scaled by
        2.38^2 / D;
        ``de``: DE 80 % + DE snooker 20 % (emcee's recommendation); ``stretch``: emcee's
        default.
    post : LogPosterior
        Its ``laplace_mean`` (D,), ``laplace_cov`` (D, D) and ``ndim`` shape the ``auto`` mix.
    nwalkers : int, keyword-only
        Walkers of the ensemble (decides DE or random walk in ``auto``).
    weight : float, keyword-only
        Weight of the independence move (default :data:`INDEPENDENCE_WEIGHT`; >= 1: alone).
    scale, dof : float, keyword-only
        Options of :func:`independence_move` (defaults :data:`PROPOSAL_SCALE`,
        :data:`PROPOSAL_DOF`).

    Returns
    -------
    list of (emcee.moves.Move, float)
        Moves and their weights, for ``emcee.EnsembleSampler(moves=...)``.

    Raises
    ------
    InputError
        For a ``kind`` not in :data:`MOVE_KINDS`.
    """
    if kind == "auto":
        w = INDEPENDENCE_WEIGHT if weight is None else weight
        ind = independence_move(post.laplace_mean, post.laplace_cov, dof=dof or PROPOSAL_DOF,
                                scale=scale or PROPOSAL_SCALE)
        if w >= 1:
            return [(ind, 1.0)]
        if nwalkers is not None and nwalkers >= 2 * post.ndim:
            other = emcee.moves.DEMove()
        else:
            other = random_walk_move(post.laplace_cov * 2.38 ** 2 / post.ndim)
        return [(ind, w), (other, 1 - w)]
    if kind == "de":
        return [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]
    if kind == "stretch":
        return [(emcee.moves.StretchMove(), 1.0)]
    raise InputError(f"moves {kind!r} not known (allowed: {', '.join(MOVE_KINDS)})")


def describe_moves(kind):
    """One line naming the move mix ``kind`` (for ``result.json`` and the report).

    Parameters
    ----------
    kind : str
        A name of :data:`MOVE_KINDS`; other strings are returned unchanged.

    Returns
    -------
    str
    """
    return {"auto": f"independence proposal (Gaussian {GAUSS_WEIGHT:.0%} + t {PROPOSAL_DOF:g} dof "
                    f"{PROPOSAL_SCALE:g} x Laplace cov {1 - GAUSS_WEIGHT:.0%}) "
                    f"{INDEPENDENCE_WEIGHT:.0%} + DE/random-walk {1 - INDEPENDENCE_WEIGHT:.0%}",
            "de": "DEMove 80 % + DESnookerMove 20 %", "stretch": "StretchMove"}.get(kind, kind)
