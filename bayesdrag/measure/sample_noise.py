"""Per-sample noise of a track: how much noisier (or quieter) each sample is than its channel's
typical sample, read off the track's optional columns (docs/radar.md, "Per-sample noise").

* ``sigma_<channel>`` [the channel's file unit; radians inside for the angles]: the sample's
  noise sd as the radar reports it. The fit takes its shape (each sample's sd over the column's
  median) and, unless the round's ``[radar] sigma`` gives the channel's sd, its level (the
  median, held like a declared sigma).
* ``snr`` [dB]: the echo's signal-to-noise ratio, one per sample, for every channel of the track
  (the echo is one for all of them). A radar's range, angle and Doppler estimates have a noise sd
  proportional to ``1 / sqrt(SNR)`` (linear power ratio; the Cramér-Rao bound of a tone's
  frequency and of a delay in white noise), so a sample's sd is the channel's sd times
  ``10 ** ((median_dB - snr_dB) / 20)``: 6 dB less echo is twice the sd. The channel's level
  stays the round's sigma, or is estimated as without the column.

A ``sigma_<channel>`` column wins over ``snr`` for its channel and is taken as given. The SNR's
scales are clipped to [:data:`SCALE_MIN`, :data:`SCALE_MAX`] (its law holds for a well-formed
echo, not for a glint or a fade) (a sample 40 dB below the median still counts a little,
a sample far above it no more than 25 median samples); a missing value (NaN) is a median sample.
"""
from __future__ import annotations

import numpy as np

__all__ = ["sample_noise", "SCALE_MIN", "SCALE_MAX", "SNR_COLUMN", "sigma_column"]

#: the smallest and largest per-sample noise scale, relative to the channel's median sample
SCALE_MIN = 0.2
SCALE_MAX = 100.0
#: the extra column of the echo's signal-to-noise ratio [dB]
SNR_COLUMN = "snr"


def sigma_column(channel):
    """The name of a channel's per-sample sd column (``sigma_<channel>``)."""
    return f"sigma_{channel}"


def sample_noise(track, channels):
    """Each sample's noise sd relative to its channel's median sample, and the levels the
    ``sigma_<channel>`` columns give.

    Parameters
    ----------
    track : RadarTrack
    channels : sequence of str
        The fit's channels.

    Returns
    -------
    (ndarray (N, C) or None, dict channel -> float)
        The scales (None: every sample alike, no column applies) and the channels' sd from their
        ``sigma_<channel>`` columns (their median, in the channel's unit).
    """
    n = track.n
    scale = np.ones((n, len(channels)))
    level = {}
    snr = track.extra.get(SNR_COLUMN)
    snr_scale = None
    if snr is not None:
        s = np.asarray(snr, float)
        ok = np.isfinite(s)
        if ok.any():
            med = float(np.median(s[ok]))
            snr_scale = np.clip(np.where(ok, 10.0 ** ((med - np.where(ok, s, med)) / 20.0), 1.0), SCALE_MIN, SCALE_MAX)
    used = False
    for j, c in enumerate(channels):
        col = track.extra.get(sigma_column(c))
        if col is not None:
            a = np.asarray(col, float)
            ok = np.isfinite(a) & (a > 0)
            if ok.any():
                med = float(np.median(a[ok]))
                level[c] = med
                scale[:, j] = np.where(ok, a / med, 1.0)
                used = True
                continue
        if snr_scale is not None:
            scale[:, j] = snr_scale
            used = True
    if not used:
        return None, level
    return scale, level
