"""The session's flat-fire integrator against scipy's DOP853, and what the chronograph reports."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from bayesdrag.dynamics.flat_fire import G_STANDARD, fly
from bayesdrag.measure.chronograph import offset_term, reported_speed

#: agreement with a tight-tolerance reference over a 0.15 s flight [m] and [m/s]
POSITION_TOL_M = 1e-6
SPEED_TOL_MPS = 1e-5


def _reference(v0, el, k_air, c, mach, cd, t):
    def rhs(_, s):
        u = math.hypot(s[2], s[3])
        k = k_air * np.interp(u / c, mach, cd) * u
        return [s[2], s[3], -k * s[2], -k * s[3] - G_STANDARD]

    sol = solve_ivp(rhs, (0, t[-1] + 0.01), [0, 0, v0 * math.cos(el), v0 * math.sin(el)], method="DOP853",
                    rtol=1e-12, atol=1e-11, dense_output=True)
    return sol.sol(t)


@pytest.mark.parametrize("v0, el", [(960.0, 0.0), (330.0, 0.01), (760.0, -0.005)])
def test_flight_matches_a_tight_reference(v0, el):
    mach = np.arange(0.5, 3.5, 5e-4)
    cd = 0.3 + 0.05 * np.sin(3 * mach)
    k_air, c = 1.225 * math.pi * 0.0057 ** 2 / 4 / (2 * 0.00356), 340.294
    t = np.linspace(0.004, 0.15, 60)
    ref = _reference(v0, el, k_air, c, mach, cd, t)
    x, z, vx, vz = fly([v0], [0.0], [1.0], (mach[0], 5e-4, cd), [t], k_air=k_air, sound_speed=c, elevation=el)[0]
    assert np.max(np.abs(x - ref[0])) < POSITION_TOL_M
    assert np.max(np.abs(z - ref[1])) < POSITION_TOL_M
    assert np.max(np.abs(vx - ref[2])) < SPEED_TOL_MPS
    assert np.max(np.abs(vz - ref[3])) < SPEED_TOL_MPS


def test_each_shot_flies_with_its_own_scale_and_time_origin():
    mach = np.arange(1.0, 3.5, 5e-4)
    cd = np.full(mach.size, 0.3)
    t = [np.linspace(0.01, 0.1, 20), np.linspace(0.012, 0.1, 15)]
    both = fly([800.0, 800.0], [0.0, 0.002], [1.0, 1.1], (mach[0], 5e-4, cd), t, k_air=1e-3, sound_speed=340.0)
    alone = fly([800.0], [0.002], [1.1], (mach[0], 5e-4, cd), [t[1]], k_air=1e-3, sound_speed=340.0)
    np.testing.assert_allclose(both[1][2], alone[0][2], rtol=0, atol=1e-12)


def test_a_sample_before_the_time_origin_is_refused():
    mach = np.arange(1.0, 3.5, 5e-4)
    with pytest.raises(ValueError, match="before its shot's time origin"):
        fly([800.0], [0.01], [1.0], (mach[0], 5e-4, np.full(mach.size, 0.3)), [np.array([0.005, 0.02])],
            k_air=1e-3, sound_speed=340.0)


def test_the_device_reports_the_offset_only_through_q():
    """A device at (x_d, y_d, z_d) with offset d typed reports radial speed * R / sqrt(R^2 - d^2)."""
    rng = np.random.default_rng(3)
    x, z = rng.uniform(5, 100, 50), rng.uniform(-0.2, 0.1, 50)
    vx, vz = rng.uniform(300, 900, 50), rng.uniform(-2, 2, 50)
    for site, typed in [((0.2, 0.6, -0.05), 0.5), ((-0.3, 1.0, 0.0), 1.0), ((0.0, 0.4, 0.1), None)]:
        dx, dy, dz = x - site[0], -site[1], z - site[2]
        R = np.sqrt(dx * dx + dy * dy + dz * dz)
        radial = (dx * vx + dz * vz) / R
        d = typed or 0.0
        expect = radial * R / np.sqrt(R * R - d * d)
        got = reported_speed(x, z, vx, vz, offset_term(site[1], typed), site[0], site[2])
        np.testing.assert_allclose(got, expect, rtol=1e-12)
