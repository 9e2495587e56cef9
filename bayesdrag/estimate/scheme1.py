"""Scheme 1: Cd(M) over the whole flight together with the initial conditions (paper §3-4).

Choices written down:

* **Default drag model: ``spline``** with knots from :func:`bayesdrag.drag.default_spline_knots`
  over the Mach span the flight covers (taken from a first simulation with the reference drag,
  or from the data's speeds). It is the only model that follows a transonic rise; over a purely
  supersonic or subsonic span it reduces to a few coefficients. ``poly2`` and ``poly2-split``
  are the paper's and are kept for comparison; their misfit is reported, not hidden.
* **Initial conditions** at the first sample: from the round's launch (muzzle at the origin,
  ``velocity`` and ``elevation``) when the track starts at t = 0; otherwise from a quadratic
  Savitzky-Golay derivative of the first samples. Components the track cannot see are fixed
  (no ``y`` channel: Y0 = Uy0 = 0; no position channel: the muzzle position).
* **Earth rotation** is in the model when the round gives ``[launch] latitude`` (with
  ``azimuth``), as in ``bayesdrag simulate``.
* **Noise**: the round's ``[radar] sigma`` when given for a channel, else estimated by
  relaxation.
* **Determined Mach range**: where the Cramér-Rao sd of Cd is below 1 % of Cd, inside the Mach
  span of the data. Near the top of the span Cd correlates with the launch speed, so that end
  is often less determined than it looks.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import savgol_filter

from ..drag import make_drag_model
from ..dynamics.pointmass import PointMassModel, initial_state
from ..errors import InputError
from .ml import OutputErrorProblem

#: relative CRB sd of Cd below which Cd counts as determined by the data
DETERMINED_REL_SD = 0.01


def _initial_state(track, rnd):
    L = rnd.launch
    t0 = float(track.t[0])
    if abs(t0) < 1e-9 and L.velocity is not None and L.elevation_deg is not None:
        return initial_state(L.velocity, L.elevation_deg)
    pos = [track.channels.get(c) for c in ("x", "y", "z")]
    n = min(track.n, 21)
    if n < 7 or pos[0] is None or pos[2] is None:
        raise InputError(f"{track.source}: the track starts at t = {t0:g} s; initial conditions need "
                         f"x and z samples there (>= 7) or [launch] velocity and elevation with t = 0")
    tt = track.t[:n]
    dt = float(np.median(np.diff(tt)))
    s = np.zeros(6)
    for k, p in enumerate(pos):
        if p is None:
            continue
        s[k] = savgol_filter(p[:n], n if n % 2 else n - 1, 2, mode="interp")[0]
        s[3 + k] = savgol_filter(p[:n], n if n % 2 else n - 1, 2, deriv=1, delta=dt, mode="interp")[0]
    return s


def _coriolis(rnd):
    L = rnd.launch
    return (L.latitude_deg, L.azimuth_deg) if L.latitude_deg is not None else None


def mach_span(track, rnd, state0):
    """Mach range of the flight from a simulation with the reference (or a generic) drag."""
    from ..drag import Poly2

    ref = rnd.reference_drag
    drag = ref if ref is not None else Poly2()
    params = () if ref is not None else (0.3, 0.0, 0.0)
    model = PointMassModel(rnd.projectile.mass, rnd.projectile.diameter, drag, rnd.atmosphere,
                           coriolis=_coriolis(rnd))
    tr = model.simulate(params, state0, track.t, t_start=float(track.t[0]))
    m = tr.mach[np.isfinite(tr.mach)]
    return float(m.min()), float(m.max())


def launch_priors(track, rnd, P):
    """Gaussian priors from the round's ``[launch]`` on the initial state, when the track
    starts at the muzzle (t = 0): muzzle position (``position_sd`` per axis), launch speed
    (``velocity_sd``) and elevation (``elevation_sd``). They are weak against a full x, y, z, v
    track but keep a speed-only (Doppler) track's elevation where the gun put it."""
    from .ml import Prior

    L = rnd.launch
    if abs(float(track.t[0])) > 1e-9 or L.velocity is None or L.elevation_deg is None:
        return ()
    pri = [Prior(f"{n}_muzzle", (lambda th, k=k: th[P + k]), 0.0, L.position_sd)
           for k, n in enumerate(("X0", "Y0", "Z0"))]
    pri.append(Prior("launch_speed", lambda th: float(np.linalg.norm(th[P + 3:P + 6])), L.velocity, L.velocity_sd))
    pri.append(Prior("elevation", lambda th: float(np.degrees(np.arctan2(th[P + 5], np.hypot(th[P + 3], th[P + 4])))),
                     L.elevation_deg, L.elevation_sd_deg))
    return tuple(pri)


