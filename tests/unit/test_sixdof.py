"""Tests of the 6-DOF simulator (bayesdrag.dynamics.sixdof).

The references here are self-contained: a point-mass model (paper Eqs. 20-22) and McCoy's
modified point-mass yaw-of-repose drift (Modern Exterior Ballistics, 1999, ch. 11) are
integrated with scipy inside this file, so the tests do not depend on the package's own
point-mass module.
"""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from bayesdrag.air.atmosphere import G0, Atmosphere
from bayesdrag.dynamics.shell import Shell, gyroscopic_stability, linear_theory, m107_aero, table1_shell
from bayesdrag.dynamics.sixdof import simulate_6dof

# named tolerances -----------------------------------------------------------------------------
RANGE_VS_POINT_MASS_REL = 0.03     # full 6-DOF vs point mass, same Cd0 [-] (task requirement)
DECOUPLED_POS_TOL_M = 0.05         # 6-DOF without yaw-dependent forces vs point mass [m]
DECOUPLED_SPEED_TOL_MS = 0.005     # [m/s]
TINY_YAW_RANGE_REL = 0.005         # full aero, subsonic short flight vs point mass [-]
DRIFT_FRACTION_MIN = 0.001         # drift / range at QE 7-15 deg [-], see test_drift
DRIFT_FRACTION_MAX = 0.03
DRIFT_VS_MPM_REL = 0.05            # 6-DOF drift vs modified-point-mass yaw-of-repose drift [-]
SPIN_TABLE1_RAD_S = 1657.0         # paper Table 1
SPIN_TOL_RAD_S = 2.0

SHELL = table1_shell()


@pytest.fixture(scope="module")
def shell():
    return SHELL


# self-contained point-mass reference ----------------------------------------------------------
def point_mass(shell, v0, qe_deg, mpm_drift=False, atmosphere=None):
    """Point mass, d2r/dt2 = -rho S Cd(M) V v / (2 m) + g (x downrange, y right, z up).

    With ``mpm_drift`` the lift on McCoy's yaw of repose is added:
    alpha_R = 2 Ix p (g_perp) / (rho S d C_M_alpha V^3) (nose right for right-hand spin) with
    the spin p from the 6-DOF run interpolated in time, and a lift acceleration
    rho S V^2 C_L_alpha alpha_R / (2 m) to the right.
    """
    atm = atmosphere or Atmosphere()
    S, m, d = shell.area, shell.mass, shell.diameter

    def rhs(t, s, spin_of_t):
        x, y, z, vx, vy, vz = s
        air = atm.at_height(z)
        rho, a = float(air.density), float(air.speed_of_sound)
        V = math.sqrt(vx * vx + vy * vy + vz * vz)
        k = rho * S * float(shell.cd0.value(V / a)) * V / (2.0 * m)
        ax, ay, az = -k * vx, -k * vy, -k * vz - G0
        if spin_of_t is not None:
            c = shell.aero.at(V / a)
            p = spin_of_t(t)
            vh = np.array([vx, vy, vz]) / V
            g_perp = G0 * math.sqrt(max(0.0, 1.0 - vh[2] ** 2))   # g cos(theta)
            alpha_r = 2.0 * shell.Ix * p * g_perp / (rho * S * d * c["cm_alpha"] * V ** 3)
            a_lift = rho * S * V * V * c["cl_alpha"] * alpha_r / (2.0 * m)
            # horizontal unit vector to the right of the velocity (y right frame)
            h = math.hypot(vx, vy)
            ax += a_lift * (-vy / h)
            ay += a_lift * (vx / h)
        return [vx, vy, vz, ax, ay, az]

    spin_of_t = None
    if mpm_drift:
        ref = simulate_6dof(shell, v0, qe_deg, rtol=1e-7, atol=1e-7)
        spin_of_t = lambda t: float(np.interp(t, ref.t, ref.spin))  # noqa: E731

    def hit(t, s, *a):
        return s[2]

    hit.terminal, hit.direction = True, -1
    th = math.radians(qe_deg)
    sol = solve_ivp(rhs, (0.0, 400.0), [0, 0, 0, v0 * math.cos(th), 0, v0 * math.sin(th)],
                    method="DOP853", rtol=1e-9, atol=1e-9, events=hit, dense_output=True,
                    args=(spin_of_t,))
    return sol


