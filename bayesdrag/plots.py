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
    plt = _plt()
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 4), layout="constrained")
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
    plt = _plt()
    if ax is None:
        _, ax = plt.subplots(figsize=(7, 4), layout="constrained")
    for name, d in diffs.items():
        unit = "m/s" if name == "v" else "m"
        ax.plot(t, d, label=f"{name} [{unit}]")
    ax.axhline(0, color="k", lw=0.5)
    ax.set(xlabel="time [s]", ylabel="difference", title=title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    return ax
