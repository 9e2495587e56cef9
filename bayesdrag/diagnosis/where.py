"""Where the nominal simulation misses the track (step 7 of :mod:`bayesdrag.diagnosis`).

The normalised baseline residuals are smoothed over ~1 % of the flight; a segment is where the
smoothed residual exceeds the noise sd (merged over short breaks), by channel, with its time,
Mach range, phase (ascent, apex = within ``APEX_FRACTION`` of the flight time of the summit,
descent; ``whole flight`` for a segment through the apex that covers most of the track) and share
of the systematic residual energy (:func:`where_segments`). A start that misses the muzzle at
t = 0 by at least :data:`LAUNCH_MISFIT_SD` prior sd is a segment of its own, ``launch``
(:func:`with_launch_misfit`); a smaller misfit is noise and is not reported. What the baseline
fit absorbed into its launch state (a cross drift taken up by turning the launch heading) is not
in any channel's residual; :func:`absorbed_by_launch` says how much it was.
"""
from __future__ import annotations

import numpy as np

__all__ = ["where_segments", "with_launch_misfit", "phase", "absorbed_by_launch"]

#: apex phase: within this fraction of the flight time of the summit
APEX_FRACTION = 0.1
#: a segment through the apex covering at least this fraction of the track is the whole flight
WHOLE_FLIGHT_FRACTION = 0.8
#: a launch-prior misfit below this many prior sd is noise: not reported as a miss
LAUNCH_MISFIT_SD = 2.0
#: a launch angle the fit moved by at least this many prior sd is reported as absorbing a miss
ABSORBED_SD = 1.0


def phase(t, t_apex, t_end, t0):
    """Phase of the flight at time ``t``: ``"apex"`` within ``APEX_FRACTION`` of the flight time
    of the summit, else ``"ascent"`` or ``"descent"``.

    Parameters
    ----------
    t, t_apex, t_end, t0 : float [s]
        The time asked about, the summit's, the track's last and first.

    Returns
    -------
    str
    """
    span = max(t_end - t0, 1e-9)
    if abs(t - t_apex) <= APEX_FRACTION * span:
        return "apex"
    return "ascent" if t < t_apex else "descent"


