"""How well a fit fits, and where its Cd is determined: the gate no answer passes unexamined.

:func:`assess` looks at a finished maximum-likelihood fit and returns ``ml.quality`` of
``result.json`` plus the ``cd`` rows with ``determined`` and ``band_sd`` filled in:

Goodness of fit, per channel
    ``chi2_per_sample`` = mean squared residual over the noise variance: against the round's
    ``[radar] sigma`` where given, else against the noise the track's own high-frequency content
    shows (:func:`bayesdrag.estimate.model.noise.noise_and_outliers`), never against the fit's own
    residual rms (which would make every fit perfect). Above :data:`CHI2_LIMIT` the residuals
    are far above the noise: the model misses the track. The lag-1 autocorrelation of the
    residuals above :data:`ACF_LIMIT` says the misfit is structured (model error), not noise,
    when the residuals are not negligible (:data:`STRUCTURED_CHI2_MIN`: a noise-free track's
    smooth 1e-5 m residuals are no misfit). Far below the stated noise
    (:data:`SIGMA_HIGH_CHI2`) a note says the round's sigma looks too large.
Bands
    ``band_sd`` of each ``cd`` row is the sd behind the ML band the result stands by: the
    Cramér-Rao sd when the residuals look like the noise, and the larger of it and the
    colored-residual sd (Morelli & Klein: the residuals' own size and correlation, a sandwich
    estimate) when they do not. So a fit whose residuals show model error gets the wider band,
    and a white-noise fit keeps the Cramér-Rao one.
Model error
    A row's ``model_error_sd`` (:mod:`bayesdrag.estimate.cd.model_error`: the Cd shift an effect
    the diagnosis finds, or a robust fit of the noise, implies) is added to its band in squares.
Where Cd is determined
    A ``cd`` row is determined when its band less the declared systematic sources' share (those
    widen the total band, but a well-measured Cd conditional on a known 1 % density uncertainty
    is still determined by the data) is below 1 % of Cd (:func:`~bayesdrag.estimate.cd.claims.claimed`), it
    lies inside the Mach span the data cover, the drag model is not clamped there (beyond its
    end knots the spline is held flat), and no coefficient acting there sits at its bound.
    ``undetermined`` lists the Mach intervals of the grid where it is not.
Short tracks
    A track of a few samples (8-24: a Doppler report every 100 m, a sparse tracking radar) sees
    the drag only as its integral between consecutive samples; how Cd bends between them is
    not in the data, and the smoothness penalty's band, which assumes the curve is as smooth
    as the penalty, does not hold it. On a short track (fewer samples than the knot rules want
    coefficients, ``ml.model_size.short``) each row's ``band_sd`` therefore includes
    :func:`unresolved_bend`: half the error a curve known only at points the local sample gap
    apart in Mach can have, bounded by the bends the standard drag curves have at that Mach
    (steep in the transonic rise, gentle above Mach 1.6).
Rigid models
    ``poly2``, ``poly2-split`` and ``reference-scale`` cannot follow every curve, and their
    Cramér-Rao band holds only the noise, not their shape error; on a coarse or noisy track the
    residuals may not show it either. :func:`check_against_flexible` compares their curve with
    the default flexible fit of the same track: where the two differ by more than
    :data:`RIGID_K` sd of the flexible band, the rigid curve is not determined there, and the
    result says so.
Problems
    One line each (``problems``), also printed by the CLI: residuals far above the noise,
    structured residuals, parameters at bounds, clamped or flat segments, a smoothing weight at
    the end of its grid, launch values of the round the track contradicts.
"""
from __future__ import annotations

import math

import numpy as np

from ...errors import FitWarning
from ..model.noise import noise_and_outliers
from .claims import DataBand, claim, claimed

#: a channel whose residuals have a mean square above this many noise variances misses the track
CHI2_LIMIT = 4.0
#: lag-1 residual autocorrelation above which the residuals are structured (white: ~0 +- 2/sqrt(N))
ACF_LIMIT = 0.5
#: structured residuals count as model error only when they are this large (chi2 per sample):
#: a noise-free track's residuals (1e-5 of the noise) are smooth, and say nothing of the model
STRUCTURED_CHI2_MIN = 0.25
#: a channel's residuals below this chi2 per sample (rms under a third of the round's sigma, on
#: more than 20 samples) say the stated sigma is too large: a note
SIGMA_HIGH_CHI2 = 0.1
#: a rigid model's curve further than this many flexible-band sd from the flexible fit's misses
RIGID_K = 3.0
#: a coefficient within this fraction of its bound range of a bound sits at it
BOUND_FRACTION = 1e-6


