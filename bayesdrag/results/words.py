"""The sentences the console, the report and ``summary()`` share about a fit's answer: written
once here, so the three say the same thing in the same words. Every number in them is one the
result's ``result.json`` holds (rounded for reading)."""
from __future__ import annotations

from typing import Iterable, Sequence

__all__ = ["mach_interval", "determined_words"]


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
