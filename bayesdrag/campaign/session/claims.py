"""What a session fit claims: Cd rows with their bands, the central row, form factors and
ballistic coefficients against the standard drag functions, the muzzle speeds, the drag
scatter between shots and what the range rate saw of the device's site.

Every band is Student's t with the session's ``S - 1`` degrees of freedom (the shot-to-shot
scatter is estimated from the shots themselves). A row's ``sd`` is the band's normal-equivalent
1-sd width (its 90 % half width over 1.645: with five shots 1.3 times the t scale ``sd_t``), so
that "within 3 sd" means what it means for every other row bayesdrag writes; a row is
``determined`` when ``sd`` is below :data:`DETERMINED_REL_SD` of its Cd, by the one rule of every
row bayesdrag writes (:func:`~bayesdrag.estimate.cd.claims.claimed`).
"""
from __future__ import annotations

import numpy as np
from scipy.stats import chi2 as chi2_dist
from scipy.stats import t as t_dist

from ...estimate.cd.claims import DETERMINED_REL_SD, DataBand, claimed  # noqa: F401  (session.run reads it here)
from .fit import paule_mandel

__all__ = ["rows", "central_row", "form_factor", "ballistic_coefficient", "muzzle_velocity", "scatter",
           "site", "MACH_ROW_STEP", "LB_PER_KG", "M_PER_IN", "CLAIM_REL_SD"]

#: the normal distribution's 95 % quantile (a 90 % band is +-Z90 sd)
Z90 = 1.6448536269514722
#: spacing of the Cd rows [Mach]
MACH_ROW_STEP = 0.01
#: a row whose 1-sd band is at most this fraction of Cd is claimed (it may be claimed without
#: being determined, and says so)
CLAIM_REL_SD = 0.015
LB_PER_KG = 1.0 / 0.45359237
M_PER_IN = 0.0254


def _curve_gradient(fit, mach):
    """d Cd / d theta at ``mach`` (only the curve coefficients move a row), shape (len(mach), P)."""
    mach = np.atleast_1d(np.asarray(mach, float))
    L, m = fit.layout, fit.model
    G = np.zeros((mach.size, L.size))
    G[:, : L.K] = m.reference(mach)[:, None] * m.correction_basis(mach, L.K)
    return G


def _band(fit, mach, extra_rel_sd=0.0):
    """(Cd, 1-sd band, t quantile) at ``mach``: the curve's covariance plus a relative term."""
    mach = np.atleast_1d(np.asarray(mach, float))
    cd = fit.model.cd(fit.layout.curve(fit.theta), mach)
    G = _curve_gradient(fit, mach)
    var = np.einsum("ij,jk,ik->i", G, fit.cov, G) + (cd * extra_rel_sd) ** 2
    return cd, np.sqrt(np.clip(var, 0.0, None)), float(t_dist.ppf(0.95, max(fit.dof, 1)))


def _row(mach, cd, sd, tq, ref):
    # the 1-sd band a reader compares with: the t band's half width over the normal 90 % quantile,
    # so that "within 3 sd" keeps its meaning with few shots (sd_t is the t distribution's scale)
    sd_eq = sd * tq / Z90
    rel = sd_eq / cd if cd > 0 else np.inf
    _, det = claimed([cd], DataBand.plain([sd_eq], usable=cd > 0))
    return {"mach": float(mach), "mean": float(cd), "sd": float(sd_eq), "sd_t": float(sd), "q05": float(cd - tq * sd),
            "q95": float(cd + tq * sd), "reference": None if ref is None else float(ref),
            "rel_sd": float(rel), "determined": bool(det[0]),
            "claimed": bool(cd > 0 and rel <= CLAIM_REL_SD), "physical": bool(cd > 0)}


def flown_span(fit):
    """(lowest, highest) Mach of the samples fitted."""
    m = np.concatenate([mm[k] for mm, k in zip(fit.mach, fit.keep)])
    return float(m.min()), float(m.max())


def rows(fit, extra_rel_sd=0.0, step=MACH_ROW_STEP):
    """The Cd rows every ``step`` of Mach across the flown span (its ends included).

    Parameters
    ----------
    fit : SessionFit
    extra_rel_sd : float
        A relative sd added to every row (a declared wind's, :func:`wind_rel_sd`).

    Returns
    -------
    list of dict
        ``mach, mean, sd, q05, q95, reference, rel_sd, determined, claimed``.
    """
    lo, hi = flown_span(fit)
    grid = np.arange(np.ceil(lo / step) * step, hi + 1e-12, step)
    grid = np.unique(np.concatenate([[lo], grid[(grid > lo) & (grid < hi)], [hi]]))
    cd, sd, tq = _band(fit, grid, extra_rel_sd)
    ref = fit.model.reference(grid)
    return [_row(m, c, s, tq, r) for m, c, s, r in zip(grid, cd, sd, ref)]


def central_row(fit, extra_rel_sd=0.0):
    """The row at the session's information-weighted Mach (where its band is narrowest)."""
    m = fit.model.mach_center
    cd, sd, tq = _band(fit, [m], extra_rel_sd)
    return _row(m, cd[0], sd[0], tq, fit.model.reference([m])[0])


