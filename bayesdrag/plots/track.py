"""Figures of radar tracks: the trajectory, drift, speed and height; differences between two tracks."""
from __future__ import annotations

import numpy as np

from .common import MARGINS, Margins, channel_scale, channel_unit, fixed_figure, new_axes

__all__ = ['plot_track', 'plot_differences']

#: fixed layout of the 2 x 2 track figure [inch]: room above for a figure title (``suptitle``)
TRACK_MARGINS = Margins(top=0.6, hgap=0.75)


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
    if fig is None:
        fig = fixed_figure((10, 6.5), 2, 2, TRACK_MARGINS)
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
    ax = new_axes(ax, (7, 4), MARGINS)
    for name, d in diffs.items():
        ax.plot(t, channel_scale(name)[0] * np.asarray(d), label=f"{name} [{channel_unit(name)}]")
    ax.axhline(0, color="k", lw=0.5)
    ax.set(xlabel="time [s]", ylabel="difference", title=title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    return ax
