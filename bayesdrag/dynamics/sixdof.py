"""Six-degree-of-freedom (6-DOF) rigid-body simulator of a spin-stabilised shell: synthetic truth.

This is the model the paper (Eqs. 1-17) used to make its simulated radar
tracks: a rotationally symmetric rigid body under gravity and the full set of linear
aerodynamic forces and moments, integrated from the muzzle to impact. The estimators of this
package fit a *point-mass* model (paper Eqs. 20-22) to such tracks; the 6-DOF model supplies
what the point-mass model leaves out (yaw drag, lift and drift from the yaw of repose, Magnus
effects, the epicyclic motion after a muzzle disturbance), so that a fit to 6-DOF data shows
honestly what the simplification costs.

Formulation: McCoy's vector equations instead of the paper's Euler angles
-------------------------------------------------------------------------
The paper writes the motion in body axes rolling with the shell (u, v, w, p, q, r; Eqs. 6-11)
with Euler angles (phi, theta, psi; Eqs. 12-14) and transforms the body velocity to the earth
frame (Eqs. 15-17). With p = 1657 rad/s the roll angle phi turns ~16 000 times in a 60 s
flight, and u, v, w, q, r oscillate at the spin frequency even when the motion *of the axis*
is smooth. An explicit integrator must then take steps of a fraction of a millisecond (the
paper used fixed-step RK4), and theta = 90 deg is singular (Eq. 14).

Here the same physics is written in the vector form of R. L. McCoy, *Modern Exterior
Ballistics* (Schiffer, 1999), chapter 9, which describes the body by two earth-frame vectors
instead of body axes:

* ``x_hat``: unit vector along the shell's axis of symmetry (nose direction);
* ``w = H / Iy``: the angular momentum divided by the transverse inertia [rad/s].

For a symmetric body (Iy = Iz, which the paper's Eqs. 9-11 also assume) the angular velocity
is ``omega = p x_hat + omega_t`` and ``H = Ix p x_hat + Iy omega_t``, so

    d x_hat / dt = omega_t x x_hat = w x x_hat                (kinematics, replaces Eqs. 12-14)
    d w / dt     = M / Iy                                       (Euler's equations, Eqs. 9-11)
    d u / dt     = F / m                                        (Newton, Eqs. 6-8 + 15-17)
    d r / dt     = u                                            (earth-frame position, 15-17)
    p            = (Iy / Ix) (w . x_hat)                        (spin, Eq. 9)

where u is the ground-relative velocity of the centre of mass and r its position. This is
exactly equivalent to Eqs. 6-17 (a change of variables: body-axis components -> earth-frame
vectors; the Coriolis-like terms ``-q w + r v`` etc. of Eqs. 6-8 and ``q r (Iy - Iz)``,
``r p (Iz - Ix)``, ``p q (Ix - Iy)`` of Eqs. 9-11 are what the rotation of the body axes adds
to the time derivatives; in the earth frame they do not appear). The spin enters only through
``w . x_hat``, so no state oscillates at the spin frequency: the fastest motion left is the
physical nutation (fast epicyclic mode) at ~Ix p / Iy ~ 140 rad/s, which an adaptive
integrator follows with steps of a few milliseconds. There is no attitude singularity.

The paper's aerodynamic model (Eqs. 1-5: lift ``C_L_alpha``, pitch moment ``C_m_alpha`` and
damping ``C_m_q``, the symmetric yaw counterparts, roll damping ``C_l_p``) maps term by term
onto the vector forces below (its ``C_L_alpha`` -> lift, ``C_m_alpha`` -> overturning moment,
``C_m_q`` -> pitch damping ``C_M_q + C_M_alpha_dot``, ``C_l_p`` -> spin damping); this module adds
the two Magnus terms and the yaw-dependent drag that a spinning shell needs for realistic
drift and yaw damping (McCoy ch. 9).

Forces and moments (McCoy ch. 9 sign conventions)
-------------------------------------------------
With air-relative velocity ``V = u - wind`` (speed V, direction ``v_hat``), dynamic pressure
``q = rho V^2 / 2``, reference area ``S = pi d^2 / 4``, total yaw ``delta`` (angle between
``x_hat`` and ``v_hat``) and spin p > 0 for a right-hand (clockwise seen from behind) spin:

=====================  ======================================================================
drag                   ``-q S (C_D0(M) + C_D_delta2(M) sin^2 delta) v_hat``
lift                   ``+q S C_L_alpha [x_hat - (v_hat . x_hat) v_hat]``
Magnus force           ``+q S (p d / V) C_N_p_alpha (v_hat x x_hat)``
gravity                ``m g``, g = 9.80665 m/s^2 downward (flat, non-rotating Earth)
overturning moment     ``+q S d C_M_alpha (v_hat x x_hat)``  (C_M_alpha > 0: statically unstable)
pitch damping moment   ``+q S d (d / V) (C_M_q + C_M_alpha_dot) omega_t``  (negative coefficient)
Magnus moment          ``+q S d (p d / V) C_n_p_alpha [x_hat x (v_hat x x_hat)]``
spin damping moment    ``+q S d (p d / V) C_l_p x_hat``  (C_l_p < 0)
=====================  ======================================================================

With these signs the linearised motion is McCoy's (ch. 10): ``xi'' + (H - iP) xi' - (M + iPT)
xi = 0`` with ``P = Ix p d / (Iy V)``, ``M = rho S d / (2m) k_t^-2 C_M_alpha``,
``H = rho S d / (2m) [C_L_alpha - C_D - k_t^-2 (C_M_q + C_M_alpha_dot)]``,
``T = rho S d / (2m) [C_L_alpha + k_a^-2 C_n_p_alpha]`` (per calibre of travel; k_a^2 =
Ix / (m d^2), k_t^2 = Iy / (m d^2)). :func:`linear_theory` evaluates the gyroscopic and
dynamic stability factors and the damping rates of the two epicyclic modes from these.

A right-hand spin and the downward curvature of the trajectory produce the yaw of repose, a
small nose-right yaw; lift acting on it gives the classic rightward drift (y > 0).

Frames
------
Outputs are in the track frame: x downrange (horizontal, along the firing azimuth), **y to the right**
looking downrange, z up; origin at the muzzle, t = 0 at launch. (x, y-right, z-up) is a
*left-handed* triad, so cross products are evaluated internally in the right-handed frame
(x downrange, y' = -y to the LEFT, z up) and the y components of positions, velocities, wind
and axis are negated at the edges (:func:`_to_internal` / :func:`_to_design`).

Aerodynamic data
----------------
* Zero-yaw drag ``C_D0(M)``: the 155 mm HE M101 curve of BRL MR-1167 (Odom, 1958) shipped as
  ``bayesdrag/data/cd_m101.csv`` (:func:`bayesdrag.io.drag_tables.load_m101`), the same curve the
  estimators use as the reference, so that 6-DOF tracks are "truth" for that drag.
* All other coefficients (:func:`m107_aero`): representative values of the 155 mm HE M107
  shell, a close relative of the M101 (same ogive-cylinder-boattail family; the M101 and M107
  differ mainly in the rotating band), after the M107 aerodynamic data compiled in McCoy,
  *Modern Exterior Ballistics* (1999), chs. 2 and 10, which come from BRL spark-range and
  wind-tunnel tests. CAUTION: the numbers were entered as rounded, smoothed values of the
  size and Mach trend of those data *without the book at hand* (no machine-readable copy was
  available when this module was written); they are a *representative* synthetic-truth shell,
  not a transcription, and individual values may differ from McCoy's by tens of percent. The
  range depends on them only weakly (0.1-0.3 % vs the point mass), the drift roughly as
  C_L_alpha / C_M_alpha, and the stability checks in the tests are made against linear theory
  with the same numbers. Replace the table with measured data for a specific projectile
  where that matters. (The paper's own Table 1 shell is "a direct
  fire artillery shell", 0.8 m long, 42.6 kg, whose coefficients the paper does not give.)

Numerics
--------
The right-hand side is compiled with numba (``cache=True``); the atmosphere is tabulated once
per run on a 25 m height grid (:meth:`bayesdrag.air.atmosphere.Atmosphere.table`, relative error
< 1e-6) and ``C_D0`` is evaluated from the exact cubic-cell form of the PCHIP reference table
(:meth:`bayesdrag.drag.ReferenceTable.kernel_table`), so the model's drag is the same function
as ``load_m101().value``. The other coefficients are interpolated linearly between the table
nodes (``numpy.interp``), held constant outside. Integration uses ``scipy.integrate.solve_ivp``
(DOP853 by default) with a terminal event at z = 0 on descent.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.integrate import solve_ivp

from ..air.atmosphere import G0, MAX_ALTITUDE, MIN_ALTITUDE, Atmosphere
from ..drag import MachGrid
from .shell import MAX_VALID_YAW, Shell, default_spin_rate, gyroscopic_stability

__all__ = ["SixDofResult", "simulate_6dof"]





















# ---------------------------------------------------------------------------------------------
# compiled right-hand side
# ---------------------------------------------------------------------------------------------
# parameter vector layout
_P_MASS, _P_D, _P_S, _P_IX, _P_IY, _P_G, _P_WX, _P_WY, _P_WZ = range(9)
_N_PAR = 9


@njit(cache=True, fastmath=False)
def _atm_lookup(z, atm, z0, inv_dz):
    n = atm.shape[0]
    zi = (z - z0) * inv_dz
    if zi <= 0.0:
        return atm[0, 0], atm[0, 1]
    j = int(zi)
    if j >= n - 1:
        return atm[n - 1, 0], atm[n - 1, 1]
    f = zi - j
    return (atm[j, 0] + f * (atm[j + 1, 0] - atm[j, 0]),
            atm[j, 1] + f * (atm[j + 1, 1] - atm[j, 1]))


@njit(cache=True, fastmath=False)
def _cd0_lookup(mach, cd_tab, m0, dm):
    n_cells = cd_tab.shape[0]
    mi = (mach - m0) / dm
    k = int(mi) if mi > 0.0 else 0
    if k > n_cells - 1:
        k = n_cells - 1
    u = mach - (m0 + k * dm)
    if u < 0.0:
        u = 0.0
    elif u > dm:
        u = dm
    return cd_tab[k, 0] + u * (cd_tab[k, 1] + u * (cd_tab[k, 2] + u * cd_tab[k, 3]))


@njit(cache=True, fastmath=False)
def _wind_lookup(x, z, wtab, w0, inv_dw, wax, waz):
    """Wind (internal frame, y left) of a wind profile's table at downrange x and height z [m]:
    its coordinate is ``x wax + z waz`` (zeros without a profile)."""
    n = wtab.shape[0]
    si = (x * wax + z * waz - w0) * inv_dw
    if si <= 0.0:
        return wtab[0, 0], wtab[0, 1]
    j = int(si)
    if j >= n - 1:
        return wtab[n - 1, 0], wtab[n - 1, 1]
    f = si - j
    return wtab[j, 0] + f * (wtab[j + 1, 0] - wtab[j, 0]), wtab[j, 1] + f * (wtab[j + 1, 1] - wtab[j, 1])


@njit(cache=True, fastmath=False)
def _rhs(t, y, par, atm, z0, inv_dz, cd_tab, m0, dm, aero, wtab, w0, inv_dw, wax, waz):
    """State y = [r(3), u(3), x_hat(3), w(3)] in the internal right-handed frame
    (x downrange, y LEFT, z up); returns dy/dt."""
    out = np.empty(12)
    m = par[_P_MASS]
    d = par[_P_D]
    S = par[_P_S]
    Ix = par[_P_IX]
    Iy = par[_P_IY]
    # axis (renormalised: the integrator does not keep |x_hat| = 1 exactly)
    ax, ay, az = y[6], y[7], y[8]
    nrm = math.sqrt(ax * ax + ay * ay + az * az)
    ax /= nrm
    ay /= nrm
    az /= nrm
    wx, wy, wz = y[9], y[10], y[11]
    # air-relative velocity (the constant wind plus the atmosphere's wind profile)
    pwx, pwy = _wind_lookup(y[0], y[2], wtab, w0, inv_dw, wax, waz)
    Vx = y[3] - par[_P_WX] - pwx
    Vy = y[4] - par[_P_WY] - pwy
    Vz = y[5] - par[_P_WZ]
    V = math.sqrt(Vx * Vx + Vy * Vy + Vz * Vz)
    vx, vy, vz = Vx / V, Vy / V, Vz / V
    rho, a = _atm_lookup(y[2], atm, z0, inv_dz)
    mach = V / a
    # coefficients
    mn = aero[:, 0]
    cdd2 = np.interp(mach, mn, aero[:, 1])
    cla = np.interp(mach, mn, aero[:, 2])
    cma = np.interp(mach, mn, aero[:, 3])
    cmq = np.interp(mach, mn, aero[:, 4])
    cnpa = np.interp(mach, mn, aero[:, 5])
    cnpa_m = np.interp(mach, mn, aero[:, 6])
    clp = np.interp(mach, mn, aero[:, 7])
    cd0 = _cd0_lookup(mach, cd_tab, m0, dm)
    # kinematic quantities
    wa = wx * ax + wy * ay + wz * az          # w . x_hat = (Ix/Iy) p
    p = Iy * wa / Ix
    otx, oty, otz = wx - wa * ax, wy - wa * ay, wz - wa * az   # transverse angular velocity
    cosd = vx * ax + vy * ay + vz * az
    # v_hat x x_hat
    cx = vy * az - vz * ay
    cy = vz * ax - vx * az
    cz = vx * ay - vy * ax
    sin2 = cx * cx + cy * cy + cz * cz
    qS = 0.5 * rho * V * V * S
    spin_ratio = p * d / V
    # forces
    cd = cd0 + cdd2 * sin2
    fx = -qS * cd * vx + qS * cla * (ax - cosd * vx) + qS * spin_ratio * cnpa * cx
    fy = -qS * cd * vy + qS * cla * (ay - cosd * vy) + qS * spin_ratio * cnpa * cy
    fz = -qS * cd * vz + qS * cla * (az - cosd * vz) + qS * spin_ratio * cnpa * cz
    fz -= m * par[_P_G]
    # moments: x_hat x (v_hat x x_hat) = v_hat - cosd x_hat
    qSd = qS * d
    pdamp = qSd * d / V * cmq
    mag = qSd * spin_ratio * cnpa_m
    spin = qSd * spin_ratio * clp
    mx = qSd * cma * cx + pdamp * otx + mag * (vx - cosd * ax) + spin * ax
    my = qSd * cma * cy + pdamp * oty + mag * (vy - cosd * ay) + spin * ay
    mz = qSd * cma * cz + pdamp * otz + mag * (vz - cosd * az) + spin * az
    out[0] = y[3]
    out[1] = y[4]
    out[2] = y[5]
    out[3] = fx / m
    out[4] = fy / m
    out[5] = fz / m
    # d x_hat/dt = w x x_hat
    out[6] = wy * az - wz * ay
    out[7] = wz * ax - wx * az
    out[8] = wx * ay - wy * ax
    out[9] = mx / Iy
    out[10] = my / Iy
    out[11] = mz / Iy
    return out


# ---------------------------------------------------------------------------------------------
# result and driver
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class SixDofResult:
    """Sampled 6-DOF trajectory (track frame: x downrange, y right, z up; SI units).

    Attributes
    ----------
    t : ndarray (N,), s
    position : ndarray (N, 3), m
        [x, y, z] of the centre of mass.
    velocity : ndarray (N, 3), m/s
        Ground-relative velocity [vx, vy, vz] in the earth frame.
    speed : ndarray (N,), m/s
        Ground speed |velocity| (the radar's ``v``).
    mach : ndarray (N,)
        Air-relative speed / local speed of sound.
    yaw : ndarray (N,), rad
        Total yaw angle delta between the axis and the air-relative velocity.
    spin : ndarray (N,), rad/s
        Axial spin rate p (> 0: right-hand spin).
    sg : ndarray (N,)
        Gyroscopic stability factor along the flight.
    sg0 : float
        Gyroscopic stability factor at launch.
    axis : ndarray (N, 3)
        Unit vector of the shell's axis in the earth frame.
    impact_time : float, s
        Time at z = 0 on descent (NaN if not reached).
    impact_range, impact_drift : float, m
        x and y at impact (NaN if not reached).
    success : bool
        True when the integration reached impact (or the end of ``t_out``) with a valid state
        and a yaw below :data:`MAX_VALID_YAW`.
    message : str
    nfev : int
        Right-hand-side evaluations.
    runtime : float, s
        Wall-clock time of the integration.
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    speed: np.ndarray
    mach: np.ndarray
    yaw: np.ndarray
    spin: np.ndarray
    sg: np.ndarray
    sg0: float
    axis: np.ndarray
    impact_time: float
    impact_range: float
    impact_drift: float
    success: bool
    message: str
    nfev: int = 0
    runtime: float = 0.0

    @property
    def delta(self):
        """Alias of :attr:`yaw` (total yaw angle, rad)."""
        return self.yaw

    @property
    def p(self):
        """Alias of :attr:`spin` (rad/s)."""
        return self.spin


def _to_internal(v):
    """track frame (x, y right, z up) -> internal right-handed (x, y left, z up)."""
    v = np.array(v, dtype=float)
    v[..., 1] *= -1.0
    return v


_to_design = _to_internal  # the map is its own inverse


def _launch_state(shell, velocity, elevation_deg, azimuth_deg, spin_rate, initial_yaw_deg,
                  initial_yaw_rate):
    """Initial state in the internal frame; ``azimuth_deg`` here is the bore's angle from the x
    axis toward +y (0 for all public calls)."""
    el, az = math.radians(elevation_deg), math.radians(azimuth_deg)
    # internal frame: azimuth positive toward design +y = internal -y
    e_v = np.array([math.cos(el) * math.cos(az), -math.cos(el) * math.sin(az), math.sin(el)])
    # unit vectors normal to the velocity: "up" in the vertical plane, "right" horizontal
    e_right = np.array([-math.sin(az), -math.cos(az), 0.0])   # design +y rotated by azimuth
    e_up = np.cross(e_right, e_v)
    e_up /= np.linalg.norm(e_up)
    dy = math.radians(initial_yaw_deg)
    x_hat = math.cos(dy) * e_v + math.sin(dy) * e_up          # nose above the velocity
    # transverse angular velocity that swings the nose to the right: omega x x_hat ~ e_right
    omega_t = initial_yaw_rate * np.cross(x_hat, e_right)
    omega_t -= np.dot(omega_t, x_hat) * x_hat
    w = (shell.Ix / shell.Iy) * spin_rate * x_hat + omega_t
    return np.concatenate([np.zeros(3), velocity * e_v, x_hat, w])


def _profile_wind(atmosphere, r):
    """The atmosphere's wind profile at positions r (N, 3) of the internal frame, in that frame
    (zeros without a profile)."""
    prof = getattr(atmosphere, "wind", None)
    out = np.zeros_like(r)
    if prof is not None:
        s = r[:, 0] if prof.axis == "downrange" else r[:, 2] + atmosphere.gun_altitude
        w = prof.at(s)
        out[:, 0], out[:, 1] = w[:, 0], -w[:, 1]
    return out


def _derived(shell, ys, atmosphere, wind_int):
    """Derived outputs for states ys (N, 12) in the internal frame."""
    r, u, xh, w = ys[:, 0:3], ys[:, 3:6], ys[:, 6:9], ys[:, 9:12]
    xh = xh / np.linalg.norm(xh, axis=1, keepdims=True)
    Vrel = u - wind_int - _profile_wind(atmosphere, r)
    V = np.linalg.norm(Vrel, axis=1)
    cosd = np.clip(np.sum(Vrel * xh, axis=1) / V, -1.0, 1.0)
    sind = np.linalg.norm(np.cross(Vrel / V[:, None], xh), axis=1)
    yaw = np.arctan2(sind, cosd)
    spin = shell.Iy * np.sum(w * xh, axis=1) / shell.Ix
    z = np.clip(r[:, 2], MIN_ALTITUDE - atmosphere.gun_altitude,
                MAX_ALTITUDE - atmosphere.gun_altitude)
    air = atmosphere.at_height(z)
    mach = V / air.speed_of_sound
    sg = gyroscopic_stability(shell, V, spin, air.density, mach)
    return xh, V, yaw, spin, mach, np.atleast_1d(sg)


def simulate_6dof(shell, velocity, elevation_deg, t_out=None, dt=0.027, atmosphere=None,
                  wind=(0.0, 0.0, 0.0), spin_rate=None, twist_calibres=20.0, initial_yaw_deg=0.0,
                  initial_yaw_rate=0.0, azimuth_deg=0.0, stop_at_impact=True, rtol=1e-8,
                  atol=1e-8, max_time=400.0, method="DOP853"):
    """Fly a spin-stabilised shell with the 6-DOF model from the muzzle to impact.

    Parameters
    ----------
    shell : Shell
        E.g. :func:`table1_shell`.
    velocity : float, m/s
        Muzzle velocity (ground-relative, along the bore).
    elevation_deg : float, deg
        Quadrant elevation of the bore.
    t_out : array_like, optional, s
        Output times (>= 0, increasing). Without it the output is every ``dt`` from 0 to
        impact: the samples ``0, dt, 2 dt, ...`` strictly before impact, **plus the impact point
        itself as the last sample** (so the last interval is shorter than ``dt``). With
        ``stop_at_impact`` the samples of ``t_out`` after impact are dropped (and the message
        says how many).
    dt : float, s
        Output interval when ``t_out`` is not given (paper: 0.027 s).
    atmosphere : Atmosphere, optional
        Default: ICAO standard atmosphere with the gun at sea level.
    wind : (wx, wy, wz), m/s
        Constant wind, track frame (wx > 0 tailwind, wy > 0 blows toward +y = right, wz up). It
        adds to the atmosphere's wind profile (``atmosphere.wind``, by height or by downrange
        distance), which the shell flies when there is one.
    spin_rate : float, rad/s, optional
        Muzzle spin; default ``2 pi velocity / (twist_calibres d)`` (right-hand twist).
        Negative for a left-hand twist.
    twist_calibres : float
        Calibres per turn of the rifling (used only when ``spin_rate`` is None).
    initial_yaw_deg : float, deg
        Initial angle of the axis above the velocity (in the vertical plane of fire).
    initial_yaw_rate : float, rad/s
        Initial transverse angular velocity, turning the nose to the right (a muzzle
        disturbance). The first yaw maximum is about ``2 initial_yaw_rate / (omega_F -
        omega_S)`` rad, with the epicyclic frequencies of :func:`linear_theory` (Table 1 shell,
        818 m/s, sea level: omega_F - omega_S ~ 108 rad/s, so 3 rad/s gives ~3 deg).
    azimuth_deg : float, deg
        Firing azimuth, clockwise from true north. It does not change the output:
        x is *defined* along the firing azimuth, the wind is given in that frame, and the Earth
        here is flat and non-rotating (no Coriolis). Accepted so that callers can pass the
        round's launch data unchanged.
    stop_at_impact : bool
        Stop at z = 0 on descent. If False, integrate to ``max(t_out)`` (or ``max_time``).
    rtol, atol : float
        Integrator tolerances (state: m, m/s, unit vector, rad/s).
    max_time : float, s
        Longest flight integrated.
    method : str
        ``solve_ivp`` method; DOP853 (default) or RK45 / LSODA / Radau.

    Returns
    -------
    SixDofResult
    """
    _check_inputs(shell, velocity, elevation_deg, t_out, dt, azimuth_deg)
    atmosphere = Atmosphere() if atmosphere is None else atmosphere
    if spin_rate is None:
        spin_rate = default_spin_rate(velocity, shell.diameter, twist_calibres)
    wind = np.asarray(wind, dtype=float)
    if wind.shape != (3,) or not np.all(np.isfinite(wind)):
        raise ValueError(f"wind must be three finite numbers (wx, wy, wz) in m/s, got {wind!r}")
    wind_int = _to_internal(wind)
    t_req, t_end = _requested_times(t_out, max_time)
    args, z0, z_top = _rhs_tables(shell, atmosphere, wind_int)
    # the bore points along +x by definition of the frame, whatever the azimuth from north
    y0 = _launch_state(shell, float(velocity), elevation_deg, 0.0, float(spin_rate),
                       initial_yaw_deg, initial_yaw_rate)

    def fun(t, y):
        return _rhs(t, y, *args)

    def impact(t, y):
        return y[2]

    impact.terminal = True
    impact.direction = -1.0

    def out_of_air(t, y):  # leave the tabulated atmosphere: stop
        return (y[2] - z0) * (z_top - y[2])

    out_of_air.terminal = True

    events = [out_of_air] + ([impact] if stop_at_impact else [])
    if t_req is None:
        t_eval = np.arange(0.0, t_end + 0.5 * dt, dt)
        t_eval = t_eval[t_eval <= t_end]
    else:
        t_eval = t_req[t_req <= t_end]
    # (the muzzle is at z = 0 but the impact event only counts downward crossings)
    t0 = time.perf_counter()
    sol = solve_ivp(fun, (0.0, t_end), y0, method=method, t_eval=t_eval, events=events,
                    rtol=rtol, atol=atol)
    runtime = time.perf_counter() - t0

    ts, ys, success, notes, (impact_time, impact_range, impact_drift) = _trim_at_impact(
        sol, y0, t_req, stop_at_impact, max_time)
    xh, V, yaw, spin, mach, sg = _derived(shell, ys, atmosphere, wind_int)
    air0 = atmosphere.at_height(0.0)
    V0 = float(np.linalg.norm(y0[3:6] - wind_int - _profile_wind(atmosphere, y0[None, :3])[0]))
    sg0 = gyroscopic_stability(shell, V0, spin_rate, float(air0.density),
                               V0 / float(air0.speed_of_sound))
    if np.max(yaw) > MAX_VALID_YAW:
        success = False
        notes.append(f"total yaw reached {math.degrees(np.max(yaw)):.1f} deg (> "
                     f"{math.degrees(MAX_VALID_YAW):.0f} deg): linear aerodynamics not valid")
    if sg0 <= 1.0:
        notes.append(f"gyroscopically unstable at launch (Sg = {sg0:.2f} <= 1)")
    if success and not notes:
        message = ("reached impact" if np.isfinite(impact_time) else
                   "reached the last output time") \
            + f" after {sol.nfev} evaluations in {runtime:.2f} s"
    else:
        message = "; ".join(notes) if notes else sol.message

    pos = _to_design(ys[:, 0:3])
    vel = _to_design(ys[:, 3:6])
    return SixDofResult(
        t=ts, position=pos, velocity=vel, speed=np.linalg.norm(vel, axis=1), mach=mach,
        yaw=yaw, spin=spin, sg=sg, sg0=float(sg0), axis=_to_design(xh),
        impact_time=impact_time, impact_range=impact_range, impact_drift=impact_drift,
        success=success, message=message, nfev=int(sol.nfev), runtime=runtime,
    )


def _check_inputs(shell, velocity, elevation_deg, t_out, dt, azimuth_deg):
    """ValueError for inputs :func:`simulate_6dof` cannot fly."""
    if not isinstance(shell, Shell):
        raise ValueError(f"shell must be a Shell (e.g. table1_shell()), got {type(shell).__name__}")
    if not (np.isfinite(velocity) and velocity > 0):
        raise ValueError(f"velocity must be a finite positive speed in m/s, got {velocity!r}")
    if not (np.isfinite(elevation_deg) and -10.0 < elevation_deg < 90.0):
        raise ValueError(f"elevation_deg must be in (-10, 90) degrees, got {elevation_deg!r}")
    if t_out is None and not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
    if not np.isfinite(azimuth_deg):
        raise ValueError(f"azimuth_deg must be a finite number of degrees, got {azimuth_deg!r}")


def _requested_times(t_out, max_time):
    """(requested output times or None, end of the integration [s])."""
    if t_out is None:
        return None, max_time
    t_req = np.asarray(t_out, dtype=float).ravel()
    if t_req.size == 0 or np.any(~np.isfinite(t_req)) or np.any(t_req < 0) or np.any(np.diff(t_req) <= 0):
        raise ValueError("t_out must be finite, >= 0 and strictly increasing seconds")
    return t_req, min(float(t_req[-1]), max_time)


def _rhs_tables(shell, atmosphere, wind_int):
    """Arguments of the compiled right-hand side (parameters, atmosphere and drag tables) and
    the tabulated atmosphere's height range [m]."""
    z0 = MIN_ALTITUDE - atmosphere.gun_altitude + 1.0
    z_top = MAX_ALTITUDE - atmosphere.gun_altitude - 50.0
    z0, dz, atm = atmosphere.table(z_min=z0, z_max=z_top, dz=25.0)
    grid = MachGrid(0.0, 0.01, 500)
    cd_tab = np.ascontiguousarray(shell.cd0.kernel_table((), grid))
    par = np.zeros(_N_PAR)
    par[_P_MASS], par[_P_D], par[_P_S] = shell.mass, shell.diameter, shell.area
    par[_P_IX], par[_P_IY], par[_P_G] = shell.Ix, shell.Iy, G0
    par[_P_WX:_P_WZ + 1] = wind_int
    wtab, w0, inv_dw, wax, waz = np.zeros((2, 2)), 0.0, 1.0, 0.0, 0.0
    prof = getattr(atmosphere, "wind", None)
    if prof is not None:  # the profile tabulated as the point-mass kernel does, in the internal frame
        from .kernel import N_PAR
        from .pointmass import wind_tables

        kpar = np.zeros((1, N_PAR))
        tabs, _, w0, dw = wind_tables([prof], atmosphere.gun_altitude, kpar)
        wtab = np.ascontiguousarray(tabs[1] * np.array([1.0, -1.0]))
        inv_dw = 1.0 / dw
        wax, waz = (1.0, 0.0) if prof.axis == "downrange" else (0.0, 1.0)
    args = (par, np.ascontiguousarray(atm), float(z0), 1.0 / dz, cd_tab, grid.m0, grid.dm, shell.aero.table(),
            wtab, float(w0), float(inv_dw), wax, waz)
    return args, z0, z_top


def _trim_at_impact(sol, y0, t_req, stop_at_impact, max_time):
    """The integrator's samples cut at impact (the impact point appended to a regular output),
    whether the flight succeeded, notes, and (impact time [s], range [m], drift [m])."""
    ts, ys = sol.t, sol.y.T
    notes = []
    success = bool(sol.status >= 0)
    impact_time = impact_range = impact_drift = math.nan
    if stop_at_impact and sol.status == 1 and len(sol.t_events[-1]) > 0:
        ti = float(sol.t_events[-1][0])
        yi = sol.y_events[-1][0]
        impact_time, impact_range, impact_drift = ti, float(yi[0]), float(-yi[1])
        if t_req is None:
            keep = ts < ti - 1e-9
            ts = np.append(ts[keep], ti)
            ys = np.vstack([ys[keep], yi[None, :]])
        else:
            n_after = int(np.sum(t_req > ti))
            keep = ts <= ti
            ts, ys = ts[keep], ys[keep]
            if n_after:
                notes.append(f"{n_after} requested output time(s) after impact at {ti:.3f} s "
                             f"dropped")
    elif len(sol.t_events[0]) > 0:
        success = False
        notes.append(f"left the atmosphere model's height range at t = {sol.t_events[0][0]:.2f} s")
    elif stop_at_impact and sol.status == 0 and t_req is None:
        success = False
        notes.append(f"no impact within max_time = {max_time} s")
    if sol.status < 0:
        notes.append(f"integrator failed: {sol.message}")

    if len(ts) == 0:
        ts, ys = np.zeros(1), y0[None, :]
    if not np.all(np.isfinite(ys)):
        success = False
        notes.append("non-finite state")
        good = np.all(np.isfinite(ys), axis=1)
        ts, ys = ts[good], ys[good]
    return ts, ys, success, notes, (impact_time, impact_range, impact_drift)
