"""Numba kernel: batched fixed-step RK4 integration of the point-mass equations.

This module is deliberately small and free of Python objects: everything arrives as arrays so
that numba compiles it once (``cache=True`` writes the machine code next to this file, or to
``NUMBA_CACHE_DIR``, so a new process does not recompile) and runs the blocks of a batch on
several threads (:func:`bayesdrag.dynamics.threads.run_split`: the compiled code releases the GIL).

State per trajectory: ``[x, y, z, vx, vy, vz]`` (m, m/s), ground-relative, in the track frame
frame (x downrange, y right, z up). Acceleration (paper Eqs. 20-22 in 3-D, plus effects):

    a = -k_ref * rho_scale * rho(z) * Cd_eff * |u| u + (0, 0, -g) + C_cor @ v
        + L q s(M) g / |u|^2 * (-u_y, u_x, 0)
        + L q s(M) g / |u|^2 * m q / (|u|^2 (1 + C x_m)) * (-u_x u_z, -u_y u_z, u_x^2 + u_y^2)
    dq/dt = -kappa k_ref rho_scale rho(z) |u| q,     q(t_start) = 1

with ``u = v - w`` the airspeed vector, ``k_ref = pi d^2 / (8 m)``,
``Cd_eff = cd_scale * Cd(M) * (1 + yaw_amp * exp(-2 decay t))``, ``M = |u| / a(z)``,
``rho_scale`` a density multiplier (effect ``density``), ``C_cor`` the Coriolis matrix
(``-2 Omega x``, in the local frame) and ``L`` [m/s] the lift-on-yaw-of-repose constant
(effect ``lift``, see :func:`bayesdrag.dynamics.forces.lift_parameter`): a horizontal
acceleration of size ``L g cos(theta) / |u|`` to the right of the airspeed (+y for a shell
flying downrange), i.e. McCoy's modified-point-mass drift of a right-hand spinning shell,
scaled by the Mach shape ``s(M) = 1 + A x / (1 + B x)``, ``x = max(M - 1, 0)`` of the
lift-to-overturning ratio and by the spin fraction ``q = p / p0``, a seventh state integrated
with the others (spin damping kappa = -C_lp / k_a^2). The next term is the vertical force on
the same yaw of repose (Magnus force and lift on the yaw's vertical part), normal to u in its
vertical plane (up for a right-hand spin), with the speed ``m = nu p0 d`` and a Mach fall-off
``1 / (1 + C x_m)``, ``x_m = max(M - 0.8, 0)``. ``A = B = kappa = m = 0`` is the constant-L
model.

Per-trajectory parameters live in the rows of ``par`` with the column layout ``P_*`` below
(``P_HAS_COR`` is not read: the Coriolis terms are always evaluated, branch-free).

Wind: ``w = (P_WX, P_WY, P_WZ)`` plus, horizontally, the trajectory's wind table (a wind that
changes along the flight, :class:`bayesdrag.air.wind.WindProfile`), linear on a uniform grid of the
coordinate ``s = x P_WIND_AX_X + z P_WIND_AX_Z`` (height, or downrange distance). The table is
read at the second and fourth RK4 stages and at each output row; the third stage and the step's
end take the wind along the cell's line read there (:func:`_wind_near`: they lie centimetres
away). Without a table (``wind_flat`` None) numba compiles the kernel without any of this: the
constant-wind results are bit-identical to the kernel before wind tables existed.

Integration: classic RK4 on a uniform step h (``pointmass.output_schedule``; ~0.074 s for a
155 mm shell, against 0.027 s radar samples) with the acceleration at the step end re-used as
the next step's first stage (4 evaluations per step), and a cubic Hermite interpolant through
the states and accelerations at both ends of a step for every output time inside it.

Layout. Trajectories are processed in blocks of ``nl`` lanes (8, fewer for tiny batches,
:func:`lanes_per_block`); inside a block every RK stage is one loop over the lanes, lane index
innermost and contiguous, so that LLVM vectorises it (one AVX-512 register of doubles, gathers
for the table reads). That needs lane loops with a run-time trip count (a constant one is
unrolled before the vectoriser runs), array arguments LLVM knows not to alias (without that the
table gathers could alias the stores): :func:`integrate_blocks` is compiled with numba's
``noalias`` flag (:class:`_NoAliasCompiler`) and takes every scratch array as an argument of
its own; and the helpers inlined (``forceinline``). Its threads each take a contiguous range of
blocks; the scratch arrays are kept per thread slot by the threads' pool (``run_split``'s
``scratch``: a call allocates nothing, and no two threads share one), 64-byte aligned. The
compiled integrators hold no reference counting (numba's pruning must succeed: see
:func:`_wind_near`). Fewer than 8 trajectories run as one block of B lanes in
:data:`integrate_blocks_scalar`, the same code compiled without ``noalias`` (scalar lane loops:
faster for 1-2 lanes than the vector loops' remainder). There is no ``prange``: numba's parfor
compiled the whole body two more times (the outlined loop and its caller), which took half of
a first run's compile time. What each choice bought, measured: docs/bayes.md "The kernel's
layout".
"""
import numpy as np
from numba import njit
from numba.core.compiler import CompilerBase, DefaultPassBuilder

