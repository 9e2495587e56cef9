"""What ``bayesdrag diagnose`` writes: ``diagnosis.json`` (the record of
:func:`bayesdrag.diagnosis.diagnose` and its paragraph), the figures as PNG,
``diagnosis.html`` (self-contained, figures embedded), through the reports' one jinja2
environment and figure helper (:mod:`bayesdrag.report.render`), and the air the diagnosis found
as a met file (``diagnosis_met.csv``, and ``diagnosis_wind_downrange.csv`` for a wind by
downrange distance). No analysis here."""
from __future__ import annotations

from ..io.met import write_met_profile, write_wind_profile
from ..io.outputs import ensure_output_dir, write_bytes, write_json
from ..plots.diagnosis import plot_ranking, plot_residuals_before_after, plot_where
from ..plots.wind import plot_found_wind, wind_layer_table
from ..results.words import impact_text, reported_values, diagnosis_paragraph
from ..results.document import jsonable
from .render import figure_png, png_base64, render_report
from ..effects import WIND

__all__ = ["write_diagnosis", "diagnosis_figures"]

#: resolution of the diagnosis figures, written and embedded [dots per inch]
DIAGNOSIS_DPI = 90
#: the air the diagnosis found: a met CSV by height, and a wind CSV by downrange distance
MET_FILE = "diagnosis_met.csv"
WIND_FILE = "diagnosis_wind_downrange.csv"


def diagnosis_figures(d):
    """The figures of a diagnosis: ``{name: Figure}`` for ``residuals``, ``ranking``, ``where``
    and, with a wind in the verdict, ``wind`` (written as ``diagnosis_<name>.png``)."""
    figs = {"residuals": plot_residuals_before_after(d), "ranking": plot_ranking(d.record).figure,
            "where": plot_where(d)}
    if wind_layer_table(d.record)[0]:
        figs[WIND.name] = plot_found_wind(d.record).figure
    return figs


def write_found_air(out, d):
    """``diagnosis_met.csv`` (and ``diagnosis_wind_downrange.csv``): the air the diagnosis found
    (:func:`bayesdrag.diagnosis.found_air.found_atmosphere`), when its verdict changes the air.
    Returns the names written."""
    met, down, head = d.found_air if d.found_air is not None else (None, None, [])
    names = []
    if met is not None:
        write_met_profile(out / MET_FILE, met, comment="\n".join(head))
        names.append(MET_FILE)
    if down is not None:
        write_wind_profile(out / WIND_FILE, down.wind, comment="\n".join(head))
        names.append(WIND_FILE)
    return names


def write_diagnosis(out, d, *, track_name="", round_name=""):
    """Write ``diagnosis.json``, ``diagnosis.html`` and the PNG figures into ``out``.

    Parameters
    ----------
    out : path
        Output folder (created if missing).
    d : Diagnosis
    track_name, round_name : str
        Shown in the report.

    Returns
    -------
    str
        The summary paragraph (also ``diagnosis.json``'s ``summary``).
    """
    out = ensure_output_dir(out)
    paragraph = diagnosis_paragraph(d.record)
    s = dict(d.record, summary=paragraph)
    write_json(out / "diagnosis.json", jsonable(s))
    b64 = {}
    for name, fig in diagnosis_figures(d).items():
        png = figure_png(fig, dpi=DIAGNOSIS_DPI)
        write_bytes(out / f"diagnosis_{name}.png", png)
        b64[name] = png_base64(png)
    rows = {e["name"]: e for e in s["effects"]}
    detected = [dict(e, shown=reported_values(e), impact=impact_text(e), judged_against=e.get("judged_against"))
                for e in [rows[n] for n in list(s["verdict"]) + list(s.get("immaterial") or []) if n in rows]]
    met_files = write_found_air(out, d)
    wind_rows, wind_axis = wind_layer_table(s)
    render_report(out / "diagnosis.html", dict(
        s=s, paragraph=paragraph, detected=detected, notes=s.get("notes", []), track_name=track_name,
        round_name=round_name, fig_residuals=b64["residuals"], fig_ranking=b64["ranking"], fig_where=b64["where"],
        fig_wind=b64.get("wind"), wind_rows=wind_rows, wind_axis=wind_axis, met_files=met_files),
        template="diagnosis.html.j2")
    return paragraph
