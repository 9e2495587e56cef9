"""``campaign.json``, the campaign figures and ``campaign.html``."""
from __future__ import annotations

import datetime
from pathlib import Path

from ..io.outputs import write_bytes, write_json
from ..plots.campaign import plot_campaign_overlay, plot_campaign_relative, plot_deltas, plot_scatter_posterior
from .render import figure_png, png_base64, render_report, versions

__all__ = ["write_campaign_report"]


def write_campaign_report(out, camp, inputs, pooled, doc, truth=None):
    """Write ``campaign.json``, the PNG figures and ``campaign.html`` into ``out``.

    Parameters
    ----------
    out : path
    camp : Campaign
    inputs : list of dict
    pooled : PooledResult
    doc : dict
        :func:`bayesdrag.campaign.campaign_json`.
    truth : dict, optional
        For simulated campaigns: ``{"cd": callable, "scatter": float, "deltas": [...]}``; drawn
        in the figures and checked in the report.
    """
    out = Path(out)
    write_json(out / "campaign.json", doc)
    tr = truth or {}
    figs = [("campaign_cd.png", plot_campaign_overlay(inputs, pooled, truth=tr.get("cd")).figure,
             "Cd(M) of every round and the campaign",
             "Each round's ML curve with its 90 % Cramér-Rao band (colours, the paper's Fig. 4 overlay), "
             "the campaign (population) median and 90 % credible band (black), the reference (dashed)."),
            ("campaign_relative.png", plot_campaign_relative(inputs, pooled, truth=tr.get("cd")).figure,
             "Rounds relative to the campaign",
             "A round that differs by a constant factor is a flat line; a tilted or bent line is a Mach-"
             "dependent difference the common-factor model does not describe."),
            ("campaign_scatter.png", plot_scatter_posterior(pooled, truth=tr.get("scatter")).figure,
             "Round-to-round scatter", "Posterior of the relative sd of Cd between rounds."),
            ("campaign_deltas.png", plot_deltas(pooled, truth=tr.get("deltas")).figure,
             "Round offsets", "Posterior median and 90 % interval of each round's Cd offset.")]
    b64 = []
    for name, fig, title, caption in figs:
        png = figure_png(fig)
        write_bytes(out / name, png)
        b64.append({"title": title, "caption": caption, "png": png_base64(png)})
    checks = []
    if truth:
        rows = doc["cd"]
        cov = [r["q05"] <= float(truth["cd"](r["mach"])) <= r["q95"] for r in rows]
        s = doc["scatter"]
        checks = [("campaign truth inside the 90 % band", f"{sum(cov)} of {len(cov)} nodes"),
                  ("true scatter inside the 90 % interval",
                   f"{'yes' if s['q05'] <= truth['scatter'] <= s['q95'] else 'no'} "
                   f"({100 * truth['scatter']:.3g} % in {100 * s['q05']:.3g}-{100 * s['q95']:.3g} %)")]
    ctx = {"title": f"bayesdrag campaign: {camp.name}", "created": datetime.datetime.now().isoformat(timespec="seconds"),
           "doc": doc, "figures": b64, "checks": checks, "versions": versions(),
           "inputs": [(r["name"], f"{r['mach_range'][0]:.3f}-{r['mach_range'][1]:.3f}", r["drag_model"], len(r["mach"]))
                      for r in inputs]}
    render_report(out / "campaign.html", ctx, template="campaign.html.j2")
