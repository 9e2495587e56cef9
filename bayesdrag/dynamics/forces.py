"""Forces besides drag and gravity in the point-mass model: Earth rotation (Coriolis) and the
lift on the yaw of repose of a spin-stabilised shell (the modified point mass of the ``lift``
effect), with the constants that shape them."""
from __future__ import annotations

import math

import numpy as np

__all__ = ["OMEGA_EARTH", "LIFT_REF_FRACTION", "LIFT_MACH_RISE", "LIFT_MACH_SAT", "SPIN_DECAY",
           "LIFT_VERTICAL_FRACTION", "LIFT_VERTICAL_MACH_SAT", "lift_parameter", "lift_mach_shape",
           "coriolis_matrix"]

#: Earth's rotation rate [rad/s] (sidereal)
OMEGA_EARTH = 7.292115e-5


#: Lift constant L = Ix p C_La / (m d C_Ma) of a typical spin-stabilised shell as a fraction of
#: its muzzle velocity [-] (effect ``lift`` with ``factor = 1``); see :func:`lift_parameter`.
LIFT_REF_FRACTION = 0.02


#: Mach shape of the lift-to-overturning ratio C_La / C_Ma of a spin-stabilised shell,
#: ``s(M) = 1 + A x / (1 + B x)`` with ``x = max(M - 1, 0)`` (1 subsonic): A, B fitted to the
#: representative 155 mm M107 coefficients (:func:`bayesdrag.dynamics.shell.m107_aero`: C_La /
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
#:   representative values, :func:`bayesdrag.dynamics.shell.m107_aero`);
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
    ``(0, 0, -g)`` and v by the airspeed vector u, this becomes, in the track frame (x downrange, y right, z up; docs/formats.md)
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
    """Matrix C [1/s] with Coriolis acceleration ``a = C @ v`` in the track frame (x downrange, y right, z up; docs/formats.md).

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
