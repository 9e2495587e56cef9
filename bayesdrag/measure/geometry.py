"""Measurement equations of a radar in the gun's flat frame: the channels a radar records from
its own site (slant range, azimuth, elevation, range rate) and the gun-frame channels (x, y, z,
v), computed from the simulated state, with their analytic Jacobians and the inverse.

The frame (docs/radar.md): origin at the muzzle at launch, ``x`` horizontal downrange along the
firing azimuth, ``y`` horizontal to the right looking downrange, ``z`` up; the same flat local
frame the point-mass model flies in. The radar stands at ``p = (px, py, pz)`` in that frame and
looks at the shell along ``d = r - p``:

* ``range = |d|`` [m] (+ a range bias);
* ``azimuth = A + atan2(dy, dx)`` [rad, clockwise from true north], ``A`` the firing azimuth:
  ``+y`` is to the right of downrange, i.e. clockwise seen from above (+ an azimuth bias);
* ``elevation = atan2(dz, hypot(dx, dy))`` [rad] above the radar's horizontal (+ a bias);
* ``range_rate = d . u / |d|`` [m/s], ``u`` the ground-relative velocity: positive receding.

What the flat frame leaves out (docs/radar.md gives the ranges where it starts to matter): the
Earth's curvature (the true height exceeds the tangent-plane ``z`` by about ``x^2 / (2 Re)``)
and the refraction of the radar's elevation. Both are candidates for later effects.

Every function is pure, takes states of shape ``(..., 6)`` (any leading batch dimensions:
samples, trajectories) and returns arrays with the same leading dimensions.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from ..errors import InputError
from ..track import ALL_CHANNELS as CHANNELS, ANGLE_CHANNELS, GUN_CHANNELS, NATIVE_CHANNELS, RadarTrack

__all__ = ["RadarSite", "site_of", "chronograph_factor", "wrap_angle", "channel_values", "channel_jacobian", "to_gun_frame",
           "gun_frame_track", "near_branch", "native_only", "gun_equivalent", "EARTH_RADIUS",
           "VERTICAL_LINE_OF_SIGHT", "MIN_ANGLE_RANGE",
           "angle_blind_samples"]

#: mean Earth radius [m], for the curvature figure x^2 / (2 Re) of the docs
EARTH_RADIUS = 6_371_000.0


@dataclass(frozen=True)
class RadarSite:
    """Where the radar stands and how it is calibrated.

    Attributes
    ----------
    position : tuple of 3 floats, m
        The site in the gun's frame at launch (x downrange, y right, z up).
    azimuth : float, rad
        The firing azimuth (direction of +x) clockwise from true north.
    range_bias : float, m
        Constant offset added to the measured range.
    azimuth_bias, elevation_bias : float, rad
        Constant offsets added to the measured angles.
    device_offset : float or None, m
        A chronograph radar's offset from the line of fire as typed into the device: the device
        reports its range rate divided by the cosine of the angle that offset makes at the
        measured range, ``range_rate * R / sqrt(R^2 - d^2)`` (:func:`chronograph_factor`);
        None: the range rate as measured.
    """

    position: tuple = (0.0, 0.0, 0.0)
    azimuth: float = 0.0
    range_bias: float = 0.0
    azimuth_bias: float = 0.0
    elevation_bias: float = 0.0
    device_offset: float | None = None

    def __post_init__(self):
        pos = tuple(float(v) for v in np.asarray(self.position, float).reshape(-1))
        if len(pos) != 3 or not all(math.isfinite(v) for v in pos):
            raise ValueError(f"radar position must be 3 finite numbers [m], got {self.position!r}")
        object.__setattr__(self, "position", pos)
        for k in (f.name for f in fields(self) if f.type == "float"):   # the angle and the biases
            v = float(getattr(self, k))
            if not math.isfinite(v):
                raise ValueError(f"radar {k} must be finite, got {v}")
            object.__setattr__(self, k, v)
        if self.device_offset is not None:
            d = float(self.device_offset)
            if not (math.isfinite(d) and d >= 0.0):
                raise ValueError(f"radar device_offset must be a finite distance >= 0 [m], got {d}")
            object.__setattr__(self, "device_offset", d or None)


#: the device's cosine correction is held at this factor where the range nears its offset (a
#: chronograph radar tracks from a few metres on; the first metre is not a measurement)
CHRONOGRAPH_FACTOR_MAX = 10.0


def chronograph_factor(R, d):
    """The factor a chronograph radar multiplies its range rate by for an offset ``d`` typed
    into it: ``R / sqrt(R^2 - d^2)`` at slant range ``R`` (the cosine of the angle between its
    line of sight and a line of fire at distance ``d``), with its derivative in R.

    Parameters
    ----------
    R : array_like, m
    d : float, m

    Returns
    -------
    (ndarray, ndarray)
        The factor [-] (at most :data:`CHRONOGRAPH_FACTOR_MAX`) and d factor / d R [1/m].
    """
    R = np.asarray(R, float)
    lo = d * CHRONOGRAPH_FACTOR_MAX / math.sqrt(CHRONOGRAPH_FACTOR_MAX ** 2 - 1.0)
    Rc = np.maximum(R, lo)
    q = np.sqrt(Rc * Rc - d * d)
    f = Rc / q
    df = np.where(R > lo, -d * d / q ** 3, 0.0)
    return f, df


def site_of(rnd, channels=()):
    """The :class:`RadarSite` of a round (``[radar] position``, ``[launch] azimuth``; no bias).

    Parameters
    ----------
    rnd : bayesdrag.round.Round
    channels : sequence of str
        The channels to be measured: angle channels need the firing azimuth.

    Raises
    ------
    InputError
        An angle channel while the round does not give ``[launch] azimuth``.
    """
    angles = [c for c in channels if c in ANGLE_CHANNELS]
    if angles and not rnd.launch.azimuth_given:
        raise InputError(f"{rnd.path or 'round'}: [launch] azimuth is missing: the track has the radar's "
                         f"{' and '.join(angles)}, measured from true north; give the firing azimuth "
                         f"(deg clockwise from true north)")
    return RadarSite(rnd.radar.position, rnd.launch.azimuth, device_offset=rnd.radar.device_offset)


def wrap_angle(a):
    """Angle(s) [rad] wrapped into [-pi, pi).

    Parameters
    ----------
    a : array_like, rad

    Returns
    -------
    ndarray like ``a``
    """
    return (np.asarray(a, float) + np.pi) % (2.0 * np.pi) - np.pi


#: below this range [m] the shell is taken to be at the site: the line of sight is then the
#: direction of flight (the limit a radar at the muzzle sees at launch)
AT_SITE = 1e-6


def _parts(state, site):
    """Line of sight ``d`` (..., 3) [m], velocity (..., 3) [m/s] and ``|d|^2`` (...) [m^2]; at the
    site itself ``d`` is a tiny step along the velocity, so range rate is the speed and the
    angles the flight's."""
    state = np.asarray(state, float)
    if state.shape[-1] != 6:
        raise ValueError(f"state must have 6 entries (x, y, z, ux, uy, uz) on its last axis, got {state.shape}")
    d = state[..., :3] - np.asarray(site.position)
    u = state[..., 3:]
    with np.errstate(over="ignore", invalid="ignore"):     # a diverged trial state: inf, rejected by the fit
        R2 = _norm2(d)
        at = R2 < AT_SITE ** 2
    if np.any(at):
        d = np.where(at[..., None], d + AT_SITE * u / np.maximum(np.linalg.norm(u, axis=-1), 1e-300)[..., None], d)
        R2 = _norm2(d)
    return d, u, R2