#: Mach nodes and coefficients ``A`` of the bend bound: a drag curve known only at Mach points
#: ``g`` apart is interpolated (cubic, in ln Cd) to within ``A(M) g^2``. Measured on the ten
#: standard curves (G1, G2, G5, G6, G7, G8, GI, GS, RA4 and M101) for g = 0.05-0.6, every phase
#: of the points: each coefficient is the largest error / g^2 over the tables between its two
#: neighbouring nodes, and a row takes the larger of the two nodes around it
#: (tests/unit/test_short_tracks.py checks the bound against the tables)
BEND_MACH = (0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6, 1.7, 1.8, 1.9, 2.0, 2.2, 2.4, 2.6,
             2.8)
BEND_A = (0.9, 1.4, 3.9, 4.4, 12.3, 29.0, 29.0, 28.1, 5.9, 3.0, 1.31, 0.9, 0.64, 0.4, 0.37, 0.3, 0.22, 0.125, 0.115,
          0.078, 0.046)
#: largest bend [ln Cd] between two samples: a whole drag rise (the standard curves rise by at
#: most a factor 2.3 across one, ln 2.3 = 0.83)
BEND_CAP = 0.85


def bend_coefficient(mach):
    """``A(M)`` of :data:`BEND_A` at each Mach: the larger of the two neighbouring nodes
    (held beyond the ends)."""
    m = np.atleast_1d(np.asarray(mach, float))
    nodes, a = np.asarray(BEND_MACH), np.asarray(BEND_A)
    i = np.clip(np.searchsorted(nodes, m, side="right") - 1, 0, nodes.size - 1)
    j = np.clip(i + 1, 0, nodes.size - 1)
    out = np.maximum(a[i], a[j])
    out[m <= nodes[0]] = a[0]
    out[m >= nodes[-1]] = a[-1]
    return out


def _gap(points, m):
    """Width of the interval of sorted ``points`` that holds each ``m`` (the nearest one
    beyond their range)."""
    i = np.clip(np.searchsorted(points, m, side="right"), 1, points.size - 1)
    return points[i] - points[i - 1]


def unresolved_bend(mach, cd, sample_mach, knots=None):
    """The sd [relative to Cd] of what a short track cannot resolve at each ``mach``.

    The data hold only the drag's integral between consecutive samples; the fit resolves
    Cd(M) no finer than the wider of that gap and its knot interval (within which the model
    imposes its own shape: a cubic, or the table's). Two things are unseen over that width
    ``g``: how the true curve bends, at most ``A(M) g^2`` (:data:`BEND_A`, a whole drag rise at
    most, :data:`BEND_CAP`), and how the fitted curve itself bends within ``g`` of the row (its
    largest departure from a straight line in ln Cd there: wiggles the data cannot confirm). The
    error is at most their sum.

    Parameters
    ----------
    mach, cd : (K,) array
        Rows' Mach numbers (increasing) and the fitted Cd there (> 0).
    sample_mach : (N,) array
        Mach of the fitted flight at the samples (any order; an ascent and a descent through
        the same Mach both count).
    knots : (J,) array, optional
        The spline's knots.

    Returns
    -------
    (K,) ndarray
        ``expm1(bound) / 2``: the bound taken as two sd.
    """
    m = np.asarray(mach, float)
    lc = np.log(np.clip(np.asarray(cd, float), 1e-6, None))
    s = np.unique(np.asarray(sample_mach, float)[np.isfinite(sample_mach)])
    if s.size < 2:
        return np.full(m.size, math.expm1(BEND_CAP) / 2.0)
    i = np.clip(np.searchsorted(s, m, side="right"), 1, s.size - 1)
    gaps = np.diff(s)
    # a spline's value at M depends on the neighbouring intervals too: the widest of the three
    gap = np.maximum.reduce([gaps[i - 1], gaps[np.maximum(i - 2, 0)], gaps[np.minimum(i, gaps.size - 1)]])
    if knots is not None and len(knots) > 1:
        gap = np.maximum(gap, _gap(np.unique(np.asarray(knots, float)), m))
    # ... and the curve may bend anywhere within that reach
    reach = m[:, None] + gap[:, None] * np.linspace(-1.0, 1.0, 21)[None, :]
    coef = bend_coefficient(reach.ravel()).reshape(reach.shape).max(axis=1)
    truth = np.minimum(coef * gap**2, BEND_CAP)
    own = np.array([_wiggle(m, lc, x - g, x + g) for x, g in zip(m, gap)])
    return np.expm1(truth + own) / 2.0


