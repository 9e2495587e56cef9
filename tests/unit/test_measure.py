"""The measurement layer (bayesdrag.measure): native radar channels from the state, their
analytic Jacobians against finite differences, the inverse, angle wrapping."""
import math

import numpy as np
import pytest

from bayesdrag.errors import InputError
from bayesdrag.measure import (RadarSite, channel_jacobian, channel_values, gun_frame_track, near_branch, site_of,
                               to_gun_frame, wrap_angle)
from bayesdrag.round import Launch, Projectile, Radar, Round
from bayesdrag.track import ALL_CHANNELS as CHANNELS, RadarTrack

#: relative agreement of the analytic Jacobian with central differences [-]
JAC_REL = 1e-6
#: round-trip error of positions through range/azimuth/elevation and back [m]
ROUND_TRIP_M = 1e-8
#: finite-difference steps [m, m/s]
FD_STEP = 1e-4

SITES = [RadarSite((-40.0, 25.0, 2.0), math.radians(90.0)),
         RadarSite((0.0, 0.0, 0.0), math.radians(355.0), 1.5, 1e-3, -2e-3),
         RadarSite((3000.0, -5000.0, 120.0), math.radians(10.0))]


def _states(rng, n=20):
    pos = np.column_stack([rng.uniform(50, 20000, n), rng.uniform(-800, 800, n), rng.uniform(1, 8000, n)])
    vel = np.column_stack([rng.uniform(200, 800, n), rng.uniform(-20, 20, n), rng.uniform(-300, 500, n)])
    return np.concatenate([pos, vel], axis=1)


@pytest.mark.parametrize("site", SITES)
def test_jacobian_matches_finite_differences(site):
    st = _states(np.random.default_rng(1))
    J = channel_jacobian(st, CHANNELS, site)
    assert J.shape == (st.shape[0], len(CHANNELS), 6)
    for k in range(6):
        sp, sm = st.copy(), st.copy()
        sp[:, k] += FD_STEP
        sm[:, k] -= FD_STEP
        yp, ym = channel_values(sp, CHANNELS, site), channel_values(sm, CHANNELS, site)
        diff = yp - ym
        az = CHANNELS.index("azimuth")
        diff[:, az] = wrap_angle(diff[:, az])
        fd = diff / (2 * FD_STEP)
        scale = np.maximum(np.abs(J[:, :, k]), np.max(np.abs(J), axis=2))
        assert np.all(np.abs(fd - J[:, :, k]) <= JAC_REL * scale + 1e-12), k


@pytest.mark.parametrize("site", SITES)
def test_inverse_round_trip(site):
    st = _states(np.random.default_rng(2))
    y = channel_values(st, ("range", "azimuth", "elevation"), site)
    pos = to_gun_frame(y[:, 0], y[:, 1], y[:, 2], site)
    assert np.max(np.abs(pos - st[:, :3])) < ROUND_TRIP_M


def test_channel_definitions():
    """A shell 1 km due east of a radar at the muzzle, firing azimuth 90 deg (east), climbing
    at 45 deg: range 1 km, azimuth 90 deg, elevation 0, range rate the downrange speed."""
    site = RadarSite((0, 0, 0), math.radians(90.0))
    st = np.array([1000.0, 0.0, 0.0, 300.0, 0.0, 300.0])
    r, az, el, rr, v = channel_values(st, ("range", "azimuth", "elevation", "range_rate", "v"), site)
    assert r == pytest.approx(1000.0)
    assert math.degrees(az) == pytest.approx(90.0)
    assert el == pytest.approx(0.0)
    assert rr == pytest.approx(300.0)
    assert v == pytest.approx(300.0 * math.sqrt(2))
    # +y (right of downrange) is clockwise: a shell to the right of an east-firing gun is south of east
    az_right = channel_values(np.array([1000.0, 1000.0, 0, 0, 0, 0]), ("azimuth",), site)[0]
    assert math.degrees(az_right) == pytest.approx(135.0)


def test_biases_are_added():
    site0 = RadarSite((-40.0, 25.0, 2.0), 1.0)
    site1 = RadarSite((-40.0, 25.0, 2.0), 1.0, 2.0, 1e-3, -1e-3)
    st = _states(np.random.default_rng(3), 5)
    d = channel_values(st, ("range", "azimuth", "elevation"), site1) - \
        channel_values(st, ("range", "azimuth", "elevation"), site0)
    assert np.allclose(d, [2.0, 1e-3, -1e-3], atol=1e-12)


