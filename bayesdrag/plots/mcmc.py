"""Figures of a sampling run: corner plot of chosen quantities and walker traces."""
from __future__ import annotations

import contextlib
import logging
import os
import warnings

import numpy as np

from .common import Margins, fixed_figure, new_figure

__all__ = ['plot_corner', 'plot_traces']

#: fixed layout of the traces [inch]: panels stacked on a shared step axis
TRACE_MARGINS = Margins(hgap=0.15)


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
    from matplotlib.ticker import MaxNLocator, NullFormatter, ScalarFormatter

    names = list(samples)
    X = np.column_stack([np.asarray(samples[n], float) for n in names])
    tv = None if truths is None else [truths.get(n) for n in names]
    if fig is None:
        # corner's own figure size for K quantities, on a Figure outside pyplot
        K = len(names)
        dim = 1.0 + 2.0 * K + 2.0 * (K - 1) * 0.05 + 0.4
        fig = new_figure((dim, dim), layout=None)
        fig.subplots(K, K)
    with _quiet_corner():
        fig = corner.corner(X, labels=[_label(n) for n in names], truths=tv, fig=fig, quantiles=(0.05, 0.5, 0.95),
                            show_titles=False, label_kwargs={"fontsize": CORNER_LABEL_PT}, max_n_ticks=3,
                            labelpad=0.15)
    K = len(names)
    axes = np.array(fig.axes).reshape(K, K)
    for i in range(K):   # no "+2.126e2" offsets, no tick labels touching the next panel
        for j in range(i + 1):
            ax = axes[i, j]
            ax.tick_params(labelsize=CORNER_TICK_PT)
            axis_list = [(ax.xaxis, i == K - 1)] + ([(ax.yaxis, j == 0)] if j < i else [])
            for axis, labelled in axis_list:
                axis.set_major_locator(MaxNLocator(3, prune="both"))
                axis.set_major_formatter(ScalarFormatter(useOffset=False) if labelled else NullFormatter())
    for i in range(K):   # a short title per quantity: median and sd (the label says which)
        med, sd = np.median(X[:, i]), np.std(X[:, i])
        axes[i, i].set_title(f"{med:.5g} ± {sd:.2g}", fontsize=CORNER_TITLE_PT)
    fig.subplots_adjust(left=0.1, bottom=0.1, right=0.98, top=0.96, wspace=0.06, hspace=0.06)
    return fig


class _CornerRecords(logging.Filter):
    """Drops the log records corner itself makes (its module's file lies in corner's package)."""

    def __init__(self, folder):
        super().__init__()
        self.folder = folder

    def filter(self, record):
        return not str(record.pathname).startswith(self.folder)


@contextlib.contextmanager
def _quiet_corner():
    """Silence what corner says while it draws: it logs "Too few points to create valid contours"
    through the root logger (``logging.warning``, which also installs a stderr handler on a
    logger without one) when a quantity's draws are few or nearly constant, as on a short or
    resumed chain; the figure is drawn all the same, and a run with ``-q`` must stay quiet. The
    root logger gets a filter for corner's records and, while it has no handler, a null one;
    matplotlib's contour warnings are ignored for the call."""
    import corner

    root = logging.getLogger()
    quiet = _CornerRecords(os.path.dirname(os.path.abspath(corner.__file__)))
    null = logging.NullHandler() if not root.handlers else None
    root.addFilter(quiet)
    if null is not None:
        root.addHandler(null)
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=".*contour.*", category=UserWarning)
            yield
    finally:
        root.removeFilter(quiet)
        if null is not None:
            root.removeHandler(null)


#: font sizes of the corner plot [pt]: a K = 8 plot is ~18 in wide and shown ~9 in wide in the
#: report, so its text is drawn at twice the size it should be read at (8 pt was unreadable)
CORNER_LABEL_PT, CORNER_TITLE_PT, CORNER_TICK_PT = 18, 14, 12
#: units of the initial-state parameters, shown in the corner plot's labels
_UNITS = {"X0": "m", "Y0": "m", "Z0": "m", "Ux0": "m/s", "Uy0": "m/s", "Uz0": "m/s"}


def _label(name):
    """A corner-plot axis label: the quantity and its unit."""
    return f"{name} [{_UNITS[name]}]" if name in _UNITS else name


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
    names = list(chains)
    if fig is None:
        fig = fixed_figure((8, 1.5 * len(names) + 0.6), len(names), 1, TRACE_MARGINS, sharex=True, squeeze=False)
    axes = np.array(fig.axes).reshape(-1)
    for ax, n in zip(axes, names):
        c = np.asarray(chains[n])[:, :max_walkers]
        _walker_lines(ax, c)
        ax.set_ylabel(n, fontsize="small")
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("step")
    axes[0].set_title("traces (one line per walker)")
    return fig


def _walker_lines(ax, c):
    """One thin line per walker of ``c`` (steps, walkers), in the colour cycle's order, as one
    LineCollection: the look of one ``plot`` line per walker with one artist per panel."""
    from matplotlib.collections import LineCollection

    steps = np.arange(c.shape[0], dtype=float)
    segs = np.stack([np.broadcast_to(steps, c.T.shape), c.T], axis=-1)    # (walkers, steps, 2)
    colors = [f"C{k % 10}" for k in range(c.shape[1])]
    ax.add_collection(LineCollection(segs, colors=colors, linewidths=0.4, alpha=0.6))
    ax.autoscale_view()