# ---------------------------------------------------------------------------------------------
def test_default_spin_matches_table1(shell):
    r = simulate_6dof(shell, 818.0, 7.0, t_out=[0.0, 0.1])
    assert abs(r.spin[0] - SPIN_TABLE1_RAD_S) < SPIN_TOL_RAD_S


def test_gyroscopic_stability_at_launch(shell):
    """Table 1 shell, 818 m/s, 1/20 twist, ICAO sea level: Sg0 > 1, as reported and by hand."""
    r = simulate_6dof(shell, 818.0, 7.0, t_out=[0.0, 0.1])
    air = Atmosphere().at_height(0.0)
    rho, a = float(air.density), float(air.speed_of_sound)
    p = 2 * math.pi * 818.0 / (20 * 0.155)
    cma = np.interp(818.0 / a, shell.aero.mach, shell.aero.cm_alpha)
    by_hand = 0.146 ** 2 * p ** 2 / (2 * rho * (math.pi * 0.155 ** 2 / 4) * 0.155 * 1.709
                                     * 818.0 ** 2 * cma)
    assert r.sg0 > 1.3          # usual design requirement at the muzzle
    assert r.sg0 == pytest.approx(by_hand, rel=1e-9)
    assert r.sg0 == pytest.approx(gyroscopic_stability(shell, 818.0, p, rho, 818.0 / a), rel=1e-12)
    # the linear-theory P^2 / (4M) is the same number
    assert linear_theory(shell, 818.0, p, rho, 818.0 / a).sg == pytest.approx(by_hand, rel=1e-9)
    assert r.sg[0] == pytest.approx(r.sg0, rel=1e-6)


def test_linear_theory_stable_along_flight(shell):
    """Both epicyclic arms damped (lambda_F, lambda_S < 0) and Sg > 1 at every state of the
    818 m/s QE 15 deg and 360 m/s QE 7 deg flights."""
    for v0, qe in ((818.0, 15.0), (360.0, 7.0)):
        r = simulate_6dof(shell, v0, qe, dt=1.0)
        atm = Atmosphere()
        for i in range(len(r.t)):
            rho = float(atm.at_height(r.position[i, 2]).density)
            lt = linear_theory(shell, r.speed[i], r.spin[i], rho, r.mach[i])
            assert lt.stable, (v0, qe, r.t[i], lt)


def test_initial_yaw_damps(shell):
    """A muzzle disturbance (transverse rate 3 rad/s -> ~3 deg first maximum) damps out.

    The epicyclic amplitude is measured as the angle between the axis of the disturbed flight
    and that of the same flight without disturbance (this removes the slowly growing yaw of
    repose). Windows of 1 s: each holds ~20 fast-arm cycles (period ~50 ms) and 1.5-2 slow-arm
    cycles (period ~0.4-0.6 s). Over 0-5 s the 818 m/s QE 15 deg flight stays supersonic
    (Mach > 1.5), where linear theory (McCoy ch. 10) gives both arms damped, the fast one at
    ~1 /s and the slow one at ~0.6-0.7 /s. The envelope must fall monotonically and its decay
    from the first to the fifth window must lie between the fast-arm and slow-arm predictions
    (with a factor 1.5 of slack each way for the envelope-of-two-arms approximation).
    """
    t = np.arange(0.0, 5.0, 0.002)
    r = simulate_6dof(shell, 818.0, 15.0, initial_yaw_rate=3.0, t_out=t)
    r0 = simulate_6dof(shell, 818.0, 15.0, t_out=t)
    assert r.success and r0.success
    amp = np.degrees(np.linalg.norm(r.axis - r0.axis, axis=1))    # small-angle, deg
    env = np.array([amp[(t >= k) & (t < k + 1)].max() for k in range(5)])
    assert 2.0 < env[0] < 5.0                # a few degrees, as intended
    assert np.all(np.diff(env) < 0), env     # monotone decay
    assert env[4] < 0.15 * env[0]
    assert r.mach.min() > 1.5                # still supersonic in the window
    # linear-theory damping integrated over window centres 0.5 .. 3.5 s (to 4.5 s)
    atm = Atmosphere()
    lam_f, lam_s = [], []
    for k in range(4):
        i = np.searchsorted(t, k + 0.5)
        rho = float(atm.at_height(r0.position[i, 2]).density)
        lt = linear_theory(shell, r0.speed[i], r0.spin[i], rho, r0.mach[i])
        assert lt.stable, lt
        lam_f.append(lt.fast_damping)
        lam_s.append(lt.slow_damping)
    fast_ratio, slow_ratio = math.exp(sum(lam_f)), math.exp(sum(lam_s))
    ratio = env[4] / env[0]
    assert fast_ratio / 1.5 < ratio < slow_ratio * 1.5, (ratio, fast_ratio, slow_ratio)


