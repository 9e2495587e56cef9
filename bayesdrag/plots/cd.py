"""Figures of Cd(M): the ML curve with its band, the posterior bands, relative panels, Scheme 2 windows."""
from __future__ import annotations

import statistics

import numpy as np

from .common import MARGINS, new_axes

#: the standard normal (its quantiles set the bands' widths; the standard library's, so drawing a
#: figure does not import scipy.stats)
_NORMAL = statistics.NormalDist()

__all__ = ['plot_drag_curve', 'plot_cd_ml', 'plot_cd_ml_relative', 'plot_cd_posterior', 'plot_cd_posterior_relative',
           'plot_cd_relative', 'plot_windows']


def plot_drag_curve(mach, cd, ax=None, label=None, **kw):
    """Cd against Mach.

    Parameters
    ----------
    mach, cd : array_like, shape (N,)
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = new_axes(ax, (6, 4), MARGINS)
    ax.plot(mach, cd, label=label, **kw)
    ax.set(xlabel="Mach number", ylabel="drag coefficient Cd")
    ax.grid(alpha=0.3)
    if label:
        ax.legend(fontsize="small")
    return ax


def plot_cd_ml(rows, ax=None, label="ML", band=0.90):
    """Cd(M) from an ML fit with its band and the reference curve.

    The band is each row's ``band_sd`` when present (the sd the fit stands by: the Cramér-Rao sd,
    or the colored-residual sd where the residuals show model error), else its ``crb_sd``.

    Parameters
    ----------
    rows : list of dict
        ``result.json`` ``cd`` rows (keys mach, ml, crb_sd, optional band_sd, reference).
    ax : matplotlib Axes, optional
    band : float
        Central probability of the Gaussian CRB band.

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = new_axes(ax, (7, 4.5), MARGINS)
    m = np.array([r["mach"] for r in rows])
    cd = np.array([r["ml"] for r in rows])
    honest = all(r.get("band_sd") is not None for r in rows)
    sd = np.array([r["band_sd"] if honest else r["crb_sd"] for r in rows])
    k = _NORMAL.inv_cdf(0.5 + band / 2)
    ax.fill_between(m, cd - k * sd, cd + k * sd, alpha=0.3, label=f"{band:.0%} band" if honest else f"{band:.0%} CRB band")
    ax.plot(m, cd, label=label)
    ref = [r.get("reference") for r in rows]
    if all(v is not None for v in ref):
        ax.plot(m, ref, "k--", label="reference (firing table)")
    ax.set(xlabel="Mach", ylabel="Cd", title="drag coefficient")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    return ax


def plot_cd_ml_relative(rows, ax=None, label="ML", band=0.90):
    """Cd(M) of an ML fit in percent of the reference curve (of the ML curve itself without a
    reference), with its band: at a radar track's precision (Cd to ~0.1 %) the band is invisible
    on :func:`plot_cd_ml`; here it is not. Rows not determined are shaded grey.

    Parameters
    ----------
    rows : list of dict
        ``result.json`` ``cd`` rows (mach, ml, band_sd or crb_sd, determined, reference).
    ax : matplotlib Axes, optional
    band : float
        Central probability of the band (``ml`` +- z ``band_sd``).

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = new_axes(ax, (7, 3.6), MARGINS)
    m = np.array([r["mach"] for r in rows])
    cd = np.array([r["ml"] for r in rows], float)
    sd = np.array([r["band_sd"] if r.get("band_sd") is not None else r["crb_sd"] for r in rows], float)
    ref = np.array([np.nan if r.get("reference") is None else r["reference"] for r in rows], float)
    has_ref = bool(np.all(np.isfinite(ref)) and np.all(ref > 0))
    base = ref if has_ref else cd
    k = _NORMAL.inv_cdf(0.5 + band / 2)
    pct = lambda v: 100 * (np.asarray(v, float) / base - 1)  # noqa: E731
    ax.fill_between(m, pct(cd - k * sd), pct(cd + k * sd), alpha=0.3, lw=0, label=f"{band:.0%} band")
    ax.plot(m, pct(cd), label=label)
    ax.axhline(0, color="k", ls="--", lw=1, label="reference (firing table)" if has_ref else None)
    off = ~np.array([bool(r.get("determined")) for r in rows])
    if off.any():
        lo, hi = ax.get_ylim()
        ax.fill_between(m, lo, hi, where=off, color="0.85", zorder=0, lw=0, label="not determined")
        ax.set_ylim(lo, hi)
    ax.set(xlabel="Mach", ylabel="Cd vs the table [%]" if has_ref else "band around Cd [% of Cd]",
           title="drag coefficient relative to the table" if has_ref else "the band of Cd, relative")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    return ax


def plot_cd_posterior(rows, ax=None, truth=None, label="posterior", crb_band=0.90):
    """Cd(M) posterior: median, 50 % and 90 % bands, the Cramér-Rao band of the ML fit, the
    reference (firing-table) curve and the truth when known.

    Parameters
    ----------
    rows : list of dict
        ``result.json`` ``cd`` rows with the posterior part (keys mach, ml, crb_sd, q05, q25,
        q50, q75, q95, reference).
    ax : matplotlib Axes, optional
    truth : callable or (M,) array, optional
        True Cd (a drag model's ``value`` or values at the rows' Mach numbers).
    crb_band : float
        Central probability of the Gaussian CRB band drawn around the ML curve.

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = new_axes(ax, (7.5, 4.8), MARGINS)
    m = np.array([r["mach"] for r in rows])
    g = {k: np.array([r[k] for r in rows], float) for k in ("q05", "q25", "q50", "q75", "q95", "ml", "crb_sd")}
    widened = any(r.get("model_error_widening", 1.0) > 1.0 + 1e-9 for r in rows) and "sampled_q05" in rows[0]
    ax.fill_between(m, g["q05"], g["q95"], color="C0", alpha=0.22, lw=0,
                    label="90 % total band (posterior + model error)" if widened else "90 % posterior")
    ax.fill_between(m, g["q25"], g["q75"], color="C0", alpha=0.45, lw=0,
                    label="50 % total band" if widened else "50 % posterior")
    if widened:
        # the posterior as the sampler drew it, apart from the model-error widening
        for j, k in enumerate(("sampled_q05", "sampled_q95")):
            ax.plot(m, [r[k] for r in rows], color="C1", lw=0.9, ls="-.",
                    label="90 % posterior as sampled" if j == 0 else None)
    ax.plot(m, g["q50"], color="C0", lw=1.4, label=f"{label} median")
    k = _NORMAL.inv_cdf(0.5 + crb_band / 2)
    ax.plot(m, g["ml"] - k * g["crb_sd"], color="C3", ls=":", lw=1.1, label=f"{crb_band:.0%} CRB band (ML)")
    ax.plot(m, g["ml"] + k * g["crb_sd"], color="C3", ls=":", lw=1.1)
    ref = [r.get("reference") for r in rows]
    if all(v is not None for v in ref):
        ax.plot(m, ref, "k--", lw=1, label="reference (firing table)")
    if truth is not None:
        tv = truth(m) if callable(truth) else np.asarray(truth)
        ax.plot(m, tv, color="C2", lw=1.2, label="truth")
    ax.set(xlabel="Mach", ylabel="Cd", title="drag coefficient: posterior vs Cramér-Rao vs reference")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    return ax


