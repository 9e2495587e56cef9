"""A radar track: time and the measured channels, SI units (``RadarTrack``). Values only; the
track file (CSV) is read and written by :mod:`bayesdrag.io.tracks`."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["CHANNELS", "ALL_CHANNELS", "GUN_CHANNELS", "NATIVE_CHANNELS", "ANGLE_CHANNELS", "UNITS", "FILE_UNITS",
           "RadarTrack", "MAX_FIT_SAMPLES", "SAMPLE_SIGMA_FLOOR", "thin_for_fit"]

#: channels in the gun's frame: positions x, y, z [m] and ground speed v [m/s]
GUN_CHANNELS = ("x", "y", "z", "v")
#: channels a radar measures from its own site (docs/radar.md): slant range [m], azimuth
#: clockwise from true north [rad], elevation above the horizontal [rad], range rate [m/s]
#: (positive receding). The angles are in radians inside the code, degrees in files.
NATIVE_CHANNELS = ("range", "azimuth", "elevation", "range_rate")
#: the native channels that are angles (degrees in files, radians inside)
ANGLE_CHANNELS = ("azimuth", "elevation")
#: the gun-frame channels (the name older code and users know)
CHANNELS = GUN_CHANNELS
#: every channel a track may hold, in canonical order
ALL_CHANNELS = GUN_CHANNELS + NATIVE_CHANNELS
#: unit of each channel inside the code (SI)
UNITS = {"t": "s", "x": "m", "y": "m", "z": "m", "v": "m/s", "range": "m", "azimuth": "rad",
         "elevation": "rad", "range_rate": "m/s"}
#: unit of each column of a track file and of ``[radar] sigma`` in a round file
FILE_UNITS = {**UNITS, "azimuth": "deg", "elevation": "deg"}
#: the most samples a fit or a diagnosis uses: a denser track is thinned to every k-th sample.
#: 10 000 samples over a flight are 3 ms apart or more, far denser than the drag changes, and
#: samples that close are rarely independent (tracking filters correlate them), so thinning loses
#: little the bands would honestly hold; the work grows with the samples (docs/measurements.md, "Where the constants come from").
MAX_FIT_SAMPLES = 10_000
#: smallest noise sd one sample's ``sigma_<channel>`` column may give, by the channel's unit inside
#: the code (the file's: 1e-4 m, 1e-4 m/s, 5e-5 deg): as ``[radar] sigma``'s floor, below which no
#: radar measures. A sample claiming less would outweigh the whole track by its 1 / sd^2 (one
#: ``sigma_v = 1e-300`` overflowed the fit, and 1e-6 beside 0.3 m/s kept it from converging)
SAMPLE_SIGMA_FLOOR = {"m": 1e-4, "m/s": 1e-4, "rad": math.radians(5e-5)}


@dataclass(frozen=True, eq=False)
class RadarTrack:
    """A radar track: time and measured channels, SI units.

    Attributes
    ----------
    t : ndarray, shape (N,), s
        Sample times since launch, strictly increasing.
    channels : dict of str -> ndarray (N,)
        A non-empty subset of ``x, y, z`` [m] and ``v`` [m/s] (the gun's frame) and of the
        radar-native ``range`` [m], ``azimuth`` [rad, clockwise from true north],
        ``elevation`` [rad] and ``range_rate`` [m/s] (seen from the radar's site, which the
        round gives), stored in :data:`ALL_CHANNELS` order.
    extra : dict of str -> ndarray (N,)
        Further columns of the file, kept but ignored by the fit; a ``sigma_<channel>`` column
        of a present channel (each sample's noise sd, in the channel's unit inside the code)
        weights the fit and must be at least :data:`SAMPLE_SIGMA_FLOOR` (1e-4 m, 1e-4 m/s,
        5e-5 deg).
    source : str
        File path or description.
    notes : tuple of str
        One-line remarks found while reading (e.g. ignored extra columns), for the CLI to print.

    Construction checks shapes, the time axis and the per-sample noise floor and raises
    ``ValueError`` (an :class:`~bayesdrag.errors.InputError` for the noise floor); :func:`read_track`
    performs the same checks first and raises :class:`~bayesdrag.errors.InputError` with line
    numbers.
    """

    t: np.ndarray
    channels: dict
    extra: dict = field(default_factory=dict)
    source: str = ""
    notes: tuple = ()

    def __post_init__(self):
        src = self.source or "track"
        t = np.array(self.t, dtype=float).reshape(-1) if np.ndim(self.t) <= 1 else None
        if t is None:
            raise ValueError(f"{src}: t must be 1-D, got shape {np.shape(self.t)}")
        if not np.all(np.isfinite(t)):
            raise ValueError(f"{src}: t contains non-finite values")
        if t.size > 1 and np.any(np.diff(t) <= 0):
            i = int(np.argmax(np.diff(t) <= 0)) + 1
            raise ValueError(f"{src}: t must increase strictly; sample {i} has t = {t[i]} after {t[i - 1]}")
        unknown = [k for k in self.channels if k not in ALL_CHANNELS]
        if unknown:
            raise ValueError(f"{src}: unknown channel(s) {', '.join(map(str, unknown))}; "
                             f"allowed: {', '.join(ALL_CHANNELS)}")
        if not self.channels:
            raise ValueError(f"{src}: a track needs at least one of the channels {', '.join(ALL_CHANNELS)}")
        ch = {}
        for k in ALL_CHANNELS:
            if k in self.channels:
                ch[k] = self._column(k, self.channels[k], t.size, src)
                if not np.all(np.isfinite(ch[k])):
                    raise ValueError(f"{src}: channel {k} contains non-finite values")
        clash = [k for k in self.extra if k in ALL_CHANNELS or k == "t"]
        if clash:
            raise ValueError(f"{src}: extra columns may not be named like channels: {', '.join(clash)}")
        ex = {str(k): self._column(k, a, t.size, src) for k, a in self.extra.items()}
        self._check_sample_sigma(ex, ch, t, src)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "channels", ch)
        object.__setattr__(self, "extra", ex)
        object.__setattr__(self, "source", str(self.source))
        object.__setattr__(self, "notes", tuple(str(s) for s in self.notes))

    @staticmethod
    def _check_sample_sigma(extra, channels, t, src):
        """Refuse a ``sigma_<channel>`` sample below :data:`SAMPLE_SIGMA_FLOOR` (of a channel the
        track has: the fit weights each sample by it), naming the sample and its time.

        Raises
        ------
        bayesdrag.errors.InputError
            (a ``ValueError``) with the column, the sample, the value and the floor in the
            file's unit (degrees for the angles).
        """
        from .errors import InputError

        for c in channels:
            a = extra.get(f"sigma_{c}")
            if a is None:
                continue
            floor = SAMPLE_SIGMA_FLOOR[UNITS[c]]
            low = np.flatnonzero(a < floor)          # NaN and <= 0 are the reader's to name
            if low.size:
                i = int(low[0])
                angle = c in ANGLE_CHANNELS
                v, lo = (np.degrees(a[i]), np.degrees(floor)) if angle else (a[i], floor)
                raise InputError(f"{src}: sample {i + 1} (t = {t[i]:g} s): sigma_{c} = {v:g} {FILE_UNITS[c]} is below "
                                 f"{lo:g} {FILE_UNITS[c]}, more precise than any radar measures (a unit mistake?); "
                                 f"give each sample's noise sd in {FILE_UNITS[c]}, or leave the column out")

    @staticmethod
    def _column(name, a, n, src):
        a = np.array(a, dtype=float)
        if a.shape != (n,):
            raise ValueError(f"{src}: column {name} has shape {a.shape}, expected ({n},) like t")
        return a

    def _get(self, k):
        return self.channels.get(k)

    x = property(lambda self: self._get("x"), doc="Downrange position [m], shape (N,), or None.")
    y = property(lambda self: self._get("y"), doc="Cross-range position [m], shape (N,), or None.")
    z = property(lambda self: self._get("z"), doc="Height above the muzzle [m], shape (N,), or None.")
    v = property(lambda self: self._get("v"), doc="Ground speed [m/s], shape (N,), or None.")

    @property
    def native(self):
        """The radar-native channels present (tuple of str, :data:`NATIVE_CHANNELS` order)."""
        return tuple(k for k in NATIVE_CHANNELS if k in self.channels)

    @property
    def names(self):
        """Present channels, in :data:`ALL_CHANNELS` order (tuple of str)."""
        return tuple(k for k in ALL_CHANNELS if k in self.channels)

    @property
    def n(self):
        """Number of samples N."""
        return int(self.t.size)

    def __len__(self):
        return self.n

    def __repr__(self):
        span = f", t in [{self.t[0]:.3f}, {self.t[-1]:.3f}] s" if self.n else ""
        return (f"RadarTrack(n={self.n}, channels={self.names}{span}, extra={tuple(self.extra)}, "
                f"source={self.source!r})")

    def subset(self, index):
        """Samples selected by a boolean mask (N,), a slice or an increasing integer index array.

        Returns
        -------
        RadarTrack
            Same channels, extras, source and notes.
        """
        if isinstance(index, slice):
            idx = index
        else:
            idx = np.asarray(index)
            if idx.dtype == bool:
                if idx.shape != self.t.shape:
                    raise ValueError(f"mask has shape {idx.shape}, expected {self.t.shape}")
            elif not np.issubdtype(idx.dtype, np.integer):
                raise TypeError(f"subset takes a boolean mask, a slice or integer indices, got {idx.dtype}")
        return RadarTrack(self.t[idx], {k: a[idx] for k, a in self.channels.items()},
                          {k: a[idx] for k, a in self.extra.items()}, self.source, self.notes)

    def with_channels(self, names):
        """Copy keeping only channels ``names`` (each must be present); extras are kept."""
        names = (names,) if isinstance(names, str) else tuple(names)
        missing = [k for k in names if k not in self.channels]
        if missing:
            raise ValueError(f"{self.source or 'track'}: channel(s) {', '.join(missing)} not in the "
                             f"track; present: {', '.join(self.names)}")
        return RadarTrack(self.t, {k: self.channels[k] for k in names}, self.extra, self.source, self.notes)


def thin_for_fit(track, max_samples=MAX_FIT_SAMPLES):
    """``track`` itself when it has at most ``max_samples`` samples, else every k-th sample
    (k = ceil(N / max_samples)), first and last kept, with a note saying so.

    Parameters
    ----------
    track : RadarTrack
    max_samples : int

    Returns
    -------
    RadarTrack
    """
    n = track.n
    if n <= max_samples:
        return track
    k = -(-n // max_samples)
    idx = np.arange(0, n, k)
    if idx[-1] != n - 1:
        idx = np.append(idx, n - 1)
    dt = float(np.median(np.diff(track.t)))
    note = (f"{track.source or 'track'}: {n} samples ({1e3 * dt:.3g} ms apart) are more than a fit uses: "
            f"using every {_ordinal(k)} ({idx.size} samples); thin the track yourself to choose which")
    out = track.subset(idx)
    return RadarTrack(out.t, out.channels, out.extra, out.source, out.notes + (note,))


def _ordinal(k):
    """2nd, 3rd, 5th, 11th, 21st, 33rd."""
    suffix = "th" if 10 <= k % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(k % 10, "th")
    return f"{k}{suffix}"