def wind_rel_sd(fit, wind_sd):
    """Relative Cd sd of a head or tail wind of sd ``wind_sd`` [m/s] not fitted: on a flat
    velocity-only track a wind ``w`` changes the air speed, hence the drag, by ``2 w / v``
    relative, which trades exactly with the Cd level."""
    if not wind_sd:
        return 0.0
    v = fit.model.mach_center * fit.model.sound_speed
    return 2.0 * float(wind_sd) / v


def form_factor(fit, table, claim_rows, extra_rel_sd=0.0):
    """The form factor against a standard drag function: the weighted least-squares mean of
    ``Cd / Cd_std`` over the rows given (weights 1 / var), its sd from the rows' full covariance
    (a smooth curve's rows are strongly correlated, so the sd is the weighted mean's, not
    ``1 / sqrt(sum w)``), widened like the rows for the shots' degrees of freedom.

    Parameters
    ----------
    table : ReferenceTable
        The standard function.
    claim_rows : list of dict
        The rows to use (the determined ones; the central row when none is).

    Returns
    -------
    dict
        ``{"value", "sd", "rows"}``.
    """
    mach = np.array([r["mach"] for r in claim_rows])
    cd, _, tq = _band(fit, mach)
    std = table.value(mach)
    G = _curve_gradient(fit, mach) / std[:, None]
    cov = G @ fit.cov @ G.T + np.diag((cd / std * extra_rel_sd) ** 2)
    var = np.clip(np.diag(cov), 1e-300, None)
    w = (1.0 / var) / np.sum(1.0 / var)
    value = float(w @ (cd / std))
    sd = float(np.sqrt(max(float(w @ cov @ w), 0.0))) * tq / Z90
    return {"value": value, "sd": sd, "rows": int(len(mach))}


def ballistic_coefficient(ff, mass, diameter):
    """Ballistic coefficients ``m / (d^2 i)`` of a form factor ``ff`` ({value, sd}).

    Parameters
    ----------
    mass : float, kg
    diameter : float, m

    Returns
    -------
    dict
        ``{"value", "sd", "unit": "lb/in^2", "value_kg_m2", "sd_kg_m2"}``.
    """
    bc_si = mass / (diameter ** 2 * ff["value"])
    bc_us = mass * LB_PER_KG / ((diameter / M_PER_IN) ** 2 * ff["value"])
    rel = ff["sd"] / ff["value"]
    return {"value": float(bc_us), "sd": float(bc_us * rel), "unit": "lb/in^2", "value_kg_m2": float(bc_si),
            "sd_kg_m2": float(bc_si * rel)}


def muzzle_velocity(fit):
    """``{"mean", "sd", "extreme_spread"}`` of the shots' fitted muzzle speeds [m/s]."""
    v0 = fit.layout.v0(fit.theta)
    return {"mean": float(np.mean(v0)), "sd": float(np.std(v0, ddof=1)) if v0.size > 1 else 0.0,
            "extreme_spread": float(np.ptp(v0))}


def _q_tau(y, s, target):
    """The tau at which the generalised Q statistic equals ``target`` (Q-profile)."""
    y, s = np.asarray(y, float), np.asarray(s, float)

    def q(t2):
        w = 1.0 / (s ** 2 + t2)
        yb = np.sum(w * y) / np.sum(w)
        return float(np.sum(w * (y - yb) ** 2))

    if q(0.0) <= target:
        return 0.0
    lo, hi = 0.0, float(np.var(y)) * 4 + 1e-12
    while q(hi) > target:
        hi *= 4
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if q(mid) > target else (lo, mid)
    return float(np.sqrt(0.5 * (lo + hi)))


def scatter(fit):
    """The shot-to-shot drag scatter (relative sd) and its 90 % interval by the Q-profile
    method: ``{"mean", "q05", "q95"}`` (``mean`` is the Paule-Mandel estimate)."""
    y, s = fit.levels, fit.level_sd
    df = max(y.size - 1, 1)
    return {"mean": float(paule_mandel(y, s)), "q05": _q_tau(y, s, float(chi2_dist.ppf(0.95, df))),
            "q95": _q_tau(y, s, float(chi2_dist.ppf(0.05, df)))}


def site(fit, typed_offset):
    """What the range rate saw of the device's site.

    Returns
    -------
    dict
        ``q`` = y_d^2 - d^2 [m^2] and its sd when fitted; ``offset`` (the distance from the line of
        fire ``sqrt(q + d^2)``) [m] and its sd when that is real; ``not_determined``: the site
        components a range rate does not see.
    """
    L = fit.layout
    d = 0.0 if typed_offset is None else float(typed_offset)
    out = {"typed_offset": typed_offset, "fitted": bool(L.fit_q),
           "not_determined": ["the device's position along the line of fire (held at the round's [radar] position "
                              "x)", "whether its offset is sideways or in height (only the distance from the line "
                              "of fire enters)"]}
    if L.fit_q:
        q, qsd = float(fit.theta[L.K]), float(np.sqrt(fit.cov[L.K, L.K]))
        out.update(q=q, q_sd=qsd)
        d2 = q + d * d
        if d2 > 0:
            off = float(np.sqrt(d2))
            out.update(offset=off, offset_sd=float(qsd / (2 * off)))
        else:
            out.update(offset=None, offset_sd=None)
    else:
        out.update(q=fit.model.q_fixed, q_sd=0.0)
    return out