def plot_cd_posterior_relative(rows, ax=None, truth=None, crb_band=0.90):
    """The Cd(M) posterior relative to the reference curve, in percent: 50 % and 90 % bands,
    the ML curve's CRB band, the truth when known. At a radar track's precision (Cd to
    ~0.1 %) the bands are invisible on :func:`plot_cd_posterior`; here they are not.

    Parameters
    ----------
    rows : list of dict
        ``cd`` rows with the posterior part and a non-null ``reference``.
    ax : matplotlib Axes, optional
    truth : callable or (M,) array, optional
    crb_band : float

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = new_axes(ax, (7.5, 4.2), MARGINS)
    m = np.array([r["mach"] for r in rows])
    ref = np.array([r["reference"] for r in rows], float)
    pct = lambda v: 100 * (np.asarray(v, float) / ref - 1)  # noqa: E731
    g = {k: np.array([r[k] for r in rows], float) for k in ("q05", "q25", "q50", "q75", "q95", "ml", "crb_sd")}
    ax.fill_between(m, pct(g["q05"]), pct(g["q95"]), color="C0", alpha=0.22, lw=0, label="90 % posterior")
    ax.fill_between(m, pct(g["q25"]), pct(g["q75"]), color="C0", alpha=0.45, lw=0, label="50 % posterior")
    ax.plot(m, pct(g["q50"]), color="C0", lw=1.2, label="posterior median")
    k = _NORMAL.inv_cdf(0.5 + crb_band / 2)
    ax.plot(m, pct(g["ml"] - k * g["crb_sd"]), color="C3", ls=":", lw=1.1, label=f"{crb_band:.0%} CRB band (ML)")
    ax.plot(m, pct(g["ml"] + k * g["crb_sd"]), color="C3", ls=":", lw=1.1)
    edges = [pct(g["q05"]), pct(g["q95"]), pct(g["ml"] - k * g["crb_sd"]), pct(g["ml"] + k * g["crb_sd"])]
    if all(r.get("crb_sd_colored") is not None for r in rows):
        cc = np.array([r["crb_sd_colored"] for r in rows], float)
        if np.any(cc > 1.05 * g["crb_sd"]):
            ax.plot(m, pct(g["ml"] - k * cc), color="C1", ls="-.", lw=1.1,
                    label=f"{crb_band:.0%} colored CRB band (ML, model error)")
            ax.plot(m, pct(g["ml"] + k * cc), color="C1", ls="-.", lw=1.1)
            edges += [pct(g["ml"] - k * cc), pct(g["ml"] + k * cc)]
    ax.axhline(0, color="k", ls="--", lw=1, label="reference (firing table)")
    if truth is not None:
        tv = truth(m) if callable(truth) else np.asarray(truth)
        ax.plot(m, pct(tv), color="C2", lw=1.2, label="truth")
    # limits that show every band (the narrowest would vanish under a wider one otherwise)
    lo, hi = np.nanpercentile(np.concatenate(edges), [1, 99])
    pad = 0.3 * (hi - lo) + 0.05
    ax.set_ylim(lo - pad, hi + pad)
    ax.set(xlabel="Mach", ylabel="Cd / reference − 1 [%]", title="drag coefficient relative to the reference")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    return ax


def plot_cd_relative(rows, ax=None):
    """Posterior sd of Cd over the Cramér-Rao sd against Mach (1 = the bound is attained): the
    posterior as sampled, and dashed the total band the rows report where a model-error
    widening makes it wider.

    Parameters
    ----------
    rows : list of dict
        ``cd`` rows with ``sd_over_crb`` (sampled) and ``total_sd_over_crb``.

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = new_axes(ax, (6, 3), MARGINS)
    m = np.array([r["mach"] for r in rows])
    q = np.array([np.nan if r.get("sd_over_crb") is None else r["sd_over_crb"] for r in rows])
    tot = np.array([np.nan if r.get("total_sd_over_crb") is None else r["total_sd_over_crb"] for r in rows])
    ax.axhspan(0.7, 1.5, color="0.9", label="0.7-1.5")
    ax.plot(m, q, "C0", label="posterior as sampled")
    if np.any(np.abs(tot - q) > 1e-3 * np.nan_to_num(q, nan=1.0)):
        # the model-error widening is not the sampler's: drawn as its own term
        ax.plot(m, tot, "C3", ls="--", label="total band (with the model-error widening)")
    ax.axhline(1, color="k", lw=0.6)
    ax.set(xlabel="Mach", ylabel="posterior sd / CRB sd", title="posterior width vs Cramér-Rao bound")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    return ax


