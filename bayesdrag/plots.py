"""Figures. Every function takes ``ax=`` (or ``fig=``) and returns what it drew on, so it can
be composed into reports or a user's own figures. No physics here."""
from __future__ import annotations

import numpy as np


def _plt():
    import matplotlib

    if matplotlib.get_backend().lower() not in ("agg", "pdf", "svg", "module://matplotlib_inline.backend_inline"):
        try:
            import matplotlib.pyplot as plt  # noqa: F401
        except Exception:  # pragma: no cover - headless without a GUI toolkit
            matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _axes(ax, figsize):
    """The given Axes, or one on a new constrained-layout figure of ``figsize``."""
    if ax is None:
        _, ax = _plt().subplots(figsize=figsize, layout="constrained")
    return ax


def _unit(channel):
    return "m/s" if channel == "v" else "m"


def plot_track(track, fig=None, label=None, style="-"):
    """Four panels of a radar track: height vs range, drift vs range, speed vs time, and
    height vs time.

    Parameters
    ----------
    track : RadarTrack
    fig : matplotlib Figure, optional
        A figure with 4 axes made by an earlier call (to overlay tracks), or None.
    label : str, optional
    style : str
        Matplotlib line style.

    Returns
    -------
    matplotlib.figure.Figure
    """
    plt = _plt()
    if fig is None:
        fig, axes = plt.subplots(2, 2, figsize=(10, 6.5), layout="constrained")
    axes = np.array(fig.axes).reshape(2, 2)
    t = track.t
    if track.x is not None and track.z is not None:
        axes[0, 0].plot(track.x / 1000, track.z, style, label=label)
    axes[0, 0].set(xlabel="range x [km]", ylabel="height z [m]", title="trajectory")
    if track.x is not None and track.y is not None:
        axes[0, 1].plot(track.x / 1000, track.y, style, label=label)
    axes[0, 1].set(xlabel="range x [km]", ylabel="drift y [m] (+ right)", title="drift")
    if track.v is not None:
        axes[1, 0].plot(t, track.v, style, label=label)
    axes[1, 0].set(xlabel="time [s]", ylabel="speed v [m/s]", title="speed")
    if track.z is not None:
        axes[1, 1].plot(t, track.z, style, label=label)
    axes[1, 1].set(xlabel="time [s]", ylabel="height z [m]", title="height")
    if label:
        for ax in axes.ravel():
            if ax.lines:
                ax.legend(fontsize="small")
    for ax in axes.ravel():
        ax.grid(alpha=0.3)
    return fig


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
    ax = _axes(ax, (6, 4))
    ax.plot(mach, cd, label=label, **kw)
    ax.set(xlabel="Mach number", ylabel="drag coefficient Cd")
    ax.grid(alpha=0.3)
    if label:
        ax.legend(fontsize="small")
    return ax


