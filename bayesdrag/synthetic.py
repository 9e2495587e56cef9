"""Synthetic radar data: a round's trajectory sampled like a tracking radar, with noise,
outliers, dropouts and a late radar clock.

Every random draw takes an explicit :class:`numpy.random.Generator`; nothing here touches
global random state.
"""
from __future__ import annotations

import numpy as np

from .errors import InputError
from .measure import channel_values, site_of
from .track import GUN_CHANNELS, RadarTrack

__all__ = ["simulate_round", "add_noise", "add_outliers", "drop_samples", "ar1_noise", "recordable",
           "MIN_RECORDED_RANGE"]

MODELS = ("pointmass", "6dof")


def _launch_or_fail(rnd, what):
    L = rnd.launch
    if L.velocity is None or L.elevation_deg is None:
        raise InputError(f"{rnd.path}: {what} needs [launch] velocity and elevation")
    if not L.elevation_deg > 0.0:
        # the flight ends when z returns to the gun's height: fired level or down, at once
        raise InputError(f"{rnd.path}: {what} needs [launch] elevation > 0 deg (got {L.elevation_deg:g}): the "
                         f"simulated flight ends where it comes back to the gun's height, which a shell fired "
                         f"level or downwards does at once")
    return L


def _above_the_air(rnd, z, model):
    """Refuse a simulated flight that rises above the atmosphere model (32 km above sea level)."""
    from .air.atmosphere import MAX_ALTITUDE

    top = float(np.max(z)) + rnd.atmosphere.gun_altitude if np.size(z) else 0.0
    if top > MAX_ALTITUDE - 1.0:
        raise InputError(f"{rnd.path}: the {model} flight of [launch] velocity {rnd.launch.velocity:g} m/s at "
                         f"elevation {rnd.launch.elevation_deg:g} deg climbs above {MAX_ALTITUDE / 1000:.1f} km "
                         f"above sea level, the top of the atmosphere model; lower the velocity or the elevation")


def simulate_round(rnd, model="pointmass", dt=0.027, *, clock_offset=0.0, wind=(0.0, 0.0, 0.0),
                   channels=GUN_CHANNELS, max_time=600.0, site=None):
    """Noise-free radar track of one round from launch to impact (z back to 0).

    Parameters
    ----------
    rnd : bayesdrag.round.Round
        Needs ``[projectile] reference_drag`` and ``[launch] velocity, elevation``; Coriolis is
        on when ``[launch] latitude`` is given (with ``azimuth``).
    model : {"pointmass", "6dof"}
        ``pointmass`` integrates paper Eqs. 20-22 (scipy reference backend); ``6dof`` the
        paper's Eqs. 1-17 with the M107-like aerodynamics of
        :mod:`bayesdrag.dynamics.sixdof` and the round's mass, diameter and drag.
    dt : float, s
        Sample interval; samples at 0, dt, 2 dt, ... up to impact, plus the impact sample.
    clock_offset : float, s
        The radar clock is late by this much: recorded time = true time - clock_offset
        (effect ``radar_time``). Samples are recorded at 0, dt, ... on the radar's clock.
    wind : (3,) m/s
        Constant wind in the track frame (x downrange, y right, z up; docs/formats.md).
    channels : sequence of str
        Channels to record, among x, y, z, v and the radar-native range, azimuth, elevation,
        range_rate (:mod:`bayesdrag.measure`).
    site : bayesdrag.measure.RadarSite, optional
        Where the radar stands; default the round's (``[radar] position``, ``[launch]
        azimuth``, which angle channels require).

    Returns
    -------
    RadarTrack
    """
    if model not in MODELS:
        raise InputError(f"--model {model!r} is not allowed; use one of {', '.join(MODELS)}")
    if not (np.isfinite(dt) and 1e-4 <= dt <= 5.0):
        raise InputError(f"--dt {dt!r} s is not allowed; use a sample interval in [0.0001, 5] s")
    ref = rnd.reference_drag
    if ref is None:
        raise InputError(f"{rnd.path}: simulate needs [projectile] reference_drag (a mach,cd table)")
    L = _launch_or_fail(rnd, "simulate")
    if model == "pointmass":
        t, pos, vel = _pointmass(rnd, ref, L, dt, clock_offset, wind, max_time)
    else:
        t, pos, vel = _sixdof(rnd, ref, L, dt, clock_offset, wind, max_time)
    channels = tuple(channels)
    if site is None:
        site = site_of(rnd, channels)
    values = channel_values(np.concatenate([pos, vel], axis=1), channels, site)
    src = f"bayesdrag simulate --model {model} ({rnd.path})"
    return RadarTrack(t, {c: values[:, j] for j, c in enumerate(channels)}, {}, source=src)


