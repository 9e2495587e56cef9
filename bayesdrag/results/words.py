"""The sentences the console, the report and ``summary()`` share about a fit's answer: written
once here, so the three say the same thing in the same words. Every number in them is one the
result's ``result.json`` holds (rounded for reading)."""
from __future__ import annotations

import math
from typing import Any, Iterable, Sequence

from ..effects import EFFECTS

__all__ = ["mach_interval", "determined_words", "alternatives", "verdict_words", "grouped_effects", "effect_lines"]


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
