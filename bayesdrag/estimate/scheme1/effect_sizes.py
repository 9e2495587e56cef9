"""How sure an added effect's size is: ``ml.with_effects.sizes`` of a Scheme 1 fit.

An effect's fitted size (a constant wind, a radar clock, a lift factor) is a claim like a Cd row.
Its Cramér-Rao sd holds the noise only, and its colored form the residuals' correlation; neither
holds what the effect absorbs of a misfit the model cannot follow. Beside the spin drift of a
6-DOF shell, ``lift`` stands in for a drift of another shape, and a cross wind fitted with it
takes up the difference of the shapes: measured on a 105 mm 6-DOF flight in a 5 m/s cross wind
(the honesty suite's w-6dof-wind-37), ``wind.wy`` was -2.5 +- 1.0 from the whole track, 3.3 +-
0.8 without its last quarter and 5.2 +- 1.1 without its last half.

* **Split consistency.** Where the residuals show structure (a channel with AR(1) model-error
  noise), the fit's own problem is fitted again on the track's first samples only, without
  the last :data:`SPLIT_SHARES` of them, from its estimate (the same drag model, smoothing,
  priors and noise models: nested data under one model). Under a model that is right, such a part's estimate differs from
  the whole's by noise of variance ``V_part - V_whole`` (the part holds less information; nested
  data). What the difference squared exceeds that by is the model error's variance, estimated
  from each cut (method of moments, never below zero) and averaged over the cuts: ``split_sd``.
  The parts keep the launch: a part that starts later is another model (a radar clock then
  trades with the free initial state, and a spin-drift lift starts from another spin; a point
  mass with lift, the true model, gave a factor 0.85 +- 0.001 for 1.000 +- 0.001 from such a
  part).
* **The sd reported.** ``sd = sqrt(max(crb, crb_colored)^2 + split_sd^2)``; ``crb_sd`` and
  ``crb_sd_colored`` keep the bounds. A fit with white residuals gets no split fits (the model
  follows the track; its bound stands). Wind layers are sized in
  :func:`~bayesdrag.estimate.build.winds.layer_sizes` (a part of the track leaves layers
  empty).
"""
from __future__ import annotations

import numpy as np

from ...errors import FitError, InputError
from ...effects import WIND_PROFILE

__all__ = ["effect_sizes", "split_excess", "SPLIT_SHARES"]

#: shares of the samples left out at the end of the track, one split fit each
SPLIT_SHARES = (0.25, 0.5)


def split_excess(whole, whole_sd, parts):
    """Model-error variance of one parameter from fits of parts of the track [unit^2].

    Parameters
    ----------
    whole, whole_sd : float
        The estimate from the whole track and its sd.
    parts : sequence of (float, float)
        Each part's estimate and its sd.

    Returns
    -------
    float or None
        The mean over the parts of ``max(0, (part - whole)^2 - (part_sd^2 - whole_sd^2))``: what
        the difference squared exceeds the noise a part adds (``part_sd^2 - whole_sd^2``, nested
        data, never below 0); None without parts.
    """
    ex = [max(0.0, (p - whole) ** 2 - max(s ** 2 - whole_sd ** 2, 0.0)) for p, s in parts
          if np.isfinite(p) and np.isfinite(s)]
    return float(np.mean(ex)) if ex else None


def _bound(res, j):
    """The larger of a parameter's Cramér-Rao sd and its colored form (NaN when neither is finite)."""
    sds = [float(v) for v in (res.crb[j], res.crb_colored[j]) if np.isfinite(v)]
    return max(sds) if sds else float("nan")


def _part_fits(f1):
    """Fits of the track without its last :data:`SPLIT_SHARES` of samples: the fit's own problem
    over its first samples (:meth:`~bayesdrag.estimate.model.problem.OutputErrorProblem.part`),
    started at its estimate. The drag model, its smoothing, the priors, the effects and the noise
    models stay the whole fit's: the parts are nested data under one model, as the method of
    moments assumes (a fit of a part from its own start would also choose other knots and another
    smoothing, and their difference is not the effect's model error). The ones that fail or do not
    converge are left out: a plain spline (no smoothness penalty) whose coefficients at low Mach
    only the track's end reaches leaves them undetermined in a part, whose fit then fails."""
    prob, res = f1.problem, f1.ml
    n = prob.track.n
    out = []
    for share in SPLIT_SHARES:
        idx = np.arange(0, n - int(round(share * n)))
        try:
            part = prob.part(idx, theta0=res.theta).fit(fallback=True)
        except (InputError, FitError, FloatingPointError, ValueError, np.linalg.LinAlgError):
            continue
        if part.success:
            out.append(part)
    return out


def effect_sizes(f1):
    """``ml.with_effects.sizes``: each added effect parameter (wind layers apart) with the sd the
    fit stands by.

    Parameters
    ----------
    f1 : Scheme1Fit
        The fit with the effects.

    Returns
    -------
    dict
        ``{name: {"value", "sd", "crb_sd", "crb_sd_colored", "split_sd"}}`` for every free
        parameter of ``f1.effects`` except ``wind_profile``'s; ``split_sd`` is None where no
        split fit was made (white residuals) or none succeeded. Empty without such parameters.
    """
    res = f1.ml
    names = list(res.names)
    idx = [j for j, n in enumerate(names) if res.free[j] and "." in n
           and n.split(".")[0] in f1.effects and n.split(".")[0] != WIND_PROFILE.name]
    if not idx:
        return {}
    structured = any(m == "ar1" for m in (getattr(f1.problem, "noise_model", None) or {}).values())
    parts = _part_fits(f1) if structured else []
    out = {}
    for j in idx:
        n = names[j]
        base = _bound(res, j)
        sub = [(float(p.theta[list(p.names).index(n)]), _bound(p, list(p.names).index(n)))
               for p in parts if n in p.names and p.free[list(p.names).index(n)]]
        ex = split_excess(float(res.theta[j]), base, sub)
        out[n] = {"value": float(res.theta[j]), "sd": float(np.hypot(base, np.sqrt(ex or 0.0))),
                  "crb_sd": float(res.crb[j]), "crb_sd_colored": float(res.crb_colored[j]),
                  "split_sd": None if ex is None else float(np.sqrt(ex))}
    return out
