"""The sentences the console, the report and ``summary()`` share about a fit's answer and a
diagnosis: written once here, so the three say the same thing in the same words. Every number in
them is one the result's ``result.json`` (or ``diagnosis.json``) holds, rounded for reading.

The diagnosis's words (:func:`diagnosis_paragraph`, :func:`diagnosis_lines`, the report's
phrases per effect) are generated from ``diagnosis.json`` alone: each figure is a value of the
JSON (its own key, rounded to the digits shown; never a percentage or a difference computed here),
so a reader can find it in the file and a test can check them all. The figures of a verdict effect
are those of the fit the verdict rests on: the detected effects' joint fit when there are several
(``params_joint``, ``sd_joint``, ``shrink_given_others``), else its own fit. Nothing is said about
the firing table's shape unless ``drag_shape`` is in the verdict.

"Summary" names one thing in the Python API: a result's printable table, ``summary()``
(:class:`~bayesdrag.results.summary.Summary`). The files keep their older key ``summary`` for the
one paragraph (``diagnosis.json``, ``plan.json``), which the API calls ``paragraph``. A plan's
paragraphs are the plan's own (:mod:`bayesdrag.planning.plan`): written into ``plan.json`` once,
and the console and :class:`~bayesdrag.results.PlanResult` read them from there."""
from __future__ import annotations

import math
from typing import Any, Iterable, Sequence

from .._runtime.renamed import renamed_getattr
from ..effects import DRAG_SHAPE, EFFECTS

__all__ = ["mach_interval", "determined_words", "alternatives", "verdict_words", "grouped_effects", "effect_lines",
           "why_not_clean", "outcome_line", "SITE_NOT_GIVEN", "NOISE_FREE_SD", "CHECK_NAMES", "diagnosis_paragraph",
           "diagnosis_lines", "verdict_lines", "impact_text", "reported_values", "absorbed_text", "fmt"]


def mach_interval(lo: float, hi: float, digits: int = 2) -> str:
    """``"1.00-1.03"``, or ``"1.05"`` for an interval that rounds to one Mach number (a single
    row of the table: a zero-width "1.05-1.05" reads as a typing slip)."""
    a, b = f"{lo:.{digits}f}", f"{hi:.{digits}f}"
    return a if a == b else f"{a}-{b}"


def determined_words(determined: Sequence[float] | None, undetermined: Iterable[Sequence[float]] = (),
                     digits: int = 2) -> str:
    """Where Cd is determined, with the holes inside that range: ``"Mach 0.89-2.34 except
    1.00-1.03, 1.05"``, or ``"nowhere"``.

    Parameters
    ----------
    determined : (lo, hi) or None
        ``ml.mach_range_determined`` of ``result.json``.
    undetermined : sequence of (lo, hi)
        ``ml.quality.undetermined``: the Mach intervals of rows not determined.
    digits : int
        Decimals of the Mach numbers.
    """
    if not determined:
        return "nowhere"
    lo, hi = float(determined[0]), float(determined[1])
    holes = [(float(a), float(b)) for a, b in undetermined if lo < float(a) and float(b) < hi]
    out = f"Mach {mach_interval(lo, hi, digits)}"
    if holes:
        out += " except " + ", ".join(mach_interval(a, b, digits) for a, b in holes)
    return out


def alternatives(name: str, effects: Sequence[dict], verdict: Sequence[str]) -> list:
    """The candidates the track cannot tell verdict member ``name`` from and that are not in the
    verdict themselves: what could stand in its place (``density`` for ``drag_scale``: one
    signature). ``effects``: the diagnosis's candidate rows."""
    rows = {e["name"]: e for e in effects}
    return [p for p in (rows.get(name, {}).get("confounded_with") or [])
            if p not in verdict and p in rows and not rows[p].get("superseded_by")]


def verdict_words(verdict: Sequence[str], effects: Sequence[dict]) -> str:
    """The verdict with each member's stand-ins beside it: ``"density or drag_scale, lift"`` -- an
    air effect and a drag effect of one signature are named together, neither first alone."""
    return ", ".join(" or ".join([n] + alternatives(n, effects, verdict)) for n in verdict)