def _sample_times(t_impact, dt, clock_offset):
    """Radar times 0, dt, ... whose true times lie in [0, t_impact], plus the impact."""
    t_rec = np.arange(0.0, t_impact - clock_offset, dt)
    t_rec = t_rec[t_rec + clock_offset >= 0.0]
    last = t_impact - clock_offset
    if last - t_rec[-1] > 1e-6 * dt:
        t_rec = np.append(t_rec, last)
    return t_rec


def _pointmass(rnd, ref, L, dt, clock_offset, wind, max_time):
    from .dynamics.pointmass import PointMassModel
    from .dynamics.trajectory import initial_state

    cor = (L.latitude_deg, L.azimuth_deg) if L.latitude_deg is not None else None
    model = PointMassModel(rnd.projectile.mass, rnd.projectile.diameter, ref, rnd.atmosphere,
                           wind=tuple(wind), coriolis=cor)
    s0 = initial_state(L.velocity, L.elevation_deg)
    try:
        first = model.simulate((), s0, backend="scipy", stop_at_impact=True, dt=dt, max_time=max_time)
    except ValueError as exc:
        if "atmosphere" not in str(exc):
            raise
        _above_the_air(rnd, [np.inf], "point-mass")
    if not first.success or first.t_impact is None:
        raise InputError(f"{rnd.path}: the simulated round does not land within {max_time:.0f} s "
                         f"({first.message}); check [launch] elevation and velocity")
    t_rec = _sample_times(first.t_impact, dt, clock_offset)
    tr = model.simulate((), s0, t_rec + clock_offset, backend="scipy")
    return t_rec, tr.state[:, :3], tr.state[:, 3:]


def _sixdof(rnd, ref, L, dt, clock_offset, wind, max_time):
    from .dynamics import shell as shells, sixdof

    base = shells.table1_shell()
    # Another projectile: Table 1 inertias scaled as m d^2 (geometrically similar shell) and the
    # same M107-like aerodynamics; its own mass, diameter and zero-yaw drag.
    k = (rnd.projectile.mass / base.mass) * (rnd.projectile.diameter / base.diameter) ** 2
    shell = shells.Shell(mass=rnd.projectile.mass, diameter=rnd.projectile.diameter,
                         Ix=base.Ix * k, Iy=base.Iy * k, aero=base.aero, cd0=ref,
                         name=rnd.projectile.name)
    res = sixdof.simulate_6dof(shell, L.velocity, L.elevation_deg, dt=dt, atmosphere=rnd.atmosphere,
                               wind=tuple(wind), azimuth_deg=L.azimuth_deg, max_time=max_time)
    if not res.success:
        raise InputError(f"{rnd.path}: the 6-DOF simulation failed: {res.message}")
    _above_the_air(rnd, res.position[:, 2], "6-DOF")   # the 6-DOF holds the air at its top: refuse
    t_imp = float(res.t[-1])
    t_rec = _sample_times(t_imp, dt, clock_offset)
    # every requested time, the impact included: a second run's impact event may land a hair
    # before the first's and drop the last sample
    res = sixdof.simulate_6dof(shell, L.velocity, L.elevation_deg, t_out=t_rec + clock_offset,
                               atmosphere=rnd.atmosphere, wind=tuple(wind),
                               azimuth_deg=L.azimuth_deg, max_time=max_time, stop_at_impact=False)
    return t_rec, res.position, res.velocity


def ar1_noise(n, sd, rho, rng):
    """Stationary AR(1) noise of marginal sd ``sd`` and lag-one correlation ``rho``.

    Parameters
    ----------
    n : int
    sd : float
    rho : float in (-1, 1)
    rng : numpy.random.Generator

    Returns
    -------
    ndarray, shape (n,)
    """
    if not -1.0 < rho < 1.0:
        raise ValueError(f"AR(1) correlation must be in (-1, 1), got {rho}")
    e = rng.standard_normal(n) * sd * np.sqrt(1.0 - rho * rho)
    out = np.empty(n)
    out[0] = rng.standard_normal() * sd
    for i in range(1, n):
        out[i] = rho * out[i - 1] + e[i]
    return out


