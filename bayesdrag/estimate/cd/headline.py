"""The headline of a fit: what a reader wants first, as numbers (``result.json`` ``headline``).

Cd at a few Mach numbers of the determined range with the total band the rows report, the
determined range, and whether the answer is clean (with the reason and the next step when it is
not). The report opens with it; the numbers are the rows' own, so the page and the JSON agree.
"""
from __future__ import annotations

import numpy as np

__all__ = ["headline", "HEADLINE_POINTS", "HEADLINE_LEVEL_Z"]

#: Mach numbers the headline shows, spread evenly over the determined range
HEADLINE_POINTS = 5
#: a 90 % band is ML +- this many band sd where no posterior quantiles are given
HEADLINE_LEVEL_Z = 1.6448536269514722


def headline(rows, determined_range, clean, reason=None, points=HEADLINE_POINTS):
    """``result.json`` ``headline``.

    Parameters
    ----------
    rows : list of dict
        ``cd`` rows (``mach``, ``ml``, ``band_sd``, ``determined``, optional ``q05``/``q95``).
    determined_range : (float, float) or None
    clean : bool
        ``ml.quality.ok``.
    reason : str, optional
        Why the answer is not clean and the next step (the command's outcome line says the same).
    points : int

    Returns
    -------
    dict
        ``cd`` [{``mach``, ``cd``, ``band_sd``, ``q05``, ``q95``, ``determined``}], ``band``
        (``"posterior"`` total band or ``"ml"``: ML +- 1.645 band sd), ``determined_range``,
        ``clean``, ``not_clean_because``.
    """
    mach = np.array([r["mach"] for r in rows], float)
    lo, hi = determined_range if determined_range else (mach.min(), mach.max())
    picks = []
    for x in np.linspace(lo, hi, points):
        i = int(np.argmin(np.abs(mach - x)))
        if i not in picks:
            picks.append(i)
    sampled = all("q05" in rows[i] for i in picks)
    out = []
    for i in picks:
        r = rows[i]
        sd = float(r.get("band_sd", r.get("crb_sd", 0.0)))
        q05, q95 = ((r["q05"], r["q95"]) if sampled else
                    (r["ml"] - HEADLINE_LEVEL_Z * sd, r["ml"] + HEADLINE_LEVEL_Z * sd))
        out.append({"mach": float(r["mach"]), "cd": float(r["ml"]), "band_sd": sd, "q05": float(q05),
                    "q95": float(q95), "determined": bool(r.get("determined", False))})
    return {"cd": out, "band": "posterior" if sampled else "ml",
            "determined_range": [float(lo), float(hi)] if determined_range else None,
            "clean": bool(clean), "not_clean_because": None if clean else reason}