def grouped_effects(effects: Sequence[dict]) -> list:
    """The candidate rows in their ranked order, each followed at once by the rows it cannot be
    told from (confounded alternatives read together, not apart down the table)."""
    rows = {e["name"]: e for e in effects}
    out, seen = [], set()
    for e in effects:
        if e["name"] in seen:
            continue
        group = [e] + [rows[p] for p in (e.get("confounded_with") or []) if p in rows and p not in seen]
        for g in group:
            if g["name"] not in seen:
                seen.add(g["name"])
                out.append(g)
    return out


def _value(v: float, sd: float, unit: str) -> str:
    """``"0.972 ± 0.026"`` with its unit; an angle in degrees, as the round gives angles."""
    if unit == "rad":
        v, sd, unit = math.degrees(v), math.degrees(sd), "deg"
    return f"{v:.4g} ± {sd:.2g}" + ("" if unit in ("", "-") else f" {unit}")


def effect_lines(with_effects: dict[str, Any] | None) -> list:
    """What the fit added beside Cd, one line per effect (``ml.with_effects``): the effect's own
    label, its parameters with the sd the fit stands by; layers of wind as a small table by
    height or downrange distance. Empty when the fit added nothing."""
    if not with_effects:
        return []
    how = "found and fitted" if with_effects.get("added_by") == "default" else "fitted"
    sizes = with_effects.get("sizes") or {}
    layers = with_effects.get("wind_layers") or {}
    out = []
    for name in with_effects.get("effects") or []:
        e = EFFECTS.get(name)
        label = e.headline if e is not None else name
        units = dict(zip([p.name for p in e.params], e.units)) if e is not None else {}
        if e is not None and "wind_layers" in e.needs and layers.get("layers"):
            where = "height" if layers.get("axis") == "altitude" else "downrange distance"
            out.append(f"{how}: {name} ({label}), {len(layers['layers'])} layers by {where} "
                       f"[{layers.get('edges_unit', 'm')}], the wind beyond the round's own:")
            out += [f"  {lay['from']:.0f}-{lay['to']:.0f}: wx {lay['wx']:+.1f} ± {lay['wx_sd']:.1f} m/s, "
                    f"wy {lay['wy']:+.1f} ± {lay['wy_sd']:.1f} m/s" for lay in layers["layers"]]
            continue
        vals = [f"{k.split('.', 1)[1]} = {_value(v['value'], v['sd'], units.get(k.split('.', 1)[1], ''))}"
                for k, v in sizes.items() if k.split(".", 1)[0] == name]
        out.append(f"{how}: {name} ({label})" + (f": {', '.join(vals)}" if vals else ""))
    return out


#: how the noise checks are named in the problem line
CHECK_NAMES = {"student-t": "robust fit (Student-t, white noise)", "white": "white-noise fit"}

#: the reason a native track fitted from the default site (the muzzle) is not clean
SITE_NOT_GIVEN = ("the round gives no [radar] position (the site defaults to the muzzle) but the track is not seen from "
                  "there: every radar channel, and the Cd with them, may be off by more than the bands hold, which the "
                  "fitted site's own Cd shift does not size")

#: an estimated noise sd below this [m or m/s] is no radar's: the track is (nearly) noise-free,
#: and residuals above it are the simulator's or the integrator's, not a missed effect
NOISE_FREE_SD = 1e-3