#: a line of sight within this angle of the site's vertical [rad] has no azimuth to plan with:
#: straight above or below the site the azimuth is undefined, and the angles' derivatives divide
#: by the horizontal distance (a radar's mount cannot follow through its zenith either)
VERTICAL_LINE_OF_SIGHT = math.radians(0.1)
#: nearer than this to the site [m] the shell has no angles a radar measures: at the antenna
#: itself (a site at the muzzle at launch) the angles' derivatives grow as 1 / range
MIN_ANGLE_RANGE = 1.0


def angle_blind_samples(state, site=RadarSite()):
    """The samples whose azimuth and elevation a radar at ``site`` cannot measure: the shell
    within :data:`MIN_ANGLE_RANGE` of the site (a site at the muzzle, at launch) or straight
    above or below it (the line of sight within :data:`VERTICAL_LINE_OF_SIGHT` of the vertical:
    a site on the vertical of the muzzle).

    Parameters
    ----------
    state : array_like, shape (N, 6)
        Position [m] and velocity [m/s] in the gun's frame.
    site : RadarSite

    Returns
    -------
    ndarray of int
        Their indices, increasing (empty when the angles are defined at every sample).
    """
    d = np.asarray(state, float)[..., :3] - np.asarray(site.position)
    R = np.sqrt(_norm2(d))
    rho = np.hypot(d[..., 0], d[..., 1])
    return np.flatnonzero((R < MIN_ANGLE_RANGE) | (rho <= math.tan(VERTICAL_LINE_OF_SIGHT) * R))


