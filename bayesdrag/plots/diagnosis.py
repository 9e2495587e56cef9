"""Figures of a gap diagnosis (:func:`bayesdrag.diagnosis.diagnose`): residuals before and after
the explanation, the candidates' ranking and where the nominal simulation misses."""
from __future__ import annotations

import numpy as np

from .common import new_axes, new_figure

__all__ = ["plot_residuals_before_after", "plot_ranking", "plot_where", "smoothed_residual"]

#: the where-map smooths over ~1 % of the flight, at least this many samples
WHERE_MIN_WINDOW = 9


def smoothed_residual(t, resid, weights, sigma):
    """A channel's normalised residual smoothed over ~1 % of the flight (a moving mean over
    ``max(WHERE_MIN_WINDOW, N / 100)`` samples, odd, outliers out), as the where-map draws it.

    Parameters
    ----------
    t : (N,) array [s]
    resid : (N,) array
        Residual, in the channel's unit [m or m/s].
    weights : (N,) array
        0 for a sample left out.
    sigma : float
        Noise sd, in the channel's unit.

    Returns
    -------
    (N,) array
        Smoothed residual / sigma.
    """
    k = np.ones(max(WHERE_MIN_WINDOW, int(round(t.size / 100)) | 1))
    r = np.where(weights > 0, resid / sigma, 0.0)
    return np.convolve(r, k, "same") / np.maximum(np.convolve((weights > 0) * 1.0, k, "same"), 1)


def plot_residuals_before_after(d, fig=None):
    """Normalised residuals per channel: nominal simulation (left) and with the best effect or
    the detected effects' joint fit (right), the noise band (±1 sd) shaded.

    Parameters
    ----------
    d : Diagnosis
        ``t`` [s], ``resid_base`` and ``resid_best`` (N, C) [m, m/s], ``sigma``, ``weights``,
        ``channels``, ``best``.
    fig : matplotlib Figure, optional
        With C x 2 axes; default a new figure.

    Returns
    -------
    matplotlib.figure.Figure
    """
    C = len(d.channels)
    if fig is None:
        fig = new_figure((11, 1.9 * C + 0.8))
        fig.subplots(C, 2, sharex=True, sharey="row", squeeze=False)
    axes = np.array(fig.axes).reshape(C, 2)
    for j, c in enumerate(d.channels):
        w = d.weights[:, j] > 0
        axes[j, 0].plot(d.t[w], d.resid_base[w, j] / d.sigma[c], ".", ms=1.5, color="C3")
        if d.resid_best is not None:
            axes[j, 1].plot(d.t[w], d.resid_best[w, j] / d.sigma[c], ".", ms=1.5, color="C0")
        for ax in axes[j]:
            ax.axhspan(-1, 1, color="C2", alpha=0.15)
        axes[j, 0].set_ylabel(f"{c} residual / sd")
    axes[0, 0].set_title("nominal simulation")
    axes[0, 1].set_title(f"with {d.best}" if d.best else "no candidate")
    axes[-1, 0].set_xlabel("time [s]")
    axes[-1, 1].set_xlabel("time [s]")
    return fig


def plot_ranking(s, ax=None):
    """Horizontal bars of the fraction of the gap each candidate removes alone (green: verdict,
    orange: detectable but immaterial, blue: significant alone, grey: the rest).

    Parameters
    ----------
    s : dict
        The diagnosis record (``diagnosis.json``).
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib Axes
    """
    ax = new_axes(ax, (7, 0.35 * max(len(s["effects"]), 2) + 1))
    eff = s["effects"][::-1]
    names = [e["name"] for e in eff]
    vals = [e["shrink"] for e in eff]
    imm = set(s.get("immaterial") or [])
    colors = ["C2" if e["name"] in s["verdict"] else "C1" if e["name"] in imm else "C0" if e["significant"] else "0.7"
              for e in eff]
    ax.barh(names, vals, color=colors)
    # the colours in a legend, not in the title: a title that long was clipped at the right edge
    from matplotlib.patches import Patch

    keys = [("C2", "verdict"), ("C1", "detectable but immaterial"), ("C0", "significant alone"), ("0.7", "the rest")]
    ax.legend(handles=[Patch(color=c, label=lab) for c, lab in keys], loc="lower right", fontsize="small",
              framealpha=0.9)
    ax.set(xlim=(0, 1.05), xlabel="shrink (fraction of the gap removed, each fitted alone)",
           title="candidate effects, ranked")
    return ax


def plot_where(d, fig=None):
    """Where-map: the smoothed normalised residual of the nominal simulation against time
    (left) and Mach (right) per channel (:func:`smoothed_residual`), the noise band shaded.

    Parameters
    ----------
    d : Diagnosis
        ``t`` [s], ``mach``, ``resid_base`` (N, C) [m, m/s], ``sigma``, ``weights``, ``channels``.
    fig : matplotlib Figure, optional
        With at least two axes; default a new figure.

    Returns
    -------
    matplotlib.figure.Figure
    """
    if fig is None:
        fig = new_figure((10, 3.6))
        fig.subplots(1, 2)
    ax_t, ax_m = fig.axes[:2]
    for j, c in enumerate(d.channels):
        sm = smoothed_residual(d.t, d.resid_base[:, j], d.weights[:, j], d.sigma[c])
        ax_t.plot(d.t, sm, label=c)
        ax_m.plot(d.mach, sm, label=c)
    for ax in (ax_t, ax_m):
        ax.axhspan(-1, 1, color="C2", alpha=0.15)
        ax.grid(alpha=0.3)
    ax_t.set(xlabel="time [s]", ylabel="smoothed residual / sd", title="nominal misfit along time")
    ax_m.set(xlabel="Mach", title="... and along Mach")
    ax_t.legend(fontsize="small")
    return fig
