"""The ``cd`` rows of a Scheme 1 result: the Mach grid, Cd and its Cramér-Rao sd at each grid point,
and the model-error floor of the colored-noise fit.

Rows are plain dicts (the ``cd`` list of ``result.json``); :mod:`bayesdrag.estimate.cd.quality`
adds ``band_sd`` and ``determined`` to them.
"""
from __future__ import annotations

import math

import numpy as np

from .claims import DETERMINED_REL_SD, set_floor

__all__ = ["cd_grid", "cd_table", "determined_range", "model_error_floor", "DETERMINED_REL_SD",
           "CD_GRID_STEP", "CD_GRID_MIN_ROWS"]




#: largest Mach step of the result's ``cd`` grid (the kernel's Mach grid: a steep drag rise is
#: ~0.1 Mach wide and a table interpolated through the rows must follow it)
CD_GRID_STEP = 0.01


#: fewest rows of the result's ``cd`` grid
CD_GRID_MIN_ROWS = 81


def cd_grid(mach_min, mach_max):
    """The result's Mach grid over [mach_min, mach_max]: uniform, at least
    :data:`CD_GRID_MIN_ROWS` rows, no step above :data:`CD_GRID_STEP`, rounded to 1e-4."""
    n = max(CD_GRID_MIN_ROWS, int(math.ceil((mach_max - mach_min) / CD_GRID_STEP - 1e-9)) + 1)
    return np.round(np.linspace(mach_min, mach_max, n), 4)


def model_error_floor(fit1, rows):
    """Raise the rows' colored sd to the model-error floor of an ``auto`` fit that chose ``ar1``.

    The generalised least squares with AR(1) model-error noise gives the better estimate
    (on the shipped 6-DOF demo the largest Cd error fell from 1.1 % to 0.43 %), but its bound
    assumes the model error *is* a stationary AR(1) process. The white-noise fit's
    colored-residual bound (Morelli & Klein) assumes no form at all. Where the two disagree the
    band takes the larger, with the declared sources' share added in squares: a form of model
    error the data cannot check is not claimed away. (Measured on the demo: GLS bound alone
    covers the table at 75 % of the grid, the floor brings the band to the colored bound's
    ~97 %.) ``ar1`` chosen by the user trusts the AR(1) form: no floor.

    Parameters
    ----------
    fit1 : Scheme1Fit
    rows : list of dict
        ``cd`` rows (``crb_sd``, ``crb_sd_colored``, optional ``crb_sd_statistical``); updated
        in place: ``crb_sd_colored`` raised to the floor, ``model_error_floor`` added.

    Returns
    -------
    bool
        Whether a floor was applied.
    """
    if fit1.white_ml is None:
        return False
    mach = np.array([r["mach"] for r in rows], float)
    # the white fit's drag model is the same object (the refit keeps the problem's model)
    mk = cd_table(fit1.white_ml, fit1.drag_model, mach)
    set_floor(rows, [math.sqrt(w["crb_sd_colored"] ** 2
                               + max(r["crb_sd"] ** 2 - r.get("crb_sd_statistical", r["crb_sd"]) ** 2, 0.0))
                     for r, w in zip(rows, mk)])
    return True


def cd_table(result, drag_model, mach, reference=None):
    """Cd(M) rows for result.json: ML value, CRB sd (delta method), reference."""
    P = drag_model.n_params
    B = drag_model.jacobian(mach)
    cd = drag_model.cd(result.drag_params, mach)
    var = np.einsum("ij,jk,ik->i", B, result.cov[:P, :P], B)
    varc = np.einsum("ij,jk,ik->i", B, result.cov_colored[:P, :P], B)
    cov_noise = getattr(result, "cov_noise", None)
    # the noise model's own uncertainty: a row's share is kept only where it widens (a
    # correlation shorter than the estimate narrows some rows; the estimate's band stands there)
    varn = (np.einsum("ij,jk,ik->i", B, cov_noise[:P, :P], B) if cov_noise is not None else None)
    rows = []
    for i, m in enumerate(mach):
        rows.append({"mach": round(float(m), 4), "ml": float(cd[i]), "crb_sd": float(np.sqrt(max(var[i], 0))),
                     "crb_sd_colored": float(np.sqrt(max(varc[i], 0))),
                     "reference": float(reference.value(m)) if reference is not None else None})
        if varn is not None:
            rows[-1]["noise_model_sd"] = float(np.sqrt(max(varn[i], 0)))
    return rows


def determined_range(rows):
    """Mach interval spanned by the rows marked ``determined`` (:mod:`bayesdrag.estimate.cd.quality`;
    holes inside it are listed in ``ml.quality.undetermined``), or, for rows not yet assessed,
    where the CRB relative sd of Cd is below :data:`DETERMINED_REL_SD`."""
    if rows and "determined" in rows[0]:
        ok = [r["mach"] for r in rows if r["determined"]]
    else:
        ok = [r["mach"] for r in rows if r["ml"] > 0 and r["crb_sd"] / r["ml"] < DETERMINED_REL_SD]
    return (min(ok), max(ok)) if ok else None
