"""Knots and smoothness penalty of the flexible drag model, placed from the shapes the data and
the table show.

Knots (:func:`adaptive_knots`)
    Where a shell's Cd(M) bends depends on the shell: a G1-like curve rises gently from Mach
    0.7, a boat-tail G7-like one steeply between 0.9 and 1.0, a table of another shell may put
    its rise 0.05 Mach off. Fixed knots cannot serve all: 0.04-Mach knots miss a G7 rise by
    1.4 %, 0.01-Mach knots everywhere cost 200 coefficients. The knots are refined where the
    *shape curves* need them: start from :data:`COARSE` spacing and halve every interval in which
    a least-squares cubic spline on the current knots misses any shape curve by more than
    :data:`KNOT_TOL` (relative), down to :data:`FINE` (the kernel's Mach grid step); neighbouring
    intervals then differ by at most a factor two (no abrupt change of resolution). The shape
    curves are the data-driven start curve (:mod:`bayesdrag.estimate.build.start`), which shows where
    this shell's drag bends, and, when there is a firing table, the table itself. Because the
    start is smeared over a steep rise, every interval within :data:`RISE_MARGIN` Mach of a
    refined one is kept at most 0.02 Mach wide, so the sharper true rise still fits. Measured: a
    cubic spline on such knots follows the G1, G2, G5, G6, G7, G8, GI, GS, RA4 and M101 tables
    to 0.05-0.3 % (``tests/unit/test_start.py``). A short track, with fewer samples than these
    rules want coefficients, gets :func:`sparse_knots` instead: at most one coefficient per
    sample (:func:`coefficient_budget`), and no knot between two samples the data cannot tell
    apart.
Penalty (:func:`smoothness_rows`)
    A Gaussian pseudo-prior on the second derivative of the *relative* correction
    ``s = Cd / base`` (base: the table, or the start curve without one), from divided second
    differences of ``c_j / base_j`` at the knots' Greville abscissae, each row weighted by the
    square root of its Mach width, so that ``sum rows^2 = integral s''(M)^2 dM`` whatever the
    knot spacing: one sd means the same smoothness at 0.01 and 0.1 Mach spacing. A constant or
    linear correction costs nothing (a correct table, a table 10 % off). Each row's sd is
    ``sd * w_j`` with ``w_j = min(1 + kappa_j / median(kappa), MAX_FLEX)``: kappa the base's own relative
    curvature, so the correction may bend more where the drag itself bends (rises move and
    change height from shell to shell and from table to shell) and is held smooth elsewhere.
"""
from __future__ import annotations

import math

import numpy as np

from ...drag import Spline

#: coarsest knot spacing [Mach]
COARSE = 0.1
#: finest knot spacing [Mach] (the kernel's Mach grid)
FINE = 0.01
#: relative error to which the spline must follow each shape curve
KNOT_TOL = 1e-3
#: around intervals refined to :data:`FINE` intervals are kept at most :data:`NEAR_FINE` wide
#: within this many Mach (the start curve is smeared over a steep rise)
RISE_MARGIN = 0.06
NEAR_FINE = 0.02
#: relative slope |d ln Cd / dM| above which the drag is rising (or falling) steeply: a drag rise
#: has 2-8 (G1 ~2, G7 and M101 ~7), the supersonic decline 0.1-0.4
RISE_SLOPE = 1.0
#: Mach band where a gun-launched projectile's drag rises: the critical Mach of blunt shapes is
#: ~0.7, the drag peak lies below Mach 1.3 (G1 ~1.3-1.4, boat tails ~1.0-1.1, spheres ~1.5)
RISE_BAND = (0.6, 1.6)
#: knot spacing inside a steep rise [Mach] (a cubic spline on 0.01 follows a G7 rise to 0.2 %,
#: on 0.02 to 0.7 %)
RISE_SPACING = 0.01
#: largest flexibility weight of a penalty row: a sharp table rise has a curvature hundreds of
#: times its median, and an unbounded weight there switches the penalty off where the data are
#: often weakest (a rise at the launch Mach, seen only in the first seconds), leaving the
#: correction free to wander with the initial state
MAX_FLEX = 30.0
#: fewest coefficients of a short track's spline (:func:`coefficient_budget`)
MIN_COEFFICIENTS = 5
#: dense evaluation step for the knot refinement [Mach]
_EVAL_STEP = 0.0025


