"""``bayesdrag diagnose``: run :func:`bayesdrag.diagnose.diagnose` and write ``diagnosis.json``,
``diagnosis.html`` (self-contained, figures embedded), the figures as PNG and a one-paragraph
summary on stderr. I/O and plotting only; the analysis lives in :mod:`bayesdrag.diagnose`.
"""
from __future__ import annotations

import base64
import io
from pathlib import Path

import numpy as np

from .io.outputs import atomic_write, ensure_output_dir, write_json


def _pct(x):
    """A relative change as a percentage with a sensible number of digits (0.013 %, 2.4 %)."""
    return f"{100 * x:.2g} %" if abs(x) < 0.01 else f"{100 * x:.3g} %"


def impact_text(e):
    """What ignoring an effect would do, in words: "Cd shift 0.05 %, end of track moved 0.3
    noise sd" (each figure from the fit the row reports; missing ones are left out)."""
    parts = []
    if e.get("cd_shift_max") is not None:
        parts.append(f"Cd shift {_pct(e['cd_shift_max'])}")
    if e.get("end_shift_sd") is not None:
        parts.append(f"end of track moved {e['end_shift_sd']:.2g} noise sd")
    return ", ".join(parts)


def reported_values(e):
    """(params, sd, share-of-the-gap text) a detected effect is reported with: its figures in
    the detected effects' joint fit when there is one, else its own fit (then the same fit)."""
    if "params_joint" in e:
        pv, sd = e["params_joint"], e["sd_joint"]
    else:
        pv, sd = e["params"], e["sd"]
    if e.get("shrink_given_others") is not None:
        share = f"removing {100 * e['shrink_given_others']:.1f} % of what the others leave"
    else:
        share = f"removing {100 * e['shrink']:.1f} % of the gap"
    return pv, sd, share


def summary_paragraph(s):
    """One paragraph (no line breaks) saying what the diagnosis found: the material effects
    (figures from their joint fit), then the detectable but immaterial ones, worded as such."""
    b = s["baseline"]
    parts = [f"Baseline chi2/sample {b['chi2_per_sample']:.3g} (gap {b['gap']:.4g})."]
    if not s["reference_drag"]:
        parts.append("No reference drag: effects are judged relative to a fitted Cd (the penalised spline of a "
                     "Scheme 1 fit).")
    rows = {e["name"]: e for e in s["effects"]}
    immaterial = s.get("immaterial") or []
    if not s["verdict"]:
        if immaterial:
            parts.append("No material effect: nothing the track shows would shift a fitted Cd by more than "
                         f"{_pct(s['materiality']['cd_shift'])} or move its end by more than "
                         f"{s['materiality']['end_sd']:g} noise sd.")
        else:
            parts.append("The nominal simulation explains the track within its noise: no effect is significant"
                         f" (family-wise false-alarm rate {s['tests']['alpha']:g}).")
    else:
        for i, n in enumerate(s["verdict"]):
            e = rows[n]
            pv, sd, share = reported_values(e)
            ps = ", ".join(f"{k} = {v:.4g} ± {sd.get(k, float('nan')):.2g}" for k, v in pv.items())
            txt = f"{'Found' if i == 0 else 'Also'}: {n}" + (f" ({ps})" if ps else "") + f", {share}"
            if e.get("judged_against"):
                txt += f" (judged against a {e['judged_against']})"
            if e["confounded_with"]:
                txt += f" (the data cannot tell it from {', '.join(e['confounded_with'])})"
            imp = impact_text(e)
            if imp:
                txt += f"; ignored: {imp}"
            parts.append(txt + ".")
        if "drag_shape" in s["verdict"]:
            parts.append("The firing table's shape does not fit this track (a table of another shell, or air "
                         "whose speed of sound is not the round's).")
        joint = s.get("joint")
        if joint:
            parts.append(f"Together {'they' if len(joint['effects']) > 2 else 'the two'} remove "
                         f"{100 * joint['shrink']:.1f} % of the gap.")
            for c in joint.get("strongly_correlated", []):
                a, b2 = c["params"]
                parts.append(f"Caution: {a} and {b2} are correlated {c['corr']:+.2f} in the joint fit, "
                             f"so their split rests on the models' shapes more than on the data.")
            left = 1.0 - joint["shrink"]
        else:
            left = rows[s["verdict"][0]]["remaining_gap_fraction"]
        if left > 0.05:
            parts.append(f"{100 * left:.0f} % of the gap remains (e.g. an effect that varies along the path).")
    if immaterial:
        parts.append("Detectable but immaterial: " + "; ".join(
            f"{n} ({impact_text(rows[n])})" for n in immaterial) + ".")
    if s["where"]:
        w = s["where"][0]
        if w["channel"] == "launch":
            worst = max(w["prior_misfit_sd"].items(), key=lambda kv: abs(kv[1]))
            parts.append(f"Largest miss: the track's start is inconsistent with the muzzle at t = 0 "
                         f"({worst[0]} off by {abs(worst[1]):.1f} sd).")
        else:
            parts.append(f"Largest miss: {w['channel']} {w['t_start']:.1f}-{w['t_end']:.1f} s ({w['phase']}, "
                         f"{100 * w['share']:.0f} % of the systematic residual).")
    return " ".join(parts)