def test_azimuth_wraps_across_north():
    """Firing at 359 deg, the shell drifting right crosses north: azimuths stay in [0, 2 pi)
    and residuals against the near branch are small."""
    site = RadarSite((0, 0, 0), math.radians(359.0))
    st = np.array([[1000.0, 0.0, 10, 1, 0, 0], [1000.0, 50.0, 10, 1, 0, 0]])
    az = channel_values(st, ("azimuth",), site)[:, 0]
    assert np.all((az >= 0) & (az < 2 * math.pi))
    assert math.degrees(az[1]) < 5.0
    meas = np.array([math.radians(0.1)])
    pred = np.array([math.radians(359.9)])
    assert math.degrees(float((meas - near_branch(pred, meas))[0])) == pytest.approx(0.2)


def test_radar_at_the_shell_takes_the_flight_direction():
    st = np.array([0.0, 0.0, 0.0, 800.0, 0.0, 100.0])
    rr, el = channel_values(st, ("range_rate", "elevation"), RadarSite())
    assert rr == pytest.approx(math.hypot(800.0, 100.0))
    assert el == pytest.approx(math.atan2(100.0, 800.0))


def test_gun_frame_track_inverts_a_native_track():
    site = SITES[0]
    st = _states(np.random.default_rng(4), 8)
    st = st[np.argsort(st[:, 0])]
    y = channel_values(st, ("range", "azimuth", "elevation", "v"), site)
    tr = RadarTrack(np.arange(8.0), {c: y[:, j] for j, c in enumerate(("range", "azimuth", "elevation", "v"))})
    g = gun_frame_track(tr, site)
    assert g.names == ("x", "y", "z", "v")
    assert np.max(np.abs(np.column_stack([g.x, g.y, g.z]) - st[:, :3])) < ROUND_TRIP_M
    assert gun_frame_track(tr.with_channels(("range", "v")), site) is None


def test_site_of_needs_the_azimuth_for_angles(m101):
    rnd = Round(Projectile("p", 42.6, 0.155, m101), Launch(45.0, 818.0), radar=Radar(position=(-40, 25, 2)),
                path="r.toml")
    with pytest.raises(InputError, match=r"r.toml: \[launch\] azimuth is missing.*azimuth"):
        site_of(rnd, ("range", "azimuth"))
    assert site_of(rnd, ("range", "range_rate")).position == (-40.0, 25.0, 2.0)
    rnd2 = Round(Projectile("p", 42.6, 0.155, m101), Launch(45.0, 818.0, azimuth_deg=0.0), path="r.toml")
    assert site_of(rnd2, ("elevation",)).azimuth == 0.0


def test_state_shape_is_checked():
    with pytest.raises(ValueError, match="6 entries"):
        channel_values(np.zeros((3, 4)), ("range",))


def test_problem_outputs_put_the_azimuth_on_the_measured_branch():
    """The output-error problem's predictions of the azimuth lie within pi of the measurement,
    so that its residual (measured minus predicted) is the wrapped angle difference."""
    from bayesdrag.estimate.model.problem import outputs

    site = RadarSite((0.0, 0.0, 0.0), math.radians(359.0))
    st = np.array([[[1000.0, 0.0, 10.0, 800.0, 0.0, 100.0], [1000.0, 40.0, 10.0, 800.0, 0.0, 100.0]]])
    meas = np.array([[math.radians(359.5)], [math.radians(1.0)]])
    y = outputs(st, ("azimuth",), site, meas)
    r = meas[None] - y
    assert np.all(np.abs(r) < math.radians(2.0))
    plain = channel_values(st, ("azimuth",), site)
    assert np.allclose(wrap_angle(y - plain), 0.0, atol=1e-12)


def test_a_batch_of_gun_frame_channels_is_each_trajectorys_own_to_the_bit():
    # a batch (B, N, 6) takes the compiled pass; one trajectory (N, 6) the numpy expressions:
    # the same numbers, a diverged trial state's inf and NaN included
    rng = np.random.default_rng(11)
    state = rng.normal(0.0, 400.0, (5, 300, 6))
    state[1, 7, 4] = np.inf
    state[2, 9, 0] = np.nan
    chans = ("v", "z", "x", "y")
    batch = channel_values(state, chans)
    one = np.stack([channel_values(s, chans) for s in state])
    assert batch.shape == (5, 300, 4)
    np.testing.assert_array_equal(batch, one)