from .threads import run_split

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
P_LIFT = 20      # lift constant L = Ix p0 C_La / (m d C_Ma) at subsonic speed [m/s] (> 0: drift to +y)
P_LIFT_RISE = 21  # supersonic rise A of the lift shape s(M) = 1 + A x / (1 + B x), x = max(M - 1, 0) [-]
P_LIFT_SAT = 22   # its saturation B [-]
P_SPIN_DECAY = 23  # spin damping kappa = -C_lp / k_a^2 [-]: dq/dt = -kappa k_ref rho |u| q
P_LIFT_VERT = 24     # vertical-force speed m = nu p0 d [m/s]: vertical / lift = m q / (|u| (1 + C x_m))
P_LIFT_VERT_SAT = 25  # its Mach fall-off C [-], x_m = max(M - 0.8, 0)
P_WIND_AX_X = 26  # the wind table's coordinate is s = x * P_WIND_AX_X + z * P_WIND_AX_Z [m]:
P_WIND_AX_Z = 27  # (0, 1) a wind by height, (1, 0) by downrange distance, (0, 0) no table
N_PAR = 28

#: rows of the per-block lane parameter array (``_L_*``): copies of the ``par`` columns laid out
#: lane-contiguous so every RK stage loop reads them with plain vector loads
_L_KREF, _L_WX, _L_WY, _L_WZ, _L_G, _L_LIFT, _L_COR = 0, 1, 2, 3, 4, 5, 6   # _L_COR: 9 rows
_L_SCALE, _L_YAW_AMP, _L_YAW_RATE, _L_T0, _L_F0, _L_FH2, _L_FH = 15, 16, 17, 18, 19, 20, 21
_L_LRISE, _L_LSAT, _L_SPIN, _L_LVERT, _L_LVSAT = 22, 23, 24, 25, 26
_L_WAX, _L_WAZ = 27, 28
_N_L = 29

#: lanes per block are a multiple of this (8 doubles = one AVX-512 register)
LANE_WIDTH = 8
#: largest lanes per block: one vector per block keeps the block's scratch in L1 and splits a
#: 21-trajectory ML batch into 3 blocks for 2 threads (docs/bayes.md "The kernel's layout")
MAX_LANES = 8

_OPTS = dict(fastmath=True, error_model="numpy", boundscheck=False)
#: the lane helpers: inlined into the block integrators and never called from Python, so numba
#: builds no Python or C entry for them (less to compile on a first run)
_HELPER = dict(forceinline=True, no_cpython_wrapper=True, no_cfunc_wrapper=True, **_OPTS)
#: smallest airspeed^2 [m^2/s^2] in the lift term's denominator
V2_FLOOR = 1e-12
#: |L| in the vertical lift force is L^2 / sqrt(L^2 + LIFT_EPS^2) [m/s]: smooth at L = 0 and
#: within 0.5 % of |L| for a typical shell's L ~ 0.02 v0 >= 5 m/s
LIFT_EPS = 0.5


