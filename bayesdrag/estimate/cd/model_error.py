"""Model error: the Cd uncertainty a misfit the fit's own band does not hold implies.

A Cd band from the Cramér-Rao bound (or its colored-residual and AR(1) widenings) holds the noise
and correlated residuals. It does not hold a *bias*: an undeclared wind, a late radar clock or a
yawing launch is partly absorbed by the Cd curve itself, so the residuals may look clean while Cd
is off by many band sd. The gap is measured where it can be: by fitting the cause.

Effects
    When the diagnosis finds material effects the round does not declare, the fit is repeated
    with them as nuisance parameters. The plain Cd then differs from the corrected one by
    ``shift``, and the corrected Cd is itself uncertain by its band ``band_alt``; so the plain
    Cd's error is ``shift + (Cd_alt - truth)``, of sd ``sqrt(shift^2 + band_alt^2)``. The model
    error is what that adds to the plain band: ``sqrt(shift^2 + max(band_alt^2 - band^2, 0))``.
Noise
    A Gaussian fit of a track with gross outliers, or with a correlated model-error process the
    ``auto`` noise model approximates as AR(1), rests on a noise model the data cannot fully
    check. Another consistent estimator of the same track is the check: a robust fit (Student-t,
    white) where the track has gross outliers, else the white-noise fit the AR(1) fit started
    from. Both estimators are consistent when the model is right, so their curves differ by
    noise alone, of variance the difference of their variances (Hausman: the efficient one is
    uncorrelated with the difference); what the difference holds beyond that is a bias, taken as
    one sd (:func:`check_sd`). On a white track without outliers neither check runs.

The model error enters the row's band in squares, and ``uncertainty_budget.by_source.model_error``
(:func:`fold_into_budget`), so the budget's squares still add up to the band the row reports.
"""
from __future__ import annotations

import numpy as np

__all__ = ["shift_sd", "check_sd", "combine", "fold_into_budget", "describe"]


def shift_sd(ml, band, ml_alt, band_alt=None):
    """Model-error sd [Cd] of each row from an alternative fit of the same track.

    Parameters
    ----------
    ml, band : (M,) array_like
        The reported fit's Cd and band sd at the grid.
    ml_alt : (M,) array_like
        The alternative fit's Cd at the same grid.
    band_alt : (M,) array_like, optional
        Its band sd: given when the alternative is the better model (an effect fitted), so its
        own uncertainty is carried over; None when it is only a check (the noise model).

    Returns
    -------
    (M,) ndarray
        ``sqrt(shift^2 + max(band_alt^2 - band^2, 0))`` (``|shift|`` without ``band_alt``).
    """
    ml, band, alt = (np.asarray(a, float) for a in (ml, band, ml_alt))
    extra = 0.0 if band_alt is None else np.clip(np.asarray(band_alt, float)**2 - band**2, 0, None)
    out = np.sqrt((ml - alt)**2 + extra)
    return np.where(np.isfinite(out), out, np.inf)


def check_sd(ml, sd, ml_alt, sd_alt):
    """Model-error sd [Cd] of each row from a check: another consistent estimator of the same
    track under another noise model.

    When the model is right both estimate the same Cd and differ by noise only, with variance
    ``|sd_alt^2 - sd^2|`` (Hausman: the more efficient estimator is uncorrelated with the
    difference). The part of the squared difference beyond that is the bias the noise models
    disagree on: ``sqrt(max(shift^2 - |sd_alt^2 - sd^2|, 0))``.

    Parameters
    ----------
    ml, sd : (M,) array_like
        The reported fit's Cd and the sd of its estimator at the grid (a larger ``sd`` than the
        estimator has grants the difference less noise: conservative).
    ml_alt, sd_alt : (M,) array_like
        The check's Cd and the sd of its estimator (its honest band) at the same grid.

    Returns
    -------
    (M,) ndarray
    """
    ml, sd, alt, sda = (np.asarray(a, float) for a in (ml, sd, ml_alt, sd_alt))
    out = np.sqrt(np.clip((ml - alt)**2 - np.abs(sda**2 - sd**2), 0, None))
    return np.where(np.isfinite(out), out, np.inf)


def combine(*parts):
    """Independent model-error terms added in squares (None parts skipped); zeros when none."""
    parts = [np.asarray(p, float) for p in parts if p is not None]
    if not parts:
        return None
    return np.sqrt(sum(p**2 for p in parts))


def fold_into_budget(budget, rows):
    """Make ``uncertainty_budget`` add up to the band each row reports.

    ``statistical`` becomes the data's band less the declared sources (the Cramér-Rao sd where
    the residuals look like the noise, the colored or AR(1)-floor sd where they do not), the
    sources and ``cross`` stay as linearised, ``model_error`` is the rows' ``model_error_sd``,
    and ``total_sd`` is ``band_sd``: squares plus ``cross`` give ``total_sd`` squared.

    Parameters
    ----------
    budget : dict
        ``uncertainty_budget`` as :func:`bayesdrag.estimate.cd.budget.budget_rows` wrote it (updated
        in place; ``linearised_total_sd`` keeps its former total).
    rows : list of dict
        ``cd`` rows after :func:`bayesdrag.estimate.cd.quality.assess` (same grid).
    """
    r6 = lambda a: [float(f"{v:.6g}") for v in np.asarray(a, float)]  # noqa: E731
    band = np.array([r["band_sd"] for r in rows], float)
    me = np.array([r.get("model_error_sd", 0.0) for r in rows], float)
    by = budget["by_source"]
    others = sum(np.asarray(v, float)**2 for k, v in by.items() if k not in ("statistical", "cross", "model_error"))
    cross = np.asarray(by.get("cross", np.zeros(band.size)), float)
    stat = np.sqrt(np.clip(band**2 - me**2 - others - cross, 0, None))
    budget["linearised_total_sd"] = list(budget["total_sd"])
    by["statistical"] = r6(stat)
    if np.any(me > 0):
        by["model_error"] = r6(me)
    budget["total_sd"] = r6(band)
    return budget


def describe(mach, ml, me):
    """How far a model-error term reaches: "up to X % (at Mach M)"."""
    mach, ml, me = (np.asarray(a, float) for a in (mach, ml, me))
    rel = np.where(ml > 0, me / np.abs(ml), 0.0)
    i = int(np.argmax(rel))
    return f"up to {100 * rel[i]:.2g} % (at Mach {mach[i]:.2f})"