def _snap(x, dm=FINE):
    return np.round(np.asarray(x, float) / dm) * dm


def _lsq_rel_error(knots, mach, targets):
    """Largest relative LS misfit per knot interval of a cubic spline to each target."""
    spl = Spline(tuple(knots))
    B = spl.basis(mach)
    worst = np.zeros(len(knots) - 1)
    idx = np.clip(np.searchsorted(knots, mach, side="right") - 1, 0, len(knots) - 2)
    for f in targets:
        A = B / f[:, None]
        c, *_ = np.linalg.lstsq(A, np.ones_like(f), rcond=None)
        err = np.abs(A @ c - 1.0)
        np.maximum.at(worst, idx, err)
    return worst


def rise_regions(mach_min, mach_max, shape, slope=None, margin=0.03, band=None):
    """Mach intervals inside the transonic ``band`` (:data:`RISE_BAND`) where ``shape`` rises or
    falls steeply: ``|d ln Cd / dM|`` above ``slope`` (:data:`RISE_SLOPE`), each widened by
    ``margin`` (the shape is smeared). Outside the band a steep start curve is an artefact of
    the track's ends (the least certain part of a smoothed derivative), not a drag rise.

    Returns
    -------
    list of (float, float)
    """
    slope = RISE_SLOPE if slope is None else slope
    band = RISE_BAND if band is None else band
    mach_min, mach_max = max(mach_min, band[0]), min(mach_max, band[1])
    if not mach_max > mach_min:
        return []
    m = np.linspace(mach_min, mach_max, max(int((mach_max - mach_min) / _EVAL_STEP) + 1, 20))
    f = np.clip(np.asarray(shape(m), float), 1e-3, None)
    r = np.abs(np.gradient(np.log(f), m))
    on = r > slope
    out = []
    i = 0
    while i < m.size:
        if on[i]:
            j = i
            while j + 1 < m.size and on[j + 1]:
                j += 1
            out.append((max(mach_min, m[i] - margin), min(mach_max, m[j] + margin)))
            i = j + 1
        else:
            i += 1
    return out


