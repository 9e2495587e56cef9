"""What ``bayesdrag plan`` writes: ``plan.json`` (:meth:`Plan.to_dict`), the figures as PNG and
``plan.html`` (self-contained, figures embedded) through the reports' one jinja2 environment and
figure helper (:mod:`bayesdrag.report.render`). No statistics here."""
from __future__ import annotations

import datetime

import numpy as np

from ..io.outputs import ensure_output_dir, write_bytes, write_json
from ..plots.plan import plot_budget, plot_plan
from .render import figure_png, png_base64, render_report, versions

__all__ = ["write_plan", "plan_figures", "PLAN_FILES"]

#: the files a plan writes into its folder
PLAN_FILES = ("plan.json", "plan.html", "plan.png", "plan_budget.png")


def plan_figures(plan):
    """The figures of a plan: ``[(file name, title, caption, Figure)]``; the budget figure only
    when systematic sources are declared or the rounds are pooled."""
    figs = [("plan.png", "Predicted sd of Cd by Mach",
             "Relative sd of Cd each planned case will give (log scale), with its rounds pooled; dotted: the part of "
             "the shared systematic sources; dashed: the target; thick grey: the recommended cases pooled, the "
             "green band the Mach interval where they reach the target. A ripple at the spline's knot spacing is the "
             "fit's own: its reported band has it too.", plot_plan(plan).figure)]
    c = _best_case(plan)
    if c is not None and (c.by_source or c.rounds > 1 or c.scatter > 0):
        figs.append(("plan_budget.png", f"Uncertainty budget of QE {c.elevation_deg:g}°, {c.velocity:g} m/s",
                     "The total sd and its parts: the statistical part (radar noise, launch priors and the fit's "
                     "smoothness prior; with the round-to-round scatter, over the square root of the rounds) and "
                     "each declared systematic source, shared by all rounds.", plot_budget(c).figure))
    return figs


def _best_case(plan):
    if not plan.cases:
        return None
    return min(plan.cases, key=lambda c: float(np.min(c.sd / c.cd)))


def _rows(plan, doc):
    rows = []
    for c, d in zip(plan.cases, doc["cases"]):
        rel = c.sd / c.cd
        k = int(np.argmin(rel))
        rows.append({"elevation": c.elevation_deg, "velocity": c.velocity, "rounds": c.rounds,
                     "flight": f"{c.t_tracked[0]:.1f}-{c.t_tracked[1]:.1f} s ({c.samples} samples)",
                     "mach": f"{c.mach_range[0]:.2f}-{c.mach_range[1]:.2f}", "best": f"{100 * rel[k]:.3g} % at Mach {c.mach[k]:.2f}",
                     "worst": f"{100 * rel.max():.3g} %", "model": c.drag_model,
                     "smoothing": f"{c.smoothing['sd']:.3g}" + (f" ({c.smoothing['at_grid_end']} end)" if c.smoothing["at_grid_end"] else ""),
                     "target": (f"{d['target_mach_range'][0]:.2f}-{d['target_mach_range'][1]:.2f}"
                                if d.get("target_mach_range") else ("—" if "target_mach_range" in d else None))})
    return rows


def write_plan(out, plan, *, round_name="", seconds=None):
    """Write ``plan.json``, ``plan.html`` and the PNG figures into ``out``.

    Parameters
    ----------
    out : path
        Output folder (created if missing).
    plan : Plan
    round_name : str
        Shown in the report.
    seconds : float, optional
        Wall time of the plan [s], shown in the report.

    Returns
    -------
    list of Path
        The files written.
    """
    out = ensure_output_dir(out)
    doc = plan.to_dict()
    figs = []
    for name, title, caption, fig in plan_figures(plan):
        png = figure_png(fig)
        figs.append((name, title, caption, png))
    write_json(out / "plan.json", doc)
    written = [out / "plan.json"]
    for name, _, _, png in figs:
        write_bytes(out / name, png)
        written.append(out / name)
    budget = _budget_rows(plan)
    render_report(out / "plan.html", dict(
        doc=doc, rows=_rows(plan, doc), budget=budget, round_name=round_name or plan.round_path,
        figures=[{"title": t, "caption": c, "png": png_base64(p)} for _, t, c, p in figs],
        created=datetime.datetime.now().isoformat(timespec="seconds"), versions=versions(),
        seconds=seconds), template="plan.html.j2")
    written.append(out / "plan.html")
    return written


def _budget_rows(plan):
    """Per case, the shares at the Mach of its best relative sd [% of Cd]: the statistical part
    of one round, the statistical part pooled over the case's rounds (with the round-to-round
    scatter) when that differs, each systematic source, and the total; the pooled statistical
    part and the sources add up in squares to the total."""
    out = []
    for c in plan.cases:
        k = int(np.argmin(c.sd / c.cd))
        cd = c.cd[k]
        parts = {"statistical, 1 round": c.statistical[k] / cd}
        if c.rounds > 1 or c.scatter > 0:
            pooled = np.sqrt((c.statistical[k] ** 2 + (c.scatter * cd) ** 2) / c.rounds) / cd
            what = "statistical" + (" + scatter" if c.scatter > 0 else "")
            parts[f"{what}, {c.rounds} round{'s' if c.rounds > 1 else ''}"] = pooled
        parts.update({s: abs(v[k]) / cd for s, v in c.by_source.items()})
        out.append({"case": f"QE {c.elevation_deg:g}°, {c.velocity:g} m/s", "mach": float(c.mach[k]),
                    "parts": {n: f"{100 * p:.3g} %" for n, p in parts.items()}, "total": f"{100 * c.sd[k] / cd:.3g} %"})
    return out