def test_right_hand_spin_drifts_right(shell):
    """Right-hand spin -> yaw of repose nose-right -> lift to the right: y > 0 at impact.

    Plausible size: 155 mm firing tables give drifts of a few mils at low quadrant elevation,
    i.e. 0.1-1 % of range, growing with elevation; we accept 0.1-3 % at QE 7 and 15 deg.
    A left-hand spin must mirror the drift.
    """
    for qe in (7.0, 15.0):
        r = simulate_6dof(shell, 818.0, qe)
        assert r.success, r.message
        assert r.impact_drift > 0.0
        frac = r.impact_drift / r.impact_range
        assert DRIFT_FRACTION_MIN < frac < DRIFT_FRACTION_MAX, frac
    left = simulate_6dof(shell, 818.0, 15.0, spin_rate=-2 * math.pi * 818.0 / (20 * 0.155))
    assert left.impact_drift == pytest.approx(-r.impact_drift, rel=1e-3)
    assert left.impact_range == pytest.approx(r.impact_range, rel=1e-6)


def test_drift_matches_yaw_of_repose_theory(shell):
    """The 6-DOF drift agrees with McCoy's modified-point-mass estimate (lift on the yaw of
    repose alpha_R = 2 Ix p g cos(theta) / (rho S d C_M_alpha V^3)) to within 5 % (observed
    < 1 %); the rest is Magnus and pitch-damping cross terms the MPM estimate leaves out."""
    r = simulate_6dof(shell, 818.0, 15.0)
    mpm = point_mass(shell, 818.0, 15.0, mpm_drift=True)
    y_mpm = mpm.y_events[0][0][1]
    assert r.impact_drift == pytest.approx(y_mpm, rel=DRIFT_VS_MPM_REL)


@pytest.mark.parametrize("v0, qe", [(818.0, 7.0), (818.0, 15.0), (360.0, 7.0)])
def test_range_close_to_point_mass(shell, v0, qe):
    """Full 6-DOF range within 3 % of the point mass with the same Cd0(M)."""
    r = simulate_6dof(shell, v0, qe)
    pm = point_mass(shell, v0, qe)
    x_pm = pm.y_events[0][0][0]
    assert r.success, r.message
    assert abs(r.impact_range - x_pm) / x_pm < RANGE_VS_POINT_MASS_REL
    assert r.impact_time == pytest.approx(pm.t_events[0][0], rel=RANGE_VS_POINT_MASS_REL)


def test_decoupled_6dof_equals_point_mass(shell):
    """With yaw drag, lift and Magnus force switched off the translation no longer depends on
    the attitude: the 6-DOF centre of mass must follow the point mass to integrator accuracy."""
    aero = shell.aero.scaled(cd_delta2=0.0, cl_alpha=0.0, cnpa_force=0.0)
    sh = Shell(shell.mass, shell.diameter, shell.Ix, shell.Iy, aero, shell.cd0)
    r = simulate_6dof(sh, 818.0, 15.0, initial_yaw_rate=2.0)
    pm = point_mass(sh, 818.0, 15.0)
    s = pm.sol(r.t[:-1])
    assert np.max(np.abs(r.position[:-1] - s[0:3].T)) < DECOUPLED_POS_TOL_M
    assert np.max(np.abs(r.speed[:-1] - np.linalg.norm(s[3:6], axis=0))) < DECOUPLED_SPEED_TOL_MS
    assert r.impact_range == pytest.approx(pm.y_events[0][0][0], abs=DECOUPLED_POS_TOL_M)


