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

from .problem import Prior

__all__ = ["LAUNCH_CONFLICT_K", "launch_state_priors", "unseen_launch_priors", "checked_launch_priors"]

#: a launch prior that disagrees with the track by more than this many combined sd is dropped
LAUNCH_CONFLICT_K = 4.0


def launch_state_priors(L, P, heading=False, names=None):
    """Gaussian priors on the state at launch (t = 0) from a round's ``[launch]`` ``L``, for a
    parameter vector whose initial state starts at index ``P``: muzzle at the origin
    (``position_sd`` per axis), launch speed (``velocity_sd``), elevation (``elevation_sd``) and,
    with ``heading``, a heading along +x with the elevation's sd (the diagnosis); ``names``
    keeps only the priors of those names.

    The functions take one parameter vector (n,) or many (W, n): the sampler evaluates all
    walkers at once.
    """
    pri = [Prior(f"{n}_muzzle", (lambda th, k=k: th[..., P + k]), 0.0, L.position_sd)
           for k, n in enumerate(("X0", "Y0", "Z0"))]
    pri.append(Prior("launch_speed", lambda th: np.sqrt(th[..., P + 3] ** 2 + th[..., P + 4] ** 2
                                                        + th[..., P + 5] ** 2), L.velocity, L.velocity_sd))
    pri.append(Prior("elevation", lambda th: np.degrees(np.arctan2(th[..., P + 5], np.hypot(th[..., P + 3],
                                                                                           th[..., P + 4]))),
                     L.elevation_deg, L.elevation_sd_deg))
    if heading:
        pri.append(Prior("heading", lambda th: np.degrees(np.arctan2(th[..., P + 4], th[..., P + 3])),
                         0.0, L.elevation_sd_deg))
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
    out = []
    if "x" not in chans:
        out.append("X0_muzzle")
    if "z" not in chans:
        out += ["Z0_muzzle", "elevation"]
    return tuple(out)


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


def checked_launch_priors(track, rnd, model, res, P, skip=()):
    """The round's launch priors (except those named in ``skip``) that agree with a fit made
    without them.

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
    muzzle = [n for n in ("X0_muzzle", "Y0_muzzle", "Z0_muzzle") if n in vals]
    r0 = math.sqrt(sum(vals[n][0] ** 2 for n in muzzle))
    pos_conflict = any(abs(vals[n][0]) > LAUNCH_CONFLICT_K * math.hypot(L.position_sd, vals[n][1])
                       for n in muzzle if vals[n][1] > 0 or True)
    used = []
    for p in cands:
        v, sd_fit = vals[p.name]
        sd = math.hypot(p.sd, sd_fit)
        z = (v - p.mean) / sd if sd > 0 else 0.0
        if pos_conflict or abs(z) > LAUNCH_CONFLICT_K:
            unit = {"launch_speed": "m/s", "elevation": "deg"}.get(p.name, "m")
            msg = (f"the round's {p.name.replace('_', ' ')} {p.mean:g} +- {p.sd:g} {unit} disagrees with the "
                   f"track ({v:.4g} {unit}, {z:+.1f} sd): left out of the fit")
            if pos_conflict and p.name in muzzle:
                speed = float(np.linalg.norm(res.state0[3:]))
                msg = (f"the first sample is {r0:.1f} m from the muzzle at t = {t0:g} s: the track's time origin "
                       f"is not the launch (it looks about {r0 / max(speed, 1.0):.2f} s late); launch priors "
                       f"left out; shift t so that t = 0 is the launch to use them")
            entry = {"prior": p.name, "round": p.mean, "track": v, "sd": sd, "z": z, "message": msg}
            if pos_conflict and p.name not in muzzle:
                # left out with the muzzle position (the launch values hold at the launch, which
                # is not at t = 0): not a finding of its own, one line says it
                entry["message"] = f"left out with the muzzle position (time origin): {msg}"
                entry["secondary"] = True
            check["conflicts"].append(entry)
        else:
            used.append(p)
            check["applied"].append(p.name)
    # one message for the time origin is enough
    if pos_conflict:
        first = next(c for c in check["conflicts"] if c["prior"] in muzzle)
        check["conflicts"] = [first] + [c for c in check["conflicts"] if c["prior"] not in muzzle]
        check["time_origin_offset"] = r0 / max(float(np.linalg.norm(res.state0[3:])), 1.0)
    return tuple(used), check
