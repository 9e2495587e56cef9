"""Figures of a chronograph session: its Cd(M) with the shots' own levels, and one shot's
residuals."""
from __future__ import annotations

import numpy as np

from .common import new_axes, new_figure

__all__ = ["plot_session_cd", "plot_shot_residuals"]


def plot_session_cd(record, ax=None):
    """The session's Cd rows with their 90 % band (Student t), the reference, the central row, and
    each shot's own drag level placed at its mean Mach.

    Parameters
    ----------
    record : dict
        The session's ``campaign.json`` record.
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib Axes
    """
    ax = new_axes(ax, (7.0, 4.2))
    rows = record["cd"]
    if not rows:
        ax.text(0.5, 0.5, "no physical Cd (campaign.json warnings)", ha="center", transform=ax.transAxes)
        return ax
    m = np.array([r["mach"] for r in rows])
    mean = np.array([r["mean"] for r in rows])
    ax.fill_between(m, [r["q05"] for r in rows], [r["q95"] for r in rows], color="C0", alpha=0.25,
                    label="90 % band (t, shots' dof)")
    ax.plot(m, mean, color="C0", lw=1.8, label="session Cd(M)")
    det = np.array([r["determined"] for r in rows])
    if det.any():
        ax.plot(m[det], mean[det], ".", color="C0", ms=4, label="determined rows (band ≤ 1 %)")
    ref = [r["reference"] for r in rows]
    if all(v is not None for v in ref):
        ax.plot(m, ref, "--", color="0.4", lw=1, label=f"reference ({record.get('reference', '')})")
    c = record["central"]
    ax.errorbar([c["mach"]], [c["mean"]], yerr=[[c["mean"] - c["q05"]], [c["q95"] - c["mean"]]], fmt="o",
                color="C3", capsize=3, label="central row (90 %)")
    shots = [s for s in record["shots"] if not s["skipped"] and s.get("mach_mean")]
    if shots:
        mm = np.array([s["mach_mean"] for s in shots])
        lv = np.array([s["drag_level"] for s in shots])
        ax.plot(mm, np.interp(mm, m, mean) * lv, "x", color="C1", ms=5, label="each shot's own level")
    ax.set_xlabel("Mach")
    ax.set_ylabel("Cd")
    ax.legend(fontsize=8, loc="best")
    ax.set_title(f"{record['name']}: {len(record['rounds'])} shots, one Cd(M)", fontsize=10)
    return ax


def plot_shot_residuals(t, residual, keep, noise_sd, name="", fig=None):
    """One shot's residuals (reported minus the session model) against time, outliers marked.

    Parameters
    ----------
    t, residual : ndarray, s and m/s
    keep : ndarray of bool
        False at the outliers left out of the fit.
    noise_sd : float or ndarray, m/s
        The noise sd (per sample when it follows the echo's SNR).

    Returns
    -------
    matplotlib Figure
    """
    fig = fig or new_figure((6.0, 2.8))
    ax = fig.add_subplot(1, 1, 1)
    sd = np.broadcast_to(np.asarray(noise_sd, float), t.shape)
    ax.fill_between(t * 1e3, -2 * sd, 2 * sd, color="0.9", label="±2 noise sd")
    ax.plot(t[keep] * 1e3, residual[keep], ".", ms=3, color="C0", label="samples fitted")
    if (~keep).any():
        ax.plot(t[~keep] * 1e3, residual[~keep], "x", color="C3", ms=5, label="outliers (left out)")
    ax.axhline(0.0, color="0.3", lw=0.8)
    ax.set_xlabel("time [ms]")
    ax.set_ylabel("reported − model [m/s]")
    ax.set_title(f"{name}: residuals of the session fit", fontsize=10)
    ax.legend(fontsize=7, loc="best")
    return fig