def _norm2(a):
    """Squared norm over the last axis of length 3 (component sums: numpy's reduction over a
    last axis of 3 is several times slower, and this runs on every trial trajectory)."""
    return a[..., 0] * a[..., 0] + a[..., 1] * a[..., 1] + a[..., 2] * a[..., 2]


def _dot(a, b):
    """Dot product over the last axis of length 3."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


#: the gun-frame channels as columns of :func:`bayesdrag.dynamics.pointmass.positions_and_speed`
_GUN_COLUMN = {"x": 0, "y": 1, "z": 2, "v": 3}


def channel_values(state, channels, site=RadarSite()):
    """Channels measured from the states.

    Parameters
    ----------
    state : array_like, shape (..., 6)
        Position [m] and ground-relative velocity [m/s] in the gun's frame.
    channels : sequence of str
        Among :data:`bayesdrag.track.ALL_CHANNELS`.
    site : RadarSite
        The radar (used by the native channels only).

    Returns
    -------
    ndarray, shape (..., C)
        ``x, y, z, range`` [m], ``v, range_rate`` [m/s], ``azimuth`` [rad] in [0, 2 pi),
        ``elevation`` [rad] in [-pi/2, pi/2]; biases added.
    """
    state = np.asarray(state, float)
    if any(c in NATIVE_CHANNELS for c in channels):
        d, u, R2 = _parts(state, site)
    else:                                # the gun-frame channels need no line of sight
        if state.shape[-1] != 6:
            raise ValueError(f"state must have 6 entries (x, y, z, ux, uy, uz) on its last axis, got {state.shape}")
        if state.ndim == 3 and all(c in _GUN_COLUMN for c in channels):
            # a batch of trajectories (every trial step of a fit): one compiled pass, same numbers
            from ..dynamics.pointmass import positions_and_speed

            return positions_and_speed(state, [_GUN_COLUMN[c] for c in channels])
        d, u, R2 = None, state[..., 3:], None
    out = np.empty(state.shape[:-1] + (len(channels),))
    R = None
    for j, c in enumerate(channels):
        if c in ("x", "y", "z"):
            out[..., j] = state[..., "xyz".index(c)]
        elif c == "v":
            out[..., j] = np.sqrt(_norm2(u))
        elif c == "range":
            R = np.sqrt(R2) if R is None else R
            out[..., j] = R + site.range_bias
        elif c == "azimuth":
            out[..., j] = (site.azimuth + np.arctan2(d[..., 1], d[..., 0]) + site.azimuth_bias) % (2.0 * np.pi)
        elif c == "elevation":
            out[..., j] = np.arctan2(d[..., 2], np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1])) \
                + site.elevation_bias
        elif c == "range_rate":
            R = np.sqrt(R2) if R is None else R
            out[..., j] = _dot(d, u) / R
            if site.device_offset:
                out[..., j] *= chronograph_factor(R, site.device_offset)[0]
        else:
            raise ValueError(f"unknown channel {c!r}; allowed: {', '.join(CHANNELS)}")
    return out


def channel_jacobian(state, channels, site=RadarSite()):
    """Analytic derivatives of the channels with respect to the state.

    Parameters
    ----------
    state : array_like, shape (..., 6)
        As :func:`channel_values`. The native channels are singular where the shell is at the
        site (range 0) and the angles straight above it (horizontal distance 0).
    channels : sequence of str
    site : RadarSite

    Returns
    -------
    ndarray, shape (..., C, 6)
        ``d channel / d (x, y, z, ux, uy, uz)`` in the channel's unit per m or per m/s (biases
        are constants and drop out).
    """
    d, u, R2 = _parts(state, site)
    J = np.zeros(d.shape[:-1] + (len(channels), 6))
    R = np.sqrt(R2)
    rho2 = d[..., 0] ** 2 + d[..., 1] ** 2
    rho = np.sqrt(rho2)
    for j, c in enumerate(channels):
        if c in ("x", "y", "z"):
            J[..., j, "xyz".index(c)] = 1.0
        elif c == "v":
            J[..., j, 3:] = u / np.sqrt(np.sum(u * u, axis=-1))[..., None]
        elif c == "range":
            J[..., j, :3] = d / R[..., None]
        elif c == "azimuth":
            J[..., j, 0] = -d[..., 1] / rho2
            J[..., j, 1] = d[..., 0] / rho2
        elif c == "elevation":
            k = -d[..., 2] / (R2 * rho)
            J[..., j, 0] = k * d[..., 0]
            J[..., j, 1] = k * d[..., 1]
            J[..., j, 2] = rho / R2
        elif c == "range_rate":
            du = np.sum(d * u, axis=-1)
            J[..., j, :3] = u / R[..., None] - (du / (R2 * R))[..., None] * d
            J[..., j, 3:] = d / R[..., None]
            if site.device_offset:
                f, df = chronograph_factor(R, site.device_offset)
                J[..., j, :] *= f[..., None]
                J[..., j, :3] += ((du / R) * df / R)[..., None] * d
        else:
            raise ValueError(f"unknown channel {c!r}; allowed: {', '.join(CHANNELS)}")
    return J


def to_gun_frame(rng, azimuth, elevation, site=RadarSite()):
    """Positions in the gun's frame from a radar's range and angles (the inverse of
    :func:`channel_values` for ``range, azimuth, elevation``; biases removed).

    Parameters
    ----------
    rng : array_like, m
        Slant range.
    azimuth : array_like, rad
        Clockwise from true north.
    elevation : array_like, rad
    site : RadarSite

    Returns
    -------
    ndarray, shape (..., 3)
        x, y, z [m].
    """
    r = np.asarray(rng, float) - site.range_bias
    phi = np.asarray(azimuth, float) - site.azimuth_bias - site.azimuth
    el = np.asarray(elevation, float) - site.elevation_bias
    ce = np.cos(el)
    pos = np.stack([r * ce * np.cos(phi), r * ce * np.sin(phi), r * np.sin(el)], axis=-1)
    return pos + np.asarray(site.position)


def near_branch(predicted, measured):
    """Predicted azimuths [rad] moved by whole turns to lie within pi of the measured ones, so
    that ``measured - predicted`` is the wrapped angle difference (and finite differences of
    predictions stay continuous across north).

    Parameters
    ----------
    predicted : array_like, rad, shape (..., N)
    measured : array_like, rad, shape (N,)

    Returns
    -------
    ndarray like ``predicted``
    """
    m = np.asarray(measured, float)
    return m + wrap_angle(np.asarray(predicted, float) - m)


def gun_frame_track(track, site=RadarSite()):
    """The track with its range and angles turned into ``x, y, z`` (for starting values and
    figures, never for the fit, which compares the radar's own channels).

    Parameters
    ----------
    track : RadarTrack
        Needs all of ``range, azimuth, elevation`` to give positions; its ``v`` is kept.
    site : RadarSite

    Returns
    -------
    RadarTrack
        Channels ``x, y, z`` (and ``v`` when the track has it); None when the track lacks one of
        range, azimuth and elevation.
    """
    if not all(c in track.channels for c in ("range", "azimuth", "elevation")):
        return None
    ch = track.channels
    pos = to_gun_frame(ch["range"], ch["azimuth"], ch["elevation"], site)
    out = {"x": pos[:, 0], "y": pos[:, 1], "z": pos[:, 2]}
    for c in GUN_CHANNELS:
        if c in ch and c not in out:
            out[c] = ch[c]
    note = f"{track.source or 'track'}: range, azimuth and elevation turned into x, y, z from the radar's site"
    return RadarTrack(track.t, out, {}, track.source, track.notes + (note,))


#: the gun-frame quantity each native channel mainly observes, for decisions made by channel
#: name (which initial-state components the data determine, which launch priors it checks)
_OBSERVES = {"range": "x", "azimuth": "y", "elevation": "z", "range_rate": "v"}


def gun_equivalent(names):
    """The gun-frame channels a set of channels stands in for (tuple, ``GUN_CHANNELS`` order):
    the gun channels themselves, ``range`` for ``x``, ``azimuth`` for ``y``, ``elevation`` for
    ``z`` and ``range_rate`` for ``v`` (range and both angles locate the shell: ``x, y, z``)."""
    have = {c for c in names if c in GUN_CHANNELS} | {_OBSERVES[c] for c in names if c in _OBSERVES}
    return tuple(c for c in GUN_CHANNELS if c in have)


def native_only(names):
    """Whether channel names hold no gun-frame channel (bool)."""
    return all(c in NATIVE_CHANNELS for c in names)