def why_not_clean(quality: dict[str, Any]) -> str:
    """The reason a Scheme 1 fit is not a clean answer and the next step
    (its ``ml.quality``)."""
    from ..estimate.cd.quality import ACF_LIMIT, CHI2_LIMIT

    me = quality.get("model_error") or {}
    if me.get("unsized"):
        return (f"the diagnosis finds {', '.join(me['unsized'])}, whose Cd shift could not be sized: no row is "
                f"claimed; next: `bayesdrag diagnose TRACK ROUND -o DIR`")
    if me.get("site_not_given"):
        return SITE_NOT_GIVEN + "; next: give [radar] position (and position_sd)"
    if me.get("effects"):
        eff = ",".join(me["effects"])
        rel = 100 * me.get("effects_max_rel", 0.0)
        nxt = (f"`bayesdrag fit ... --with {eff}` fits it" if "effects_from" not in me else
               "`bayesdrag diagnose TRACK ROUND -o DIR` (the fit with it failed)")
        return f"an undeclared {', '.join(me['effects'])} moves Cd by up to {rel:.2g} % (in the bands); next: {nxt}"
    air_rec = quality.get("air") or {}
    if air_rec.get("rule") == "contradicted":
        names = air_rec.get("found") or [c["source"] for c in air_rec.get("contradicted") or []]
        return (f"the track contradicts the measured air ({', '.join(names)} unlike the met "
                f"profile's); next: check the met data's datum, time and place (`bayesdrag diagnose TRACK ROUND -o "
                f"DIR` writes the air the track implies as a met file)")
    why = me.get("diagnosis_failed") or me.get("diagnosis_skipped")
    if why:
        return f"the model check could not run ({why}); next: `bayesdrag diagnose TRACK ROUND -o DIR`"
    chans = quality.get("channels") or {}
    bad = {c: f for c, f in chans.items()
           if f["chi2_per_sample"] > CHI2_LIMIT or (f["lag1"] > ACF_LIMIT and f["n"] > 20)}
    if bad:
        if all(f["noise_source"] != "round" and f["noise_sd"] < NOISE_FREE_SD for f in bad.values()):
            return (f"a (nearly) noise-free track: residuals of rms {max(f['rms'] for f in bad.values()):.2g} "
                    f"against a noise of {max(f['noise_sd'] for f in bad.values()):.2g} estimated from it; give "
                    f"[radar] sigma in the round for bands that hold the radar's noise")
        return (f"the model misses the track in {', '.join(bad)}; next: `bayesdrag diagnose TRACK ROUND -o DIR` "
                f"names the cause")
    origin = (quality.get("launch") or {}).get("origin")
    if origin:
        return {"clock": "the track's clock is not the launch's", "position": "the track's origin is not at the gun"
                }.get(origin["kind"], "the track does not start at the muzzle at t = 0") + \
            "; next: declare time_offset_sd / [launch] position_sd, or trim the track"
    if me.get("noise_check"):
        nc = me["noise_check"]
        nxt = "--likelihood student-t" if nc["against"] == "student-t" else "`bayesdrag diagnose TRACK ROUND -o DIR`"
        return f"a {CHECK_NAMES[nc['against']]} moves Cd ({nc['why']}, in the bands); next: {nxt}"
    return "a parameter sits at a bound (see ml.quality.at_bounds); next: `bayesdrag diagnose TRACK ROUND -o DIR`"


def outcome_line(result: Any) -> str:
    """The outcome the command prints of a :class:`~bayesdrag.results.FitResult` ``result``
    (typed ``Any``: results.fit imports this module): converged, determined range, caveat and
    next step, and a second line on the air when the Cd is conditional on it or the track
    contradicts it."""
    s = result.record
    if s["scheme"] == 2:
        m = s["ml"]
        lo, hi = s["cd"][0]["mach"], s["cd"][-1]["mach"]
        return (f"fit (Scheme 2): {m['windows_converged']}/{m['windows']} windows of {s['window']} samples "
                f"converged, Mach {lo:.2f}-{hi:.2f}")
    ml = s["ml"]
    det = ml["mach_range_determined"]
    caveat = "" if ml["quality"]["ok"] else f" -- NOT a clean answer: {why_not_clean(ml['quality'])}"
    head = (f"fit: {ml['message']} in {ml['iterations']} iterations; Cd determined over "
            f"{determined_words(det, ml['quality'].get('undetermined', []))}"
            if det else f"fit: {ml['message']}; Cd nowhere determined to 1 %")
    out = ml["quality"].get("outliers")
    if out:         # the noise model took one-sided outliers (estimate.model.contamination)
        head += "; one-sided outliers down-weighted: " + ", ".join(
            f"{len(e.get('down_weighted', []))} {e['side']} {c} samples" for c, e in out["channels"].items())
    air = (ml["quality"].get("air") or {})
    return head + caveat + (f"\nair: {air['line']}" if air.get("line") else "")