def where_segments(t, resid_norm, weights, mach, z_model, channels, window=None):
    """Segments where the systematic (smoothed) normalised residual exceeds the noise sd.

    Parameters
    ----------
    t : (N,) s; resid_norm : (N, C) residual / sigma; weights : (N, C); mach : (N,);
    z_model : (N,) model height (for the apex); channels : tuple of str

    Returns
    -------
    list of dicts (channel, t_start, t_end, mach_min, mach_max, phase, phases, share,
    peak_sigma), sorted by share.
    """
    N, C = resid_norm.shape
    w = window or max(9, int(round(N / 100)) | 1)
    k = np.ones(w)
    smooth = np.zeros_like(resid_norm)
    for j in range(C):
        r = np.where(weights[:, j] > 0, resid_norm[:, j], 0.0)
        num = np.convolve(r, k, mode="same")
        den = np.convolve((weights[:, j] > 0).astype(float), k, mode="same")
        smooth[:, j] = num / np.maximum(den, 1)
    energy = smooth ** 2
    total = float(energy.sum())
    t_apex = float(t[int(np.argmax(z_model))]) if z_model is not None else float(t[N // 2])
    segs = []
    if total <= 0:
        return segs
    for j, c in enumerate(channels):
        on = np.abs(smooth[:, j]) > 1.0
        # close short breaks, drop short runs
        idx = np.flatnonzero(on)
        if idx.size == 0:
            continue
        runs = np.split(idx, np.flatnonzero(np.diff(idx) > w) + 1)
        for run in runs:
            a, b = int(run[0]), int(run[-1])
            if b - a + 1 < max(3, w // 2):
                continue
            sl = slice(a, b + 1)
            share = float(energy[sl, j].sum() / total)
            ph_t = [phase(tt, t_apex, t[-1], t[0]) for tt in t[sl]]
            phases = [p for p in ("ascent", "apex", "descent") if p in ph_t]
            e_by = {p: float(energy[sl, j][np.array(ph_t) == p].sum()) for p in phases}
            m = mach[sl]
            m = m[np.isfinite(m)]
            segs.append({"channel": c, "t_start": float(t[a]), "t_end": float(t[b]),
                         "mach_min": float(m.min()) if m.size else None,
                         "mach_max": float(m.max()) if m.size else None,
                         "phase": _phase_name(phases, e_by, t[a], t[b], t[0], t[-1]), "phases": phases,
                         "share": share,
                         "peak_sigma": float(np.max(np.abs(smooth[sl, j])))})
    segs.sort(key=lambda s: -s["share"])
    return segs


def _phase_name(phases, energy_by_phase, ta, tb, t0, t1):
    """The phase a segment is named by: ``whole flight`` when it runs from ascent to descent over
    most of the track, else the phase holding most of its residual energy."""
    if "ascent" in phases and "descent" in phases and tb - ta >= WHOLE_FLIGHT_FRACTION * max(t1 - t0, 1e-9):
        return "whole flight"
    return max(energy_by_phase, key=energy_by_phase.get)


def absorbed_by_launch(prior_terms, prior_sd, x_end):
    """What the baseline fit took up by moving its launch angles from the round's values.

    Parameters
    ----------
    prior_terms : dict name -> float
        Normalised launch-prior misfit ``(mean - value) / sd`` of the baseline fit.
    prior_sd : dict name -> float
        The priors' sd (degrees for ``heading`` and ``elevation``).
    x_end : float [m]
        Range of the track's last sample.

    Returns
    -------
    list of dict
        ``{"name", "moved_deg", "moved_sd", "drift_m", "channel"}`` for ``heading`` (cross drift,
        channel y) and ``elevation`` (height, channel z) moved by at least :data:`ABSORBED_SD`
        prior sd: ``drift_m`` is how far that turn moves the track's end.
    """
    out = []
    for name, channel in (("heading", "y"), ("elevation", "z")):
        k = prior_terms.get(name)
        if k is None or abs(k) < ABSORBED_SD or name not in prior_sd:
            continue
        moved = -float(k) * float(prior_sd[name])
        out.append({"name": name, "moved_deg": moved, "moved_sd": abs(float(k)), "channel": channel,
                    "drift_m": float(abs(x_end) * np.tan(np.radians(abs(moved))))})
    return out


def with_launch_misfit(where, t_first, prior_terms, gap):
    """Add the launch-prior misfit to the where-list as a segment ``launch`` (from t = 0 to the
    first sample) when there is one and a gap, and rescale the channels' shares to the rest of
    the gap so that all shares add up to at most 1.

    Parameters
    ----------
    where : list of dict
        :func:`where_segments`; changed in place.
    t_first : float [s]
        Time of the track's first sample.
    prior_terms : dict name -> float
        Normalised launch-prior misfit ``(mean - value) / sd`` of the baseline fit.
    gap : float
        Baseline gap (chi2 above its noise floor, prior misfit included).

    Returns
    -------
    list of dict
        ``where``, sorted by share.
    """
    prior_chi2 = float(sum(v * v for v in prior_terms.values()))
    worst = max((abs(v) for v in prior_terms.values()), default=0.0)
    if prior_chi2 > 0 and gap > 0 and worst >= LAUNCH_MISFIT_SD:
        where.append({"channel": "launch", "t_start": 0.0, "t_end": float(t_first),
                      "mach_min": None, "mach_max": None, "phase": "launch", "phases": ["launch"],
                      "share": float(min(prior_chi2 / max(gap + prior_chi2, 1e-9), 1.0)),
                      "peak_sigma": float(max(abs(v) for v in prior_terms.values())),
                      "prior_misfit_sd": prior_terms})
        # channel shares are of the systematic residual energy; rescale them to the part of the
        # gap that is not launch-prior misfit so that all shares add up to at most 1
        launch_share = where[-1]["share"]
        for w in where[:-1]:
            w["share"] *= 1.0 - launch_share
        where.sort(key=lambda w: -w["share"])
    return where
