"""Cd(M) from posterior draws: the curve of every draw on a Mach grid, the posterior part of the
``cd`` rows (mean and quantiles), and the draws widened to the rows' model-error floor."""
from __future__ import annotations

import numpy as np

__all__ = ["cd_draws", "cd_posterior_rows", "widen_to_floor", "needs_widening"]


# --------------------------------------------------------------------------- Cd from the draws
def cd_draws(result, drag_model, mach, n_drag):
    """Cd on a Mach grid for every retained draw.

    Parameters
    ----------
    result : BayesResult
    drag_model : DragModel
        Its ``jacobian(mach)`` (M, P) maps the P drag coefficients to Cd (linear models).
    mach : (M,) array_like
        Mach numbers [-].
    n_drag : int
        P, the leading drag coefficients of ``result.thetas``.

    Returns
    -------
    (chains, draws, M) ndarray
        Cd [-].
    """
    B = drag_model.jacobian(np.asarray(mach, float))  # (M, P)
    return np.einsum("wsp,mp->wsm", result.thetas[..., :n_drag], B)


def cd_posterior_rows(rows, cd, sampled=None):
    """Add the posterior part to ``cd_table`` rows.

    Parameters
    ----------
    rows : list of dict
        From :func:`bayesdrag.estimate.cd.table.cd_table` (keys mach, ml, crb_sd, ...).
    cd : (chains, draws, M) ndarray
        Posterior draws of Cd at the rows' Mach numbers (widened by :func:`widen_to_floor`
        where the rows carry model error: the honest total band).
    sampled : (chains, draws, M) ndarray, optional
        The draws as sampled, before any widening (default ``cd``).

    Returns
    -------
    list of dict
        Each row with ``mean``, ``sd``, ``q05``, ``q25``, ``q50``, ``q75``, ``q95`` (of ``cd``),
        ``sampled_sd``, ``sampled_q05``, ``sampled_q50``, ``sampled_q95`` (of ``sampled``: the
        posterior itself), ``sd_over_crb`` (sampled sd / Cramér-Rao sd; None where the CRB sd is
        0) and ``total_sd_over_crb`` (the same for ``sd``).
    """
    flat = cd.reshape(-1, cd.shape[-1])
    q = np.quantile(flat, [0.05, 0.25, 0.5, 0.75, 0.95], axis=0)
    mean = flat.mean(axis=0)
    sd = flat.std(axis=0, ddof=1)
    sflat = flat if sampled is None else sampled.reshape(-1, sampled.shape[-1])
    sq = q if sampled is None else np.quantile(sflat, [0.05, 0.25, 0.5, 0.75, 0.95], axis=0)
    ssd = sd if sampled is None else sflat.std(axis=0, ddof=1)
    out = []
    for i, r in enumerate(rows):
        r = dict(r)
        crb = r.get("crb_sd")
        r.update(mean=float(mean[i]), sd=float(sd[i]), q05=float(q[0, i]), q25=float(q[1, i]),
                 q50=float(q[2, i]), q75=float(q[3, i]), q95=float(q[4, i]),
                 sampled_sd=float(ssd[i]), sampled_q05=float(sq[0, i]), sampled_q50=float(sq[2, i]),
                 sampled_q95=float(sq[4, i]),
                 sd_over_crb=float(ssd[i] / crb) if crb else None,
                 total_sd_over_crb=float(sd[i] / crb) if crb else None)
        out.append(r)
    return out


def needs_widening(rows):
    """Whether the rows carry a model-error floor or a model-error term the draws must hold."""
    return any(r.get("model_error_floor") or r.get("model_error_sd") for r in rows)


def widen_to_floor(cd, rows):
    """Posterior Cd draws (chains, draws, M) widened about their mean, Mach by Mach, to the
    rows' honest sd: the larger of the sampled sd and the model-error floor
    (:func:`~bayesdrag.estimate.cd.table.model_error_floor`), with the rows' ``model_error_sd``
    (:mod:`bayesdrag.estimate.cd.model_error`: a bias the sampler cannot see) added in squares.
    Rows gain ``model_error_widening`` (the factor, 1 where none)."""
    flat = cd.reshape(-1, cd.shape[-1])
    mean = flat.mean(axis=0)
    sd = flat.std(axis=0, ddof=1)
    floor = np.array([r.get("model_error_floor", 0.0) for r in rows], float)
    me = np.array([r.get("model_error_sd", 0.0) for r in rows], float)
    target = np.sqrt(np.maximum(sd, floor) ** 2 + me ** 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.where(sd > 0, np.maximum(1.0, target / sd), 1.0)
    for r, v in zip(rows, k):
        r["model_error_widening"] = float(v)
    return mean + (cd - mean) * k