def adaptive_knots(mach_min, mach_max, shapes, tol=KNOT_TOL, coarse=COARSE, fine=FINE, regions=()):
    """Knots over [mach_min, mach_max] refined until a cubic spline follows every shape.

    Parameters
    ----------
    mach_min, mach_max : float
        Span [Mach]; the ends are rounded outwards to the :data:`FINE` grid.
    shapes : sequence of callables
        ``f(mach) -> Cd`` (> 0), the curves the spline must be able to follow.
    tol : float
        Relative error target.
    coarse, fine : float
        Largest and smallest knot spacing [Mach].
    regions : sequence of (float, float, float)
        ``(a, b, h)``: Mach intervals given spacing ``h`` from the start (a drag rise).
    Returns
    -------
    (K,) ndarray
        Increasing knots on multiples of ``fine``, ends included.
    """
    lo = math.floor(mach_min / fine + 1e-9) * fine
    hi = math.ceil(mach_max / fine - 1e-9) * fine
    if hi - lo < 3 * fine:
        mid = 0.5 * (lo + hi)
        lo, hi = mid - 1.5 * fine, mid + 1.5 * fine
    n = max(3, int(math.ceil((hi - lo) / coarse - 1e-9)))
    knots = np.unique(_snap(np.linspace(lo, hi, n + 1), fine))
    for a, b, h in regions:
        a, b = max(a, lo), min(b, hi)
        if b > a:
            k = max(int(math.ceil((b - a) / h - 1e-9)), 1)
            knots = np.unique(np.concatenate([knots, _snap(np.linspace(a, b, k + 1), fine)]))
    mach = np.linspace(lo, hi, max(int((hi - lo) / _EVAL_STEP) + 1, 50))
    targets = [np.clip(np.asarray(f(mach), float), 1e-3, None) for f in shapes]
    for _ in range(12):
        worst = _lsq_rel_error(knots, mach, targets)
        width = np.diff(knots)
        split = (worst > tol) & (width > fine * 1.5)
        if not split.any():
            break
        mids = _snap(0.5 * (knots[:-1] + knots[1:])[split], fine)
        knots = np.unique(np.concatenate([knots, mids]))
    # near the finest intervals (a steep rise) keep the spacing at most NEAR_FINE
    width = np.diff(knots)
    finest = 0.5 * (knots[:-1] + knots[1:])[width < 1.5 * fine]
    if finest.size:
        extra = []
        for a, b in zip(knots[:-1], knots[1:]):
            c = 0.5 * (a + b)
            if b - a > NEAR_FINE * 1.01 and np.min(np.abs(finest - c)) < RISE_MARGIN + 0.5 * (b - a):
                k = int(math.ceil((b - a) / NEAR_FINE - 1e-9))
                extra += list(np.linspace(a, b, k + 1)[1:-1])
        knots = np.unique(np.concatenate([knots, _snap(extra, fine)]))
    # grade: neighbours differ by at most a factor two
    for _ in range(20):
        width = np.diff(knots)
        bad = np.flatnonzero((width[1:] > 2.01 * width[:-1]) | (width[:-1] > 2.01 * width[1:]))
        if not bad.size:
            break
        mids = []
        for i in bad:
            j = i if width[i] > width[i + 1] else i + 1
            mids.append(0.5 * (knots[j] + knots[j + 1]))
        new = np.unique(np.concatenate([knots, _snap(mids, fine)]))
        if new.size == knots.size:
            break
        knots = new
    return knots


def coefficient_budget(n_samples):
    """Most spline coefficients a track of ``n_samples`` samples is given: one per sample (the
    penalty decides the rest; :data:`MIN_COEFFICIENTS` at least, a cubic on two intervals)."""
    return max(MIN_COEFFICIENTS, int(n_samples))


