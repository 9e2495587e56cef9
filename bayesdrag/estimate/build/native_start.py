"""Starting values of a radar-native track: its range, angles or range rate read as the gun-frame
channels the start from the data (:mod:`bayesdrag.estimate.build.start`) works on. The fit
itself compares the radar's own channels; this view only starts it."""
from __future__ import annotations

import numpy as np

from ...errors import InputError
from ...measure import channel_values, gun_frame_track
from ...track import GUN_CHANNELS, RadarTrack

__all__ = ["start_view", "start_position", "MIN_RADIAL_FRACTION", "NOMINAL_CD"]

#: a Doppler sample is used for the start only where the line of sight is within ~73 deg of the
#: flight (range rate at least this fraction of the speed on the nominal flight): nearer
#: perpendicular, the speed read off it is mostly the nominal flight's own guess
MIN_RADIAL_FRACTION = 0.3
#: the drag a nominal flight flies when the round has no reference table (a shell's Cd spans
#: ~0.15-0.4; the nominal flight only gives the geometry of the line of sight)
NOMINAL_CD = 0.3


def start_view(track, rnd, site):
    """The track as the start from the data reads it: gun-frame channels.

    A track of gun-frame channels is itself. A radar's range, azimuth and elevation are turned
    into ``x, y, z`` (:func:`bayesdrag.measure.gun_frame_track`); a range rate alone into a
    speed, by the ratio of speed to range rate on the round's nominal flight (its launch
    velocity and elevation, its reference drag) seen from the radar's site. The fit itself always
    compares the radar's own channels; this only gives starting values.

    Parameters
    ----------
    track : RadarTrack
    rnd : Round
    site : bayesdrag.measure.RadarSite

    Returns
    -------
    RadarTrack
        Channels among ``x, y, z, v``.
    """
    if not track.native:
        return track
    gun = tuple(c for c in track.names if c in GUN_CHANNELS)
    if "x" in gun and "z" in gun:
        return track.with_channels(gun)
    view = gun_frame_track(track, site)
    if view is not None:
        return _with_doppler_speed(view, track, rnd, site)
    if "range_rate" in track.channels:
        return _doppler_view(track, rnd, site)
    if gun:
        return track.with_channels(gun)
    raise InputError(f"{track.source or 'track'}: the channels {', '.join(track.names)} do not locate the shell: a "
                     f"fit needs range, azimuth and elevation together, or range_rate, or x, y, z, v")


#: the least share of a track's samples a speed read off its range rate must cover to be used
#: beside its positions (else the positions alone start the fit)
MIN_SPEED_SHARE = 0.5


def _with_doppler_speed(view, track, rnd, site):
    """The position view with a speed read off the range rate where the line of sight is within
    ~73 deg of the flight (:data:`MIN_RADIAL_FRACTION`): positions from angles 0.03 deg apart
    at 10 km are 5 m apart, and the speed differentiated from them starts the drag far off (a
    factor 0.1-1.4 measured on a 155 mm QE 45 track), while a range rate of 0.1 m/s gives it
    directly. The view keeps the samples where the speed is read (when they are at least
    :data:`MIN_SPEED_SHARE` of the track); else it is the positions alone."""
    if "range_rate" not in track.channels or "v" in view.channels:
        return view
    speed = _doppler_view(track, rnd, site, note=False)
    if speed is None or speed.n < MIN_SPEED_SHARE * track.n:
        return view
    keep = np.isin(track.t, speed.t)
    out = view.subset(keep)
    note = f"{track.source or 'track'}: starting speed from the range rate through the nominal flight's line of sight"
    return RadarTrack(out.t, {**out.channels, "v": speed.channels["v"]}, {}, out.source, out.notes + (note,))


def _doppler_view(track, rnd, site, note=True):
    """A speed track read off a range rate through the nominal flight's geometry."""
    from ...drag import ReferenceTable
    from ...dynamics.pointmass import PointMassModel
    from ...dynamics.trajectory import initial_state

    L = rnd.launch
    rr = track.channels["range_rate"]
    if not note and (L.velocity is None or L.elevation_deg is None or np.any(track.t < 0)):
        return None                      # beside positions: no nominal flight, no speed
    note = f"{track.source or 'track'}: starting values from the range rate "
    if L.velocity is None or L.elevation_deg is None or np.any(track.t < 0):
        return RadarTrack(track.t, {"v": np.abs(rr)}, {}, track.source,
                          track.notes + (note + "taken as the speed (no [launch] velocity and elevation)",))
    ref = rnd.reference_drag or ReferenceTable((0.0, 6.0), (NOMINAL_CD, NOMINAL_CD), source="nominal")
    model = PointMassModel(rnd.projectile.mass, rnd.projectile.diameter, ref, rnd.atmosphere)
    # the compiled kernel: the nominal flight only gives the line of sight (no tight tolerance needed)
    tr = model.simulate((), initial_state(L.velocity, L.elevation_deg), np.asarray(track.t, float))
    y = channel_values(tr.state, ("range_rate", "v"), site)
    frac = y[:, 0] / np.maximum(y[:, 1], 1e-9)
    keep = frac > MIN_RADIAL_FRACTION
    keep[0] = True
    v = np.abs(rr) / np.clip(frac, MIN_RADIAL_FRACTION, None)
    return RadarTrack(track.t[keep], {"v": v[keep]}, {}, track.source,
                      track.notes + (note + "through the nominal flight's line of sight",))


def start_position(state0, t0, channels):
    """The starting state with its position flown out from the muzzle when the channels are a
    range rate without positions and the track starts after launch.

    The start from a speed knows no position; a radar far from the gun barely cares, but a
    chronograph radar a few decimetres beside the muzzle sees the sign of its range rate flip
    if the shell is started behind it. The shell is started where the start's velocity carries
    it from the muzzle in ``t0`` (drag and gravity move it by ``~ a t0^2 / 2``, centimetres over
    a chronograph's first milliseconds).

    Parameters
    ----------
    state0 : (6,) ndarray
        Position [m] and velocity [m/s] at ``t0``.
    t0 : float, s
    channels : sequence of str

    Returns
    -------
    (6,) ndarray
    """
    if "range_rate" not in channels or any(c in channels for c in ("x", "y", "z", "range", "azimuth", "elevation")):
        return state0
    out = np.array(state0, float, copy=True)
    out[:3] = out[3:] * max(float(t0), 0.0)
    return out
