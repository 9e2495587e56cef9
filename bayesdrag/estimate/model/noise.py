"""Noise sd and gross outliers from a track's own high-frequency content.

Per channel, the residual about a local cubic (Savitzky-Golay over :data:`HF_WINDOW` samples,
never across a dropout or gap) measures what no smooth flight can produce: noise. Its robust sd,
corrected for the part the smoother absorbs, estimates the noise sd; samples further than
``OUTLIER_K`` robust sd from the local curve are gross outliers. The fit's residuals are never
used for this: a misfit would inflate the estimate and hide itself (the fit's goodness-of-fit
gate, :mod:`bayesdrag.estimate.cd.quality`, compares the two).

The outlier rule is local. A gross outlier is a lone sample that stands out from its
neighbours' residuals; where a projectile decelerates fast and the track is coarse (a bullet
through the transonic drag rise sampled every 0.1 s), the local cubic cannot follow the flight
and several neighbouring samples share a large, smooth residual that is flight, not error. The
scale a sample is judged against is therefore the larger of the channel's robust sd, the robust
sd of the residual over its own neighbourhood (:data:`LOCAL_WINDOW` samples) and
:data:`OUTLIER_MIN_SD` (a noise-free track has a residual sd near zero, and without a floor the
smoother's own round-off flagged half its samples). A sample whose interval to its neighbour
differs from the one before by more than :data:`END_IRREGULARITY` at either end of the track (the
impact sample of a simulated track) is not smoothed with the others.
"""
from __future__ import annotations

import math

import numpy as np

from .filters import savgol_coeffs, savgol_smooth

#: gross-outlier threshold in robust sd of the high-frequency residual
OUTLIER_K = 5.0
#: Savitzky-Golay window (samples) and order of the local smoother for noise and outliers
HF_WINDOW, HF_ORDER = 11, 3
#: neighbourhood [samples] over which the local residual scale of the outlier rule is taken
LOCAL_WINDOW = 11
#: the smallest scale [m, m/s] a sample is judged an outlier against: 5 mm is never a gross error,
#: and below it are round-off and the 4 decimals a track file holds
OUTLIER_MIN_SD = 1e-3
#: relative change of the sample interval at a track's first or last sample that sets it apart
END_IRREGULARITY = 0.1


def hf_residual_t(t, z, window=HF_WINDOW, order=HF_ORDER):
    """:func:`hf_residual` applied per run of regular sampling: the track is split where a
    sample interval exceeds 1.5 times the median (dropouts, gaps), so the smoother never
    bridges a gap. Runs shorter than the window get residual 0 and ``valid`` False."""
    dtt = np.diff(t)
    med = np.median(dtt) if dtt.size else 1.0
    cuts = np.flatnonzero(dtt > 1.5 * med) + 1
    if dtt.size >= 2:     # an end sample off the regular grid (the impact sample) stands apart
        extra = []
        if abs(dtt[0] / dtt[1] - 1.0) > END_IRREGULARITY:
            extra.append(1)
        if abs(dtt[-1] / dtt[-2] - 1.0) > END_IRREGULARITY:
            extra.append(z.size - 1)
        cuts = np.unique(np.concatenate([cuts, np.asarray(extra, dtype=cuts.dtype)]))
    e = np.zeros_like(z)
    valid = np.zeros(z.size, bool)
    fac = 1.0
    for seg in np.split(np.arange(z.size), cuts):
        if seg.size >= window:
            e[seg], fac = hf_residual(z[seg], window, order)
            valid[seg] = True
    if not valid.any():
        e, fac = hf_residual(z, window, order)
        valid[:] = True
    return e, fac, valid