def plot_windows(windows, ax=None, reference=None):
    """Scheme 2: Cd per window against its Mach number with the posterior 90 % interval (or the
    ML ±1.645 CRB sd when there is no posterior) and the reference curve.

    Parameters
    ----------
    windows : list of dict
        ``result.json`` ``windows`` rows (mach, ml, crb_sd, optional q05, q95, mean, reference).
    ax : matplotlib Axes, optional
    reference : callable, optional
        Reference Cd(M) drawn as a curve.

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = new_axes(ax, (7, 4.5), MARGINS)
    m = np.array([w["mach"] for w in windows])
    if all(w.get("q05") is not None for w in windows):
        mid = np.array([w["mean"] for w in windows])
        lo = mid - np.array([w["q05"] for w in windows])
        hi = np.array([w["q95"] for w in windows]) - mid
        lab = "window posterior mean, 90 % interval"
    else:
        mid = np.array([w["ml"] for w in windows])
        lo = hi = 1.645 * np.array([w["crb_sd"] for w in windows])
        lab = "window ML, 90 % CRB interval"
    ax.errorbar(m, mid, yerr=[lo, hi], fmt="o", ms=3, capsize=2, label=lab)
    if reference is not None:
        mm = np.linspace(m.min(), m.max(), 300)
        ax.plot(mm, reference(mm), "k--", lw=1, label="reference (firing table)")
    ax.set(xlabel="Mach", ylabel="Cd", title="Scheme 2: constant Cd per window")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    return ax


def plot_uncertainty_budget(budget, ax=None, cd=None):
    """The Cd uncertainty budget against Mach: total sd and each source's share (GUM).

    Parameters
    ----------
    budget : dict
        result.json ``uncertainty_budget`` (``mach``, ``total_sd``, ``by_source``, optional
        ``model_error_floor``).
    ax : matplotlib Axes, optional
    cd : (M,) array_like, optional
        Cd at the budget's Mach values: the sds are then drawn in percent of Cd.

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = new_axes(ax, (7.5, 4.0), MARGINS)
    m = np.asarray(budget["mach"], float)
    scale = 100.0 / np.asarray(cd, float) if cd is not None else 1.0
    unit = " [% of Cd]" if cd is not None else ""
    # on top of the sources: where one source is the whole band, the total must not hide under it
    ax.plot(m, np.asarray(budget["total_sd"]) * scale, color="k", lw=1.8, ls=(0, (5, 2)), zorder=4,
            label="total (the band the rows report)")
    for i, (k, v) in enumerate(budget["by_source"].items()):
        if k == "cross":
            continue
        ax.plot(m, np.asarray(v, float) * scale, lw=1.2, color=f"C{i}", label=k)
    if budget.get("model_error_floor"):
        ax.plot(m, np.asarray(budget["model_error_floor"], float) * scale, color="C3", ls="-.", lw=1.2,
                label="model-error floor (band)")
    ax.set_yscale("log")
    ax.set(xlabel="Mach", ylabel="sd of Cd" + unit, title="uncertainty budget of Cd")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize="small", ncol=2)
    return ax
