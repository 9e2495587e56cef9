"""The diagnosis in words, generated from ``diagnosis.json`` alone: the one-paragraph summary, the
console summary (one line per verdict effect) and the phrases the report shows for each effect.

Every number these texts print is a value of the JSON (its own key, rounded to the digits shown;
never a percentage or a difference computed here), so a reader can find each figure in the file
and a test can check them all (``tests/integration/test_diagnose.py``). The figures of a verdict
effect are those of the fit the verdict rests on: the detected effects' joint fit when there are
several (``params_joint``, ``sd_joint``, ``shrink_given_others``), else its own fit.
Nothing is said about the firing table's shape unless ``drag_shape`` is in the verdict.
"""
from __future__ import annotations

import math

from ..effects import DRAG_SHAPE
from ..results.words import alternatives

__all__ = ["summary_paragraph", "console_summary", "verdict_lines", "impact_text", "reported_values",
           "absorbed_text", "fmt"]


def fmt(v, sig=4):
    """A JSON number as printed: ``sig`` significant digits, plain notation where short ("-7.9",
    "0.0016", "1.2e+04"); "n/a" for a missing (null) value."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "n/a"
    return f"{float(v):.{sig}g}"


def impact_text(e):
    """What ignoring an effect would do, in words and the row's own figures: "Cd would shift by
    up to 0.004 (relative) and the track's end move by 4.2 noise sd" (missing figures left out).

    Parameters
    ----------
    e : dict
        A row of ``diagnosis.json`` ``effects``.

    Returns
    -------
    str
    """
    parts = []
    if e.get("cd_shift_max") is not None:
        parts.append(f"Cd would shift by up to {fmt(e['cd_shift_max'], 2)} (relative)")
    if e.get("end_shift_sd") is not None:
        parts.append(f"the track's end move by {fmt(e['end_shift_sd'], 2)} noise sd")
    return " and ".join(parts)


def reported_values(e):
    """The figures a detected effect is reported with: its values in the detected effects'
    joint fit when there is one, else its own fit (then the same fit).

    Parameters
    ----------
    e : dict
        A row of ``diagnosis.json`` ``effects``.

    Returns
    -------
    (dict, dict, str)
        Parameters (the effect library's units), their sd, and the share of the gap it removes
        in words (the JSON's fraction).
    """
    if "params_joint" in e:
        pv, sd = e["params_joint"], e["sd_joint"]
    else:
        pv, sd = e["params"], e["sd"]
    if e.get("shrink_given_others") is not None:
        share = f"shrink {fmt(e['shrink_given_others'], 3)} (the fraction it removes of what the others leave)"
    else:
        share = f"shrink {fmt(e['shrink'], 3)} (the fraction of the gap it removes)"
    return pv, sd, share


def _params_text(pv, sd):
    return ", ".join(f"{k} = {fmt(v)} ± {fmt((sd or {}).get(k), 2)}" for k, v in pv.items())


def _layers_text(e):
    """How a wind profile's layers lie (``wind_profile``: axis and edges, from the row)."""
    lay = e.get("layers")
    if not lay:
        return ""
    what = "height above the gun" if lay.get("axis") == "altitude" else "downrange distance"
    return f"by {what}, layer edges {', '.join(fmt(v, 5) for v in lay['edges'])} m; "


def verdict_lines(s):
    """One sentence per verdict effect: its figures in the fit the verdict rests on, the share of
    the gap it removes, what the data cannot tell it from, and what ignoring it would do.

    Parameters
    ----------
    s : dict
        ``diagnosis.json`` (or the in-memory summary it is written from).

    Returns
    -------
    list of str
    """
    rows = {e["name"]: e for e in s.get("effects") or []}
    shape_named = DRAG_SHAPE.name in (s.get("verdict") or [])
    out = []
    verdict = s.get("verdict") or []
    for i, n in enumerate(verdict):
        e = rows[n]
        pv, sd, share = reported_values(e)
        ps = _layers_text(e) + _params_text(pv, sd)
        stand_ins = alternatives(n, s.get("effects") or [], verdict)
        # a member's stand-ins are named with it, not after it: an air effect and a drag effect of
        # one signature are one finding the track cannot split, neither the lead alone
        lead = " or ".join([n] + stand_ins) + (" (one signature: the track cannot tell which)" if stand_ins else "")
        txt = f"{'Found' if i == 0 else 'Also'}: {lead}" + (f" ({ps})" if ps else "") + f"; {share}"
        if e.get("judged_against"):
            why = " (the table has another shell's shape)" if shape_named else ""
            txt += f"; judged against a {e['judged_against']}{why}"
        confused = [n for n in e.get("confounded_with") or [] if not rows.get(n, {}).get("superseded_by")
                    and n not in stand_ins]
        if confused:
            txt += f"; the data cannot tell it from {', '.join(confused)}"
        imp = impact_text(e)
        if imp:
            txt += f"; if ignored, {imp}"
        out.append(txt + ".")
    return out


#: at most this many strongly correlated parameter pairs are worded (diagnosis.json lists all)
MAX_CAUTIONS = 3


def _separate_sentences(s):
    """The pairs the data cannot separate (``cannot_separate``), with each one's size alone in
    sd of the fit that holds both."""
    parts = []
    for p in s.get("cannot_separate") or []:
        a, b = p["effects"]
        if "rival_share" in p:
            named = (f"{a} is named, never {b}, as the cause of a wind's signature" if p.get("named")
                     else f"{a}, beside the others, is not named")
            parts.append(f"The data cannot separate {a} from {b}: in its place {b} removes {fmt(p['rival_share'], 2)} "
                         f"of what it removes; {named}.")
            continue
        z, z0 = p["size_over_sd"], p["size_alone_over_sd"]
        how = "in the verdict's joint fit" if p.get("in_verdict") else f"when {b} is fitted beside it"
        parts.append(f"The data cannot separate {a} from {b}: {how}, their sizes are {fmt(z[a], 2)} and "
                     f"{fmt(z[b], 2)} sd (alone {fmt(z0[a], 2)} and {fmt(z0[b], 2)} sd).")
    return parts


def _caution_sentences(s):
    """The strongly correlated parameters of the joint fit (the first :data:`MAX_CAUTIONS`)."""
    joint = s.get("joint") or {}
    parts = []
    for c in (joint.get("strongly_correlated") or [])[:MAX_CAUTIONS]:
        a, b = c["params"]
        parts.append(f"Caution: {a} and {b} are correlated {fmt(c['corr'], 2)} in the joint fit, so their "
                     f"split rests on the models' shapes more than on the data.")
    return parts


def _head(s):
    b = s["baseline"]
    parts = [f"Baseline chi2/sample {fmt(b['chi2_per_sample'], 3)} (gap {fmt(b['gap'])})."]
    if not s.get("reference_drag", True):
        parts.append("No reference drag: effects are judged relative to a fitted Cd (the penalised spline of a "
                     "Scheme 1 fit).")
    return parts


def _verdict_tail(s):
    """After the verdict lines: the table's shape (only when named), the joint fit and what is left."""
    parts = []
    verdict = s.get("verdict") or []
    rows = {e["name"]: e for e in s.get("effects") or []}
    if DRAG_SHAPE.name in verdict:
        parts.append("The firing table's shape does not fit this track (a table of another shell, or air "
                     "whose speed of sound is not the round's).")
    joint = s.get("joint")
    if joint:
        parts.append(f"Fitted together they remove {fmt(joint['shrink'], 3)} of the gap.")
        parts += _caution_sentences(s)
        left = joint.get("remaining_gap_fraction")
    else:
        left = rows[verdict[0]].get("remaining_gap_fraction")
    parts += _separate_sentences(s)
    if left is not None and left > 0.05:
        parts.append(f"A fraction {fmt(left, 2)} of the gap remains (e.g. an effect that varies along the path).")
    return parts


def _nothing(s):
    immaterial = s.get("immaterial") or []
    if immaterial:
        m = s["materiality"]
        return [f"No material effect: nothing the track shows would shift a fitted Cd by more than "
                f"{fmt(m['cd_shift'])} (relative) or move its end by more than {fmt(m['end_sd'])} noise sd."]
    return ["The nominal simulation explains the track within its noise: no effect is significant "
            f"(family-wise false-alarm rate {fmt(s['tests']['alpha'])})."]


def _tail(s):
    """The detectable-but-immaterial effects, the largest miss and what the launch absorbed."""
    rows = {e["name"]: e for e in s.get("effects") or []}
    parts = []
    immaterial = s.get("immaterial") or []
    if immaterial:
        parts.append("Detectable but immaterial: " + "; ".join(
            f"{n} (if ignored, {impact_text(rows[n])})" for n in immaterial) + ".")
    if s.get("where"):
        w = s["where"][0]
        if w["channel"] == "launch":
            worst = max(w["prior_misfit_sd"].items(), key=lambda kv: abs(kv[1]))
            parts.append(f"Largest miss: the track's start is inconsistent with the muzzle at launch "
                         f"({worst[0]} misfit {fmt(worst[1], 2)} sd).")
        else:
            parts.append(f"Largest miss: {w['channel']} from {fmt(w['t_start'], 4)} s to {fmt(w['t_end'], 4)} s "
                         f"({w['phase']}, share {fmt(w['share'], 2)} of the systematic residual).")
    parts += [absorbed_text(a) for a in s.get("absorbed") or []]
    return parts


def summary_paragraph(s):
    """One paragraph (no line breaks) saying what the diagnosis found, from ``diagnosis.json``
    alone: the material effects (one sentence each, figures of the fit the verdict rests on),
    the pairs the data cannot separate, then the detectable but immaterial ones, worded as such.

    Parameters
    ----------
    s : dict
        ``diagnosis.json`` (or the in-memory summary it is written from).

    Returns
    -------
    str
    """
    parts = _head(s)
    if s.get("verdict"):
        parts += verdict_lines(s) + _verdict_tail(s)
    else:
        parts += _nothing(s)
    return " ".join(parts + _tail(s))


def console_summary(s):
    """The diagnosis as the console prints it, from ``diagnosis.json`` alone: a first line with the
    baseline and the verdict, then one line per verdict effect, then one line with the rest.

    Returns
    -------
    list of str
    """
    verdict = s.get("verdict") or []
    head = " ".join(_head(s)) + f" Verdict: {', '.join(verdict) if verdict else 'none'}."
    lines = [head]
    if verdict:
        lines += ["  " + v for v in verdict_lines(s)]
        rest = _verdict_tail(s) + _tail(s)
    else:
        rest = _nothing(s) + _tail(s)
    if rest:
        lines.append("  " + " ".join(rest))
    return lines


def absorbed_text(a):
    """One sentence on a miss the baseline fit absorbed into its launch angles (a row of the
    summary's ``absorbed``)."""
    what = "cross drift (y)" if a["channel"] == "y" else "height (z)"
    return (f"Absorbed: the fit turned the launch {a['name']} by {fmt(a['moved_deg'], 3)} deg ({fmt(a['moved_sd'], 2)} "
            f"sd of the round's launch uncertainty), which takes up a {what} of {fmt(a['drift_m'], 3)} m at the "
            f"end of the track; the ranking of where the simulation misses counts only what is left.")
