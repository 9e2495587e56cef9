"""Point-mass trajectory model (paper Eqs. 20-22 in 3-D) with wind, atmosphere and effects.

Equations of motion (track frame: x downrange, y right, z up; ground-relative velocity v)::

    dv/dt = -(pi d^2 / 8m) rho(z) Cd(M) |u| u  +  (0, 0, -g)  +  C_cor v
            +  q s(M) g / |u|^2 [L (-u_y, u_x, 0) + |L| m q / (|u|^2 (1 + C x_m)) (-u_x u_z, -u_y u_z, u_h^2)]
    dq/dt = -kappa (pi d^2 / 8m) rho(z) |u| q,     q = 1 at the initial state
    u     = v - w,   M = |u| / a(z)

The last term is the lift on the yaw of repose (effect ``lift``, modified point mass; see
:func:`lift_parameter` and :func:`lift_mach_shape`), zero unless ``lift_factor`` is set; q is
the fraction of the initial spin left and the second bracket term the Magnus force on the same
yaw and the lift on its vertical part (:data:`LIFT_VERTICAL_FRACTION`).

The paper writes ``V (dx/dt - Wx)`` with V the total velocity; physically (and in every
point-mass model in use, e.g. STANAG 4355, McCoy ch. 5) the speed in the drag term and in the
Mach number is the *airspeed* |v - w|, so that is what is used here. Gravity is constant
(9.80665 m/s^2) and the Earth flat apart from the optional Coriolis term: at 20 km range the
neglected curvature and the change of g with height move a 155 mm shell by less than its
Coriolis deflection and are left to the diagnosis.

Two backends compute the same trajectories:

``backend="scipy"``
    :func:`scipy.integrate.solve_ivp` (DOP853, tight tolerances) with the exact drag model and
    the exact atmosphere; it supports the impact event and is the reference in the tests.
``backend="kernel"``
    :mod:`bayesdrag.dynamics.kernel`, classic RK4 with a uniform step (see
    :func:`output_schedule`: at most ``max_step``, by default 0.1 s or 1 % of the drag time
    scale, whichever is smaller) and cubic Hermite interpolation of the states between steps
    at the output times, run for a whole batch of parameter sets at once (vectorised lanes,
    parallel threads); the drag curve and the atmosphere are tabulated (exact for the drag
    models, < 1e-6 relative for the atmosphere). Agreement with the scipy backend is below
    1e-3 m over a full 155 mm trajectory (tests/unit/test_pointmass.py); the step depends only on
    the model and the output times, never on the parameters, so finite differences of the
    kernel are smooth.
"""
from __future__ import annotations

import math
from functools import lru_cache
from dataclasses import dataclass, field, replace

import numba
import numpy as np
from scipy.integrate import solve_ivp

from ..air.atmosphere import G0, Atmosphere
from ..drag import DragModel, MachGrid
from ..errors import FitError
from ..air.wind import same_shape, tables_at
from . import kernel as K
from .forces import (LIFT_MACH_RISE, LIFT_MACH_SAT, LIFT_VERTICAL_FRACTION, LIFT_VERTICAL_MACH_SAT,
                     SPIN_DECAY, coriolis_matrix, lift_parameter)
from .trajectory import DEFAULT_MAX_STEP, STEP_DRAG_FRACTION, Trajectory, output_schedule

__all__ = ["PointMassModel", "atmosphere_table", "wind_tables", "positions_and_speed"]






















