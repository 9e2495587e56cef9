"""The sentences the console, the report and ``summary()`` share about a fit's answer: written
once here, so the three say the same thing in the same words. Every number in them is one the
result's ``result.json`` holds (rounded for reading)."""
from __future__ import annotations

import math
from typing import Any, Iterable, Sequence

from ..effects import EFFECTS

__all__ = ["mach_interval", "determined_words", "alternatives", "verdict_words", "grouped_effects", "effect_lines",
           "why_not_clean", "summary_line", "SITE_NOT_GIVEN", "NOISE_FREE_SD", "CHECK_NAMES"]


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
    """The summary's reason a Scheme 1 fit is not a clean answer and the next step
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


def summary_line(result: Any) -> str:
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
