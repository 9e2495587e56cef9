"""Figures of a firing plan: the predicted relative sd of Cd by Mach, one curve per planned case
with the target as a line, and the uncertainty budget of one case by source."""
from __future__ import annotations

import matplotlib
import numpy as np
from matplotlib.ticker import FuncFormatter, LogLocator

from ..planning.plan import combine
from .common import new_axes

__all__ = ["plot_plan", "plot_budget", "PLAN_FIGSIZE"]

#: size of a plan figure [inch]
PLAN_FIGSIZE = (8, 4.6)


def plot_plan(plan, ax=None):
    """Relative sd of Cd [%] against Mach, one curve per case (with its rounds), the pooled
    recommendation (with a target) and the target as a horizontal line.

    Parameters
    ----------
    plan : Plan
        :func:`bayesdrag.planning.plan.make_plan` (``PlanResult.plan``).
    ax : matplotlib Axes, optional

    Returns
    -------
    Axes
    """
    ax = new_axes(ax, PLAN_FIGSIZE)
    cmap = matplotlib.colormaps["tab10"]
    for i, c in enumerate(plan.cases):
        col = cmap(i % 10)
        ax.plot(c.mach, 100 * c.sd / c.cd, color=col, lw=1.5,
                label=f"QE {c.elevation_deg:g}°, {c.velocity:g} m/s" + (f" × {c.rounds}" if c.rounds > 1 else ""))
        if c.by_source:
            ax.plot(c.mach, 100 * c.systematic / c.cd, color=col, lw=0.8, ls=":")
    if plan.target is not None:
        ax.axhline(100 * plan.target, color="k", lw=1.0, ls="--", label=f"target {100 * plan.target:g} %")
        best = plan.best or {}
        if best.get("cases") and len(best["cases"]) > 1:
            grid, cd, sd, _ = combine(plan.cases, best["cases"])
            ok = np.isfinite(sd)
            what = "recommended cases" if best.get("mach_range") else "closest combination"
            ax.plot(grid[ok], 100 * sd[ok] / cd[ok], color="k", lw=2.2, alpha=0.6, label=f"{what} pooled")
        if best.get("mach_range"):
            ax.axvspan(*best["mach_range"], color="tab:green", alpha=0.08, lw=0)
    _percent_log_axis(ax)
    ax.set(xlabel="Mach", ylabel="predicted sd of Cd [% of Cd]",
           title="Predicted Cd accuracy" + (" (dotted: shared systematic part)" if plan.declared else ""))
    _legend_below(ax)
    return ax


def _legend_below(ax):
    """The legend under the axes (outside them: the curves of many cases would hide behind it);
    up to four entries a row."""
    n = len(ax.get_legend_handles_labels()[0])
    ax.legend(fontsize="small", ncol=min(4, max(n, 1)), loc="upper center", bbox_to_anchor=(0.5, -0.14),
              frameon=False)


def _percent_log_axis(ax):
    """A log y axis labelled in plain percent numbers (0.01, 0.1, 1) with a light grid."""
    ax.set_yscale("log")
    fmt = FuncFormatter(lambda v, _: f"{v:.3g}")
    ax.yaxis.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0)))
    ax.yaxis.set_major_formatter(fmt)
    ax.yaxis.set_minor_formatter(FuncFormatter(lambda v, _: ""))
    ax.grid(True, which="both", alpha=0.3)


def plot_budget(case, ax=None):
    """The uncertainty budget of one case [% of Cd]: the total, the statistical part for its
    rounds and each systematic source's share.

    Parameters
    ----------
    case : CasePlan
    ax : matplotlib Axes, optional

    Returns
    -------
    Axes
    """
    ax = new_axes(ax, PLAN_FIGSIZE)
    cd = case.cd
    ax.plot(case.mach, 100 * case.sd / cd, color="k", lw=2.0, label="total")
    stat = np.sqrt((case.statistical ** 2 + (case.scatter * cd) ** 2) / case.rounds)
    ax.plot(case.mach, 100 * stat / cd, color="tab:blue", lw=1.3,
            label="statistical" + (f" / √{case.rounds}" if case.rounds > 1 else ""))
    cmap = matplotlib.colormaps["tab10"]
    for i, (stem, v) in enumerate(case.by_source.items()):
        ax.plot(case.mach, 100 * np.abs(v) / cd, color=cmap((i + 1) % 10), lw=1.0, ls="--", label=stem)
    _percent_log_axis(ax)
    # down to the smallest share drawn, but not below two decades under the smallest total
    # (a share that small does not matter)
    shown = [100 * stat / cd] + [100 * np.abs(v) / cd for v in case.by_source.values()]
    total_min = float(np.min(100 * case.sd / cd))
    ax.set_ylim(bottom=0.7 * max(float(np.min(shown)), total_min / 100.0))
    ax.set(xlabel="Mach", ylabel="sd of Cd [% of Cd]",
           title=f"Budget of QE {case.elevation_deg:g}°, {case.velocity:g} m/s")
    _legend_below(ax)
    return ax
