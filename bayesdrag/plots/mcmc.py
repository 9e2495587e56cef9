"""Figures of a sampling run: corner plot of chosen quantities and walker traces."""
from __future__ import annotations

import numpy as np

from .common import new_figure

__all__ = ['plot_corner', 'plot_traces']


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

    names = list(samples)
    X = np.column_stack([np.asarray(samples[n], float) for n in names])
    tv = None if truths is None else [truths.get(n) for n in names]
    if fig is None:
        # corner's own figure size for K quantities, on a Figure outside pyplot
        K = len(names)
        dim = 1.0 + 2.0 * K + 2.0 * (K - 1) * 0.05 + 0.4
        fig = new_figure((dim, dim), layout=None)
        fig.subplots(K, K)
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
    names = list(chains)
    if fig is None:
        fig = new_figure((8, 1.5 * len(names) + 0.6))
        fig.subplots(len(names), 1, sharex=True, squeeze=False)
    axes = np.array(fig.axes).reshape(-1)
    for ax, n in zip(axes, names):
        c = np.asarray(chains[n])
        ax.plot(c[:, :max_walkers], lw=0.4, alpha=0.6)
        ax.set_ylabel(n, fontsize="small")
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("step")
    axes[0].set_title("traces (one line per walker)")
    return fig
