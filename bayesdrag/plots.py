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