def plot_differences(t, diffs, ax=None, title="6-DOF minus point mass"):
    """Differences between two tracks per channel against time.

    Parameters
    ----------
    t : (N,) s
    diffs : dict channel -> (N,) array (m or m/s)
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = _axes(ax, (7, 4))
    for name, d in diffs.items():
        ax.plot(t, d, label=f"{name} [{_unit(name)}]")
    ax.axhline(0, color="k", lw=0.5)
    ax.set(xlabel="time [s]", ylabel="difference", title=title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    return ax


def plot_cd_ml(rows, ax=None, label="ML", band=0.90):
    """Cd(M) from an ML fit with its Cramér-Rao band and the reference curve.

    Parameters
    ----------
    rows : list of dict
        ``result.json`` ``cd`` rows (keys mach, ml, crb_sd, reference).
    ax : matplotlib Axes, optional
    band : float
        Central probability of the Gaussian CRB band.

    Returns
    -------
    matplotlib.axes.Axes
    """
    from scipy.stats import norm

    ax = _axes(ax, (7, 4.5))
    m = np.array([r["mach"] for r in rows])
    cd = np.array([r["ml"] for r in rows])
    sd = np.array([r["crb_sd"] for r in rows])
    k = norm.ppf(0.5 + band / 2)
    ax.fill_between(m, cd - k * sd, cd + k * sd, alpha=0.3, label=f"{band:.0%} CRB band")
    ax.plot(m, cd, label=label)
    ref = [r.get("reference") for r in rows]
    if all(v is not None for v in ref):
        ax.plot(m, ref, "k--", label="reference (firing table)")
    ax.set(xlabel="Mach", ylabel="Cd", title="drag coefficient")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    return ax


def plot_residuals(t, residuals, sigma, fig=None):
    """Residuals (measured minus fitted) per channel with ±σ bands.

    Parameters
    ----------
    t : (N,) s
    residuals : dict channel -> (N,)
    sigma : dict channel -> float
    fig : matplotlib Figure, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    plt = _plt()
    chans = list(residuals)
    if fig is None:
        fig, axes = plt.subplots(len(chans), 1, figsize=(8, 2.2 * len(chans)), sharex=True,
                                 layout="constrained", squeeze=False)
    axes = np.array(fig.axes).reshape(-1)
    for ax, c in zip(axes, chans):
        s = sigma[c]
        ax.axhspan(-s, s, color="0.85", label="±σ")
        ax.plot(t, residuals[c], ".", ms=2)
        ax.set_ylabel(f"{c} [{_unit(c)}]")
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    axes[0].set_title("residuals: measured minus fitted")
    return fig


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
    from scipy.stats import norm

    ax = _axes(ax, (7.5, 4.8))
    m = np.array([r["mach"] for r in rows])
    g = {k: np.array([r[k] for r in rows], float) for k in ("q05", "q25", "q50", "q75", "q95", "ml", "crb_sd")}
    ax.fill_between(m, g["q05"], g["q95"], color="C0", alpha=0.22, lw=0, label="90 % posterior")
    ax.fill_between(m, g["q25"], g["q75"], color="C0", alpha=0.45, lw=0, label="50 % posterior")
    ax.plot(m, g["q50"], color="C0", lw=1.4, label=f"{label} median")
    k = norm.ppf(0.5 + crb_band / 2)
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
    from scipy.stats import norm

    ax = _axes(ax, (7.5, 4.2))
    m = np.array([r["mach"] for r in rows])
    ref = np.array([r["reference"] for r in rows], float)
    pct = lambda v: 100 * (np.asarray(v, float) / ref - 1)  # noqa: E731
    g = {k: np.array([r[k] for r in rows], float) for k in ("q05", "q25", "q50", "q75", "q95", "ml", "crb_sd")}
    ax.fill_between(m, pct(g["q05"]), pct(g["q95"]), color="C0", alpha=0.22, lw=0, label="90 % posterior")
    ax.fill_between(m, pct(g["q25"]), pct(g["q75"]), color="C0", alpha=0.45, lw=0, label="50 % posterior")
    ax.plot(m, pct(g["q50"]), color="C0", lw=1.2, label="posterior median")
    k = norm.ppf(0.5 + crb_band / 2)
    ax.plot(m, pct(g["ml"] - k * g["crb_sd"]), color="C3", ls=":", lw=1.1, label=f"{crb_band:.0%} CRB band (ML)")
    ax.plot(m, pct(g["ml"] + k * g["crb_sd"]), color="C3", ls=":", lw=1.1)
    ax.axhline(0, color="k", ls="--", lw=1, label="reference (firing table)")
    if truth is not None:
        tv = truth(m) if callable(truth) else np.asarray(truth)
        ax.plot(m, pct(tv), color="C2", lw=1.2, label="truth")
    lo, hi = np.nanpercentile(np.concatenate([pct(g["q05"]), pct(g["q95"])]), [2, 98])
    pad = 0.3 * (hi - lo) + 0.05
    ax.set_ylim(lo - pad, hi + pad)
    ax.set(xlabel="Mach", ylabel="Cd / reference − 1 [%]", title="drag coefficient relative to the reference")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    return ax


