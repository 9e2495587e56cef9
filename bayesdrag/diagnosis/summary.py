"""The diagnosis in words: the one-paragraph summary of ``diagnosis.json`` and the phrases the
report shows for each effect ("Cd shift 0.05 %, end of track moved 0.3 noise sd")."""
from __future__ import annotations

__all__ = ["summary_paragraph", "impact_text", "reported_values", "absorbed_text"]


def _pct(x):
    """A relative change as a percentage with a sensible number of digits (0.013 %, 2.4 %)."""
    return f"{100 * x:.2g} %" if abs(x) < 0.01 else f"{100 * x:.3g} %"


def impact_text(e):
    """What ignoring an effect would do, in words: "Cd shift 0.05 %, end of track moved 0.3
    noise sd" (each figure from the fit the row reports; missing ones are left out).

    Parameters
    ----------
    e : dict
        A row of the summary's ``effects``.

    Returns
    -------
    str
    """
    parts = []
    if e.get("cd_shift_max") is not None:
        parts.append(f"Cd shift {_pct(e['cd_shift_max'])}")
    if e.get("end_shift_sd") is not None:
        parts.append(f"end of track moved {e['end_shift_sd']:.2g} noise sd")
    return ", ".join(parts)


def reported_values(e):
    """The figures a detected effect is reported with: its values in the detected effects'
    joint fit when there is one, else its own fit (then the same fit).

    Parameters
    ----------
    e : dict
        A row of the summary's ``effects``.

    Returns
    -------
    (dict, dict, str)
        Parameters (the effect library's units), their sd, and the share of the gap it removes in words.
    """
    if "params_joint" in e:
        pv, sd = e["params_joint"], e["sd_joint"]
    else:
        pv, sd = e["params"], e["sd"]
    if e.get("shrink_given_others") is not None:
        share = f"removing {100 * e['shrink_given_others']:.1f} % of what the others leave"
    else:
        share = f"removing {100 * e['shrink']:.1f} % of the gap"
    return pv, sd, share


def _verdict_sentences(s, rows):
    """The sentences about the material effects: each with its figures, then the joint fit and
    what is left of the gap."""
    parts = []
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
    return parts


def summary_paragraph(s):
    """One paragraph (no line breaks) saying what the diagnosis found: the material effects
    (figures from their joint fit), then the detectable but immaterial ones, worded as such.

    Parameters
    ----------
    s : dict
        The diagnosis summary (``Diagnosis.summary``).

    Returns
    -------
    str
    """
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
        parts += _verdict_sentences(s, rows)
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
    parts += [absorbed_text(a) for a in s.get("absorbed") or []]
    return " ".join(parts)


def absorbed_text(a):
    """One sentence on a miss the baseline fit absorbed into its launch angles (a row of the
    summary's ``absorbed``)."""
    what = "cross drift (y)" if a["channel"] == "y" else "height (z)"
    return (f"Absorbed: the fit turned the launch {a['name']} by {a['moved_deg']:+.3g} deg ({a['moved_sd']:.1f} sd of "
            f"the round's launch uncertainty), which takes up a {what} of {a['drift_m']:.3g} m at the end of the "
            f"track; the ranking of where the simulation misses counts only what is left.")
