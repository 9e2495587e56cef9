"""A chronograph session's outputs: ``campaign.json``, ``session_cd.png``, ``campaign.html``,
and each shot's folder (``shot.json``, ``residuals.png``)."""
from __future__ import annotations

import datetime
from pathlib import Path

import numpy as np

from ..io.outputs import write_bytes, write_json
from ..plots.session import plot_session_cd, plot_shot_residuals
from .render import figure_png, png_base64, render_report, versions

__all__ = ["write_session_report", "write_shot", "shot_record", "write_drag_tables"]


def write_drag_tables(out, record, fit, mass, diameter, reference):
    """The session's Cd(M) for shooters' solvers: ``drag_table.json`` (a py-ballisticcalc custom
    table with its bc) and ``drag_table.csv`` (plain ``mach,cd``), both over Mach 0-10: the fitted
    curve over the flown span, the reference's shape scaled to meet it beyond, as each file says."""
    from ..io.export import export_curve
    from ..io.outputs import atomic_write

    rows = record["cd"]
    if not rows:
        return []
    span = (rows[0]["mach"], rows[-1]["mach"])
    coefs = fit.layout.curve(fit.theta)
    src = f"bayesdrag chronograph session {record['name']}"
    doc = export_curve(Path(out) / "drag_table.json", lambda m: fit.model.cd(coefs, m), span, mass, diameter, src,
                       reference=reference)
    body = (f"# {src}: Cd(M) fitted over Mach {span[0]:.3f}-{span[1]:.3f}; {doc['notes'][0]}\nmach,cd\n"
            + "".join(f"{p['Mach']:.6g},{p['CD']:.8g}\n" for p in doc["drag_table"]))
    atomic_write(Path(out) / "drag_table.csv", lambda tmp: Path(tmp).write_text(body, encoding="utf-8"))
    return ["drag_table.json", "drag_table.csv"]


def write_session_report(out, record):
    """Write ``campaign.json``, ``session_cd.png`` and ``campaign.html`` into ``out``."""
    out = Path(out)
    write_json(out / "campaign.json", record)
    png = figure_png(plot_session_cd(record).figure)
    write_bytes(out / "session_cd.png", png)
    ctx = {"title": f"bayesdrag chronograph session: {record['name']}",
           "created": datetime.datetime.now().isoformat(timespec="seconds"), "doc": record,
           "figure": png_base64(png), "versions": versions()}
    render_report(out / "campaign.html", ctx, template="session.html.j2")


def shot_record(record, fit, i):
    """``shot.json`` of the ``i``-th shot fitted: its entry of the session record and its samples."""
    shot = fit.shots[i]
    entry = next(s for s in record["shots"] if s["name"] == shot.name)
    res, keep = fit.residuals[i], fit.keep[i]
    return {**entry, "session": record["name"],
            "residual_rms": float(np.sqrt(np.mean(res[keep] ** 2))),
            "samples_table": {"t": shot.t.tolist(), "reported": shot.v.tolist(),
                              "model": (shot.v - res).tolist(), "mach": fit.mach[i].tolist(),
                              "outlier": (~keep).tolist()}}


def write_shot(out, record, fit, i, figures=True):
    """Write the ``i``-th shot's ``shot.json`` (and ``residuals.png``) into ``out``."""
    out = Path(out)
    doc = shot_record(record, fit, i)
    write_json(out / "shot.json", doc)
    if figures:
        fig = plot_shot_residuals(fit.shots[i].t, fit.residuals[i], fit.keep[i],
                                  float(fit.sigma[i]) * np.asarray(fit.scale[i]), fit.shots[i].name)
        write_bytes(out / "residuals.png", figure_png(fig))
