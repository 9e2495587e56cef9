"""The round's launch values as priors on the initial state, and their check against the track.

When the track starts at t = 0 and the round gives the launch velocity and elevation, the muzzle
at the origin, the launch speed and the elevation are Gaussian priors (:func:`launch_state_priors`).
The round may be wrong, so each prior is first compared with a fit made without it, in units of
the combined sd (the prior's and the fit's colored-residual sd); one further than
:data:`LAUNCH_CONFLICT_K` is reported and left out (:func:`checked_launch_priors`): a nominal
muzzle velocity 15 % off, a time origin at the first radar sample. Launch values the channels
cannot see (no ``z``: the muzzle height and the elevation) stay priors unchecked
(:func:`unseen_launch_priors`). A track that starts later gets no launch priors; its state is
extrapolated back to t = 0 and compared with the round's launch speed.
"""
from __future__ import annotations

import math

import numpy as np

from ...air.atmosphere import G0
from ...measure import gun_equivalent
from ..model.layout import ParameterLayout
from ..model.problem import Prior

__all__ = ["LAUNCH_CONFLICT_K", "ORIGIN_NOISE_K", "launch_state_priors", "unseen_launch_priors",
           "checked_launch_priors", "origin_offset", "path_angle_prior", "PATH_ANGLE_TURN_MAX",
           "FLAT_FIRE_SD_DEG", "FLAT_FIRE_REACH"]

#: a launch prior that disagrees with the track by more than this many combined sd is dropped
LAUNCH_CONFLICT_K = 4.0
#: a first sample away from the muzzle counts only beyond this many single-sample noise sd
ORIGIN_NOISE_K = 4.0
#: relative uncertainty of the speed change a fit carries back to the muzzle (its Cd there)
ORIGIN_EXTRAPOLATION = 0.05


def launch_state_priors(L, P, heading=False, names=None):
    """Gaussian priors on the state at launch (t = 0) from a round's ``[launch]`` ``L``, for a
    parameter vector whose initial state starts at index ``P``: muzzle at the origin
    (``position_sd`` per axis), launch speed (``velocity_sd``), elevation (``elevation_sd``) and,
    with ``heading``, a heading along +x with the elevation's sd (the diagnosis); ``names``
    keeps only the priors of those names.

    The functions take one parameter vector (n,) or many (W, n): the sampler evaluates all
    walkers at once.
    """
    lay = ParameterLayout(P)
    x, y, z, vx, vy, vz = (lay.index(c) for c in ("x", "y", "z", "vx", "vy", "vz"))
    vel = (vx, vy, vz)
    pri = [Prior(f"{n}_muzzle", (lambda th, k=k: th[..., k]), 0.0, L.position_sd, depends=(k,))
           for k, n in zip((x, y, z), ("X0", "Y0", "Z0"))]
    pri.append(Prior("launch_speed", lambda th: np.sqrt(th[..., vx] ** 2 + th[..., vy] ** 2 + th[..., vz] ** 2),
                     L.velocity, L.velocity_sd, depends=vel))
    pri.append(Prior("elevation", lambda th: np.degrees(np.arctan2(th[..., vz], np.hypot(th[..., vx], th[..., vy]))),
                     L.elevation_deg, L.elevation_sd_deg, depends=vel))
    if heading:
        pri.append(Prior("heading", lambda th: np.degrees(np.arctan2(th[..., vy], th[..., vx])),
                         0.0, L.elevation_sd_deg, depends=(vx, vy)))
    if names is not None:
        pri = [p for p in pri if p.name in names]
    return tuple(pri)


def unseen_launch_priors(track, rnd, chans):
    """Names of the launch priors on quantities the channels do not observe (no ``z``: the
    muzzle height and the elevation; no ``x``: the muzzle's downrange position): the data
    cannot check them, so they are applied as given. Empty when no launch priors apply."""
    L = rnd.launch
    if abs(float(track.t[0])) > 1e-9 or L.velocity is None or L.elevation_deg is None:
        return ()
    chans = gun_equivalent(chans)      # a radar's range, angles, range rate observe x, y, z, v
    out = []
    if "x" not in chans:
        out.append("X0_muzzle")
    if "z" not in chans:
        out += ["Z0_muzzle", "elevation"]
    return tuple(out)