# --- the diagnosis in words (from diagnosis.json alone) ---
def fmt(v: Any, sig: int = 4) -> str:
    """A JSON number as printed: ``sig`` significant digits, plain notation where short ("-7.9",
    "0.0016", "1.2e+04"); "n/a" for a missing (null) value."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "n/a"
    return f"{float(v):.{sig}g}"


def impact_text(e: dict[str, Any]) -> str:
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


def reported_values(e: dict[str, Any]) -> tuple:
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


def _params_text(pv: dict[str, Any], sd: dict[str, Any] | None) -> str:
    return ", ".join(f"{k} = {fmt(v)} ± {fmt((sd or {}).get(k), 2)}" for k, v in pv.items())


def _layers_text(e: dict[str, Any]) -> str:
    """How a wind profile's layers lie (``wind_profile``: axis and edges, from the row)."""
    lay = e.get("layers")
    if not lay:
        return ""
    what = "height above the gun" if lay.get("axis") == "altitude" else "downrange distance"
    return f"by {what}, layer edges {', '.join(fmt(v, 5) for v in lay['edges'])} m; "


def verdict_lines(s: dict[str, Any]) -> list:
    """One sentence per verdict effect: its figures in the fit the verdict rests on, the share of
    the gap it removes, what the data cannot tell it from, and what ignoring it would do.

    Parameters
    ----------
    s : dict
        ``diagnosis.json`` (or the in-memory record it is written from).

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


def _separate_sentences(s: dict[str, Any]) -> list:
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


def _caution_sentences(s: dict[str, Any]) -> list:
    """The strongly correlated parameters of the joint fit (the first :data:`MAX_CAUTIONS`)."""
    joint = s.get("joint") or {}
    parts = []
    for c in (joint.get("strongly_correlated") or [])[:MAX_CAUTIONS]:
        a, b = c["params"]
        parts.append(f"Caution: {a} and {b} are correlated {fmt(c['corr'], 2)} in the joint fit, so their "
                     f"split rests on the models' shapes more than on the data.")
    return parts


def _head(s: dict[str, Any]) -> list:
    b = s["baseline"]
    parts = [f"Baseline chi2/sample {fmt(b['chi2_per_sample'], 3)} (gap {fmt(b['gap'])})."]
    if not s.get("reference_drag", True):
        parts.append("No reference drag: effects are judged relative to a fitted Cd (the penalised spline of a "
                     "Scheme 1 fit).")
    return parts


def _verdict_tail(s: dict[str, Any]) -> list:
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


def _nothing(s: dict[str, Any]) -> list:
    immaterial = s.get("immaterial") or []
    if immaterial:
        m = s["materiality"]
        return [f"No material effect: nothing the track shows would shift a fitted Cd by more than "
                f"{fmt(m['cd_shift'])} (relative) or move its end by more than {fmt(m['end_sd'])} noise sd."]
    return ["The nominal simulation explains the track within its noise: no effect is significant "
            f"(family-wise false-alarm rate {fmt(s['tests']['alpha'])})."]


def _tail(s: dict[str, Any]) -> list:
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


def diagnosis_paragraph(s: dict[str, Any]) -> str:
    """One paragraph (no line breaks) saying what the diagnosis found, from ``diagnosis.json``
    alone: the material effects (one sentence each, figures of the fit the verdict rests on),
    the pairs the data cannot separate, then the detectable but immaterial ones, worded as such.

    Parameters
    ----------
    s : dict
        ``diagnosis.json`` (or the in-memory record it is written from).

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


def diagnosis_lines(s: dict[str, Any]) -> list:
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


def absorbed_text(a: dict[str, Any]) -> str:
    """One sentence on a miss the baseline fit absorbed into its launch angles (a row of the
    record's ``absorbed``)."""
    what = "cross drift (y)" if a["channel"] == "y" else "height (z)"
    return (f"Absorbed: the fit turned the launch {a['name']} by {fmt(a['moved_deg'], 3)} deg ({fmt(a['moved_sd'], 2)} "
            f"sd of the round's launch uncertainty), which takes up a {what} of {fmt(a['drift_m'], 3)} m at the "
            f"end of the track; the ranking of where the simulation misses counts only what is left.")

#: old names, kept with a warning until release 0.3
__getattr__ = renamed_getattr(__name__, {"summary_line": "outcome_line"}, globals())
