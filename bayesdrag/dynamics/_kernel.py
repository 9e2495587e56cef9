"""Numba kernel: batched fixed-step RK4 integration of the point-mass equations.

This module is deliberately small and free of Python objects: everything arrives as arrays so
that numba compiles it once (``cache=True`` writes the machine code next to this file, or to
``NUMBA_CACHE_DIR``, so a new process does not recompile) and runs the trajectories of a batch
in parallel threads (``prange``).

State per trajectory: ``[x, y, z, vx, vy, vz]`` (m, m/s), ground-relative, in the DESIGN.md
frame (x downrange, y right, z up). Acceleration (paper Eqs. 20-22 in 3-D, plus effects):

    a = -k_ref * rho_scale * rho(z) * Cd_eff * |u| u + (0, 0, -g) + C_cor @ v
        + L g / |u|^2 * (-u_y, u_x, 0)

with ``u = v - w`` the airspeed vector, ``k_ref = pi d^2 / (8 m)``,
``Cd_eff = cd_scale * Cd(M) * (1 + yaw_amp * exp(-2 decay t))``, ``M = |u| / a(z)``,
``rho_scale`` a density multiplier (effect ``density``), ``C_cor`` the Coriolis matrix
(``-2 Omega x``, in the local frame) and ``L`` [m/s] the lift-on-yaw-of-repose constant
(effect ``lift``, see :func:`bayesdrag.dynamics.pointmass.lift_parameter`): a horizontal
acceleration of size ``L g cos(theta) / |u|`` to the right of the airspeed (+y for a shell
flying downrange), i.e. McCoy's modified-point-mass drift of a right-hand spinning shell.

Per-trajectory parameters live in the rows of ``par`` with the column layout ``P_*`` below.
"""
import numpy as np
from numba import njit, prange

P_KREF = 0       # pi d^2 / (8 m)  [m^2/kg]
P_WX = 1         # wind [m/s]
P_WY = 2
P_WZ = 3
P_COR = 4        # 9 entries, row-major 3x3 Coriolis matrix [1/s]
P_G = 13         # gravity [m/s^2]
P_CD_SCALE = 14  # drag multiplier [-]
P_YAW_AMP = 15   # k * delta0^2 [-]
P_YAW_DECAY = 16  # decay rate of the yaw amplitude [1/s]
P_RHO_SCALE = 17  # density multiplier [-]
P_HAS_COR = 18   # 1.0 when the Coriolis matrix is non-zero
P_T0 = 19        # time since launch at the initial state [s] (yaw decay clock)
P_LIFT = 20      # lift constant L = Ix p C_La / (m d C_Ma) [m/s] (> 0: right-hand spin, drift to +y)
N_PAR = 21


@njit(inline="always", fastmath=True)
def _lookup(z, V, atm, z0, inv_dz, zmax):
    """Density and Mach from the height table (columns rho, 1/a), clamped at its ends."""
    zi = min(max((z - z0) * inv_dz, 0.0), zmax)
    j = int(zi)
    f = zi - j
    rho = atm[j, 0] + f * (atm[j + 1, 0] - atm[j, 0])
    mach = V * (atm[j, 1] + f * (atm[j + 1, 1] - atm[j, 1]))
    return rho, mach


@njit(inline="always", fastmath=True)
def _accel(z, vx, vy, vz, fac, wx, wy, wz, kref, g, cor, has_cor, lift, cdt, m0, inv_dm, dm, kmax,
           atm, z0, inv_dz, zmax):
    vax = vx - wx
    vay = vy - wy
    vaz = vz - wz
    V = np.sqrt(vax * vax + vay * vay + vaz * vaz)
    rho, mach = _lookup(z, V, atm, z0, inv_dz, zmax)
    mi = min(max((mach - m0) * inv_dm, 0.0), kmax)
    k = int(mi)
    u = (mi - k) * dm
    cd = cdt[k, 0] + u * (cdt[k, 1] + u * (cdt[k, 2] + u * cdt[k, 3]))
    kd = kref * fac * rho * cd * V
    ax = -kd * vax
    ay = -kd * vay
    az = -kd * vaz - g
    if lift != 0.0:
        # yaw-of-repose lift: L g / |u|^2 * (-u_y, u_x, 0) (derivation in pointmass.lift_parameter)
        kl = lift * g / (V * V)
        ax -= kl * vay
        ay += kl * vax
    if has_cor:
        ax += cor[0] * vx + cor[1] * vy + cor[2] * vz
        ay += cor[3] * vx + cor[4] * vy + cor[5] * vz
        az += cor[6] * vx + cor[7] * vy + cor[8] * vz
    return ax, ay, az


@njit(inline="always", fastmath=True)
def _yaw_factor(p, t):
    if p[P_YAW_AMP] == 0.0:
        return p[P_CD_SCALE] * p[P_RHO_SCALE]
    return p[P_CD_SCALE] * p[P_RHO_SCALE] * (1.0 + p[P_YAW_AMP] * np.exp(-2.0 * p[P_YAW_DECAY] * (t + p[P_T0])))


#: trajectories advanced together by one thread: their independent RK4 chains overlap in the
#: CPU pipeline (the evaluation is latency-bound); 4 measured best on the 2-core AMD EPYC dev box
CHUNK = 4


