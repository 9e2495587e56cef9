"""Point-mass trajectory model (paper Eqs. 20-22 in 3-D) with wind, atmosphere and effects.

Equations of motion (DESIGN.md frame: x downrange, y right, z up; ground-relative velocity v)::

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
    :mod:`bayesdrag.dynamics._kernel`, classic RK4 with a uniform step (see
    :func:`output_schedule`: at most ``max_step``, by default 0.1 s or 1 % of the drag time
    scale, whichever is smaller) and cubic Hermite interpolation of the states between steps
    at the output times, run for a whole batch of parameter sets at once (vectorised lanes,
    parallel threads); the drag curve and the atmosphere are tabulated (exact for the drag
    models, < 1e-6 relative for the atmosphere). Agreement with the scipy backend is below
    1e-3 m over a full 155 mm trajectory (tests/test_pointmass.py); the step depends only on
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

from ..atmosphere import G0, Atmosphere
from ..drag import DragModel, MachGrid
from . import _kernel as K

#: Earth's rotation rate [rad/s] (sidereal)
OMEGA_EARTH = 7.292115e-5

#: Lift constant L = Ix p C_La / (m d C_Ma) of a typical spin-stabilised shell as a fraction of
#: its muzzle velocity [-] (effect ``lift`` with ``factor = 1``); see :func:`lift_parameter`.
LIFT_REF_FRACTION = 0.02
#: Mach shape of the lift-to-overturning ratio C_La / C_Ma of a spin-stabilised shell,
#: ``s(M) = 1 + A x / (1 + B x)`` with ``x = max(M - 1, 0)`` (1 subsonic): A, B fitted to the
#: representative 155 mm M107 coefficients (:func:`bayesdrag.dynamics.sixdof.m107_aero`: C_La /
#: C_Ma = 0.42 subsonic, 0.72 at Mach 1.5, 0.88 at 2, 0.98 at 2.5; this formula gives 0.42,
#: 0.71, 0.89, 1.01). The rise is general for spinning shells and bullets -- C_La grows and C_Ma
#: falls with supersonic Mach (McCoy 1999, ch. 2 and 10) -- its size is not: see the lift notes.
LIFT_MACH_RISE = 1.79
LIFT_MACH_SAT = 0.6
#: spin damping kappa = -C_lp / k_a^2 [-] of a typical shell (C_lp = -0.010 to -0.016, axial
#: radius of gyration squared k_a^2 = Ix / (m d^2) ~ 0.12-0.15): the spin fraction q = p / p0
#: obeys dq/dt = -kappa k_ref rho |u| q, i.e. it decays over the path in air; 155 mm at 818 m/s:
#: q = 0.76 / 0.70 / 0.65 at impact at QE 10 / 20 / 45 deg (6-DOF: 0.78 / 0.70 / 0.64), and the
#: drift with factor 1 is 93 / 253 / 863 m (6-DOF 89 / 245 / 832 m).
SPIN_DECAY = 0.09
#: Vertical force on the yaw of repose as a fraction of its horizontal lift, ``(p d / |u|) nu``.
#: Two parts, both up for a right-hand spin (McCoy 1999, ch. 10: the yaw of repose
#: ``xi_R = i P G / (M + i P T)`` is not purely horizontal):
#:
#: * the Magnus force, ``|C_Npa| / C_La`` of the lift: 0.18 subsonic, 0.05 at Mach 2 (M107
#:   representative values, :func:`bayesdrag.dynamics.sixdof.m107_aero`);
#: * lift on the vertical part of the yaw of repose, ``P T / M = (p d / V) (k_a^2 C_La +
#:   C_npa) / C_Ma`` of the horizontal yaw: 0.14 subsonic, 0.17 at Mach 2.4.
#:
#: Their sum nu = 0.21-0.33 over Mach 0.6-2.4 is nearly flat, so nu = 0.25 is taken constant
#: (``LIFT_VERTICAL_MACH_SAT = 0``; a fall-off ``1 / (1 + C max(M - 0.8, 0))`` is available).
#: With p0 = 2 pi v0 / (n d) the fraction is ``m q / |u|`` with the speed
#: ``m = LIFT_VERTICAL_FRACTION * v0``, ``LIFT_VERTICAL_FRACTION = nu 2 pi / n`` = 0.0785 for a
#: 1-in-20-calibre twist. The force is normal to the airspeed in its vertical plane; 5-10 % of
#: the lift, it raises a 155 mm shell by ~15 m at QE 20 deg, which a fit without it puts into a
#: muzzle 4-8 m below the gun (6-DOF: docs/diagnosis.md).
LIFT_VERTICAL_FRACTION = 0.25 * 2.0 * math.pi / 20.0
LIFT_VERTICAL_MACH_SAT = 0.0


def lift_parameter(factor, v0):
    """Kernel column ``P_LIFT`` (the subsonic lift constant L [m/s]) for the ``lift`` effect.

    Physics (McCoy, *Modern Exterior Ballistics*, 1999, ch. 9 and 11, modified point mass): a
    spinning shell flies with its yaw of repose
    ``alpha_R = -(2 Ix p / (rho S d v^4 C_Ma)) (v x dv/dt)`` (right-handed axes), and the lift
    on it is ``a_L = (rho S v^2 C_La / 2m) alpha_R = -(Ix p C_La / (m d C_Ma)) (v x dv/dt) / v^2``.
    Drag is along v and drops out of the cross product; with dv/dt replaced by gravity
    ``(0, 0, -g)`` and v by the airspeed vector u, this becomes, in the DESIGN.md frame
    (x downrange, y right, z up -- left-handed, so the cross product is taken with y flipped
    and flipped back)::

        a_L = L(t) g / |u|^2 * (-u_y, u_x, 0),      |a_L| = L(t) g cos(theta) / |u|,

    horizontal and to the right of the airspeed for L > 0 (right-hand spin drifts right), with
    ``L(t) = Ix p(t) C_La(M) / (m d C_Ma(M))``. Neither factor of L is constant: the ratio
    C_La / C_Ma more than doubles from subsonic speed to Mach 2.5 and the spin decays by a
    quarter to a third over a long flight, so L falls by a factor ~3 between muzzle and
    impact (155 mm, 818 m/s). A constant L fitted to such a drift leaves a misfit of metres,
    which a cross wind (2 parameters) then explains better than the lift itself (measured on
    the 6-DOF: docs/diagnosis.md). So ``L(t) = L q(t) s(M)``: q the spin fraction (its own
    state, damping ``kappa``, :data:`SPIN_DECAY`), s(M) the Mach shape of C_La / C_Ma
    (:func:`lift_mach_shape`, 1 subsonic), and L, the *subsonic* constant at the initial spin,
    ``Ix p0 (C_La / C_Ma)_sub / (m d)``. None of Ix, p0, C_La, C_Ma comes with a round file,
    so it is parametrised as ``L = factor * LIFT_REF_FRACTION * v0``: for a spin-stabilised
    shell Ix = k_a^2 m d^2 with k_a^2 ~ 0.12-0.15, spin p0 = 2 pi v0 / (n d) with a twist of
    n ~ 20-35 calibres, and (C_La / C_Ma)_sub ~ 0.4-0.5 give L ~ 0.01-0.02 v0 whatever the
    calibre; ``factor`` absorbs the shell's actual values (the paper's Table 1 shell: 0.94).
    This is the modified point mass's "lift factor" (STANAG 4355 fits one to firing data the
    same way). Neglected: the Coriolis and lift parts of dv/dt in alpha_R, and a shell whose
    Mach shape differs from the generic one (what is left then shows in the remaining gap).

    Parameters
    ----------
    factor : float or array_like, shape (B,)
        Effect parameter [-]; 1 is the typical shell, 0 no lift, < 0 a left-hand spin.
    v0 : float or array_like, shape (B,)
        Speed [m/s] that sets the spin: the muzzle velocity (:class:`PointMassModel` uses its
        ``lift_v0`` or, by default, the speed of each trajectory's initial state).

    Returns
    -------
    float or ndarray, shape (B,)
        L [m/s], for ``simulate_batch(..., overrides={_kernel.P_LIFT: L})``.
    """
    return np.asarray(factor, dtype=float) * LIFT_REF_FRACTION * np.asarray(v0, dtype=float)


def lift_mach_shape(mach, rise=LIFT_MACH_RISE, sat=LIFT_MACH_SAT):
    """Mach shape s(M) of the yaw-of-repose lift, ``1 + rise x / (1 + sat x)``, ``x = max(M - 1, 0)``.

    Parameters
    ----------
    mach : float or array_like
        Mach number [-].
    rise, sat : float
        Shape constants (defaults :data:`LIFT_MACH_RISE`, :data:`LIFT_MACH_SAT`; 0, 0 = constant).

    Returns
    -------
    float or ndarray
        s(M) [-], 1 at and below Mach 1.
    """
    x = np.maximum(np.asarray(mach, dtype=float) - 1.0, 0.0)
    return 1.0 + rise * x / (1.0 + sat * x)


def coriolis_matrix(latitude_deg, azimuth_deg, omega=OMEGA_EARTH):
    """Matrix C [1/s] with Coriolis acceleration ``a = C @ v`` in the DESIGN.md frame.

    ``a = -2 Omega x v`` evaluated in east-north-up axes and projected on x (downrange, along
    ``azimuth_deg`` clockwise from north), y (to the right) and z (up). Note that (x, y, z) is
    left-handed, which is why the cross product is taken in ENU axes.

    Parameters
    ----------
    latitude_deg : float
        Geodetic latitude, north positive [deg].
    azimuth_deg : float
        Firing azimuth clockwise from true north [deg].

    Returns
    -------
    ndarray, shape (3, 3)
    """
    lat, az = math.radians(latitude_deg), math.radians(azimuth_deg)
    om = omega * np.array([0.0, math.cos(lat), math.sin(lat)])  # ENU
    ex = np.array([math.sin(az), math.cos(az), 0.0])
    ey = np.array([math.cos(az), -math.sin(az), 0.0])
    ez = np.array([0.0, 0.0, 1.0])
    E = np.stack([ex, ey, ez])  # rows: local axes in ENU
    C = np.empty((3, 3))
    for j in range(3):
        a_enu = -2.0 * np.cross(om, E[j])  # acceleration for a unit velocity along local axis j
        C[:, j] = E @ a_enu
    return C


@dataclass(frozen=True)
class Trajectory:
    """States of one or many trajectories at common times.

    Attributes
    ----------
    t : ndarray, shape (N,), s
    state : ndarray, shape (N, 6) or (B, N, 6)
        ``[x, y, z, vx, vy, vz]`` in m and m/s.
    mach : ndarray, shape (N,) or (B, N)
        Mach number (airspeed over local speed of sound).
    success : bool
    message : str
    t_impact : float or None
        Time at which z returned to 0 on descent (scipy backend with ``stop_at_impact``).
    """

    t: np.ndarray
    state: np.ndarray
    mach: np.ndarray
    success: bool = True
    message: str = ""
    t_impact: float | None = None

    @property
    def position(self):
        return self.state[..., :3]

    @property
    def velocity(self):
        return self.state[..., 3:]

    @property
    def speed(self):
        """Ground speed |dr/dt| [m/s] (the radar's ``v`` channel)."""
        return np.linalg.norm(self.state[..., 3:], axis=-1)

    def channel(self, name):
        """One radar channel ``x``, ``y``, ``z`` or ``v`` as an array."""
        idx = {"x": 0, "y": 1, "z": 2}
        if name == "v":
            return self.speed
        return self.state[..., idx[name]]


def initial_state(velocity, elevation_deg, heading_deg=0.0, position=(0.0, 0.0, 0.0)):
    """State vector from muzzle velocity [m/s], elevation [deg] and heading relative to the
    firing azimuth [deg, positive to the right]."""
    el, hd = math.radians(elevation_deg), math.radians(heading_deg)
    v = velocity * np.array([math.cos(el) * math.cos(hd), math.cos(el) * math.sin(hd), math.sin(el)])
    return np.concatenate([np.asarray(position, dtype=float), v])


def step_schedule(t_out, t_start, max_step):
    """RK4 steps that land exactly on every output time (the schedule of the first kernel,
    kept for callers that want steps on the samples; the kernel now uses
    :func:`output_schedule`).

    Parameters
    ----------
    t_out : (N,) increasing times [s], all >= ``t_start``.
    t_start : float, s
    max_step : float, s

    Returns
    -------
    step_h : (S,) step sizes; step_out : (S,) output row after each step or -1;
    out_first : int, row of an output at ``t_start`` itself or -1.
    """
    t_out = _check_times(t_out, t_start)
    out_first = 0 if abs(t_out[0] - t_start) <= 1e-12 else -1
    edges = np.concatenate([[t_start], t_out[1:] if out_first == 0 else t_out])
    rows = np.arange(1, len(t_out)) if out_first == 0 else np.arange(len(t_out))
    gaps = np.diff(edges)
    nsub = np.maximum(1, np.ceil(gaps / max_step - 1e-9).astype(np.int64))
    step_h = np.repeat(gaps / nsub, nsub)
    step_out = np.full(step_h.size, -1, dtype=np.int64)
    step_out[np.cumsum(nsub) - 1] = rows
    return step_h, step_out, out_first


#: largest default kernel RK4 step [s]
DEFAULT_MAX_STEP = 0.1
#: default step as a fraction of the drag time scale (:meth:`PointMassModel.drag_time_scale`)
STEP_DRAG_FRACTION = 0.008


def output_schedule(t_out, t_start, max_step):
    """Uniform RK4 steps from ``t_start`` to the last output and where each output falls.

    The kernel steps with ``h = (t_out[-1] - t_start) / n_steps`` and interpolates each output
    inside its step with a cubic Hermite polynomial through the states and accelerations at
    both ends (error O(h^4), far below the RK4 error for smooth flight). Decoupling the steps
    from the outputs lets a 0.027 s radar track be integrated with ~0.1 s steps.

    Parameters
    ----------
    t_out : (N,) increasing times [s], all >= ``t_start``.
    t_start : float, s
    max_step : float, s

    Returns
    -------
    h : float, s
    n_steps : int
    out_step : (N,) int64, step holding each output
    out_theta : (N,) float64, position in [0, 1] of each output inside its step
    """
    t_out = _check_times(t_out, t_start)
    if not max_step > 0:
        raise ValueError(f"max_step must be positive, got {max_step}")
    span = float(t_out[-1] - t_start)
    if span <= 0.0:
        return 0.0, 1, np.zeros(t_out.size, dtype=np.int64), np.zeros(t_out.size)
    n_steps = max(1, int(math.ceil(span / max_step - 1e-9)))
    h = span / n_steps
    r = (t_out - t_start) / h
    out_step = np.clip(np.floor(r), 0, n_steps - 1).astype(np.int64)
    out_theta = np.clip(r - out_step, 0.0, 1.0)
    return h, n_steps, out_step, out_theta


def _check_times(t_out, t_start):
    t_out = np.asarray(t_out, dtype=float)
    if t_out.ndim != 1 or t_out.size == 0:
        raise ValueError("t_out must be a non-empty 1-D array of times")
    if np.any(np.diff(t_out) <= 0):
        raise ValueError("t_out must increase strictly")
    if t_out[0] < t_start - 1e-12:
        raise ValueError(f"output times start at {t_out[0]} s, before the initial state at {t_start} s")
    return t_out


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
        Constant wind ``(wx, wy, wz)`` in the DESIGN.md frame (direction the air moves).
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
        wx, wy, wz = self.wind
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

    def kernel_inputs(self, drag_params, overrides=None, atmospheres=None, state0=None):
        """Arrays for :func:`_kernel.integrate_batch` for B parameter sets.

        Parameters
        ----------
        drag_params : (B, P) array
        overrides : dict of column index -> (B,) array, optional
            Per-trajectory values of kernel parameters (``_kernel.P_*``), e.g. wind.
        atmospheres : sequence of Atmosphere, length B, optional
            Per-trajectory atmospheres (identical ones share a table).
        state0 : (B, 6) array, optional
            Initial states; they set the lift constant (:meth:`lift_constant`) unless
            ``overrides`` gives ``P_LIFT``.
        """
        drag_params = np.atleast_2d(np.asarray(drag_params, dtype=float))
        B = drag_params.shape[0]
        par = np.tile(self.par_row(), (B, 1))
        if self.lift_factor != 0.0 and self.lift_v0 is None and K.P_LIFT not in (overrides or {}):
            if state0 is None:
                raise ValueError("lift_factor needs the initial states (state0) or lift_v0 to set the spin")
            par[:, K.P_LIFT] = self.lift_constant(state0)
        if self.lift_factor != 0.0 and self.lift_v0 is None and K.P_LIFT_VERT not in (overrides or {}) \
                and state0 is not None:
            par[:, K.P_LIFT_VERT] = self.lift_vertical_speed(state0)
        for col, val in (overrides or {}).items():
            par[:, col] = val
        grid = self.mach_grid
        if self.drag.n_params == 0:
            cd_tabs = np.ascontiguousarray(self.drag.kernel_table((), grid)[None])
            cd_idx = np.zeros(B, dtype=np.int64)
        else:
            uniq, inv = np.unique(drag_params, axis=0, return_inverse=True)
            cd_tabs = self.drag.kernel_table(uniq, grid)
            cd_idx = inv.reshape(-1).astype(np.int64)
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
        atm_tabs = np.ascontiguousarray(np.stack(tabs))
        return par, cd_tabs, cd_idx, grid, atm_tabs, atm_idx, z0, dz

    def simulate_batch(self, drag_params, state0, t_out, *, t_start=0.0, overrides=None,
                       atmospheres=None, max_step=None):
        """Integrate B trajectories at once with the compiled kernel.

        Parameters
        ----------
        drag_params : array_like, shape (B, P)
        state0 : array_like, shape (B, 6)
        t_out : array_like, shape (N,)
            Common output times [s], >= ``t_start``.
        overrides, atmospheres : see :meth:`kernel_inputs`.
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
        h, n_steps, out_step, out_theta = output_schedule(t_out, t_start, max_step or self.kernel_step)
        par, cd_tabs, cd_idx, grid, atm_tabs, atm_idx, z0, dz = self.kernel_inputs(
            drag_params, overrides, atmospheres, state0)
        B = state0.shape[0]
        out = np.empty((B, t_out.size, 6))
        mach = np.empty((B, t_out.size))
        nl = K.lanes_per_block(B, numba.get_num_threads())
        run = K.integrate_batch_serial if B < K.LANE_WIDTH else K.integrate_batch
        run(state0, float(t_start), h, n_steps, out_step, out_theta, par,
                          cd_tabs.reshape(-1), cd_tabs.shape[1], cd_idx, grid.m0, grid.dm,
                          atm_tabs.reshape(-1), atm_tabs.shape[1], atm_idx, z0, dz,
                          nl, out, mach)
        # a NaN or inf propagates to the last sample, so checking that row is enough
        ok = bool(np.all(np.isfinite(out[:, -1])))
        return Trajectory(t_out, out, mach, ok, "" if ok else "non-finite state: integration failed")


@lru_cache(maxsize=128)
def _atmosphere_table(atm):
    """Tabulated (rho, a) for an Atmosphere, memoised by its (hashable, frozen) value: the
    diagnosis re-uses a handful of atmospheres thousands of times."""
    z0, dz, tab = atm.table()
    tab = tab.copy()
    tab[:, 1] = 1.0 / tab[:, 1]  # the kernel multiplies by 1/a
    tab.setflags(write=False)
    return z0, dz, tab