#: a speed-only flight that turns by less than this [rad] over its track cannot tell its path
#: angle from its drag level: gravity's along-path part is then a constant deceleration
PATH_ANGLE_TURN_MAX = 0.05
#: without a stated elevation a speed-only track this short [s since launch] is taken as flat
#: fire (a chronograph beside a rifle); a longer one keeps its path angle free (not determined)
FLAT_FIRE_REACH = 1.0
#: the path angle's sd [deg] when flat fire is assumed: a rifle aimed at a target a few degrees
#: up or down; on a chronograph track 2 deg moves Cd by about 0.1 %
FLAT_FIRE_SD_DEG = 2.0


def path_angle_prior(track, rnd, chans, P):
    """A Gaussian prior on the path angle at the first sample of a speed-only track that cannot
    see it, or ``()``.

    With no position channel the fit sees the path angle ``gamma`` only through gravity's
    along-path deceleration ``g sin(gamma)``; over a track on which the flight turns by less than
    :data:`PATH_ANGLE_TURN_MAX` that is a constant, the same as a drag level, and the two trade
    exactly (a free vertical velocity went to -19 m/s on a real 720 m/s LabRadar shot). The prior
    is the round's elevation less the gravity turn to the first sample, with its
    ``elevation_sd``; without a stated elevation, flat fire (0 +/- :data:`FLAT_FIRE_SD_DEG`) on a
    track shorter than :data:`FLAT_FIRE_REACH` s, else no prior.

    Parameters
    ----------
    track : RadarTrack
    rnd : Round
    chans : tuple of str
        The channels fitted.
    P : int
        Drag coefficients before the initial state in the parameter vector.

    Returns
    -------
    tuple of Prior
        ``(Prior("path_angle", ...),)`` in degrees, or ``()``.
    """
    seen = gun_equivalent(chans)
    if any(c in seen for c in ("x", "y", "z")) or "v" not in seen:
        return ()
    t = np.asarray(track.t, float)
    speed = np.abs(np.asarray(track.channels["v" if "v" in track.channels else "range_rate"], float))
    v_min = float(np.min(speed))
    if v_min <= 0.0 or G0 * float(t[-1]) / v_min > PATH_ANGLE_TURN_MAX:
        return ()
    L = rnd.launch
    if L.elevation_deg is not None:
        el0, sd = math.radians(L.elevation_deg), L.elevation_sd_deg
        mean = math.degrees(el0 - G0 * math.cos(el0) * float(t[0]) / float(speed[0]))
    elif float(t[-1]) <= FLAT_FIRE_REACH:
        mean, sd = 0.0, FLAT_FIRE_SD_DEG
    else:
        return ()
    lay = ParameterLayout(P)
    vx, vy, vz = (lay.index(c) for c in ("vx", "vy", "vz"))
    return (Prior("path_angle", lambda th: np.degrees(np.arctan2(th[..., vz], np.hypot(th[..., vx], th[..., vy]))),
                  mean, sd, depends=(vx, vy, vz)),)


def _prior_value_sd(prior, theta, cov, steps):
    """A prior's function at theta and its sd under ``cov`` (delta method)."""
    v = float(prior.fn(theta))
    g = np.zeros(theta.size)
    for j in np.flatnonzero((np.diag(cov) > 0) & (np.asarray(steps) > 0)):
        tp, tm = theta.copy(), theta.copy()
        tp[j] += steps[j]
        tm[j] -= steps[j]
        g[j] = (float(prior.fn(tp)) - float(prior.fn(tm))) / (2 * steps[j])
    return v, float(np.sqrt(max(g @ cov @ g, 0.0)))


