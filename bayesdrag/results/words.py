"""The sentences the console, the report and ``summary()`` share about a fit's answer: written
once here, so the three say the same thing in the same words. Every number in them is one the
result's ``result.json`` holds (rounded for reading)."""
from __future__ import annotations

from typing import Iterable, Sequence

__all__ = ["mach_interval", "determined_words", "alternatives", "verdict_words", "grouped_effects"]


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