def sparse_knots(mach_min, mach_max, shapes, max_coefficients, sample_mach, tol=KNOT_TOL, regions=(), fine=FINE):
    """Knots of a short track, whose samples are too few for :func:`adaptive_knots`' rules.

    At most ``max_coefficients`` coefficients (:func:`coefficient_budget`). The knots start
    evenly spread, :data:`COARSE` apart or using half the budget; then the interval whose
    shapes are followed worst (a least-squares misfit above ``tol``; a drag rise's region
    counts as needing its spacing) is halved, one at a time, while the budget lasts and both
    halves still hold a sample: a velocity change between two samples is the integral of the
    drag over the Mach they span, and no knot between them can be told apart by the data.

    Parameters
    ----------
    mach_min, mach_max : float
        Span [Mach]; the ends are rounded outwards to the ``fine`` grid.
    shapes : sequence of callables
        As :func:`adaptive_knots`.
    max_coefficients : int
    sample_mach : (N,) array
        Mach of the track's samples.
    tol, regions, fine
        As :func:`adaptive_knots`.

    Returns
    -------
    (K,) ndarray
        Increasing knots on multiples of ``fine``, ends included; ``K + 2 <= max_coefficients``.
    """
    lo = math.floor(mach_min / fine + 1e-9) * fine
    hi = math.ceil(mach_max / fine - 1e-9) * fine
    if hi - lo < 3 * fine:
        mid = 0.5 * (lo + hi)
        lo, hi = mid - 1.5 * fine, mid + 1.5 * fine
    span = hi - lo
    pts = np.sort(np.asarray(sample_mach, float)[np.isfinite(sample_mach)])
    n_max = max(1, max_coefficients - 3)            # intervals the budget allows
    n = max(1, min(n_max // 2, int(math.ceil(span / COARSE - 1e-9))))   # half the budget left to refine
    knots = np.unique(np.concatenate([[lo, hi], _snap(np.linspace(lo, hi, n + 1), fine)]))
    mach = np.linspace(lo, hi, max(int(span / _EVAL_STEP) + 1, 50))
    targets = [np.clip(np.asarray(f(mach), float), 1e-3, None) for f in shapes]
    while knots.size + 2 < max_coefficients:
        worst = _lsq_rel_error(knots, mach, targets)
        w = np.diff(knots)
        mid = _snap(0.5 * (knots[:-1] + knots[1:]), fine)
        need = worst > tol
        for a, b, h in regions:
            need |= (mid >= a) & (mid <= b) & (w > 2.0 * h)
        left = np.searchsorted(pts, mid) - np.searchsorted(pts, knots[:-1])
        right = np.searchsorted(pts, knots[1:], side="right") - np.searchsorted(pts, mid, side="right")
        need &= (left > 0) & (right > 0) & (w >= 2.0 * fine - 1e-9)
        if not need.any():
            break
        i = int(np.argmax(np.where(need, worst + w, -np.inf)))
        new = np.unique(np.append(knots, mid[i]))
        if new.size == knots.size:
            break
        knots = new
    return knots


def greville(knots):
    """Greville abscissae (P,) of the cubic B-spline coefficients on ``knots`` (ends tripled)."""
    k = np.asarray(knots, float)
    t = np.concatenate([[k[0]] * 3, k, [k[-1]] * 3])
    P = k.size + 2
    return np.array([t[j + 1:j + 4].mean() for j in range(P)])


def second_difference_rows(knots):
    """Rows (P - 2, P) of divided second differences at the Greville abscissae, each scaled by
    the square root of its Mach width: ``sum (D c)^2 ~ integral f''(M)^2 dM`` for coefficients
    ``c`` of a spline ``f``."""
    g = greville(knots)
    P = g.size
    D = np.zeros((P - 2, P))
    for i in range(P - 2):
        h0, h1 = g[i + 1] - g[i], g[i + 2] - g[i + 1]
        span = 0.5 * (h0 + h1)
        D[i, i] = 1.0 / (h0 * span)
        D[i, i + 1] = -(1.0 / h0 + 1.0 / h1) / span
        D[i, i + 2] = 1.0 / (h1 * span)
        D[i] *= math.sqrt(span)
    return D


def curvature_weights(knots, *shapes):
    """Flexibility weights ``w = 1 + kappa / median(kappa)`` (P - 2,) of the penalty rows:
    ``kappa`` the relative curvature ``|base''| / base`` of the base curve at the rows' Greville
    abscissae, averaged over each row's Mach width.

    Parameters
    ----------
    knots : (K,) array
    shapes : callables
        ``f(mach) -> Cd`` of the curves whose bends allow a bend of the correction (the table,
        the data's shape); each contributes its curvature over its own median, the largest
        counts.
    """
    g = greville(knots)
    m = np.linspace(g[0], g[-1], max(int((g[-1] - g[0]) / 0.002) + 1, 20))
    w = np.ones(g.size - 2)
    for shape in shapes:
        f = np.clip(np.asarray(shape(m), float), 1e-3, None)
        d2 = np.abs(np.gradient(np.gradient(f, m), m)) / f
        kap = np.array([d2[(m >= g[i] - 1e-9) & (m <= g[i + 2] + 1e-9)].mean() if np.any(
            (m >= g[i] - 1e-9) & (m <= g[i + 2] + 1e-9)) else 0.0 for i in range(g.size - 2)])
        pos = kap[kap > 0]
        med = float(np.median(pos)) if pos.size else 1.0
        w = np.maximum(w, 1.0 + kap / med)
    return np.minimum(w, MAX_FLEX)