@njit(parallel=True, fastmath=True, cache=True, error_model="numpy")
def integrate_batch(y0, t_start, step_h, step_out, out_first, par, cd_tabs, cd_idx, m0, dm,
                    atm_tabs, atm_idx, z0, dz, out, mach_out):
    """Integrate B trajectories with classic RK4 on a shared step schedule.

    Parameters
    ----------
    y0 : (B, 6) float64
        Initial states at ``t_start``.
    t_start : float
        Time of the initial state [s] (the yaw clock adds ``par[:, P_T0]``).
    step_h : (S,) float64
        Step sizes [s].
    step_out : (S,) int64
        Output row written after each step, or -1.
    out_first : int
        Output row for the initial state, or -1.
    par : (B, N_PAR) float64
        Per-trajectory parameters (column layout ``P_*``).
    cd_tabs : (T, K, 4) float64
        Cubic drag cells on the Mach grid (m0, dm); trajectory b uses ``cd_tabs[cd_idx[b]]``.
    cd_idx : (B,) int64
    m0, dm : float
        Mach grid origin and cell width.
    atm_tabs : (A, Z, 2) float64
        Density [kg/m^3] and *inverse* speed of sound [s/m] on a uniform height grid (z0, dz);
        trajectory b uses ``atm_tabs[atm_idx[b]]``.
    atm_idx : (B,) int64
    z0, dz : float
        Height grid origin and spacing [m].
    out : (B, N, 6) float64
        Filled in place with the states at the output rows.
    mach_out : (B, N) float64
        Filled in place with the Mach number at the output rows.
    """
    B = y0.shape[0]
    S = step_h.shape[0]
    inv_dm = 1.0 / dm
    inv_dz = 1.0 / dz
    kmax = cd_tabs.shape[1] - 1e-9
    zmax = atm_tabs.shape[1] - 1.000001
    n_chunks = (B + CHUNK - 1) // CHUNK
    for ch in prange(n_chunks):
        b0 = ch * CHUNK
        n = min(B, b0 + CHUNK) - b0
        st = np.empty((CHUNK, 6))
        for i in range(n):
            for c in range(6):
                st[i, c] = y0[b0 + i, c]
            if out_first >= 0:
                _store(out, mach_out, b0 + i, out_first, st[i], par[b0 + i], atm_tabs[atm_idx[b0 + i]],
                       z0, inv_dz, zmax)
        t = t_start
        for s in range(S):
            h = step_h[s]
            h2 = 0.5 * h
            h6 = h / 6.0
            for i in range(n):
                b = b0 + i
                p = par[b]
                cdt = cd_tabs[cd_idx[b]]
                atm = atm_tabs[atm_idx[b]]
                kref = p[P_KREF]
                wx = p[P_WX]
                wy = p[P_WY]
                wz = p[P_WZ]
                g = p[P_G]
                cor = p[P_COR:P_COR + 9]
                has_cor = p[P_HAS_COR] != 0.0
                lift = p[P_LIFT]
                f1 = _yaw_factor(p, t)
                f2 = _yaw_factor(p, t + h2)
                f4 = _yaw_factor(p, t + h)
                x = st[i, 0]
                y = st[i, 1]
                z = st[i, 2]
                vx = st[i, 3]
                vy = st[i, 4]
                vz = st[i, 5]
                a1x, a1y, a1z = _accel(z, vx, vy, vz, f1, wx, wy, wz, kref, g, cor, has_cor, lift, cdt, m0,
                                       inv_dm, dm, kmax, atm, z0, inv_dz, zmax)
                v2x = vx + h2 * a1x
                v2y = vy + h2 * a1y
                v2z = vz + h2 * a1z
                a2x, a2y, a2z = _accel(z + h2 * vz, v2x, v2y, v2z, f2, wx, wy, wz, kref, g, cor, has_cor, lift,
                                       cdt, m0, inv_dm, dm, kmax, atm, z0, inv_dz, zmax)
                v3x = vx + h2 * a2x
                v3y = vy + h2 * a2y
                v3z = vz + h2 * a2z
                a3x, a3y, a3z = _accel(z + h2 * v2z, v3x, v3y, v3z, f2, wx, wy, wz, kref, g, cor, has_cor, lift,
                                       cdt, m0, inv_dm, dm, kmax, atm, z0, inv_dz, zmax)
                v4x = vx + h * a3x
                v4y = vy + h * a3y
                v4z = vz + h * a3z
                a4x, a4y, a4z = _accel(z + h * v3z, v4x, v4y, v4z, f4, wx, wy, wz, kref, g, cor, has_cor, lift,
                                       cdt, m0, inv_dm, dm, kmax, atm, z0, inv_dz, zmax)
                st[i, 0] = x + h6 * (vx + 2.0 * v2x + 2.0 * v3x + v4x)
                st[i, 1] = y + h6 * (vy + 2.0 * v2y + 2.0 * v3y + v4y)
                st[i, 2] = z + h6 * (vz + 2.0 * v2z + 2.0 * v3z + v4z)
                st[i, 3] = vx + h6 * (a1x + 2.0 * a2x + 2.0 * a3x + a4x)
                st[i, 4] = vy + h6 * (a1y + 2.0 * a2y + 2.0 * a3y + a4y)
                st[i, 5] = vz + h6 * (a1z + 2.0 * a2z + 2.0 * a3z + a4z)
            t += h
            o = step_out[s]
            if o >= 0:
                for i in range(n):
                    _store(out, mach_out, b0 + i, o, st[i], par[b0 + i], atm_tabs[atm_idx[b0 + i]],
                           z0, inv_dz, zmax)
    return out


@njit(inline="always", fastmath=True)
def _store(out, mach_out, b, o, s, p, atm, z0, inv_dz, zmax):
    for c in range(6):
        out[b, o, c] = s[c]
    vax = s[3] - p[P_WX]
    vay = s[4] - p[P_WY]
    vaz = s[5] - p[P_WZ]
    V = np.sqrt(vax * vax + vay * vay + vaz * vaz)
    rho, mach = _lookup(s[2], V, atm, z0, inv_dz, zmax)
    mach_out[b, o] = mach