def _wiggle(m, lc, lo, hi):
    """Largest departure of ``lc(m)`` from its least-squares straight line over [lo, hi]."""
    sel = (m >= lo - 1e-12) & (m <= hi + 1e-12)
    if sel.sum() < 3:
        return 0.0
    x, y = m[sel], lc[sel]
    p = np.polyfit(x - x.mean(), y, 1)
    return float(np.max(np.abs(y - np.polyval(p, x - x.mean()))))


def lag1(r):
    """Lag-1 autocorrelation of a residual series (0 for fewer than 3 samples)."""
    r = np.asarray(r, float)
    if r.size < 3:
        return 0.0
    e = r - r.mean()
    d = float(e @ e)
    return float(e[1:] @ e[:-1] / d) if d > 0 else 0.0


def intervals(mach, flag):
    """Contiguous Mach intervals [lo, hi] where ``flag`` is True."""
    out = []
    i = 0
    while i < flag.size:
        if flag[i]:
            j = i
            while j + 1 < flag.size and flag[j + 1]:
                j += 1
            out.append([float(mach[i]), float(mach[j])])
            i = j + 1
        else:
            i += 1
    return out


def channel_fit(res, track, channels, sigma_given, noise=None):
    """Per-channel goodness of fit.

    Parameters
    ----------
    res : MLResult
    track : RadarTrack
    channels : sequence of str
    sigma_given : dict
        The round's noise sd per channel (used where given).
    noise : (dict, dict), optional
        ``(sigma, source)`` from :func:`bayesdrag.estimate.model.noise.noise_and_outliers` already
        computed on the whole track (Scheme 2 windows share it).

    Returns
    -------
    dict channel -> {"n", "rms", "noise_sd", "noise_source", "chi2_per_sample", "lag1"}
    """
    if noise is None:
        sig_data, source, _ = noise_and_outliers(track, channels, sigma_given)
    else:
        sig_data, source = noise
    out = {}
    w = res.weights if res.weights is not None else None
    for j, c in enumerate(channels):
        r = np.asarray(res.residuals[c], float)
        wj = np.ones_like(r) if w is None else w[:, j]
        n = float(wj.sum())
        ms = float(np.sum(wj * r**2) / max(n, 1.0))
        s = float(sig_data[c])
        out[c] = {"n": int(round(n)), "rms": math.sqrt(ms), "noise_sd": s, "noise_source": source[c],
                  "chi2_per_sample": ms / s**2 if s > 0 else float("inf"), "lag1": lag1(r[wj > 0])}
    return out


def sigma_notes(fit):
    """A note when channels' residuals are far below the round's stated noise sd (a sigma 10x
    too large, or a noise-free track): the bands, which assume the stated sigma, are too wide.
    The converse, a sigma too small, is a misfit (``chi2_per_sample`` above :data:`CHI2_LIMIT`)."""
    low = {c: f["rms"] / f["noise_sd"] for c, f in fit.items()
           if f["noise_source"] == "round" and f["n"] > 20 and f["chi2_per_sample"] < SIGMA_HIGH_CHI2}
    if not low:
        return []
    ratios = ", ".join(f"{c} {r:.2g}" for c, r in low.items())
    return [f"the residual rms is far below the round's noise sd ({ratios} of it): the stated sigma looks too large "
            f"(or the track is noise-free); the bands, which assume it, are wider than the data need"]


def _clamped(drag_model, mach):
    """Rows beyond a spline's end knots (held flat there) or beyond a table's ends."""
    fr = getattr(drag_model, "knots", None)
    if fr is None:
        return np.zeros(mach.size, bool)
    lo, hi = fr[0], fr[-1]
    return (mach < lo - 1e-9) | (mach > hi + 1e-9)


def _at_bound_support(res, drag_model, mach, lower, upper):
    """Rows where a coefficient at its bound acts (its basis function is non-zero there), and
    the names of those coefficients."""
    P = drag_model.n_params
    th = res.theta[:P]
    span = upper[:P] - lower[:P]
    at = np.isfinite(span) & ((th - lower[:P] <= BOUND_FRACTION * span) | (upper[:P] - th <= BOUND_FRACTION * span))
    at &= res.free[:P]
    if not at.any():
        return np.zeros(mach.size, bool), []
    B = drag_model.jacobian(mach)
    hit = np.abs(B[:, at]).max(axis=1) > 1e-3 * np.abs(B).max(axis=1).clip(1e-300)
    return hit, [res.names[j] for j in np.flatnonzero(at)]