def add_noise(track, sigma, rng, rho=0.0):
    """Add independent Gaussian (or AR(1) with correlation ``rho``) noise per channel.

    Parameters
    ----------
    track : RadarTrack
    sigma : dict channel -> sd in the channel's unit (m, m/s, rad); channels not in ``sigma``
        stay noise-free. A noisy azimuth is wrapped back into [0, 2 pi).
    rng : numpy.random.Generator
    rho : float
        Lag-one correlation of the noise (0 = white).
    """
    ch = {}
    for name, val in track.channels.items():
        sd = float(sigma.get(name, 0.0))
        if sd < 0 or not np.isfinite(sd):
            raise ValueError(f"noise sd for {name} must be finite and >= 0, got {sd}")
        noise = ar1_noise(val.size, sd, rho, rng) if rho else rng.standard_normal(val.size) * sd
        ch[name] = (val + noise) % (2.0 * np.pi) if name == "azimuth" else val + noise
    return RadarTrack(track.t, ch, dict(track.extra), source=track.source)


#: the smallest slant range [m] a radar records: a range is a distance, and noise that makes one
#: negative (a radar at the muzzle, at launch) gives a row no radar writes and no reader accepts
MIN_RECORDED_RANGE = 0.0


def recordable(track):
    """The samples of a (noisy) track that a radar can record: slant ``range`` at least
    :data:`MIN_RECORDED_RANGE` and ``elevation`` within [-90, 90] deg, as the track reader
    requires; the others (noise near the site, or straight above or below it, pushed them past
    the limits) are left out, with a note.

    Parameters
    ----------
    track : RadarTrack

    Returns
    -------
    (RadarTrack, int)
        The recordable samples (``track`` itself when all are) and how many were left out.
    """
    keep = np.ones(track.n, bool)
    if "range" in track.channels:
        keep &= track.channels["range"] >= MIN_RECORDED_RANGE
    if "elevation" in track.channels:
        keep &= np.abs(track.channels["elevation"]) <= 0.5 * np.pi
    dropped = int(track.n - keep.sum())
    if not dropped:
        return track, 0
    if keep.sum() < 2:
        raise InputError(f"{track.source or 'track'}: {dropped} of {track.n} samples are not what a radar records "
                         f"(a range below {MIN_RECORDED_RANGE:g} m or an elevation beyond +-90 deg after the noise): "
                         f"too few remain; move the radar's site or lower its noise")
    out = track.subset(keep)
    note = (f"{track.source or 'track'}: {dropped} sample(s) left out that a radar does not record (the noise made "
            f"the range negative or the elevation pass +-90 deg, near the radar's site or straight above or below "
            f"it), first at t = {track.t[~keep][0]:g} s")
    return RadarTrack(out.t, out.channels, out.extra, out.source, out.notes + (note,)), dropped


def add_outliers(track, fraction, size, sigma, rng):
    """Replace a ``fraction`` of samples of every channel by gross outliers.

    Each chosen sample gets ``± size * sigma[channel]`` added (random sign). Returns the new
    track and the indices hit.
    """
    n = track.n
    k = int(round(fraction * n))
    idx = np.sort(rng.choice(n, size=k, replace=False)) if k else np.zeros(0, dtype=int)
    ch = {}
    for name, val in track.channels.items():
        v = val.copy()
        v[idx] += rng.choice([-1.0, 1.0], size=k) * size * float(sigma.get(name, 1.0))
        ch[name] = v
    return RadarTrack(track.t, ch, dict(track.extra), source=track.source), idx


def drop_samples(track, fraction=0.0, gaps=(), rng=None):
    """Remove samples: a random ``fraction`` (needs ``rng``) and/or time ``gaps`` [(t0, t1), ...].

    The first sample is always kept.
    """
    keep = np.ones(track.n, dtype=bool)
    if fraction:
        if rng is None:
            raise ValueError("drop_samples with a fraction needs an rng")
        keep &= rng.random(track.n) >= fraction
    for t0, t1 in gaps:
        keep &= ~((track.t >= t0) & (track.t <= t1))
    keep[0] = True
    return track.subset(keep)