def _png_b64(fig):
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_residuals_before_after(d, fig=None):
    """Normalised residuals per channel: nominal simulation (left) and with the best effect
    (right), the noise band shaded. Returns the Figure."""
    plt = _plt()
    C = len(d.channels)
    if fig is None:
        fig, _ = plt.subplots(C, 2, figsize=(11, 1.9 * C + 0.8), sharex=True, sharey="row",
                              layout="constrained", squeeze=False)
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
    """Horizontal bars of the fraction of the gap each candidate removes. Returns the Axes."""
    plt = _plt()
    if ax is None:
        _, ax = plt.subplots(figsize=(7, 0.35 * max(len(s["effects"]), 2) + 1), layout="constrained")
    eff = s["effects"][::-1]
    names = [e["name"] for e in eff]
    vals = [e["shrink"] for e in eff]
    imm = set(s.get("immaterial") or [])
    colors = ["C2" if e["name"] in s["verdict"] else "C1" if e["name"] in imm else "C0" if e["significant"] else "0.7"
              for e in eff]
    ax.barh(names, vals, color=colors)
    ax.set(xlim=(0, 1.05), xlabel="shrink (fraction of the gap removed, each fitted alone)",
           title="candidates (green: verdict, orange: detectable but immaterial, blue: significant alone)")
    return ax


def plot_where(d, fig=None):
    """Where-map: smoothed normalised residual against time and Mach per channel."""
    plt = _plt()
    if fig is None:
        fig, axes = plt.subplots(1, 2, figsize=(10, 3.6), layout="constrained")
    ax_t, ax_m = fig.axes[:2]
    N = d.t.size
    k = np.ones(max(9, int(round(N / 100)) | 1))
    for j, c in enumerate(d.channels):
        r = np.where(d.weights[:, j] > 0, d.resid_base[:, j] / d.sigma[c], 0.0)
        sm = np.convolve(r, k, "same") / np.maximum(np.convolve((d.weights[:, j] > 0) * 1.0, k, "same"), 1)
        ax_t.plot(d.t, sm, label=c)
        ax_m.plot(d.mach, sm, label=c)
    for ax in (ax_t, ax_m):
        ax.axhspan(-1, 1, color="C2", alpha=0.15)
        ax.grid(alpha=0.3)
    ax_t.set(xlabel="time [s]", ylabel="smoothed residual / sd", title="nominal misfit along time")
    ax_m.set(xlabel="Mach", title="... and along Mach")
    ax_t.legend(fontsize="small")
    return fig


def write_diagnosis(out, d, track_name="", round_name=""):
    """Write diagnosis.json, diagnosis.html and the PNG figures into ``out``. Returns the
    summary paragraph."""
    import jinja2

    out = ensure_output_dir(out)
    s = d.summary
    paragraph = summary_paragraph(s)
    s = dict(s, summary=paragraph)
    write_json(out / "diagnosis.json", _jsonable(s))
    figs = {"residuals": plot_residuals_before_after(d), "ranking": plot_ranking(s).figure,
            "where": plot_where(d)}
    b64 = {}
    for name, fig in figs.items():
        data = io.BytesIO()
        fig.savefig(data, format="png", dpi=90)
        atomic_write(out / f"diagnosis_{name}.png", lambda tmp, b=data.getvalue(): Path(tmp).write_bytes(b))
        b64[name] = _png_b64(fig)
    env = jinja2.Environment(loader=jinja2.PackageLoader("bayesdrag", "templates"),
                             autoescape=jinja2.select_autoescape(["html", "j2"]))
    rows = {e["name"]: e for e in s["effects"]}
    detected = [dict(e, shown=reported_values(e), impact=impact_text(e)) for e in
                [rows[n] for n in list(s["verdict"]) + list(s.get("immaterial") or []) if n in rows]]
    html = env.get_template("diagnosis.html.j2").render(
        s=s, paragraph=paragraph, detected=detected, notes=s.get("notes", []), track_name=track_name,
        round_name=round_name,
        fig_residuals=b64["residuals"], fig_ranking=b64["ranking"], fig_where=b64["where"])
    atomic_write(out / "diagnosis.html", lambda tmp: Path(tmp).write_text(html, encoding="utf-8"))
    return paragraph


def _jsonable(o):
    if isinstance(o, dict):
        return {str(k): _jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_jsonable(v) for v in o]
    if isinstance(o, (np.floating, float)):
        v = float(o)
        return v if np.isfinite(v) else None
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, np.bool_):
        return bool(o)
    return o