@dataclass(frozen=True, eq=False)
class PointMassModel:
    """Point-mass model of one projectile in one environment.

    Attributes
    ----------
    mass : float, kg
    diameter : float, m
        Reference diameter; reference area ``pi d^2 / 4``.
    drag : DragModel
    atmosphere : Atmosphere
    wind : (3,) tuple, m/s
        Constant wind ``(wx, wy, wz)`` in the track frame (x downrange, y right, z up;
        docs/formats.md) (direction the air moves). It adds to the atmosphere's wind profile
        (``atmosphere.wind``, a :class:`~bayesdrag.air.atmosphere.WindProfile` by height or by
        downrange distance), which the model flies when the atmosphere carries one.
    coriolis : (latitude_deg, azimuth_deg) or None
        Earth rotation on when given.
    gravity : float, m/s^2
    cd_scale : float
        Multiplier on the drag curve (``drag_scale`` effect).
    yaw_amp, yaw_decay : float
        Yaw drag: Cd * (1 + yaw_amp * exp(-2 yaw_decay t)); yaw_amp = k delta0^2 [-],
        yaw_decay [1/s].
    lift_factor : float
        ``lift`` effect: lift on the yaw of repose, see :func:`lift_parameter` [-].
    lift_v0 : float or None, m/s
        Muzzle velocity that sets the spin for the lift; None: the speed of each trajectory's
        initial state (right for a track that starts at the muzzle).
    lift_mach_rise, lift_mach_sat : float
        Mach shape of the lift (:func:`lift_mach_shape`); 0, 0: no Mach dependence.
    spin_decay : float
        Spin damping kappa of the lift [-] (:data:`SPIN_DECAY`); 0: constant spin.
    lift_vertical_fraction, lift_vertical_mach_sat : float
        Vertical (Magnus and vertical-yaw lift) force on the yaw of repose
        (:data:`LIFT_VERTICAL_FRACTION`); 0: none.
    mach_grid : MachGrid or None
        Kernel Mach grid; by default one covering Mach 0-6 at 0.01.
    max_step : float or None, s
        Largest kernel RK4 step; None: ``min(DEFAULT_MAX_STEP, STEP_DRAG_FRACTION *
        drag_time_scale)`` (0.074 s for the 155 mm shell, 0.008 s for a 6.5 mm bullet).
    """

    mass: float
    diameter: float
    drag: DragModel
    atmosphere: Atmosphere = field(default_factory=Atmosphere)
    wind: tuple = (0.0, 0.0, 0.0)
    coriolis: tuple | None = None
    gravity: float = G0
    cd_scale: float = 1.0
    yaw_amp: float = 0.0
    yaw_decay: float = 0.0
    lift_factor: float = 0.0
    lift_v0: float | None = None
    lift_mach_rise: float = LIFT_MACH_RISE
    lift_mach_sat: float = LIFT_MACH_SAT
    spin_decay: float = SPIN_DECAY
    lift_vertical_fraction: float = LIFT_VERTICAL_FRACTION
    lift_vertical_mach_sat: float = LIFT_VERTICAL_MACH_SAT
    mach_grid: MachGrid | None = None
    max_step: float | None = None

    def __post_init__(self):
        if not (self.mass > 0 and self.diameter > 0):
            raise ValueError(f"mass and diameter must be positive, got {self.mass} kg, {self.diameter} m")
        w = tuple(float(v) for v in self.wind) + (0.0,) * (3 - len(self.wind))
        object.__setattr__(self, "wind", w[:3])
        if self.mach_grid is None:
            object.__setattr__(self, "mach_grid", MachGrid(0.0, 0.01, 600))

    # ------------------------------------------------------------------------------------
    @property
    def k_ref(self):
        """pi d^2 / (8 m) [m^2/kg]: acceleration = k_ref rho Cd V^2."""
        return math.pi * self.diameter**2 / (8.0 * self.mass)

    @property
    def drag_time_scale(self):
        """Time [s] in which drag would stop the projectile at a reference flight: 1 / (k_ref
        rho Cd V) with rho = 1.225 kg/m^3, Cd = 0.4 and V = 1000 m/s (conservative for any
        gun-launched projectile); sets the default kernel step. ~9 s for a 155 mm shell."""
        return 1.0 / (self.k_ref * 1.225 * 0.4 * 1000.0)

    @property
    def kernel_step(self):
        """Largest kernel RK4 step [s] (``max_step`` or the default rule)."""
        if self.max_step is not None:
            return float(self.max_step)
        return min(DEFAULT_MAX_STEP, STEP_DRAG_FRACTION * self.drag_time_scale)

    def with_(self, **changes):
        """Copy with some attributes changed (e.g. ``model.with_(wind=(3, 0, 0))``)."""
        return replace(self, **changes)

    def _spin_speed(self, state0):
        """Speed v0 [m/s] that sets the spin: ``lift_v0``, else each initial state's speed."""
        state0 = np.asarray(state0, dtype=float)
        v0 = self.lift_v0 if self.lift_v0 is not None else np.linalg.norm(state0[..., 3:], axis=-1)
        return np.broadcast_to(np.asarray(v0, dtype=float), state0.shape[:-1])

    def lift_constant(self, state0):
        """Lift constant L [m/s] for initial states (..., 6) (``lift_parameter``)."""
        if self.lift_factor == 0.0:
            return np.zeros(np.shape(state0)[:-1])
        return lift_parameter(self.lift_factor, self._spin_speed(state0))

    def lift_vertical_speed(self, state0):
        """Vertical-force speed m = LIFT_VERTICAL_FRACTION v0 [m/s] for initial states (..., 6)."""
        return self.lift_vertical_fraction * self._spin_speed(state0)

    def par_row(self, state0=None):
        """Kernel parameter row (N_PAR,) for this model.

        ``state0`` (6,) sets the lift constant when ``lift_factor`` is non-zero and ``lift_v0``
        is None; without it the lift column uses ``lift_v0`` or is left 0.
        """
        p = np.zeros(K.N_PAR)
        p[K.P_KREF] = self.k_ref
        p[K.P_WX:K.P_WZ + 1] = self.wind
        if self.coriolis is not None:
            p[K.P_COR:K.P_COR + 9] = coriolis_matrix(*self.coriolis).ravel()
            p[K.P_HAS_COR] = 1.0
        p[K.P_G] = self.gravity
        p[K.P_CD_SCALE] = self.cd_scale
        p[K.P_YAW_AMP] = self.yaw_amp
        p[K.P_YAW_DECAY] = self.yaw_decay
        p[K.P_RHO_SCALE] = 1.0
        p[K.P_LIFT_RISE] = self.lift_mach_rise
        p[K.P_LIFT_SAT] = self.lift_mach_sat
        p[K.P_SPIN_DECAY] = self.spin_decay
        p[K.P_LIFT_VERT_SAT] = self.lift_vertical_mach_sat
        if state0 is not None:
            p[K.P_LIFT] = self.lift_constant(state0)
            p[K.P_LIFT_VERT] = self.lift_vertical_speed(state0)
        elif self.lift_v0 is not None:
            p[K.P_LIFT] = lift_parameter(self.lift_factor, self.lift_v0)
            p[K.P_LIFT_VERT] = self.lift_vertical_fraction * self.lift_v0
        return p

    def _rhs(self, drag_params, t0, lift=0.0, magnus=0.0):
        """Right-hand side for solve_ivp with the exact drag curve and atmosphere; ``lift`` is
        the constant L [m/s] of :func:`lift_parameter`, ``magnus`` the vertical-force speed m [m/s]."""
        curve = self.drag.curve(drag_params)
        atm = self.atmosphere.density_and_sound_speed
        kref = self.k_ref
        wx0, wy0, wz = self.wind
        wind_at, by_x, h_gun = _wind_lookup(self.atmosphere)
        g = self.gravity
        C = coriolis_matrix(*self.coriolis) if self.coriolis is not None else None
        cd_scale, yaw_amp, yaw_decay = self.cd_scale, self.yaw_amp, self.yaw_decay
        rise, sat, kspin = self.lift_mach_rise, self.lift_mach_sat, self.spin_decay * kref
        msat = self.lift_vertical_mach_sat

        def rhs(t, s):
            # s[6]: spin fraction q of the lift (integrated whether or not the lift is on); a
            # 6-element state is taken at full spin and gets a 6-element derivative
            vx, vy, vz = s[3], s[4], s[5]
            q = s[6] if len(s) > 6 else 1.0
            wx, wy = wx0, wy0
            if wind_at is not None:
                px, py = wind_at(s[0] if by_x else s[2] + h_gun)
                wx, wy = wx + px, wy + py
            ax_, ay_, az_ = vx - wx, vy - wy, vz - wz
            V = math.sqrt(ax_ * ax_ + ay_ * ay_ + az_ * az_)
            rho, a = atm(s[2])
            mach = V / a
            cd = cd_scale * curve(mach)
            if yaw_amp:
                cd *= 1.0 + yaw_amp * math.exp(-2.0 * yaw_decay * (t + t0))
            kd = kref * rho * cd * V
            acc = [-kd * ax_, -kd * ay_, -kd * az_ - g]
            if lift:
                xs = max(mach - 1.0, 0.0)
                inv_v2 = 1.0 / max(V * V, K.V2_FLOOR)
                kl = lift * q * (1.0 + rise * xs / (1.0 + sat * xs)) * g * inv_v2
                kabs = kl * lift / math.sqrt(lift * lift + K.LIFT_EPS ** 2)  # smooth |kl|, as the kernel
                km = kabs * magnus * q * inv_v2 / (1.0 + msat * max(mach - 0.8, 0.0))
                acc[0] -= kl * ay_ + km * ax_ * az_
                acc[1] += kl * ax_ - km * ay_ * az_
                acc[2] += km * (ax_ * ax_ + ay_ * ay_)
            if C is not None:
                acc = [acc[i] + C[i, 0] * vx + C[i, 1] * vy + C[i, 2] * vz for i in range(3)]
            if len(s) == 6:
                return [vx, vy, vz, acc[0], acc[1], acc[2]]
            return [vx, vy, vz, acc[0], acc[1], acc[2], -kspin * rho * V * q]

        return rhs

    def mach_of(self, state):
        """Mach number of states (..., 6) (tabulation-free)."""
        state = np.asarray(state, dtype=float)
        va = state[..., 3:] - np.asarray(self.wind)
        prof = getattr(self.atmosphere, "wind", None)
        if prof is not None:
            s = state[..., 0] if prof.axis == "downrange" else state[..., 2] + self.atmosphere.gun_altitude
            va = va - np.concatenate([prof.at(s), np.zeros(s.shape + (1,))], axis=-1)
        a = self.atmosphere.at_height(state[..., 2]).speed_of_sound
        return np.linalg.norm(va, axis=-1) / a

    # ------------------------------------------------------------------------------------
    def simulate(self, drag_params, state0, t_out=None, *, backend="kernel", t_start=0.0,
                 stop_at_impact=False, dt=None, max_time=600.0, rtol=1e-11, atol=1e-9):
        """Integrate one trajectory.

        Parameters
        ----------
        drag_params : array_like, shape (P,)
            Parameters of ``self.drag`` (empty for a fixed table).
        state0 : array_like, shape (6,)
            Initial ``[x, y, z, vx, vy, vz]`` at ``t_start``.
        t_out : array_like, shape (N,), optional
            Output times [s]. With ``backend="scipy"`` and ``stop_at_impact`` it may be omitted
            together with ``dt``: outputs every ``dt`` until impact, plus the impact point.
        backend : {"kernel", "scipy"}
        stop_at_impact : bool
            scipy only: stop when z returns to 0 on descent; outputs after impact are dropped.
        dt : float, optional
            Output interval when ``t_out`` is not given.

        Returns
        -------
        Trajectory
        """
        state0 = np.asarray(state0, dtype=float)
        if backend == "kernel":
            if t_out is None:
                raise ValueError("the kernel backend needs explicit output times t_out")
            tr = self.simulate_batch(np.asarray(drag_params, dtype=float)[None], state0[None],
                                     t_out, t_start=t_start)
            return replace(tr, state=tr.state[0], mach=tr.mach[0])
        if backend != "scipy":
            raise ValueError(f"unknown backend {backend!r}; allowed: 'kernel', 'scipy'")
        rhs = self._rhs(np.asarray(drag_params, dtype=float), t_start, float(self.lift_constant(state0)),
                        float(self.lift_vertical_speed(state0)) if self.lift_factor != 0.0 else 0.0)
        t_end = t_start + max_time if t_out is None else float(np.max(t_out))

        def impact(t, s):
            return s[2]
        impact.terminal = True
        impact.direction = -1
        events = [impact] if stop_at_impact else None
        sol = solve_ivp(rhs, (t_start, t_end), np.append(state0, 1.0), method="DOP853", rtol=rtol,
                        atol=atol, dense_output=True, events=events)
        if sol.status < 0:
            return Trajectory(np.empty(0), np.empty((0, 6)), np.empty(0), False, sol.message)
        t_imp = None
        if stop_at_impact and sol.t_events[0].size:
            t_imp = float(sol.t_events[0][0])
        if t_out is None:
            if dt is None:
                raise ValueError("give t_out or dt")
            if t_imp is None:
                return Trajectory(np.empty(0), np.empty((0, 6)), np.empty(0), False,
                                  f"no impact within max_time = {max_time} s")
            t_out = np.arange(t_start, t_imp, dt)
            if t_imp - t_out[-1] > 1e-9:
                t_out = np.append(t_out, t_imp)
        t_out = np.asarray(t_out, dtype=float)
        if t_imp is not None:
            t_out = t_out[t_out <= t_imp + 1e-12]
        state = sol.sol(t_out).T[:, :6]
        msg = "impact" if t_imp is not None else sol.message
        return Trajectory(t_out, state, self.mach_of(state), True, msg, t_imp)

    def state_at(self, drag_params, state, t_from, t_to, rtol=1e-9, atol=1e-6):
        """State at ``t_to`` from ``state`` at ``t_from``, forwards or backwards in time.

        A solve_ivp (DOP853) integration with the exact drag curve and atmosphere; backwards it
        answers "where was the shell at launch" for a track that starts later. Outside the drag
        model's Mach span its curve is held at the end value, so a long backward extrapolation
        beyond the data is approximate.

        Parameters
        ----------
        drag_params : (P,) array
        state : (6,) array
            ``[x, y, z, vx, vy, vz]`` [m, m/s] at ``t_from``.
        t_from, t_to : float [s]

        Returns
        -------
        (6,) ndarray, or None when the integration failed.
        """
        state = np.asarray(state, dtype=float)
        if t_to == t_from:
            return state.copy()
        rhs = self._rhs(np.asarray(drag_params, dtype=float), 0.0, float(self.lift_constant(state)),
                        float(self.lift_vertical_speed(state)) if self.lift_factor != 0.0 else 0.0)
        try:
            sol = solve_ivp(rhs, (float(t_from), float(t_to)), np.append(state, 1.0), method="DOP853",
                            rtol=rtol, atol=atol)
        except ValueError:
            return None
        if sol.status < 0 or not np.all(np.isfinite(sol.y[:6, -1])):
            return None
        return sol.y[:6, -1].copy()

    def kernel_inputs(self, drag_params, overrides=None, atmospheres=None, state0=None, winds=None):
        """Arrays for :func:`_kernel.integrate_batch` for B parameter sets.

        Parameters
        ----------
        drag_params : (B, P) array
        overrides : dict of column index -> (B,) array, optional
            Per-trajectory values of kernel parameters (``_kernel.P_*``), e.g. wind.
        atmospheres : sequence of Atmosphere, length B, or (B, n, 2) ndarray, optional
            Per-trajectory atmospheres (identical ones share a table), or their tables on the
            model's own atmosphere grid (columns density [kg/m^3] and 1 / speed of sound [s/m],
            see :func:`atmosphere_table`).
        state0 : (B, 6) array, optional
            Initial states; they set the lift constant (:meth:`lift_constant`) unless
            ``overrides`` gives ``P_LIFT``.
        winds : sequence of WindProfile or None, length B, optional
            Per-trajectory wind profiles (the ``wind_profile`` effect); by default each
            trajectory's atmosphere's ``wind``. The constant wind (``P_WX, P_WY``) adds to them.

        Returns
        -------
        tuple ``(par, cd_tabs, cd_idx, grid, atm_tabs, atm_idx, z0, dz, wind)`` with ``wind`` =
        ``(tables (W, n_w, 2) or None, idx (B,), w0, dw)`` (:func:`wind_tables`).
        """
        drag_params = np.atleast_2d(np.asarray(drag_params, dtype=float))
        B = drag_params.shape[0]
        par = np.repeat(self.par_row()[None], B, axis=0)
        if self.lift_factor != 0.0 and self.lift_v0 is None and K.P_LIFT not in (overrides or {}):
            if state0 is None:
                raise ValueError("lift_factor needs the initial states (state0) or lift_v0 to set the spin")
            par[:, K.P_LIFT] = self.lift_constant(state0)
        if self.lift_factor != 0.0 and self.lift_v0 is None and K.P_LIFT_VERT not in (overrides or {}) \
                and state0 is not None:
            par[:, K.P_LIFT_VERT] = self.lift_vertical_speed(state0)
        for col, val in (overrides or {}).items():
            if not isinstance(col, (int, np.integer)):
                raise ValueError(f"override {col!r} is not a kernel column: the {col[0]} effect needs its model "
                                 f"around this one (bayesdrag.effects.static_model)")
            par[:, col] = val
        grid = self.mach_grid
        if self.drag.n_params == 0:
            cd_tabs = np.ascontiguousarray(self.drag.kernel_table((), grid)[None])
            cd_idx = np.zeros(B, dtype=np.int64)
        else:
            first, cd_idx = distinct_rows(drag_params)
            cd_tabs = self.drag.kernel_table(drag_params[first], grid)
        if winds is None:
            winds = ([getattr(a, "wind", None) for a in atmospheres]
                     if atmospheres is not None and not isinstance(atmospheres, np.ndarray)
                     else [getattr(self.atmosphere, "wind", None)] * B)
        elif len(winds) != B:
            raise ValueError(f"winds must give one wind profile (or None) per trajectory: {len(winds)} for {B}")
        wind = wind_tables(winds, self.atmosphere.gun_altitude, par)
        if isinstance(atmospheres, np.ndarray):
            # tables on the nominal atmosphere's grid (density, 1 / speed of sound), one per
            # trajectory: a continuous temperature offset without an Atmosphere per trajectory
            z0, dz, tab0 = _atmosphere_table(self.atmosphere)
            if atmospheres.shape != (B,) + tab0.shape:
                raise ValueError(f"atmosphere tables must be (B, {tab0.shape[0]}, 2), got {atmospheres.shape}")
            return (par, cd_tabs, cd_idx, grid, np.ascontiguousarray(atmospheres), np.arange(B, dtype=np.int64),
                    z0, dz, wind)
        atms = [self.atmosphere] * B if atmospheres is None else list(atmospheres)
        keys = {}
        atm_idx = np.empty(B, dtype=np.int64)
        tabs = []
        for i, a in enumerate(atms):
            if a not in keys:
                keys[a] = len(tabs)
                z0, dz, tab = _atmosphere_table(a)
                tabs.append(tab)
            atm_idx[i] = keys[a]
        if not tabs:
            raise ValueError("no trajectory: drag_params and state0 must hold at least one row")
        atm_tabs = np.array(tabs)              # one writable C-contiguous copy (the memo is read-only)
        return par, cd_tabs, cd_idx, grid, atm_tabs, atm_idx, z0, dz, wind

    def simulate_batch(self, drag_params, state0, t_out, *, t_start=0.0, overrides=None,
                       atmospheres=None, max_step=None, winds=None):
        """Integrate B trajectories at once with the compiled kernel.

        Parameters
        ----------
        drag_params : array_like, shape (B, P)
        state0 : array_like, shape (B, 6)
        t_out : array_like, shape (N,)
            Common output times [s], >= ``t_start``.
        overrides, atmospheres, winds : see :meth:`kernel_inputs`.
        max_step : float, optional
            Largest RK4 step [s]; default :attr:`kernel_step`.

        Returns
        -------
        Trajectory with ``state`` (B, N, 6) and ``mach`` (B, N).
        """
        state0 = np.ascontiguousarray(np.atleast_2d(np.asarray(state0, dtype=float)))
        drag_params = np.atleast_2d(np.asarray(drag_params, dtype=float))
        if drag_params.shape[0] == 1 and state0.shape[0] > 1:
            drag_params = np.repeat(drag_params, state0.shape[0], axis=0)
        if state0.shape[0] == 1 and drag_params.shape[0] > 1:
            state0 = np.repeat(state0, drag_params.shape[0], axis=0)
        if state0.shape[0] != drag_params.shape[0] or state0.shape[1] != 6:
            raise ValueError(f"state0 (B, 6) and drag_params (B, P) disagree: {state0.shape} vs {drag_params.shape}")
        t_out = np.asarray(t_out, dtype=float)
        if t_out.ndim == 1:
            h, n_steps, out_step, out_theta = _schedule(t_out.tobytes(), float(t_start),
                                                        float(max_step or self.kernel_step))
            out_step, out_theta = out_step.copy(), out_theta.copy()      # the kernel's own (writable) arrays
        else:
            h, n_steps, out_step, out_theta = output_schedule(t_out, t_start, max_step or self.kernel_step)
        par, cd_tabs, cd_idx, grid, atm_tabs, atm_idx, z0, dz, wind = self.kernel_inputs(
            drag_params, overrides, atmospheres, state0, winds)
        w_tabs, w_idx, w0, dw = wind
        B = state0.shape[0]
        if n_steps > MAX_KERNEL_STEPS:
            raise FitError(f"the trajectory from t = {t_start:g} to {t_out[-1]:g} s needs {n_steps} RK4 steps of "
                           f"{h:.3g} s (more than {MAX_KERNEL_STEPS}): the projectile's drag time scale "
                           f"{self.drag_time_scale:.3g} s is implausible; check its mass and diameter")
        out = np.empty((B, t_out.size, 6))
        mach = np.empty((B, t_out.size))
        # a long batch runs as several kernel calls of whole trajectories (each its own, exactly
        # as in one call): a Ctrl-C is then seen between two of them, within a second or so,
        # instead of after minutes inside compiled code
        per_call = max(1, CHUNK_LANE_STEPS // max(n_steps, 1))
        step = per_call if B * n_steps > CHUNK_LANE_STEPS else B
        w_flat = None if w_tabs is None else w_tabs.reshape(-1)
        w_cols = 2 if w_tabs is None else w_tabs.shape[1]
        n_threads = numba.get_num_threads()
        for b0 in range(0, B, step):
            b1 = min(B, b0 + step)
            nb = b1 - b0
            K.integrate_batch(state0[b0:b1], float(t_start), h, n_steps, out_step, out_theta, par[b0:b1],
                              cd_tabs.reshape(-1), cd_tabs.shape[1], cd_idx[b0:b1], grid.m0, grid.dm,
                              atm_tabs.reshape(-1), atm_tabs.shape[1], atm_idx[b0:b1], z0, dz,
                              w_flat, w_cols, w_idx[b0:b1], w0, dw,
                              K.lanes_per_block(nb, n_threads), out[b0:b1], mach[b0:b1], n_threads)
        # a NaN or inf propagates to the last sample, so checking that row is enough
        ok = bool(np.isfinite(out[:, -1]).all())
        return Trajectory(t_out, out, mach, ok, "" if ok else "non-finite state: integration failed")


def distinct_rows(a):
    """The distinct rows of ``a`` (B, P): ``(first, inverse)`` with ``a[first]`` the distinct rows
    in the order first met and ``a[first][inverse] == a``. One table per distinct drag parameter
    set: a finite-difference batch repeats the drag parameters of most of its rows. Bytewise
    (a dictionary of the rows' bytes: ~1 us per row, where ``np.unique(axis=0)``'s sort of a
    structured view cost ~80 us for the sampler's 16 rows).

    Parameters
    ----------
    a : (B, P) ndarray of float

    Returns
    -------
    first : (K,) int64 ndarray
    inverse : (B,) int64 ndarray
    """
    a = np.ascontiguousarray(a, dtype=float)
    seen = {}
    inverse = np.fromiter((seen.setdefault(row.tobytes(), len(seen)) for row in a), dtype=np.int64, count=a.shape[0])
    first = np.full(len(seen), -1, dtype=np.int64)
    first[inverse[::-1]] = np.arange(a.shape[0] - 1, -1, -1)
    return first, inverse


def positions_and_speed(state, columns):
    """Position coordinates and speeds of a batch of trajectories in one compiled pass (the
    gun-frame channels :func:`bayesdrag.measure.channel_values` reads off every trial batch:
    numpy's strided passes over the (B, N, 6) states cost ~3 times as long).

    Parameters
    ----------
    state : (B, N, 6) float64 ndarray
        Positions [m] and velocities [m/s].
    columns : sequence of int
        Per output column: 0, 1, 2 the position coordinate x, y, z; 3 the speed
        ``sqrt(ux^2 + uy^2 + uz^2)`` (summed in that order, as numpy does).

    Returns
    -------
    (B, N, len(columns)) ndarray
    """
    state = np.ascontiguousarray(state, dtype=float)
    cols = np.asarray(columns, dtype=np.int64)
    out = np.empty(state.shape[:-1] + (cols.size,))
    _positions_and_speed(state, cols, out)
    return out


@numba.njit(cache=True, nogil=True, error_model="numpy", boundscheck=False)
def _positions_and_speed(state, cols, out):
    B, N, _ = state.shape
    for b in range(B):
        for i in range(N):
            for j in range(cols.size):
                c = cols[j]
                if c < 3:
                    out[b, i, j] = state[b, i, c]
                else:
                    ux, uy, uz = state[b, i, 3], state[b, i, 4], state[b, i, 5]
                    out[b, i, j] = np.sqrt(ux * ux + uy * uy + uz * uz)


def atmosphere_table(atm):
    """The kernel's table of an atmosphere: ``(z0, dz, values)`` with heights above the gun
    ``z0 + dz * i`` [m] and columns density [kg/m^3] and 1 / speed of sound [s/m] (read-only,
    memoised)."""
    return _atmosphere_table(atm)


#: a batch of more than this many trajectory-steps (trajectories x RK4 steps, ~0.1-1 s of
#: kernel time) is run as several kernel calls of whole trajectories (Ctrl-C between them);
#: an ordinary fit's batch is 10-100 times smaller
CHUNK_LANE_STEPS = 2_000_000
#: most RK4 steps one trajectory may need: a plausible projectile over the longest flight needs
#: a few hundred thousand (a 4 mm, 1.3 g ball over a minute); beyond, a mass or diameter is wrong
MAX_KERNEL_STEPS = 20_000_000


@lru_cache(maxsize=16)
def _schedule(t_out, t_start, max_step):
    """:func:`output_schedule` of the times ``t_out`` (the bytes of a float array), memoised: a
    fit asks for the schedule of the same track times on every batch (arrays read-only)."""
    out = output_schedule(np.frombuffer(t_out, dtype=float), t_start, max_step)
    for a in out[2:]:
        a.setflags(write=False)
    return out


@lru_cache(maxsize=128)
def _atmosphere_table(atm):
    """Tabulated (rho, a) for an Atmosphere, memoised by its (hashable, frozen) value: the
    diagnosis re-uses a handful of atmospheres thousands of times."""
    z0, dz, tab = atm.table()
    tab = tab.copy()
    tab[:, 1] = 1.0 / tab[:, 1]  # the kernel multiplies by 1/a
    tab.setflags(write=False)
    return z0, dz, tab



#: grid spacing [m] of a wind profile's kernel table (height or downrange distance): a step in
#: the wind becomes a ramp over one cell, which a shell crosses in milliseconds
WIND_GRID_STEP = 5.0
#: most rows of a wind table (a longer span gets a coarser grid)
WIND_GRID_MAX_ROWS = 20001


def _wind_lookup(atmosphere):
    """The scipy reference's wind profile: ``(at_scalar, by_downrange, gun_altitude)`` or
    ``(None, False, 0.0)`` without one."""
    prof = getattr(atmosphere, "wind", None)
    if prof is None:
        return None, False, 0.0
    return prof.at_scalar, prof.axis == "downrange", float(atmosphere.gun_altitude)


def wind_tables(winds, gun_altitude, par):
    """The kernel's wind tables of a batch: one table per distinct profile on one grid.

    Sets the axis columns ``P_WIND_AX_X, P_WIND_AX_Z`` of ``par`` (in place): (0, 1) for a wind
    by height, (1, 0) by downrange distance, (0, 0) for a trajectory without a profile (its
    table is zeros).

    Parameters
    ----------
    winds : sequence of WindProfile or None, length B
        The profiles of a batch share their axis.
    gun_altitude : float, m
        Height of the gun above sea level (a profile by altitude is tabulated in heights above
        the gun, the kernel's z).
    par : (B, N_PAR) array

    Returns
    -------
    (tables (W, n_w, 2) or None, idx (B,) int64, w0, dw)
        Wind (wx, wy) [m/s] at ``w0 + dw * i`` [m] of the coordinate; None when no trajectory
        has a profile (the kernel then compiles without the table reads).

    Raises
    ------
    ValueError
        Profiles by different axes in one batch.
    """
    B = len(winds)
    idx = np.zeros(B, dtype=np.int64)
    present = [w for w in winds if w is not None]
    if not present:
        return None, idx, 0.0, 1.0
    axes = {w.axis for w in present}
    if len(axes) > 1:
        raise ValueError(f"one batch cannot fly winds by {' and by '.join(sorted(axes))}")
    axis = axes.pop()
    off = 0.0 if axis == "downrange" else float(gun_altitude)
    lo = min(w.levels[0] for w in present) - off
    hi = max(w.levels[-1] for w in present) - off
    dw = max(WIND_GRID_STEP, (hi - lo) / (WIND_GRID_MAX_ROWS - 1))
    n = max(int(np.ceil((hi - lo) / dw)) + 1, 2)
    keys = {}
    for b, w in enumerate(winds):
        if w is None:
            continue
        idx[b] = keys.setdefault(w, len(keys) + 1)
        par[b, K.P_WIND_AX_X] = 1.0 if axis == "downrange" else 0.0
        par[b, K.P_WIND_AX_Z] = 0.0 if axis == "downrange" else 1.0
    distinct = list(keys)
    tabs = np.zeros((len(distinct) + 1, n, 2))
    if len(distinct) > 1 and all(same_shape(distinct[0], w) for w in distinct[1:]):
        # a fit's perturbed trajectories: one profile shape, tabulated at once (the same numbers)
        tabs[1:] = tables_at(distinct, lo + off + dw * np.arange(n))
    else:
        for i, w in enumerate(distinct):
            tabs[i + 1] = _wind_table(w, lo + off, dw, n)
    return tabs, idx, float(lo), float(dw)


@lru_cache(maxsize=256)
def _wind_table(profile, s0, ds, n):
    """(n, 2) wind of a profile at ``s0 + ds * i`` of its own coordinate (memoised by value)."""
    tab = profile.at(s0 + ds * np.arange(n))
    tab.setflags(write=False)
    return tab
