"""Short flights of many shots at once: the point-mass model in the vertical plane of fire, in
constant air, for the first hundred metres or so that a chronograph radar sees.

A chronograph session (docs/radar.md, "Chronograph sessions") fits 5-30 shots of 0.05-0.5 s
each, many times over. Over such a flight the air does not change (a rifle bullet climbs or
drops centimetres), there is no cross wind unless one is declared, and Coriolis moves the
bullet by micrometres; what remains is drag along the air-relative velocity and gravity. This
module integrates exactly that for all shots together (one compiled loop over the shots, a
fixed RK4 step, the curve tabulated on a uniform Mach grid), so that one call flies a whole session and a finite-difference Jacobian column for
a per-shot parameter perturbs every shot at once. The general model (winds by height, a met
profile, Earth rotation, lift) is :class:`bayesdrag.dynamics.pointmass.PointMassModel`; the two
agree on such flights (tests/unit/test_flat_fire.py).
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["fly", "FLAT_FIRE_STEP", "G_STANDARD"]

#: standard gravity [m/s^2]
G_STANDARD = 9.80665
#: RK4 step [s]: a bullet's speed changes on a time scale of v / a >= 0.3 s (a .22 LR at its
#: steepest), so the step's error (h / T)^4 is below 1e-9 relative
FLAT_FIRE_STEP = 1e-3


def fly(v0, t0, scale, drag, t_samples, *, k_air, sound_speed, elevation=0.0, head_wind=0.0,
        step=FLAT_FIRE_STEP):
    """Fly every shot from the muzzle and return its state at its own sample times.

    Parameters
    ----------
    v0 : ndarray, shape (S,), m/s
        Each shot's speed at the muzzle.
    t0 : ndarray, shape (S,), s
        Each shot's time origin on its track's clock (when it leaves the muzzle).
    scale : ndarray, shape (S,)
        Each shot's drag relative to the session's Cd(M) (1 = the session's curve).
    drag : tuple ``(mach0, dmach, cd)``
        The session's Cd(M) tabulated on a uniform Mach grid: first Mach [-], step [-], values
        (ndarray); linear between the points, held at the ends.
    t_samples : list of S ndarrays, s
        Each shot's sample times on its track's clock; each must be >= its ``t0``.
    k_air : float, 1/m
        ``rho * A / (2 m)``: air density [kg/m^3] times the reference area [m^2] over twice the
        mass [kg]; the drag deceleration is ``k_air * Cd * |u| * u`` for air-relative velocity ``u``.
    sound_speed : float, m/s
    elevation : float or ndarray, shape (S,), rad
        The line of departure above the horizontal.
    head_wind : float, m/s
        A constant wind blowing against the line of fire (positive: head wind).
    step : float, s
        The RK4 step.

    Returns
    -------
    list of S tuples ``(x, z, vx, vz)`` of ndarrays at each shot's sample times, m and m/s: ``x``
    along the horizontal line of fire from the muzzle, ``z`` up.

    Raises
    ------
    ValueError
        A sample before its shot's time origin, or a shot that does not fly forward.
    """
    v0 = np.ascontiguousarray(v0, float)
    S = v0.size
    t0 = np.broadcast_to(np.asarray(t0, float), (S,))
    scale = np.ascontiguousarray(np.broadcast_to(np.asarray(scale, float), (S,)))
    el = np.ascontiguousarray(np.broadcast_to(np.asarray(elevation, float), (S,)))
    tau = [np.asarray(t, float) - t0[i] for i, t in enumerate(t_samples)]
    if any(t.size and t.min() < -1e-12 for t in tau):
        raise ValueError("a sample lies before its shot's time origin")
    sizes = [t.size for t in tau]
    tau_flat = np.ascontiguousarray(np.concatenate(tau)) if tau else np.zeros(0)
    which = np.repeat(np.arange(S), sizes)
    t_end = float(tau_flat.max()) if tau_flat.size else 0.0
    n = int(np.ceil(t_end / step)) + 1
    m0, dm, cd = drag
    out = np.empty((4, tau_flat.size))
    ok = _fly_kernel(v0, scale, el, float(m0), float(dm), np.ascontiguousarray(cd, float), float(k_air),
                     float(sound_speed), float(head_wind), G_STANDARD, float(step), n, tau_flat, which, out)
    if not ok:
        raise ValueError("a shot stops or flies backwards within its track")
    parts = np.split(out, np.cumsum(sizes)[:-1], axis=1)
    return [(p[0], p[1], p[2], p[3]) for p in parts]


@njit(cache=True, fastmath=False, error_model="numpy", boundscheck=False)
def _cd(mach, m0, dm, cd):
    f = (mach - m0) / dm
    if f <= 0.0:
        return cd[0]
    j = int(f)
    if j >= cd.size - 1:
        return cd[cd.size - 1]
    w = f - j
    return cd[j] * (1.0 - w) + cd[j + 1] * w


@njit(cache=True, fastmath=False, error_model="numpy", boundscheck=False)
def _rhs(s, scale, m0, dm, cd, k_air, c, wind, g, out):
    ux, uz = s[2] + wind, s[3]
    u = np.sqrt(ux * ux + uz * uz)
    k = k_air * scale * _cd(u / c, m0, dm, cd) * u
    out[0] = s[2]
    out[1] = s[3]
    out[2] = -k * ux
    out[3] = -k * uz - g


@njit(cache=True, fastmath=False, error_model="numpy", boundscheck=False)
def _fly_kernel(v0, scale, el, m0, dm, cd, k_air, c, wind, g, h, n, tau, which, out):
    """RK4 of each shot on steps of ``h`` and cubic Hermite output at its samples; False when a
    shot's forward speed reaches zero."""
    S = v0.size
    y = np.empty((n + 1, 4))
    a = np.empty((n + 1, 4))
    k1, k2, k3, k4, tmp = np.empty(4), np.empty(4), np.empty(4), np.empty(4), np.empty(4)
    for i in range(S):
        y[0, 0], y[0, 1] = 0.0, 0.0
        y[0, 2], y[0, 3] = v0[i] * np.cos(el[i]), v0[i] * np.sin(el[i])
        for j in range(n):
            s = y[j]
            _rhs(s, scale[i], m0, dm, cd, k_air, c, wind, g, k1)
            for q in range(4):
                tmp[q] = s[q] + 0.5 * h * k1[q]
            _rhs(tmp, scale[i], m0, dm, cd, k_air, c, wind, g, k2)
            for q in range(4):
                tmp[q] = s[q] + 0.5 * h * k2[q]
            _rhs(tmp, scale[i], m0, dm, cd, k_air, c, wind, g, k3)
            for q in range(4):
                tmp[q] = s[q] + h * k3[q]
            _rhs(tmp, scale[i], m0, dm, cd, k_air, c, wind, g, k4)
            for q in range(4):
                a[j, q] = k1[q]
                y[j + 1, q] = s[q] + (h / 6.0) * (k1[q] + 2.0 * k2[q] + 2.0 * k3[q] + k4[q])
            if y[j + 1, 2] <= 0.0:
                return False
        _rhs(y[n], scale[i], m0, dm, cd, k_air, c, wind, g, k1)
        for q in range(4):
            a[n, q] = k1[q]
        # cubic Hermite between steps: positions from velocity, velocity from acceleration
        for k in range(tau.size):
            if which[k] != i:
                continue
            f = tau[k] / h
            j = min(int(f), n - 1)
            th = f - j
            h00, h10 = 2 * th ** 3 - 3 * th ** 2 + 1, th ** 3 - 2 * th ** 2 + th
            h01, h11 = -2 * th ** 3 + 3 * th ** 2, th ** 3 - th ** 2
            for q in range(4):
                out[q, k] = h00 * y[j, q] + h10 * a[j, q] * h + h01 * y[j + 1, q] + h11 * a[j + 1, q] * h
    return True