def hf_residual(z, window=HF_WINDOW, order=HF_ORDER):
    """Residual of a channel about a local polynomial smoother and its variance factor.

    Parameters
    ----------
    z : (N,) array
    window, order : int

    Returns
    -------
    e : (N,) array
        ``z - smoothed(z)``.
    factor : float
        ``var(e) / sigma^2`` for white noise of sd sigma (``1 - h0``, h0 the smoother's central
        weight).
    """
    n = z.size
    w = min(window, n if n % 2 else n - 1)
    if w <= order + 1:
        return np.zeros_like(z), 1.0
    e = z - savgol_smooth(z, w, order)
    h0 = float(savgol_coeffs(w, order)[w // 2])  # central weight of the smoother
    return e, max(1.0 - h0, 1e-3)


def robust_sd(e):
    """Robust standard deviation of a sample: 1.4826 times its median absolute deviation (the
    sd of a Gaussian sample, unmoved by a few gross outliers).

    Parameters
    ----------
    e : (N,) array
        Values, in their own unit.

    Returns
    -------
    float
        The robust sd, in the unit of ``e``.
    """
    med = np.median(e)
    return 1.4826 * float(np.median(np.abs(e - med)))


def local_robust_sd(e, valid, window=LOCAL_WINDOW):
    """Robust sd (1.4826 MAD) of ``e`` over the ``window`` samples centred on each sample, from
    the valid ones (0 where fewer than 3 are valid).

    Parameters
    ----------
    e : (N,) array
    valid : (N,) bool array
    window : int, odd

    Returns
    -------
    (N,) array, the unit of ``e``
    """
    h = window // 2
    x = np.where(valid, e, np.nan)
    pad = np.pad(x, h, constant_values=np.nan)
    win = np.lib.stride_tricks.sliding_window_view(pad, window)
    ok = np.isfinite(win).sum(axis=1) >= 3
    out = np.zeros(e.size)
    if ok.any():
        w = win[ok]
        med = np.nanmedian(w, axis=1)
        out[ok] = 1.4826 * np.nanmedian(np.abs(w - med[:, None]), axis=1)
    return out


def noise_and_outliers(track, channels, sigma_given=None, k=OUTLIER_K):
    """Noise sd per channel and a gross-outlier mask, from the data's high-frequency content.

    Parameters
    ----------
    track : RadarTrack
    channels : sequence of str
    sigma_given : dict, optional
        A-priori sd per channel (the round's ``[radar] sigma``); used where given.
    k : float
        Outlier threshold in robust sd of the high-frequency residual.

    Returns
    -------
    sigma : dict channel -> sd; source : dict channel -> "round" | "estimated";
    outliers : (N, C) bool array
    """
    sigma, source = {}, {}
    out = np.zeros((track.n, len(channels)), bool)
    for j, c in enumerate(channels):
        z = np.asarray(track.channels[c], float)
        flagged = np.zeros(z.size, bool)
        e, fac, valid = hf_residual_t(track.t, z)
        for _ in range(3):  # re-smooth with the flagged samples interpolated over
            zz = z.copy()
            if flagged.any() and (~flagged).sum() > 2:
                zz[flagged] = np.interp(track.t[flagged], track.t[~flagged], z[~flagged])
            e, fac, valid = hf_residual_t(track.t, zz)
            use = valid & ~flagged
            s = robust_sd(e[use]) if use.sum() > 10 else robust_sd(e)
            if sigma_given and c in sigma_given:
                # never call a sample an outlier for deviating by less than k stated sd: on a
                # short or coarsely quantised track the smoother follows the data too closely
                # and its residual sd is far below the noise (Warner's 16-sample reports)
                s = max(s, float(sigma_given[c]))
            # the local scale without the samples the channel-wide rule would flag: a lone spike
            # (and the smear the smoother gives its neighbours) must not raise its own yardstick
            spike = np.abs(z - (zz - e)) > k * max(s, OUTLIER_MIN_SD)
            scale = np.maximum(np.maximum(s, local_robust_sd(e, valid & ~spike)), OUTLIER_MIN_SD)
            new = valid & (np.abs(z - (zz - e)) > k * scale)
            if np.array_equal(new, flagged):
                break
            flagged = new
        out[:, j] = flagged
        if sigma_given and c in sigma_given:
            sigma[c], source[c] = float(sigma_given[c]), "round"
        else:
            use = valid & ~flagged
            s = robust_sd(e[use]) if use.sum() > 10 else robust_sd(e)
            sigma[c] = max(s / math.sqrt(fac), 1e-6)
            source[c] = "estimated"
    return sigma, source, out


def hf_noise_sd(t, y):
    """Noise sd of one series from its high-frequency content (the robust sd of the residual
    about a local cubic, corrected for what the smoother absorbs); 0 for a series too short.

    Parameters
    ----------
    t, y : (N,) ndarray

    Returns
    -------
    float
    """
    y = np.asarray(y, float)
    if y.size < HF_WINDOW + 2:
        return 0.0
    e, fac, valid = hf_residual_t(np.asarray(t, float), y)
    use = valid if valid.sum() > 10 else np.ones_like(valid)
    return float(robust_sd(e[use]) / math.sqrt(fac)) if fac > 0 else 0.0
