"""What every figure function shares: a new Figure without pyplot (no global state, no
backend to choose: the figures are saved to files or embedded in reports) and the units of the
track's channels. Every plot function of :mod:`bayesdrag.plots` takes ``ax=`` (or ``fig=``) and
returns what it drew on, so it can be composed into a user's own figures."""
from __future__ import annotations

from matplotlib.figure import Figure

__all__ = ["new_figure", "new_axes", "channel_unit"]


def new_figure(figsize, layout="constrained"):
    """A matplotlib Figure of ``figsize`` [inch] that belongs to no pyplot state."""
    return Figure(figsize=figsize, layout=layout)


def new_axes(ax, figsize):
    """The given Axes, or one on a new constrained-layout figure of ``figsize``."""
    if ax is None:
        ax = new_figure(figsize).add_subplot()
    return ax


def channel_unit(channel):
    """Unit of a track channel: m for x, y, z; m/s for v."""
    return "m/s" if channel == "v" else "m"
