"""Figures of fit residuals and their autocorrelation."""
from __future__ import annotations

import numpy as np

from .common import Margins, channel_scale, channel_unit, fixed_figure

__all__ = ['plot_residuals', 'residual_acf', 'plot_residuals_acf']

#: fixed layouts [inch]: panels stacked on a shared time axis (no tick labels between them)
RESIDUAL_MARGINS = Margins(hgap=0.15)
#: residuals beside their autocorrelation: tick labels between rows and columns
ACF_MARGINS = Margins(hgap=0.35, wgap=0.75)


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
    chans = list(residuals)
    if fig is None:
        fig = fixed_figure((8, 2.2 * len(chans)), len(chans), 1, RESIDUAL_MARGINS, sharex=True, squeeze=False)
    axes = np.array(fig.axes).reshape(-1)
    for ax, c in zip(axes, chans):
        k = channel_scale(c)[0]           # the radar's angles in degrees
        s = k * sigma[c]
        ax.axhspan(-s, s, color="0.85", label="±σ")
        ax.plot(t, k * np.asarray(residuals[c]), ".", ms=2)
        ax.set_ylabel(f"{c} [{channel_unit(c)}]")
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    axes[0].set_title("residuals: measured minus fitted")
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
    chans = list(residuals)
    if fig is None:
        fig = fixed_figure((10, 2.1 * len(chans) + 0.5), len(chans), 2, ACF_MARGINS, width_ratios=[3, 1.3],
                           squeeze=False)
    axes = np.array(fig.axes).reshape(-1, 2)
    n = len(t)
    for (a, b), c in zip(axes, chans):
        k = channel_scale(c)[0]           # the radar's angles in degrees
        s = k * sigma[c]
        a.axhspan(-s, s, color="0.85")
        a.plot(t, k * np.asarray(residuals[c]), ".", ms=2)
        a.set_ylabel(f"{c} [{channel_unit(c)}]")
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
