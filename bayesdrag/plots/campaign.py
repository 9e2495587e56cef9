"""Figures of a campaign: every round's Cd(M) and the pooled band, rounds relative to the
campaign, the round-to-round scatter posterior and each round's offset."""
from __future__ import annotations

import matplotlib
import numpy as np

from ..campaign.pooling import BAND
from .common import new_axes

__all__ = ['plot_campaign_overlay', 'plot_campaign_relative', 'plot_scatter_posterior', 'plot_deltas']

#: size of a campaign figure [inch]
CAMPAIGN_FIGSIZE = (8, 4.6)


def plot_campaign_overlay(inputs, pooled, ax=None, truth=None):
    """Every round's Cd(M) with its 90 % Cramér-Rao band (the paper's Fig. 4 overlay), the
    pooled campaign band and the reference.

    Parameters
    ----------
    inputs : list of dict
        :func:`bayesdrag.campaign.pooling_input` per round.
    pooled : PooledResult
    ax : matplotlib Axes, optional
    truth : callable Mach -> Cd, optional
        Campaign truth (simulations) drawn as a black line.
    """
    ax = new_axes(ax, CAMPAIGN_FIGSIZE)
    z = 1.6448536
    cmap = matplotlib.colormaps["tab10"]
    for i, r in enumerate(inputs):
        m, cd, sd = np.asarray(r["mach"]), np.asarray(r["cd"]), np.sqrt(np.clip(np.diag(np.asarray(r["cov"])), 0, None))
        c = cmap(i % 10)
        ax.plot(m, cd, color=c, lw=1.0, label=r["name"])
        ax.fill_between(m, cd - z * sd, cd + z * sd, color=c, alpha=0.12, lw=0)
    q = np.quantile(pooled.cd_draws, BAND, axis=0)
    ax.fill_between(pooled.mach, q[0], q[1], color="k", alpha=0.25, lw=0, label="campaign 90 % band")
    ax.plot(pooled.mach, np.median(pooled.cd_draws, axis=0), color="k", lw=1.8, label="campaign median")
    if pooled.reference is not None:
        ok = np.isfinite(pooled.reference)
        ax.plot(pooled.mach[ok], pooled.reference[ok], "k--", lw=1.0, label="reference")
    if truth is not None:
        ax.plot(pooled.mach, truth(pooled.mach), color="tab:red", lw=1.0, ls=":", label="campaign truth")
    ax.set(xlabel="Mach", ylabel="Cd", title="Cd(M): every round and the campaign")
    ax.legend(fontsize="x-small", ncol=2)
    return ax


def plot_campaign_relative(inputs, pooled, ax=None, truth=None):
    """Each round's Cd relative to the campaign median [%]: a round that differs by a constant
    factor is a flat line (the model's delta_r); the pooled 90 % band around 0."""
    ax = new_axes(ax, CAMPAIGN_FIGSIZE)
    med = np.median(pooled.cd_draws, axis=0)
    idx_of = {round(float(m), 6): i for i, m in enumerate(pooled.mach)}
    cmap = matplotlib.colormaps["tab10"]
    for i, r in enumerate(inputs):
        m = np.asarray(r["mach"])
        j = np.array([idx_of[round(float(v), 6)] for v in m])
        ax.plot(m, 100 * (np.asarray(r["cd"]) / med[j] - 1), color=cmap(i % 10), lw=1.0, label=r["name"])
    q = np.quantile(pooled.cd_draws / med, BAND, axis=0)
    ax.fill_between(pooled.mach, 100 * (q[0] - 1), 100 * (q[1] - 1), color="k", alpha=0.25, lw=0,
                    label="campaign 90 % band")
    if truth is not None:
        ax.plot(pooled.mach, 100 * (truth(pooled.mach) / med - 1), color="tab:red", ls=":", label="campaign truth")
    ax.axhline(0, color="k", lw=0.6)
    ax.set(xlabel="Mach", ylabel="Cd / campaign median - 1 [%]", title="Round-to-round differences")
    ax.legend(fontsize="x-small", ncol=2)
    return ax


def plot_scatter_posterior(pooled, ax=None, truth=None):
    """Posterior of the round-to-round relative sd of Cd [%] with its 90 % interval."""
    ax = new_axes(ax, (6, 3.6))
    s = 100 * pooled.scatter_draws
    ax.hist(s, bins=60, density=True, color="0.6")
    for v in np.quantile(s, BAND):
        ax.axvline(v, color="k", ls="--", lw=1)
    if truth is not None:
        ax.axvline(100 * truth, color="tab:red", lw=1.5, label=f"truth {100 * truth:.2g} %")
        ax.legend(fontsize="small")
    ax.set(xlabel="round-to-round sd of Cd [%]", ylabel="density", title="Scatter posterior (90 % interval dashed)")
    return ax


def plot_deltas(pooled, ax=None, truth=None):
    """Each round's relative offset delta_r [%] (posterior median and 90 % interval)."""
    ax = new_axes(ax, (6, 0.4 * len(pooled.names) + 1.4))
    d = 100 * pooled.delta_draws
    q = np.quantile(d, [BAND[0], 0.5, BAND[1]], axis=0)
    y = np.arange(len(pooled.names))[::-1]
    ax.errorbar(q[1], y, xerr=[q[1] - q[0], q[2] - q[1]], fmt="o", color="k", capsize=3, label="posterior")
    if truth is not None:
        ax.plot(100 * np.asarray(truth), y, "x", color="tab:red", label="truth")
        ax.legend(fontsize="small")
    ax.set_yticks(y, pooled.names)
    ax.axvline(0, color="k", lw=0.6)
    ax.set(xlabel="delta_r: Cd_r / Cd_campaign - 1 [%]", title="Round offsets")
    return ax