def plot_cd_relative(rows, ax=None):
    """Posterior sd of Cd over the Cramér-Rao sd against Mach (1 = the bound is attained).

    Parameters
    ----------
    rows : list of dict
        ``cd`` rows with ``sd_over_crb``.

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = _axes(ax, (6, 3))
    m = np.array([r["mach"] for r in rows])
    q = np.array([np.nan if r.get("sd_over_crb") is None else r["sd_over_crb"] for r in rows])
    ax.axhspan(0.7, 1.5, color="0.9", label="0.7-1.5")
    ax.plot(m, q, "C0")
    ax.axhline(1, color="k", lw=0.6)
    ax.set(xlabel="Mach", ylabel="posterior sd / CRB sd", title="posterior width vs Cramér-Rao bound")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    return ax


def plot_corner(samples, truths=None, fig=None):
    """Corner plot (``corner``) of selected quantities.

    Parameters
    ----------
    samples : dict name -> (S,) array
        Posterior draws (flattened over chains).
    truths : dict name -> float, optional
    fig : matplotlib Figure, optional
        Passed to ``corner.corner``.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import corner

    _plt()
    names = list(samples)
    X = np.column_stack([np.asarray(samples[n], float) for n in names])
    tv = None if truths is None else [truths.get(n) for n in names]
    return corner.corner(X, labels=names, truths=tv, fig=fig, quantiles=(0.05, 0.5, 0.95),
                         show_titles=True, title_fmt=".4g", title_kwargs={"fontsize": 8},
                         label_kwargs={"fontsize": 8})


def plot_traces(chains, fig=None, max_walkers=32):
    """Traces of selected parameters, one thin line per walker.

    Parameters
    ----------
    chains : dict name -> (steps, walkers) array
        Full chains (burn-in included) as stored by emcee.
    fig : matplotlib Figure, optional
    max_walkers : int

    Returns
    -------
    matplotlib.figure.Figure
    """
    plt = _plt()
    names = list(chains)
    if fig is None:
        fig, _ = plt.subplots(len(names), 1, figsize=(8, 1.5 * len(names) + 0.6), sharex=True,
                              layout="constrained", squeeze=False)
    axes = np.array(fig.axes).reshape(-1)
    for ax, n in zip(axes, names):
        c = np.asarray(chains[n])
        ax.plot(c[:, :max_walkers], lw=0.4, alpha=0.6)
        ax.set_ylabel(n, fontsize="small")
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("step")
    axes[0].set_title("traces (one line per walker)")
    return fig


def residual_acf(r, max_lag):
    """Sample autocorrelation of residuals ``r`` (N,) at lags 0..max_lag."""
    e = np.asarray(r, float) - np.mean(r)
    n = e.size
    c = np.correlate(e, e, mode="full")[n - 1:n + max_lag] / n
    return c / c[0] if c[0] > 0 else c


def plot_residuals_acf(t, residuals, sigma, fig=None, max_lag=60):
    """Residuals per channel with ±σ bands (left) and their autocorrelation with the ±2/√N
    white-noise band (right).

    Parameters
    ----------
    t : (N,) s
    residuals : dict channel -> (N,)
    sigma : dict channel -> float (posterior or ML noise sd)
    fig : matplotlib Figure, optional
    max_lag : int

    Returns
    -------
    matplotlib.figure.Figure
    """
    plt = _plt()
    chans = list(residuals)
    if fig is None:
        fig, _ = plt.subplots(len(chans), 2, figsize=(10, 2.1 * len(chans) + 0.5), layout="constrained",
                              squeeze=False, gridspec_kw={"width_ratios": [3, 1.3]})
    axes = np.array(fig.axes).reshape(-1, 2)
    n = len(t)
    for (a, b), c in zip(axes, chans):
        s = sigma[c]
        a.axhspan(-s, s, color="0.85")
        a.plot(t, residuals[c], ".", ms=2)
        a.set_ylabel(f"{c} [{_unit(c)}]")
        a.grid(alpha=0.3)
        lag = min(max_lag, n - 1)
        b.bar(np.arange(lag + 1), residual_acf(residuals[c], lag), width=0.8)
        b.axhspan(-2 / np.sqrt(n), 2 / np.sqrt(n), color="C1", alpha=0.3)
        b.set_ylim(-0.5, 1.05)
        b.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time [s]")
    axes[-1, 1].set_xlabel("lag [samples]")
    axes[0, 0].set_title("residuals (measured − posterior-mean trajectory), ±σ")
    axes[0, 1].set_title("autocorrelation")
    return fig


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
    ax = _axes(ax, (7, 4.5))
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
