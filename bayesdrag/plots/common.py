"""What every figure function shares: a new Figure without pyplot (no global state, no
backend to choose: the figures are saved to files or embedded in reports), its layout and the
units of the track's channels. Every plot function of :mod:`bayesdrag.plots` takes ``ax=`` (or
``fig=``) and returns what it drew on, so it can be composed into a user's own figures.

The report's figures use a *fixed* layout (:func:`fixed_figure`): margins and gaps in inches,
set once when the axes are made. Constrained layout solved the margins again at every draw
from every tick label's extent, which was half of a figure's saving time (figures in
docs/report.md, "Speed"); the report's figures have known labels, so fixed margins fit them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from matplotlib.figure import Figure

__all__ = ["new_figure", "new_axes", "fixed_figure", "Margins", "MARGINS", "channel_unit", "channel_scale"]


@dataclass(frozen=True)
class Margins:
    """A fixed layout's margins around the grid of axes and the gaps between them [inch]:
    room for the tick labels and axis labels (left, bottom), titles (top) and the next
    panel's labels (``wgap``, ``hgap``)."""

    left: float = 0.85
    right: float = 0.2
    bottom: float = 0.55
    top: float = 0.35
    wgap: float = 0.85
    hgap: float = 0.6


#: margins of a figure with tick labels, axis labels and a title on every panel
MARGINS = Margins()


def new_figure(figsize, layout="constrained"):
    """A matplotlib Figure of ``figsize`` [inch] that belongs to no pyplot state."""
    return Figure(figsize=figsize, layout=layout)


def fixed_figure(figsize, nrows=1, ncols=1, margins=MARGINS, width_ratios=None, **subplots_kw):
    """A Figure of ``figsize`` [inch] outside pyplot with an ``nrows`` x ``ncols`` grid of axes
    laid out once with fixed ``margins`` (:class:`Margins`, inches): nothing is solved when it
    is drawn. ``subplots_kw`` go to :meth:`matplotlib.figure.Figure.subplots`. Returns the
    Figure (its axes in ``fig.axes``, row by row)."""
    w, h = figsize
    m = margins
    grid_w = w - m.left - m.right
    grid_h = h - m.bottom - m.top
    cell_w = (grid_w - (ncols - 1) * m.wgap) / ncols
    cell_h = (grid_h - (nrows - 1) * m.hgap) / nrows
    if cell_w <= 0 or cell_h <= 0:
        raise ValueError(f"figure {w} x {h} in is too small for {nrows} x {ncols} axes with margins {m}")
    grid = {"left": m.left / w, "right": 1 - m.right / w, "bottom": m.bottom / h, "top": 1 - m.top / h,
            "wspace": m.wgap / cell_w, "hspace": m.hgap / cell_h}
    if width_ratios is not None:
        grid["width_ratios"] = width_ratios
    fig = Figure(figsize=figsize, layout=None)
    fig.subplots(nrows, ncols, gridspec_kw=grid, **subplots_kw)
    return fig


def new_axes(ax, figsize, margins=None):
    """The given Axes, or one on a new figure of ``figsize``: with fixed ``margins``
    (:func:`fixed_figure`) when given, else constrained layout."""
    if ax is None:
        if margins is not None:
            return fixed_figure(figsize, margins=margins).axes[0]
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