def assess(fit1, rows, track, sigma_given=None):
    """Quality of a Scheme 1 ML fit (:func:`assess_claims` without its :class:`DataBand`)."""
    return assess_claims(fit1, rows, track, sigma_given)[0]


def assess_claims(fit1, rows, track, sigma_given=None):
    """Quality of a Scheme 1 ML fit and the data's band of its rows.

    Parameters
    ----------
    fit1 : Scheme1Fit
        The fit (:func:`bayesdrag.estimate.scheme1.fit.fit_scheme1`): its ML result, problem, start,
        smoothing and launch check are read.
    rows : list of dict
        ``cd`` rows (``mach``, ``ml``, ``crb_sd``, ``crb_sd_colored``); updated in place with
        ``band_sd`` and ``determined``.
    track : RadarTrack
    sigma_given : dict, optional
        The round's noise sd per channel.

    Returns
    -------
    dict
        ``ml.quality`` of result.json.
    """
    res, prob = fit1.ml, fit1.problem
    chans = prob.channels
    fit = channel_fit(res, track, chans, sigma_given or {})
    problems = []
    misfit = [c for c, f in fit.items() if f["chi2_per_sample"] > CHI2_LIMIT]
    structured = [c for c, f in fit.items() if f["lag1"] > ACF_LIMIT and f["n"] > 20
                  and f["chi2_per_sample"] > STRUCTURED_CHI2_MIN]
    for c in misfit:
        f = fit[c]
        problems.append(FitWarning("misfit", f"channel {c}: residual rms {f['rms']:.3g} against a noise sd of "
                                   f"{f['noise_sd']:.3g} ({'the round' if f['noise_source'] == 'round' else 'estimated from the track'}): "
                                   f"the model misses the track (chi2 per sample {f['chi2_per_sample']:.1f})"))
    ar = set(prob.ar_channels)
    for c in structured:
        how = ("fitted as white noise plus an AR(1) model-error process (generalised least squares)"
               if c in ar else "the band uses the colored-residual sd")
        problems.append(FitWarning("autocorrelated", f"channel {c}: residuals strongly autocorrelated (lag-1 "
                                   f"{fit[c]['lag1']:.2f}): model error, not noise; {how}"))
    honest_colored = bool(misfit or structured or any(f["chi2_per_sample"] > 1.5 for f in fit.values()))
    mach = np.array([r["mach"] for r in rows], float)
    ml = np.array([r["ml"] for r in rows], float)
    crb = np.array([r["crb_sd"] for r in rows], float)
    crbc = np.array([r.get("crb_sd_colored", r["crb_sd"]) for r in rows], float)
    # the ar1 noise's own uncertainty (noise_model_sd) is statistical: it widens the model's band
    nm = np.array([r.get("noise_model_sd", 0.0) for r in rows], float)
    crb_n = np.sqrt(crb**2 + nm**2)
    band = np.maximum(crb_n, crbc) if honest_colored else crb_n
    size = getattr(fit1, "model_size", None) or {}
    notes = [size["note"]] if size.get("note") else []
    notes += sigma_notes(fit)
    if size.get("short"):
        bend = unresolved_bend(mach, ml, res.mach, getattr(prob.model.drag, "knots", None)) * np.abs(ml)
        band = np.sqrt(band**2 + bend**2)
        worst = max(f["chi2_per_sample"] for f in fit.values())
        if worst > CHI2_LIMIT:
            # a short track leaves too few residuals to estimate the misfit's correlation (the
            # colored band): the whole band is scaled by the misfit's size instead (Birge ratio)
            band = band * math.sqrt(worst)
        notes.append(f"a short track ({size['samples']} samples, fewer than the {size['knot_rules']} spline "
                     f"coefficients a dense track would get): each band includes how far Cd may bend between "
                     f"samples (up to {_largest_gap(res.mach):.2f} Mach apart), which the data cannot show")
    origin = (fit1.launch_check or {}).get("origin")
    if origin and origin.get("density_offset"):
        # a frame not at the gun's height: the air the fit flew in is not the air the shell
        # flew in; Cd is uncertain by the density difference (as one sd)
        band = np.sqrt(band**2 + (origin["density_offset"] * np.abs(ml))**2)
    # the data's band (noise, correlated residuals, unresolved bends) less the declared sources'
    # share: what "determined" is judged on, with the model error (:mod:`.model_error`) added
    sys_var = np.clip(crb**2 - np.array([r.get("crb_sd_statistical", r["crb_sd"]) for r in rows], float)**2, 0, None)
    dm = prob.model.drag
    clamped = _clamped(dm, mach)
    bound_rows, bound_names = _at_bound_support(res, dm, mach, prob.lower, prob.upper)
    start = fit1.start
    lo, hi = (float(np.nanmin(res.mach)), float(np.nanmax(res.mach)))
    inside = (mach >= lo - 1e-4) & (mach <= hi + 1e-4)  # the grid is rounded to 1e-4
    data = DataBand(band, sys_var, inside & ~clamped & ~bound_rows)
    claim(rows, data)
    det = np.array([r["determined"] for r in rows], bool)
    if clamped.any():
        for a, b in intervals(mach, clamped):
            problems.append(FitWarning("cd_held_flat", f"Cd is held flat over Mach {a:.3f}-{b:.3f} (beyond the drag "
                                       f"model's span): not determined there"))
    if bound_names:
        for a, b in intervals(mach, bound_rows):
            problems.append(FitWarning("cd_at_bound", f"Cd sits at a bound of its model over Mach {a:.3f}-{b:.3f} "
                                       f"({', '.join(bound_names)}): not determined there", tuple(bound_names)))
    ic_bound = [w for w in res.warnings if w.kind == "at_bound" and not set(w.params) & set(bound_names)]
    problems += ic_bound
    sm = fit1.smoothing
    if sm and sm.get("at_grid_end") == "flexible":
        problems.append(FitWarning("smoothing_edge", "the smoothing weight is at the flexible end of its grid: the "
                                   "data ask for more freedom than the drag model has (the band may be too narrow "
                                   "where Cd bends)"))
    lc = fit1.launch_check or {}
    for c in lc.get("conflicts", []):
        if not c.get("secondary"):
            problems.append(FitWarning("launch_conflict", c["message"]))
    undetermined = intervals(mach, ~det)
    outliers = one_sided_outliers(fit1)
    if outliers is not None:
        notes.append(outliers["line"])
    quality = {
        "ok": not (misfit or structured or bound_names or ic_bound or origin),
        "channels": fit,
        "band": "colored" if honest_colored else "cramer-rao",
        "mach_range_data": [lo, hi],
        "undetermined": undetermined,
        "clamped": intervals(mach, clamped),
        "at_bounds": bound_names + [p for w in ic_bound for p in w.params],
        "smoothing_at_grid_end": sm.get("at_grid_end") if sm else None,
        "launch": lc or None,
        "start": ({"mach_span": list(start.mach_span), "notes": list(start.notes)} if start is not None else None),
        "problems": problems,
        "notes": notes,
    }
    if outliers is not None:
        quality["outliers"] = outliers
    return quality, data