def checked_launch_priors(track, rnd, model, res, P, skip=(), start=None, sigma=None, clock_fitted=False):
    """The round's launch priors (except those named in ``skip``) that agree with a fit made
    without them.

    The muzzle position is checked by :func:`origin_offset`: a first sample away from the muzzle
    is either a late (or early) clock or a track whose frame is not at the gun, and the check
    says which; it never fires on an offset the noise or the fit's own uncertainty could make,
    and keeps the priors when it is unsure. A clock offset with ``clock_fitted`` (the fit carries
    the ``radar_time`` effect; also an offset the flight cannot tell from one of the frame) keeps
    every launch prior: the fitted offset explains it, and
    without the priors a clock offset is the same as another initial state, so the fit could
    not size it.

    Parameters
    ----------
    start : DataStart, optional
        The track's smoothed kinematics (the first sample's position as the data show it).
    sigma : dict, optional
        Noise sd per channel (the round's).

    Returns (priors to use, check dict for result.json)."""
    L = rnd.launch
    t0 = float(track.t[0])
    check = {"applied": [], "conflicts": [], "extrapolated": None}
    if L.velocity is None or L.elevation_deg is None:
        check["note"] = "no [launch] velocity and elevation: no launch priors"
        return (), check
    if abs(t0) > 1e-9:
        check["note"] = (f"the track starts at t = {t0:g} s: the state is fitted at its first sample "
                         f"without launch priors")
        back = model.state_at(res.drag_params, res.state0, t0, 0.0) if np.all(np.isfinite(res.theta)) else None
        if back is not None:
            v = float(np.linalg.norm(back[3:]))
            el = math.degrees(math.atan2(back[5], math.hypot(back[3], back[4])))
            check["extrapolated"] = {"t": 0.0, "velocity": v, "elevation": el,
                                     "position": [float(x) for x in back[:3]]}
            # the extrapolation is only as good as the Cd it assumes above the data's Mach:
            # a generous sd (1 % of the speed) on top of the round's
            sd_v = math.hypot(L.velocity_sd, 0.01 * v)
            if abs(v - L.velocity) > LAUNCH_CONFLICT_K * sd_v:
                check["conflicts"].append({
                    "prior": "launch_speed", "round": L.velocity, "track": v, "sd": sd_v,
                    "message": f"the track extrapolated back to t = 0 left the muzzle at {v:.1f} m/s; "
                               f"the round says {L.velocity:g} +- {L.velocity_sd:g} m/s"})
        return (), check
    cands = [p for p in launch_state_priors(L, P) if p.name not in skip]
    cov = res.cov_colored if np.all(np.isfinite(res.cov_colored)) else res.cov
    vals = {}
    for p in cands:
        v, sd_fit = _prior_value_sd(p, res.theta, cov, np.r_[np.zeros(P), [0.01] * 3, [0.001] * 3])
        vals[p.name] = (v, sd_fit)
    origin = origin_offset(track, rnd, model, res, P, vals, start, sigma)
    if origin is not None and origin["kind"] in ("clock", "clock or position") and clock_fitted:
        # (where the flight cannot tell a late clock from a frame along the path, the fitted
        # offset stands for either: the two move the track alike)
        check["applied"] = [p.name for p in cands]
        check["origin"] = origin
        check["time_origin_offset"] = origin["clock_offset"]
        check["note"] = "the radar clock's offset is fitted (radar_time): the launch priors hold at the launch"
        return tuple(cands), check
    muzzle = [n for n in ("X0_muzzle", "Y0_muzzle", "Z0_muzzle") if n in vals]
    used = []
    for p in cands:
        v, sd_fit = vals[p.name]
        sd = math.hypot(p.sd, sd_fit)
        z = (v - p.mean) / sd if sd > 0 else 0.0
        if p.name in muzzle and origin is None:
            used.append(p)                # an offset the noise could make: the prior stays
            check["applied"].append(p.name)
            continue
        if origin is not None or abs(z) > LAUNCH_CONFLICT_K:
            unit = {"launch_speed": "m/s", "elevation": "deg"}.get(p.name, "m")
            msg = (f"the round's {p.name.replace('_', ' ')} {p.mean:g} +- {p.sd:g} {unit} disagrees with the "
                   f"track ({v:.4g} {unit}, {z:+.1f} sd): left out of the fit")
            if origin is not None and p.name in muzzle:
                msg = origin["message"]
            entry = {"prior": p.name, "round": p.mean, "track": v, "sd": sd, "z": z, "message": msg}
            if origin is not None and p.name not in muzzle:
                # left out with the muzzle position (the launch values hold at the launch, which
                # is not where the track's origin puts it): not a finding of its own
                entry["message"] = f"left out with the muzzle position ({origin['kind']} offset): {msg}"
                entry["secondary"] = True
            check["conflicts"].append(entry)
        else:
            used.append(p)
            check["applied"].append(p.name)
    if origin is not None:
        # one message for the origin is enough
        first = [c for c in check["conflicts"] if c["prior"] in muzzle][:1]
        check["conflicts"] = first + [c for c in check["conflicts"] if c["prior"] not in muzzle]
        check["origin"] = origin
        if origin["kind"] == "clock":
            check["time_origin_offset"] = origin["clock_offset"]
    return tuple(used), check