def test_tiny_yaw_full_aero_close_to_point_mass(shell):
    """Full aerodynamics, no muzzle disturbance, short low-speed flight (360 m/s, QE 7 deg:
    Mach 1.06 at the muzzle at ICAO sea level, subsonic after ~1 s): the yaw stays below 1 deg and
    the track is the point-mass track to 0.5 % in range and 5 m in height."""
    r = simulate_6dof(shell, 360.0, 7.0, initial_yaw_deg=0.0, initial_yaw_rate=0.0)
    pm = point_mass(shell, 360.0, 7.0)
    assert np.degrees(r.yaw.max()) < 1.0
    assert abs(r.impact_range - pm.y_events[0][0][0]) / pm.y_events[0][0][0] < TINY_YAW_RANGE_REL
    s = pm.sol(r.t[:-1])
    assert np.max(np.abs(r.position[:-1, 2] - s[2])) < 5.0


def test_output_sampling_and_frame(shell):
    dt = 0.027
    r = simulate_6dof(shell, 360.0, 7.0, dt=dt)
    assert r.t[0] == 0.0 and np.allclose(np.diff(r.t[:-1]), dt)
    assert 0.0 < r.t[-1] - r.t[-2] <= dt + 1e-12        # last sample is the impact point
    assert r.t[-1] == r.impact_time and abs(r.position[-1, 2]) < 1e-6
    assert np.allclose(r.position[0], 0.0)
    assert r.velocity[0] == pytest.approx([360 * math.cos(math.radians(7)), 0.0,
                                           360 * math.sin(math.radians(7))])
    assert r.speed == pytest.approx(np.linalg.norm(r.velocity, axis=1))
    assert np.allclose(np.linalg.norm(r.axis, axis=1), 1.0)
    # requested times beyond impact are dropped and reported
    r2 = simulate_6dof(shell, 360.0, 7.0, t_out=np.arange(0.0, 20.0, 0.5))
    assert r2.t[-1] <= r.impact_time and "dropped" in r2.message


def test_wind_pushes_along_wind(shell):
    """A crosswind toward +y (the gun frame) moves the impact toward +y; a tailwind lengthens
    the range."""
    calm = simulate_6dof(shell, 360.0, 7.0)
    cross = simulate_6dof(shell, 360.0, 7.0, wind=(0.0, 10.0, 0.0))
    tail = simulate_6dof(shell, 360.0, 7.0, wind=(10.0, 0.0, 0.0))
    assert cross.impact_drift > calm.impact_drift + 1.0
    assert tail.impact_range > calm.impact_range + 1.0


def test_azimuth_from_north_does_not_rotate_frame(shell):
    """x is along the firing azimuth by definition (the contract (docs/formats.md)); flat, non-rotating Earth."""
    a = simulate_6dof(shell, 360.0, 7.0)
    b = simulate_6dof(shell, 360.0, 7.0, azimuth_deg=90.0)
    assert np.array_equal(a.position, b.position)


def test_m107_aero_signs():
    a = m107_aero()
    assert all(v > 0 for v in a.cm_alpha)      # statically unstable shell
    assert all(v < 0 for v in a.cmq_cmad)      # pitch damping
    assert all(v < 0 for v in a.clp)           # spin damping
    assert "McCoy" in a.source


def test_initial_yaw_angle(shell):
    """``initial_yaw_deg`` tilts the axis above the velocity by that angle; it damps like the
    rate disturbance (818 m/s, QE 15 deg: < 0.5 deg total yaw, repose included, after 4 s)."""
    t = np.arange(0.0, 5.0, 0.002)
    r = simulate_6dof(shell, 818.0, 15.0, initial_yaw_deg=3.0, t_out=t)
    assert np.degrees(r.yaw[0]) == pytest.approx(3.0, abs=1e-9)
    assert r.axis[0, 2] > r.velocity[0, 2] / r.speed[0]      # nose above the velocity
    assert np.degrees(r.yaw[t >= 4.0].max()) < 0.5
    assert "last output time" in r.message and np.isnan(r.impact_time)


@pytest.mark.parametrize("kw", [dict(velocity=-1.0), dict(elevation_deg=95.0), dict(dt=0.0),
                                dict(wind=(1.0, 2.0)), dict(t_out=[0.0, 1.0, 0.5])])
def test_bad_input_is_rejected(shell, kw):
    args = dict(velocity=818.0, elevation_deg=15.0)
    args.update(kw)
    with pytest.raises(ValueError):
        simulate_6dof(shell, **args)
