"""The smoothness penalty of the flexible drag model and the choice of its weight by the evidence.

The penalty is a Gaussian pseudo-prior on the second derivative of the *relative* correction
(:mod:`bayesdrag.estimate.build.basis`); its sd is chosen by maximising the Laplace-approximated
marginal likelihood (evidence) over :data:`SMOOTHING_GRID`, walked uphill from the middle, each
fit warm-started from the previous one (:func:`fit_penalised`).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...drag import TableSpline
from .basis import curvature_weights, second_difference_rows
from ..model.problem import Prior

__all__ = ["SMOOTHING_GRID", "penalty", "smoothness_priors", "fit_penalised", "walk_evidence", "drop_coefficient_correlations"]

#: initial-condition parameters after the drag coefficients (X0, Y0, Z0, Ux0, Uy0, Uz0)
_N_IC = 6
#: candidate sd of the correction's second derivative, integral (s'')^2 dM ~ 1/sd^2 [Mach^-1.5]
#: (the penalty weight is 1/sd^2); a 5 % change over 0.05 Mach needs ~20, a 1 % tilt over the
#: whole flight ~0.05
SMOOTHING_GRID = tuple(10.0 ** np.arange(-3.0, 3.01, 0.5))


def penalty(dm, base):
    """A function ``sd -> (priors, D, sds)``: the smoothness pseudo-priors of
    :mod:`bayesdrag.estimate.build.basis` on the relative correction of ``dm``.

    With a table (:class:`TableSpline`) the coefficients *are* the correction; without one the
    penalty is on Cd's own second derivative over its typical level (the median of the data's
    shape): a wiggly start must not become the prior's mean. The weights allow more bending
    where the table or the data's shape bend.
    """
    table, shape = base
    knots = np.asarray(dm.knots)
    D = second_difference_rows(knots)
    if table is not None:
        w = curvature_weights(knots, table, shape)
        level = 1.0
    else:
        w = curvature_weights(knots, shape)
        level = float(np.median(shape(np.linspace(knots[0], knots[-1], 200))))
    Dc = D / level
    P = dm.n_params

    def priors(sd):
        sds = sd * w
        return tuple(Prior(f"smooth{i}", (lambda th, d=d: th[..., :P] @ d), 0.0, float(sds[i]),
                           row=np.concatenate([d, np.zeros(_N_IC)]))
                     for i, d in enumerate(Dc)), Dc, sds

    return priors


def smoothness_priors(dm, base, sd):
    """The smoothness pseudo-priors of a penalised Scheme 1 drag model at penalty sd ``sd``
    (``Scheme1Fit.smoothing["sd"]`` of a fit): a tuple of linear :class:`Prior` on the drag
    coefficients (the first ``dm.n_params`` parameters). ``base`` is ``Scheme1Fit.base``."""
    return penalty(dm, base)(sd)[0]


def fit_penalised(prob, base_priors, P, penalty, progress=None):
    """Choose the penalty by the Laplace evidence and return the fit at the best one.

    Parameters
    ----------
    prob : OutputErrorProblem
        Not changed: each smoothing's fit works on a copy with ``base_priors`` plus that
        smoothing's penalty, started at the previous converged fit.
    base_priors : sequence of Prior
        Priors besides the penalty (the launch priors).
    P : int
        Number of drag coefficients.
    penalty : callable
        ``sd -> (priors, D, sds)`` (:func:`penalty`).
    progress : callable, optional
        ``progress(step)`` is told each smoothing the walk fits.

    Returns
    -------
    (OutputErrorProblem, MLResult, dict or None)
        The problem at the chosen smoothing (its priors are the problem's definition, which the
        posterior samples), its fit and the smoothing record (None when no smoothing gave a
        converged fit).

    ``sd`` is walked uphill in the Laplace evidence over :data:`SMOOTHING_GRID` from its middle;
    every fit starts from the previous one. When the best value is at an end of the grid the
    smoothing record says so (``at_grid_end``): at the stiff end the data ask for no more than
    a linear (in knot position) correction of the base curve, which with a table means the
    table's shape fits; at the flexible end the penalty no longer smooths.
    """
    grid = SMOOTHING_GRID
    cache = {}
    state = {"theta": prob.theta0.copy()}

    def evaluate(i):
        if i in cache:
            return cache[i][0]
        if progress is not None:
            progress(f"choosing the smoothing by the evidence: fit {len(cache) + 1} (sd {grid[i]:.3g})")
        pen, D, sds = penalty(grid[i])
        trial = prob.replace(priors=tuple(base_priors) + pen, theta0=state["theta"])
        res = trial.fit(fallback=True)
        idx = np.flatnonzero(res.free)
        ok = np.all(np.isfinite(res.theta)) and np.all(np.isfinite(res.cov))
        sign, logdet_cov = np.linalg.slogdet(res.cov[np.ix_(idx, idx)]) if ok else (0, 0.0)
        if sign <= 0:
            cache[i] = (-np.inf, res, trial, np.nan)
            return -np.inf
        # log evidence (+ const): -1/2 chi2_penalised - 1/2 log|F| + 1/2 log|Lambda D'D|_+
        ev = -0.5 * res.cost + 0.5 * logdet_cov - float(np.sum(np.log(sds)))
        edf = float(idx.size - np.trace(res.cov[:P, :P] @ (D.T @ (D / sds[:, None] ** 2))))
        if not res.converged:
            ev = -np.inf
        cache[i] = (float(ev), res, trial, edf)
        if res.converged:
            state["theta"] = res.theta.copy()
        return float(ev)

    i = walk_evidence(evaluate, len(grid))
    best = cache[i][0]
    if not np.isfinite(best):
        # no smoothing gave a converged fit: the best finite-evidence or the last tried
        finite = [k for k, v in cache.items() if v[1].success]
        if finite:
            i = max(finite, key=lambda k: cache[k][0] if np.isfinite(cache[k][0]) else -1e300)
    ev, res, chosen, edf = cache[i]
    if not res.success and not any(v[1].success for v in cache.values()):
        return chosen, res, None
    table = [{"sd": float(grid[k]), "log_evidence": v[0], "edf": v[3], "converged": v[1].converged}
             for k, v in sorted(cache.items())]
    n_ic = int(res.free[P:].sum())
    end = "stiff" if i == 0 else ("flexible" if i == len(grid) - 1 else None)
    smoothing = {"method": "P-spline: integral of the relative correction's second derivative squared, "
                                "weighted by the base curve's curvature; Laplace evidence",
                 "base": "table" if isinstance(prob.model.drag, TableSpline) else "start curve from the track",
                 "sd": float(grid[i]), "edf": edf, "edf_drag": edf - n_ic,
                 "at_grid_end": end, "fits": len(cache), "grid": table}
    return chosen, res, smoothing


def drop_coefficient_correlations(res, P):
    """Neighbouring coefficients of a penalised spline are strongly correlated by design; only
    correlations that involve an initial condition (e.g. Cd at the top Mach vs Ux0) are news."""
    drag_names = set(res.names[:P])
    kept = tuple(w for w in res.warnings if not (w.kind == "correlated" and set(w.params) <= drag_names))
    return replace(res, warnings=kept)


def walk_evidence(evaluate, n_grid):
    """The walk over the smoothing grid that :func:`fit_penalised` makes and the planner
    predicts: from the middle uphill towards the flexible end, else towards the stiff end.
    ``evaluate(i)`` returns the evidence at grid index ``i``. Returns the chosen index."""
    i = n_grid // 2
    best = evaluate(i)
    for step in (1, -1):
        moved = False
        while 0 <= i + step < n_grid:
            ev = evaluate(i + step)
            if not ev > best:
                break
            i, best, moved = i + step, ev, True
        if moved:
            break
    return i