def _position_noise(track, sigma):
    """The noise sd [m] of one position sample: the round's, but never below what the track's
    own high-frequency content shows (a radar noisier than its round says must not make a
    correct origin look off); the largest over the position channels."""
    from ..model.noise import hf_noise_sd

    t = np.asarray(track.t, float)
    out = 0.0
    for c in ("x", "y", "z"):
        if c in track.channels:
            out = max(out, float((sigma or {}).get(c, 0.0)), hf_noise_sd(t, track.channels[c]))
    return out


def origin_offset(track, rnd, model, res, P, vals, start=None, sigma=None):
    """What the first sample's distance from the muzzle at t = 0 says, or None when it says nothing.

    An offset counts when the fit without launch priors puts the shell at t = 0 more than
    :data:`LAUNCH_CONFLICT_K` combined sd (the round's ``position_sd`` and the fit's) from the
    muzzle, *and* more than :data:`ORIGIN_NOISE_K` single-sample noise sd (one radar sample
    pins a position no better than its noise, whatever the fit's bound says), *and* the track's
    smoothed first sample is as far (the data see it, not only the fitted dynamics). Otherwise
    the launch priors stay. What it is:

    * **clock**: the offset lies along the flight path (its cross-path part within those
      limits), unless the first sample already flies at the round's launch speed while the
      fitted flight carried back to the muzzle would leave it faster than that (by more than
      :data:`LAUNCH_CONFLICT_K` sd: the round's ``velocity_sd`` and
      :data:`ORIGIN_EXTRAPOLATION` of the speed the extrapolation adds): the clock is then
      late (early) by the along-path distance over the speed;
    * **clock or position**: along the path, when the flight loses too little speed over the
      offset's time for the speeds to tell (a heavy shell's 0.4 s);
    * **position**: otherwise: the track's frame is not at the gun (a radar not at the gun's
      height, an x origin elsewhere). The Cd of such a fit is as good as its air: a height
      offset puts the fitted flight in air of another density (``density_offset``, the largest
      relative difference of density between the fitted heights and the heights above the muzzle).

    Returns
    -------
    dict or None
        ``kind`` (``clock`` or ``position``), ``offset`` [m] (3,), ``along`` and ``cross`` [m],
        ``clock_offset`` [s] (clock), ``density_offset`` [-] (position), ``message``.
    """
    muzzle = [n for n in ("X0_muzzle", "Y0_muzzle", "Z0_muzzle") if n in vals]
    if not muzzle or not np.all(np.isfinite(res.theta)):
        return None
    L = rnd.launch
    off = np.array([vals.get(f"{a}0_muzzle", (0.0, 0.0))[0] for a in "XYZ"])
    sd = np.array([vals.get(f"{a}0_muzzle", (0.0, 0.0))[1] for a in "XYZ"])
    noise = _position_noise(track, sigma)
    lim = np.maximum(LAUNCH_CONFLICT_K * np.hypot(L.position_sd, sd), ORIGIN_NOISE_K * noise)
    seen = [a for a, n in enumerate("XYZ") if f"{n}0_muzzle" in vals and abs(off[a]) > lim[a]]
    if not seen:
        return None
    if start is not None:
        first = np.asarray(start.kinematics.position[0], float)
        have = [a for a, c in enumerate("xyz") if c in track.channels]
        if have and float(np.linalg.norm(first[have])) < ORIGIN_NOISE_K * noise:
            return None                      # the data's own first sample sits at the muzzle
    vel = np.asarray(res.state0[3:], float)
    speed = max(float(np.linalg.norm(vel)), 1.0)
    u = vel / speed
    along = float(off @ u)
    cross_v = off - along * u
    cross = float(np.linalg.norm(cross_v))
    cross_lim = float(np.linalg.norm(lim * (np.abs(u) < 0.999)))  # the limits across the path
    dt = along / speed
    kind, how = "clock", "not along the flight path"
    if cross > max(cross_lim, ORIGIN_NOISE_K * noise):
        kind = "position"
    elif L.velocity is not None:
        back = model.state_at(res.drag_params, res.state0, 0.0, -dt)
        v_back = float(np.linalg.norm(back[3:])) if back is not None else math.inf
        # the extrapolation is as good as the Cd it carries back: 5 % of the speed it adds
        sd_v = math.hypot(L.velocity_sd, ORIGIN_EXTRAPOLATION * abs(v_back - speed)) if back is not None \
            else L.velocity_sd
        miss_clock = abs(v_back - L.velocity)
        miss_here = abs(speed - L.velocity)
        lim_v = LAUNCH_CONFLICT_K * sd_v
        if miss_here <= lim_v < miss_clock:
            # the first sample flies at the launch speed: not late
            kind, how = "position", "along the flight path, but flying at the launch speed"
        elif miss_here <= lim_v and miss_clock <= lim_v:
            kind = "clock or position"       # the flight loses too little speed to tell
    r0 = float(np.linalg.norm(off))
    where = ", ".join(f"{n} {v:+.1f} m" for n, v in zip("xyz", off))
    out = {"kind": kind, "offset": [float(v) for v in off], "along": along, "cross": cross}
    late = "late" if dt >= 0 else "early"
    if kind == "clock":
        out["clock_offset"] = dt
        out["message"] = (f"the first sample is {r0:.1f} m from the muzzle at t = 0 s, along the flight path: the "
                          f"track's clock looks {abs(dt):.3g} s {late} (a clock offset, not a position offset); launch "
                          f"priors left out; shift t so that t = 0 is the launch to use them")
    elif kind == "clock or position":
        out["clock_offset"] = dt
        heights = start.kinematics.z if start is not None else track.channels.get("z", np.zeros(1))
        out["density_offset"] = _density_offset(rnd, heights, off[2])
        out["message"] = (f"the first sample is {r0:.1f} m from the muzzle at t = 0 s, along the flight path: either "
                          f"the track's clock is {abs(dt):.3g} s {late} or its frame is that far along the path from "
                          f"the gun (this flight loses too little speed in that time to tell); launch priors left "
                          f"out; shift t, or the positions, so that the track starts at the muzzle at t = 0")
    else:
        heights = start.kinematics.z if start is not None else track.channels.get("z", np.zeros(1))
        out["density_offset"] = _density_offset(rnd, heights, off[2])
        rel = out["density_offset"]
        dens = (f"; the fitted flight is {abs(off[2]):.0f} m {'above' if off[2] > 0 else 'below'} the heights above "
                f"the muzzle, in air up to {100 * rel:.2g} % off in density, and Cd is uncertain by that"
                if rel is not None and abs(off[2]) > lim[2] else "")
        out["message"] = (f"the first sample is {r0:.1f} m from the muzzle at t = 0 s ({where}), {how}: the "
                          f"track's frame is not at the gun (a position offset, not a clock offset); "
                          f"launch priors left out{dens}; put the origin at the muzzle (subtract the offset) or fix "
                          f"the round's [launch] altitude")
    return out


def _density_offset(rnd, heights, dz):
    """Largest relative density difference between the fitted flight's ``heights`` [m] and the
    same heights moved by ``-dz`` (the heights above the muzzle)."""
    from ...air.atmosphere import MAX_ALTITUDE, MIN_ALTITUDE

    atm = rnd.atmosphere
    lo = MIN_ALTITUDE - atm.gun_altitude + 1.0
    hi = MAX_ALTITUDE - atm.gun_altitude - 1.0
    z = np.clip(np.atleast_1d(np.asarray(heights, float)), lo, hi)
    try:
        a = atm.at_height(z).density
        b = atm.at_height(np.clip(z - dz, lo, hi)).density
    except ValueError:        # a met profile that does not reach the shifted heights
        return None
    return float(np.max(np.abs(b / a - 1.0)))