def fit_scheme1(track, rnd, drag="spline", channels=None, sigma=None, free_ic=True, knots=None):
    """Scheme 1 ML fit of one track.

    Parameters
    ----------
    track : RadarTrack
    rnd : Round
    drag : str
        Drag model name (DESIGN.md).
    channels : sequence of str, optional
    sigma : dict, optional
        Fixed noise sd per channel (default: the round's ``[radar] sigma``).
    free_ic : bool
        Estimate the initial conditions (paper Fig. 3c) or keep them at their starting values
        (Fig. 3b).
    knots : sequence of float, optional
        Spline knots (default from the Mach span).

    Returns
    -------
    (MLResult, OutputErrorProblem)
    """
    s0 = _initial_state(track, rnd)
    lo, hi = mach_span(track, rnd, s0)
    dm = make_drag_model(drag, reference=rnd.reference_drag, mach_range=(lo, hi), knots=knots)
    model = PointMassModel(rnd.projectile.mass, rnd.projectile.diameter, dm, rnd.atmosphere,
                           coriolis=_coriolis(rnd))
    theta0 = np.concatenate([dm.initial_params(rnd.reference_drag), s0])
    free = np.ones(theta0.size, bool)
    P = dm.n_params
    chans = tuple(channels) if channels is not None else track.names
    if not free_ic:
        free[P:] = False
    if "y" not in chans:
        free[P + 1] = free[P + 4] = False
    if not any(c in chans for c in ("x", "y", "z")):
        free[P:P + 3] = False
    if drag == "poly2-split":
        if hi < 1.0:
            free[3:6] = False
        if lo >= 1.0:
            free[0:3] = False
    sig = dict(rnd.radar.sigma) if sigma is None else dict(sigma)
    prob = OutputErrorProblem(model, track, theta0, free=free, sigma=sig, channels=chans,
                              priors=launch_priors(track, rnd, P))
    return prob.fit(), prob


def cd_table(result, drag_model, mach, reference=None):
    """Cd(M) rows for result.json: ML value, CRB sd (delta method), reference."""
    P = drag_model.n_params
    B = drag_model.jacobian(mach)
    cd = drag_model.cd(result.drag_params, mach)
    var = np.einsum("ij,jk,ik->i", B, result.cov[:P, :P], B)
    varc = np.einsum("ij,jk,ik->i", B, result.cov_colored[:P, :P], B)
    rows = []
    for i, m in enumerate(mach):
        rows.append({"mach": round(float(m), 4), "ml": float(cd[i]), "crb_sd": float(np.sqrt(max(var[i], 0))),
                     "crb_sd_colored": float(np.sqrt(max(varc[i], 0))),
                     "reference": float(reference.value(m)) if reference is not None else None})
    return rows


def determined_range(rows):
    """Mach interval where the CRB relative sd of Cd is below :data:`DETERMINED_REL_SD`."""
    ok = [r["mach"] for r in rows if r["ml"] > 0 and r["crb_sd"] / r["ml"] < DETERMINED_REL_SD]
    return (min(ok), max(ok)) if ok else None