def one_sided_outliers(fit1):
    """``ml.quality.outliers`` of a fit whose noise model took one-sided outliers
    (:mod:`bayesdrag.estimate.model.contamination`, engaged by the residuals' evidence): the model,
    per channel the tail's side, fraction and mean offset [core sd], the samples down-weighted
    (weight below one half) and the weight taken off, and a one-line note; None when it did not
    engage."""
    rec = (getattr(fit1, "noise", None) or {}).get("contamination") or {}
    if not rec.get("engaged"):
        return None
    chans = {c: {k: e[k] for k in ("side", "fraction", "tail_sd", "down_weighted", "weight_lost", "lr",
                                   "lr_asymmetry", "threshold", "asymmetry_threshold") if k in e}
             for c, e in rec["channels"].items() if e.get("engaged")}
    parts = [f"{c}: {len(e.get('down_weighted', []))} {e['side']} samples down-weighted "
             f"({e.get('weight_lost', 0):.3g} samples' weight, tail {100 * max(e['fraction']):.2g} % of "
             f"{max(e['tail_sd']):.2g} sd)" for c, e in chans.items()]
    return {"model": rec["model"], "channels": chans,
            "line": ("one-sided outliers (" + "; ".join(parts) + "): fitted as a skewed contamination of the "
                     "noise (a Gaussian core and a one-sided tail), so they do not pull Cd")}


def _largest_gap(sample_mach):
    s = np.unique(np.asarray(sample_mach, float)[np.isfinite(sample_mach)])
    return float(np.max(np.diff(s))) if s.size > 1 else 0.0


