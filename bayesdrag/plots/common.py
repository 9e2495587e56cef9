"""What every figure function shares: a new Figure without pyplot (no global state, no
backend to choose: the figures are saved to files or embedded in reports) and the units of the
track's channels. Every plot function of :mod:`bayesdrag.plots` takes ``ax=`` (or ``fig=``) and
returns what it drew on, so it can be composed into a user's own figures."""
from __future__ import annotations

import math

from matplotlib.figure import Figure

__all__ = ["new_figure", "new_axes", "channel_unit", "channel_scale"]


def new_figure(figsize, layout="constrained"):
    """A matplotlib Figure of ``figsize`` [inch] that belongs to no pyplot state."""
    return Figure(figsize=figsize, layout=layout)


def new_axes(ax, figsize):
    """The given Axes, or one on a new constrained-layout figure of ``figsize``."""
    if ax is None:
        ax = new_figure(figsize).add_subplot()
    return ax


def channel_unit(channel):
    """Unit a figure shows a track channel in: m for x, y, z, range; m/s for v, range_rate;
    deg for the angles (radians inside the code, :func:`channel_scale`)."""
    return channel_scale(channel)[1]


def channel_scale(channel):
    """``(factor, unit)``: a channel's values inside the code times ``factor`` are in ``unit``,
    the unit figures show (degrees for the radar's angles)."""
    if channel in ("azimuth", "elevation"):
        return 180.0 / math.pi, "deg"
    return 1.0, ("m/s" if channel in ("v", "range_rate") else "m")
