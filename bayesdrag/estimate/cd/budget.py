"""The uncertainty budget of Cd: the linearised split of its variance by source (GUM), as
``result.json`` carries it (``uncertainty_budget``), and the analytic shares of the level sources
for Scheme 2."""
from __future__ import annotations

import numpy as np
from ...effects import DENSITY

__all__ = ["uncertainty_budget", "budget_rows", "LEVEL_SOURCES", "level_shares"]


def uncertainty_budget(cov, B, drag_slice, source_idx, names):
    """Linearised split of the Cd variance by source (GUM).

    Parameters
    ----------
    cov : (n, n) ndarray
        Joint covariance of the full parameter vector (zero rows for fixed parameters).
    B : (M, P) ndarray
        Drag basis rows at the Mach grid (``dm.jacobian(mach)``).
    drag_slice : slice
        The drag coefficients in theta.
    source_idx : sequence of int
        Indices of the source (and fitted effect) parameters.
    names : sequence of str
        Their budget keys, one per index (parameters of one effect share its key and count as
        one source; the correlation between them is inside its share, not in ``cross``).

    Returns
    -------
    dict
        ``total_sd`` (M,), ``by_source`` {``statistical``, name..., ``cross``} (sd for the
        sources, signed variance for ``cross``).
    """
    d = np.arange(cov.shape[0])[drag_slice]
    s = np.asarray(source_idx, int)
    S_dd = cov[np.ix_(d, d)]
    total = np.einsum("ij,jk,ik->i", B, S_dd, B)
    out = {"total_sd": np.sqrt(np.clip(total, 0, None)), "by_source": {}}
    if s.size == 0:
        out["by_source"]["statistical"] = out["total_sd"].copy()
        out["by_source"]["cross"] = np.zeros_like(total)
        return out
    S_ds = cov[np.ix_(d, s)]
    S_ss = cov[np.ix_(s, s)]
    A = S_ds @ np.linalg.pinv(S_ss)
    cond = S_dd - A @ S_ss @ A.T
    stat = np.einsum("ij,jk,ik->i", B, cond, B)
    out["by_source"]["statistical"] = np.sqrt(np.clip(stat, 0, None))
    acc = np.clip(stat, 0, None)
    groups = {}
    for k, n in enumerate(names):   # a multi-parameter effect (wind: wx, wy) is one source
        groups.setdefault(n, []).append(k)
    for n, ks in groups.items():
        # the source's share: g^T A_G Sigma_GG A_G^T g over its parameters G
        AG = B @ A[:, ks]                                   # (M, |G|)
        share = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", AG, S_ss[np.ix_(ks, ks)], AG), 0, None))
        out["by_source"][n] = share
        acc = acc + share ** 2
    out["by_source"]["cross"] = total - acc
    return out


def budget_rows(budget, mach):
    """The ``uncertainty_budget`` of result.json (lists, 6 significant digits)."""
    r = lambda a: [float(f"{v:.6g}") for v in np.asarray(a, float)]  # noqa: E731
    return {"mach": [round(float(m), 4) for m in mach], "total_sd": r(budget["total_sd"]),
            "by_source": {k: r(v) for k, v in budget["by_source"].items()}}


#: sources that move Cd by one factor whatever the Mach number: Cd ~ 1/rho, ~ m, ~ 1/d^2
#: the level sources: the track sees only ``rho Cd d^2 / m``, so an error of one of them is an
#: error of Cd by a fixed relative amount at every Mach: the signed relative Cd error per declared
#: sd (``density_sd`` is relative), from the sd, the mass [kg] and the diameter [m]
LEVEL_SOURCES = {
    DENSITY.source: lambda sd, m, d: -sd,              # Cd ∝ 1 / rho
    "mass": lambda sd, m, d: sd / m,              # Cd ∝ m
    "diameter": lambda sd, m, d: -2.0 * sd / d,   # Cd ∝ 1 / d^2
}


def level_shares(rnd):
    """Relative Cd sd of each declared level source (Scheme 2's budget).

    A constant Cd per window is estimated with the nominal air density, mass and diameter;
    an error in any of them moves every window's Cd by the same factor (drag ~ rho Cd d^2 / m),
    so its share is analytic: density ``sd``, mass ``sd / m``, diameter ``2 sd / d``.

    Returns
    -------
    (dict stem -> float, list of str)
        The relative shares, and the sources the windows stay conditional on (the others).
    """
    m, d = rnd.projectile.mass, rnd.projectile.diameter
    rel = {stem: abs(LEVEL_SOURCES[stem](float(sd), m, d)) for stem, sd in rnd.systematics.declared().items()
           if stem in LEVEL_SOURCES}
    from ...round import SYSTEMATIC_SOURCES

    return rel, [k for k in SYSTEMATIC_SOURCES if k not in rel]