def lanes_per_block(B, n_threads):
    """Lanes per block for a batch of B trajectories on ``n_threads`` threads: enough blocks
    for every thread, each a multiple of :data:`LANE_WIDTH`, at most :data:`MAX_LANES`.
    Fewer than :data:`LANE_WIDTH` trajectories run as one block of B lanes, i.e. the scalar
    remainder of the vector loops: a single trajectory padded to 8 lanes would cost twice the
    scalar code."""
    if B < LANE_WIDTH:
        return int(max(1, B))
    per_thread = -(-B // max(1, n_threads))
    return int(min(MAX_LANES, LANE_WIDTH * max(1, -(-per_thread // LANE_WIDTH))))


@njit(**_HELPER)
def _wind(x, z, blk, l, LP, WTO, wtf, w0, inv_dw, wmax):
    """Horizontal wind of lane ``l`` at downrange x and height z [m]: ``(wx, wy, gx, gy, s)``,
    the lane's constant wind plus its wind table (linear on the grid ``w0 + i / inv_dw``, held
    at the ends) read at the coordinate ``s = x P_WIND_AX_X + z P_WIND_AX_Z`` [m], with the
    table cell's slopes ``gx, gy`` [1/s] along s. Without tables (``wtf`` None, a batch with no
    wind profile) numba compiles the constant wind alone: the ``is None`` branch is resolved
    when the kernel is compiled for that argument type."""
    if wtf is None:
        return LP[blk, _L_WX, l], LP[blk, _L_WY, l], 0.0, 0.0, 0.0
    s = x * LP[blk, _L_WAX, l] + z * LP[blk, _L_WAZ, l]
    si = min(max((s - w0) * inv_dw, 0.0), wmax)
    j = int(si)
    f = si - j
    jw = WTO[blk, l] + 2 * j
    dx = wtf[jw + 2] - wtf[jw]
    dy = wtf[jw + 3] - wtf[jw + 1]
    return (LP[blk, _L_WX, l] + wtf[jw] + f * dx, LP[blk, _L_WY, l] + wtf[jw + 1] + f * dy,
            dx * inv_dw, dy * inv_dw, s)


@njit(**_HELPER)
def _wind_near(x, z, blk, l, LP, WD, WTO, wtf):
    """The wind at (x, z) from the last table read of lane ``l`` (``WD``: wind, slopes and
    coordinate there) along that cell's line: exact for the table while the point stays in the
    cell. RK4's second and fourth stages lie within a few centimetres of its first and third
    (h^2 a / 4), so each step reads the table twice instead of four times.

    ``WTO`` and ``wtf`` (the table offsets and tables) are not read: passing them makes the
    step's last loop their last use, so numba releases them once at the step's end instead of
    on each exit of the fourth stage's loop; otherwise LLVM's reference-count pruning fails for
    the whole kernel and every RK4 step paid ~30 atomic reference-count calls (a third of a
    wind-table batch's time: docs/measurements.md, "The block integrator against the parfor
    kernel")."""
    ds = x * LP[blk, _L_WAX, l] + z * LP[blk, _L_WAZ, l] - WD[blk, 4, l]
    return WD[blk, 0, l] + WD[blk, 2, l] * ds, WD[blk, 1, l] + WD[blk, 3, l] * ds


@njit(**_HELPER)
def _acc(z, vx, vy, vz, q, wx, wy, fac, blk, l, LP, CDO, ATO, cdf, atf, tab):
    """Acceleration (ax, ay, az) [m/s^2] and spin-fraction rate dq/dt [1/s] of lane ``l`` of
    block ``blk`` at height z [m], ground velocity (vx, vy, vz) [m/s], spin fraction q [-] and
    horizontal wind (wx, wy) [m/s], drag multiplier ``fac``. Branch-free so that the lane loops
    around it vectorise (the table reads become gathers)."""
    m0, inv_dm, dm, kmax, z0, inv_dz, zmax, w0, inv_dw, wmax = tab
    wz = LP[blk, _L_WZ, l]
    g = LP[blk, _L_G, l]
    ux = vx - wx
    uy = vy - wy
    uz = vz - wz
    V2 = ux * ux + uy * uy + uz * uz
    V = np.sqrt(V2)
    zi = min(max((z - z0) * inv_dz, 0.0), zmax)
    j = int(zi)
    f = zi - j
    ja = ATO[blk, l] + 2 * j
    rho = atf[ja] + f * (atf[ja + 2] - atf[ja])
    mach = V * (atf[ja + 1] + f * (atf[ja + 3] - atf[ja + 1]))
    mi = min(max((mach - m0) * inv_dm, 0.0), kmax)
    k = int(mi)
    u = (mi - k) * dm
    kc = CDO[blk, l] + 4 * k
    cd = cdf[kc] + u * (cdf[kc + 1] + u * (cdf[kc + 2] + u * cdf[kc + 3]))
    kd = LP[blk, _L_KREF, l] * fac * rho * cd * V
    # yaw-of-repose lift L q s(M) g / |u|^2 (-u_y, u_x, 0) (forces.lift_parameter); the floor
    # on |u|^2 keeps a shell at rest in still air finite (0 * g / 0 would poison the trajectory)
    xs = max(mach - 1.0, 0.0)
    shape = 1.0 + LP[blk, _L_LRISE, l] * xs / (1.0 + LP[blk, _L_LSAT, l] * xs)
    inv_v2 = 1.0 / max(V2, V2_FLOOR)
    kl = LP[blk, _L_LIFT, l] * q * shape * g * inv_v2
    # Magnus force on the same yaw plus lift on its vertical part: up-normal to u,
    # (-u_x u_z, -u_y u_z, u_h^2) / |u| times |lift| (p d / |u|) nu (pointmass.LIFT_VERTICAL_FRACTION)
    # (even in the spin: Magnus force and vertical yaw both flip with it, so |L|, taken smooth as
    # L^2 / sqrt(L^2 + LIFT_EPS^2) so that fits starting at L = 0 see no kink)
    L = LP[blk, _L_LIFT, l]
    kabs = q * shape * g * inv_v2 * L * L / np.sqrt(L * L + LIFT_EPS * LIFT_EPS)
    km = kabs * LP[blk, _L_LVERT, l] * q * inv_v2 / (1.0 + LP[blk, _L_LVSAT, l] * max(mach - 0.8, 0.0))
    dq = -LP[blk, _L_SPIN, l] * rho * V * q
    c = _L_COR
    ax = (-kd * ux - kl * uy - km * ux * uz
          + LP[blk, c, l] * vx + LP[blk, c + 1, l] * vy + LP[blk, c + 2, l] * vz)
    ay = (-kd * uy + kl * ux - km * uy * uz
          + LP[blk, c + 3, l] * vx + LP[blk, c + 4, l] * vy + LP[blk, c + 5, l] * vz)
    az = (-kd * uz - g + km * (ux * ux + uy * uy)
          + LP[blk, c + 6, l] * vx + LP[blk, c + 7, l] * vy + LP[blk, c + 8, l] * vz)
    return ax, ay, az, dq


@njit(**_HELPER)
def _load_lanes(blk, nl, B, y0, par, t_start, cd_idx, atm_idx, wind_idx, n_cells, n_z, n_w, yaw, BL, LP, CDO,
                ATO, WTO, ST):
    """Load block ``blk``'s lanes: state, per-lane parameters, table offsets (lanes past B
    repeat the last trajectory and are not stored)."""
    for l in range(nl):
        b = min(blk * nl + l, B - 1)
        BL[blk, l] = b
        for c in range(6):
            ST[blk, c, l] = y0[b, c]
        ST[blk, 6, l] = 1.0
        LP[blk, _L_KREF, l] = par[b, P_KREF]
        LP[blk, _L_WX, l] = par[b, P_WX]
        LP[blk, _L_WY, l] = par[b, P_WY]
        LP[blk, _L_WZ, l] = par[b, P_WZ]
        LP[blk, _L_G, l] = par[b, P_G]
        LP[blk, _L_LIFT, l] = par[b, P_LIFT]
        LP[blk, _L_LRISE, l] = par[b, P_LIFT_RISE]
        LP[blk, _L_LSAT, l] = par[b, P_LIFT_SAT]
        LP[blk, _L_SPIN, l] = par[b, P_SPIN_DECAY] * par[b, P_KREF] * par[b, P_RHO_SCALE]
        LP[blk, _L_LVERT, l] = par[b, P_LIFT_VERT]
        LP[blk, _L_LVSAT, l] = par[b, P_LIFT_VERT_SAT]
        LP[blk, _L_WAX, l] = par[b, P_WIND_AX_X]
        LP[blk, _L_WAZ, l] = par[b, P_WIND_AX_Z]
        for c in range(9):
            LP[blk, _L_COR + c, l] = par[b, P_COR + c]
        scale = par[b, P_CD_SCALE] * par[b, P_RHO_SCALE]
        LP[blk, _L_SCALE, l] = scale
        LP[blk, _L_YAW_AMP, l] = par[b, P_YAW_AMP]
        LP[blk, _L_YAW_RATE, l] = -2.0 * par[b, P_YAW_DECAY]
        LP[blk, _L_T0, l] = par[b, P_T0] + t_start
        LP[blk, _L_F0, l] = scale
        LP[blk, _L_FH2, l] = scale
        LP[blk, _L_FH, l] = scale
        CDO[blk, l] = cd_idx[b] * (n_cells * 4)
        ATO[blk, l] = atm_idx[b] * (n_z * 2)
        WTO[blk, l] = wind_idx[b] * (n_w * 2)
    if yaw:
        for l in range(nl):
            LP[blk, _L_F0, l] = LP[blk, _L_SCALE, l] * (
                1.0 + LP[blk, _L_YAW_AMP, l] * np.exp(LP[blk, _L_YAW_RATE, l] * LP[blk, _L_T0, l]))


@njit(**_HELPER)
def _rk4_step(blk, nl, s, h, h2, h6, yaw, LP, CDO, ATO, WTO, cd_flat, atm_flat, wind_flat, tab, ST, AC, K2, K3, K4,
              ST1, AC1, WD):
    """One RK4 step of every lane of block ``blk`` from ``ST``/``AC`` (state and acceleration at
    t_s) to ``ST1``/``AC1`` (at t_s + h). One loop per stage, lanes innermost: independent
    vectors in flight. The wind table is read at the second and fourth stages (``WD``); the
    third and the step's end take it along those cells' lines (:func:`_wind_near`)."""
    w0, inv_dw, wmax = tab[7], tab[8], tab[9]
    if yaw:
        for l in range(nl):
            ts = LP[blk, _L_T0, l] + s * h
            LP[blk, _L_FH2, l] = LP[blk, _L_SCALE, l] * (
                1.0 + LP[blk, _L_YAW_AMP, l] * np.exp(LP[blk, _L_YAW_RATE, l] * (ts + h2)))
            LP[blk, _L_FH, l] = LP[blk, _L_SCALE, l] * (
                1.0 + LP[blk, _L_YAW_AMP, l] * np.exp(LP[blk, _L_YAW_RATE, l] * (ts + h)))
    for l in range(nl):
        wx, wy = LP[blk, _L_WX, l], LP[blk, _L_WY, l]
        if wind_flat is not None:
            WD[blk, 0, l], WD[blk, 1, l], WD[blk, 2, l], WD[blk, 3, l], WD[blk, 4, l] = _wind(
                ST[blk, 0, l] + h2 * ST[blk, 3, l], ST[blk, 2, l] + h2 * ST[blk, 5, l], blk, l, LP, WTO, wind_flat,
                w0, inv_dw, wmax)
            wx, wy = WD[blk, 0, l], WD[blk, 1, l]
        K2[blk, 0, l], K2[blk, 1, l], K2[blk, 2, l], K2[blk, 3, l] = _acc(
            ST[blk, 2, l] + h2 * ST[blk, 5, l], ST[blk, 3, l] + h2 * AC[blk, 0, l],
            ST[blk, 4, l] + h2 * AC[blk, 1, l], ST[blk, 5, l] + h2 * AC[blk, 2, l],
            ST[blk, 6, l] + h2 * AC[blk, 3, l], wx, wy,
            LP[blk, _L_FH2, l], blk, l, LP, CDO, ATO, cd_flat, atm_flat, tab)
    for l in range(nl):
        wx, wy = LP[blk, _L_WX, l], LP[blk, _L_WY, l]
        if wind_flat is not None:
            wx, wy = _wind_near(ST[blk, 0, l] + h2 * (ST[blk, 3, l] + h2 * AC[blk, 0, l]),
                                ST[blk, 2, l] + h2 * (ST[blk, 5, l] + h2 * AC[blk, 2, l]), blk, l, LP, WD, WTO,
                                wind_flat)
        K3[blk, 0, l], K3[blk, 1, l], K3[blk, 2, l], K3[blk, 3, l] = _acc(
            ST[blk, 2, l] + h2 * (ST[blk, 5, l] + h2 * AC[blk, 2, l]),
            ST[blk, 3, l] + h2 * K2[blk, 0, l], ST[blk, 4, l] + h2 * K2[blk, 1, l],
            ST[blk, 5, l] + h2 * K2[blk, 2, l], ST[blk, 6, l] + h2 * K2[blk, 3, l], wx, wy,
            LP[blk, _L_FH2, l], blk, l, LP, CDO, ATO, cd_flat, atm_flat, tab)
    for l in range(nl):
        wx, wy = LP[blk, _L_WX, l], LP[blk, _L_WY, l]
        if wind_flat is not None:
            WD[blk, 0, l], WD[blk, 1, l], WD[blk, 2, l], WD[blk, 3, l], WD[blk, 4, l] = _wind(
                ST[blk, 0, l] + h * (ST[blk, 3, l] + h2 * K2[blk, 0, l]),
                ST[blk, 2, l] + h * (ST[blk, 5, l] + h2 * K2[blk, 2, l]), blk, l, LP, WTO, wind_flat, w0, inv_dw,
                wmax)
            wx, wy = WD[blk, 0, l], WD[blk, 1, l]
        K4[blk, 0, l], K4[blk, 1, l], K4[blk, 2, l], K4[blk, 3, l] = _acc(
            ST[blk, 2, l] + h * (ST[blk, 5, l] + h2 * K2[blk, 2, l]),
            ST[blk, 3, l] + h * K3[blk, 0, l], ST[blk, 4, l] + h * K3[blk, 1, l],
            ST[blk, 5, l] + h * K3[blk, 2, l], ST[blk, 6, l] + h * K3[blk, 3, l], wx, wy,
            LP[blk, _L_FH, l], blk, l, LP, CDO, ATO, cd_flat, atm_flat, tab)
    for l in range(nl):
        for c in range(3):
            v = ST[blk, 3 + c, l]
            a1 = AC[blk, c, l]
            # RK4 with the stage velocities v + h/2 a1, v + h/2 a2, v + h a3 folded in
            ST1[blk, c, l] = ST[blk, c, l] + h * v + h * h6 * (a1 + K2[blk, c, l] + K3[blk, c, l])
            ST1[blk, 3 + c, l] = v + h6 * (a1 + 2.0 * K2[blk, c, l] + 2.0 * K3[blk, c, l] + K4[blk, c, l])
        ST1[blk, 6, l] = ST[blk, 6, l] + h6 * (AC[blk, 3, l] + 2.0 * K2[blk, 3, l]
                                               + 2.0 * K3[blk, 3, l] + K4[blk, 3, l])
        wx, wy = LP[blk, _L_WX, l], LP[blk, _L_WY, l]
        if wind_flat is not None:
            wx, wy = _wind_near(ST1[blk, 0, l], ST1[blk, 2, l], blk, l, LP, WD, WTO, wind_flat)
        AC1[blk, 0, l], AC1[blk, 1, l], AC1[blk, 2, l], AC1[blk, 3, l] = _acc(
            ST1[blk, 2, l], ST1[blk, 3, l], ST1[blk, 4, l], ST1[blk, 5, l], ST1[blk, 6, l], wx, wy,
            LP[blk, _L_FH, l], blk, l, LP, CDO, ATO, cd_flat, atm_flat, tab)


@njit(**_HELPER)
def _hermite_row(blk, nl, th, h, tab, LP, ATO, WTO, atm_flat, wind_flat, ST, AC, ST1, AC1, OB):
    """One output row of every lane: cubic Hermite on [t_s, t_s + h] (position ``th`` in [0, 1])
    from the states and accelerations at both ends, and its Mach number, into ``OB``."""
    th2 = th * th
    th3 = th2 * th
    e00 = 2.0 * th3 - 3.0 * th2 + 1.0
    e01 = 3.0 * th2 - 2.0 * th3
    e10 = h * (th3 - 2.0 * th2 + th)
    e11 = h * (th3 - th2)
    z0, inv_dz, zmax, w0, inv_dw, wmax = tab[4], tab[5], tab[6], tab[7], tab[8], tab[9]
    for l in range(nl):
        for c in range(3):
            OB[blk, c, l] = (e00 * ST[blk, c, l] + e10 * ST[blk, c + 3, l]
                             + e01 * ST1[blk, c, l] + e11 * ST1[blk, c + 3, l])
            OB[blk, c + 3, l] = (e00 * ST[blk, c + 3, l] + e10 * AC[blk, c, l]
                                 + e01 * ST1[blk, c + 3, l] + e11 * AC1[blk, c, l])
        wx, wy, gx, gy, sw = _wind(OB[blk, 0, l], OB[blk, 2, l], blk, l, LP, WTO, wind_flat, w0, inv_dw, wmax)
        ux = OB[blk, 3, l] - wx
        uy = OB[blk, 4, l] - wy
        uz = OB[blk, 5, l] - LP[blk, _L_WZ, l]
        zi = min(max((OB[blk, 2, l] - z0) * inv_dz, 0.0), zmax)
        j = int(zi)
        ja = ATO[blk, l] + 2 * j
        OB[blk, 6, l] = np.sqrt(ux * ux + uy * uy + uz * uz) * (
            atm_flat[ja + 1] + (zi - j) * (atm_flat[ja + 3] - atm_flat[ja + 1]))


class _NoAliasCompiler(CompilerBase):
    """numba's nopython pipeline with the array arguments marked ``noalias`` (numba's
    ``Flags.noalias``, which it sets itself for a ``prange`` body it finds alias-free): LLVM may
    then vectorise the lane loops, whose table gathers could otherwise alias the scratch stores.
    Sound for :func:`integrate_blocks`: its callers pass distinct arrays, and threads running it
    side by side write disjoint blocks."""

    def define_pipelines(self):
        self.state.flags.noalias = True
        return [DefaultPassBuilder.define_nopython_pipeline(self.state)]


@njit(pipeline_class=_NoAliasCompiler, nogil=True, cache=True, no_cfunc_wrapper=True, **_OPTS)
def integrate_blocks(blk_lo, blk_hi, y0, t_start, h, n_steps, out_step, out_theta, par, cd_flat, n_cells, cd_idx,
                     m0, dm, atm_flat, n_z, atm_idx, z0, dz, wind_flat, n_w, wind_idx, w0, dw, nl, yaw, out,
                     mach_out, BL, LP, CDO, ATO, WTO, ST, AC, K2, K3, K4, ST1, AC1, OB, WD):
    """Integrate the blocks ``blk_lo <= blk < blk_hi`` of a batch (arguments as
    :func:`integrate_batch`, ``yaw`` whether any trajectory has a yaw term, then the scratch
    arrays of :func:`_scratch`). Releases the GIL: threads run disjoint block ranges."""
    B = y0.shape[0]
    N = out_step.shape[0]
    tab = (m0, 1.0 / dm, dm, n_cells - 1e-9, z0, 1.0 / dz, n_z - 1.000001, w0, 1.0 / dw, n_w - 1.000001)
    h2 = 0.5 * h
    h6 = h / 6.0
    for blk in range(blk_lo, blk_hi):
        n_real = min(B, blk * nl + nl) - blk * nl
        _load_lanes(blk, nl, B, y0, par, t_start, cd_idx, atm_idx, wind_idx, n_cells, n_z, n_w, yaw, BL, LP, CDO,
                    ATO, WTO, ST)
        for l in range(nl):
            wx, wy, gx, gy, sw = _wind(ST[blk, 0, l], ST[blk, 2, l], blk, l, LP, WTO, wind_flat, w0, 1.0 / dw,
                                       n_w - 1.000001)
            AC[blk, 0, l], AC[blk, 1, l], AC[blk, 2, l], AC[blk, 3, l] = _acc(
                ST[blk, 2, l], ST[blk, 3, l], ST[blk, 4, l], ST[blk, 5, l], ST[blk, 6, l], wx, wy,
                LP[blk, _L_F0, l], blk, l, LP, CDO, ATO, cd_flat, atm_flat, tab)
        o = 0
        for s in range(n_steps):
            _rk4_step(blk, nl, s, h, h2, h6, yaw, LP, CDO, ATO, WTO, cd_flat, atm_flat, wind_flat, tab, ST, AC, K2,
                      K3, K4, ST1, AC1, WD)
            while o < N and out_step[o] == s:
                _hermite_row(blk, nl, out_theta[o], h, tab, LP, ATO, WTO, atm_flat, wind_flat, ST, AC, ST1, AC1, OB)
                for l in range(n_real):
                    b = BL[blk, l]
                    for c in range(6):
                        out[b, o, c] = OB[blk, c, l]
                    mach_out[b, o] = OB[blk, 6, l]
                o += 1
            for l in range(nl):
                for c in range(7):
                    ST[blk, c, l] = ST1[blk, c, l]
                for c in range(4):
                    AC[blk, c, l] = AC1[blk, c, l]


def _aligned(shape, dtype=np.float64):
    """A zeroed C-contiguous array whose data starts on a 64-byte boundary (a cache line, one
    AVX-512 vector): each lane row of 8 doubles is then one line, no vector load spans two."""
    n = int(np.prod(shape)) * np.dtype(dtype).itemsize
    buf = np.zeros(n + 64, dtype=np.uint8)
    off = -buf.ctypes.data % 64
    return buf[off:off + n].view(dtype).reshape(shape)


def _scratch(n_blk, nl):
    """The kernel's scratch arrays for ``n_blk`` blocks of ``nl`` lanes, each its own allocation
    (:class:`_NoAliasCompiler` promises LLVM that no two alias), 64-byte aligned."""
    return (_aligned((n_blk, nl), np.int64),        # BL: trajectory of each lane
            _aligned((n_blk, _N_L, nl)),              # LP: lane parameters (_L_*)
            _aligned((n_blk, nl), np.int64),        # CDO, ATO, WTO: table offsets
            _aligned((n_blk, nl), np.int64),
            _aligned((n_blk, nl), np.int64),
            _aligned((n_blk, 7, nl)),                 # ST: state at t_s (row 6: spin fraction q)
            _aligned((n_blk, 4, nl)),                 # AC: acceleration and dq/dt at t_s
            _aligned((n_blk, 4, nl)),                 # K2, K3, K4: the other RK stages
            _aligned((n_blk, 4, nl)),
            _aligned((n_blk, 4, nl)),
            _aligned((n_blk, 7, nl)),                 # ST1: state at t_s + h
            _aligned((n_blk, 4, nl)),                 # AC1: acceleration there (next first stage)
            _aligned((n_blk, 7, nl)),                 # OB: one output row (state, Mach) of every lane
            _aligned((n_blk, 5, nl)))                 # WD: last wind table read (wx, wy, slopes, s)


def integrate_batch(y0, t_start, h, n_steps, out_step, out_theta, par, cd_flat, n_cells, cd_idx,
                    m0, dm, atm_flat, n_z, atm_idx, z0, dz, wind_flat, n_w, wind_idx, w0, dw, nl, out, mach_out,
                    n_threads=1):
    """Integrate B trajectories with classic RK4 on a uniform step, cubic Hermite output.

    Parameters
    ----------
    y0 : (B, 6) float64
        Initial states at ``t_start``.
    t_start : float
        Time of the initial state [s] (the yaw clock adds ``par[:, P_T0]``).
    h : float
        Step [s] (0 allowed: every output is then the initial state).
    n_steps : int
        Number of steps (>= 1).
    out_step : (N,) int64, non-decreasing
        Step whose interval [t_start + s h, t_start + (s + 1) h] holds output row n.
    out_theta : (N,) float64 in [0, 1]
        Position of output n inside that interval.
    par : (B, N_PAR) float64
        Per-trajectory parameters (column layout ``P_*``).
    cd_flat : (T * n_cells * 4,) float64
        Cubic drag cells on the Mach grid (m0, dm), flattened from (T, n_cells, 4); trajectory
        b uses table ``cd_idx[b]``.
    cd_idx : (B,) int64
    m0, dm : float
        Mach grid origin and cell width.
    atm_flat : (A * n_z * 2,) float64
        Density [kg/m^3] and *inverse* speed of sound [s/m] on a uniform height grid (z0, dz),
        flattened from (A, n_z, 2); trajectory b uses table ``atm_idx[b]``.
    atm_idx : (B,) int64
    z0, dz : float
        Height grid origin and spacing [m].
    wind_flat : (W * n_w * 2,) float64 or None
        Horizontal wind (wx, wy) [m/s] on a uniform grid (w0, dw) of the coordinate
        ``s = x par[b, P_WIND_AX_X] + z par[b, P_WIND_AX_Z]`` [m] (height, or downrange
        distance), flattened from (W, n_w, 2); trajectory b uses table ``wind_idx[b]`` and adds
        its constant wind ``par[b, P_WX:P_WY + 1]``. None: no trajectory has a wind profile
        (compiled as its own specialisation, without the table reads).
    wind_idx : (B,) int64
    w0, dw : float
        Wind grid origin and spacing [m].
    nl : int
        Lanes per block (:func:`lanes_per_block`).
    out : (B, N, 6) float64
        Filled in place with the states at the output rows.
    mach_out : (B, N) float64
        Filled in place with the Mach number at the output rows.
    n_threads : int
        Threads that integrate the blocks side by side (at most one per block): the calling
        thread and ``n_threads - 1`` helper threads (:func:`bayesdrag.dynamics.threads.run_split`),
        each a contiguous range of blocks; the results do not depend on it. Each thread uses
        the scratch arrays its slot of the pool keeps for this batch shape (fresh ones when
        another thread is using the pool).
    """
    n_blk = (y0.shape[0] + nl - 1) // nl
    if n_blk == 0:
        return out                      # nothing to integrate
    # any yaw term, found here once per batch rather than by a loop compiled into the kernel
    yaw = bool(par[0, P_YAW_AMP] != 0.0) if y0.shape[0] == 1 else bool(par[:, P_YAW_AMP].any())
    args = (y0, float(t_start), float(h), int(n_steps), out_step, out_theta, par, cd_flat, int(n_cells), cd_idx,
            float(m0), float(dm), atm_flat, int(n_z), atm_idx, float(z0), float(dz), wind_flat, int(n_w), wind_idx,
            float(w0), float(dw), int(nl), yaw, out, mach_out)
    n_run = max(1, min(int(n_threads), n_blk))
    fn = integrate_blocks_scalar if nl < LANE_WIDTH else integrate_blocks
    if n_run == 1:
        run_split(fn, [(0, n_blk) + args], ((n_blk, nl), _scratch))
        return out
    cuts = [n_blk * i // n_run for i in range(n_run + 1)]
    run_split(fn, [(cuts[i], cuts[i + 1]) + args for i in range(n_run)], ((n_blk, nl), _scratch))
    return out


def _renamed(fn, name):
    """A copy of the Python function ``fn`` under the name ``name`` (numba's on-disk cache is
    keyed by the function's qualified name and line, not by its compile options)."""
    import types

    g = types.FunctionType(fn.__code__.replace(co_name=name), fn.__globals__, name, fn.__defaults__,
                           fn.__closure__)
    g.__qualname__ = name
    g.__doc__ = fn.__doc__
    return g


#: the same block integrator compiled without ``noalias``, for batches of fewer than
#: LANE_WIDTH trajectories (one block of B lanes): LLVM then leaves the lane loops scalar, faster
#: for so few lanes than the vector loops' remainder path, with the scalar kernel's last bits
integrate_blocks_scalar = njit(nogil=True, cache=True, no_cfunc_wrapper=True, **_OPTS)(
    _renamed(integrate_blocks.py_func, "integrate_blocks_scalar"))