def check_against_flexible(rows, flexible_rows, quality, model_name, k=RIGID_K):
    """Compare a rigid model's ``cd`` rows with the flexible fit's on the same grid.

    Rows where ``|rigid - flexible| > k * sqrt(band_rigid^2 + band_flexible^2)`` are the ones
    the check withdraws (returned; the caller claims the rows again without them,
    :func:`~bayesdrag.estimate.cd.claims.claim`), and ``quality`` gains ``rigid_check`` and a
    problem line.

    Parameters
    ----------
    rows, flexible_rows : list of dict
        ``cd`` rows (after :func:`assess`) on grids over the same Mach span.
    quality : dict
        The rigid fit's ``ml.quality`` (updated in place).
    model_name : str
    k : float

    Returns
    -------
    (M,) bool ndarray
        The rows withdrawn.
    """
    fm = np.array([r["mach"] for r in flexible_rows], float)
    fc = np.array([r["ml"] for r in flexible_rows], float)
    fs = np.array([r["band_sd"] for r in flexible_rows], float)
    mach = np.array([r["mach"] for r in rows], float)
    inside = (mach >= fm.min() - 1e-9) & (mach <= fm.max() + 1e-9)
    f_cd = np.interp(mach, fm, fc)
    f_sd = np.interp(mach, fm, fs)
    z = np.zeros(mach.size)
    for i, r in enumerate(rows):
        sd = math.hypot(r["band_sd"], f_sd[i])
        z[i] = abs(r["ml"] - f_cd[i]) / sd if sd > 0 else 0.0
    off = inside & (z > k)
    worst = int(np.argmax(np.where(inside, z, 0.0))) if mach.size else 0
    quality["rigid_check"] = {"against": "spline", "k": k, "max_z": float(z[worst]) if mach.size else 0.0,
                              "mach_of_max": float(mach[worst]) if mach.size else None,
                              "misses": intervals(mach, off)}
    if off.any():
        a, b = mach[off].min(), mach[off].max()
        rel = (rows[worst]["ml"] / f_cd[worst] - 1.0) * 100.0
        quality["problems"].append(FitWarning(
            "rigid_model", f"the {model_name} curve misses the flexible fit of the same track by up to {z[worst]:.1f} sd "
            f"({rel:+.1f} % at Mach {mach[worst]:.2f}) over Mach {a:.2f}-{b:.2f}: its band does not hold "
            f"its shape error; not determined there"))
        quality["ok"] = False
    return off


def assess_window(res, channels, noise):
    """Quality fields of one Scheme 2 window (a constant Cd, parameter 0 of ``res``).

    Parameters
    ----------
    res : MLResult
    channels : sequence of str
    noise : (dict, dict)
        ``(sigma, source)`` of the whole track.

    Returns
    -------
    dict
        ``band_sd``, ``determined`` and ``quality`` (``channels`` as in :func:`channel_fit`,
        ``ok``, ``problems``).
    """
    fit = channel_fit(res, None, channels, {}, noise=noise)
    problems = []
    misfit = [c for c, f in fit.items() if f["chi2_per_sample"] > CHI2_LIMIT]
    structured = [c for c, f in fit.items() if f["lag1"] > ACF_LIMIT and f["n"] > 20]
    for c in misfit:
        problems.append(FitWarning("misfit", f"channel {c}: residual rms {fit[c]['rms']:.3g} against a noise sd of "
                                   f"{fit[c]['noise_sd']:.3g}: the constant Cd misses this window"))
    for c in structured:
        problems.append(FitWarning("autocorrelated", f"channel {c}: residuals autocorrelated (lag-1 "
                                   f"{fit[c]['lag1']:.2f}): model error"))
    colored = bool(misfit or structured or any(f["chi2_per_sample"] > 1.5 for f in fit.values()))
    cd = float(res.theta[0])
    band = max(float(res.crb[0]), float(res.crb_colored[0])) if colored else float(res.crb[0])
    at_bound = any(w.kind == "at_bound" for w in res.warnings)
    if at_bound:
        problems.append(FitWarning("at_bound", "Cd or the window's state sits at a bound"))
    if not res.converged:
        problems.append(FitWarning("not_converged", f"not converged: {res.message}"))
    b, d = claimed([cd], DataBand.plain([band], usable=res.converged and not at_bound))
    return {"band_sd": float(b[0]), "determined": bool(d[0]),
            "quality": {"ok": not (misfit or structured or at_bound or not res.converged),
                        "band": "colored" if colored else "cramer-rao", "channels": fit,
                        "problems": problems}}
