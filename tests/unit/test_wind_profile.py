"""Winds that change along the flight (issue 29): :class:`WindProfile` by height or by downrange
distance, flown by the point-mass kernel and its scipy reference alike."""
import numpy as np
import pytest

from bayesdrag.air.atmosphere import Atmosphere, MetProfile
from bayesdrag.air.wind import WIND_STEP_WIDTH, WindProfile
from bayesdrag.dynamics import kernel as K
from bayesdrag.dynamics.pointmass import PointMassModel, wind_tables
from bayesdrag.dynamics.trajectory import initial_state
from bayesdrag.io.drag_tables import load_m101

#: kernel against the scipy reference over a 155 mm flight in a wind profile [m] (1e-4 m without
#: one; steps spread over 100 m measured 1.3e-3 m, linear profiles 2e-4 m)
KERNEL_VS_SCIPY_M = 5e-3
T_OUT = np.arange(0.0, 60.0, 0.05)

BY_HEIGHT = WindProfile("altitude", (0.0, 1000.0, 3000.0, 6000.0), (-2.0, -6.0, -12.0, -18.0), (1.0, 3.0, 6.0, 4.0))
LAYERS = WindProfile.layered("altitude", (0.0, 1500.0, 4000.0, 8000.0), (5.0, -3.0, -10.0), (2.0, 0.0, -4.0))
BY_RANGE = WindProfile.layered("downrange", (0.0, 5000.0, 20000.0), (-3.0, -9.0), (0.0, 4.0))


def test_layers_hold_their_wind_and_steps_are_spread_over_the_step_width():
    w = WindProfile.layered("altitude", (0.0, 1000.0, 3000.0), (2.0, -4.0), (0.0, 1.0))
    half = WIND_STEP_WIDTH / 2
    np.testing.assert_allclose(w.at([-50.0, 500.0, 1000.0 - half, 1000.0 + half, 2000.0, 9000.0]),
                               [[2, 0], [2, 0], [2, 0], [-4, 1], [-4, 1], [-4, 1]])
    np.testing.assert_allclose(w.at(1000.0), [-1.0, 0.5])  # halfway at the level
    s = np.linspace(-100.0, 3100.0, 777)
    np.testing.assert_allclose(w.at(s), [w.at_scalar(v) for v in s], rtol=0, atol=1e-12)
    # C1: no jump in the wind or its slope across the step
    d = np.diff(w.at(np.linspace(900.0, 1100.0, 2001))[:, 0])
    assert np.max(np.abs(np.diff(d))) < 1e-4
    assert w.n_layers == 2 and w == WindProfile.layered("altitude", (0.0, 1000.0, 3000.0), (2.0, -4.0), (0.0, 1.0))


def test_profiles_add_along_one_axis():
    c = WindProfile("altitude", (0.0, 4000.0), (1.0, 5.0), (0.0, 0.0))
    s = np.linspace(-10.0, 5000.0, 301)
    far = np.min(np.abs(s[:, None] - np.array([1500.0, 4000.0])[None, :]), axis=1) > WIND_STEP_WIDTH / 2
    np.testing.assert_allclose(LAYERS.plus(c).at(s[far]), LAYERS.at(s[far]) + c.at(s[far]), atol=1e-12)
    # inside a step's width the sum's step blends c's kink at 4000 m too: within slope x width
    np.testing.assert_allclose(LAYERS.plus(c).at(s), LAYERS.at(s) + c.at(s), atol=1e-3 * WIND_STEP_WIDTH)
    with pytest.raises(ValueError, match="cannot add a wind by downrange to a wind by altitude"):
        LAYERS.plus(BY_RANGE)


@pytest.mark.parametrize("kw, match", [
    (dict(axis="height", levels=(0.0,), wind_x=(1.0,), wind_y=(0.0,)), "axis 'height' is not allowed"),
    (dict(axis="altitude", levels=(0.0, 10.0), wind_x=(1.0,), wind_y=(0.0, 0.0)), "one wind_x and wind_y per level"),
    (dict(axis="altitude", levels=(10.0, 0.0), wind_x=(1.0, 1.0), wind_y=(0.0, 0.0)), "below the previous level"),
    (dict(axis="altitude", levels=(0.0, 0.0, 5.0), wind_x=(1.0,) * 3, wind_y=(0.0,) * 3), "repeats more than once or at an end"),
    (dict(axis="downrange", levels=(0.0, 10.0), wind_x=(1.0, 200.0), wind_y=(0.0, 0.0)), "exceeds the plausible"),
])
def test_bad_wind_profiles_are_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        WindProfile(**kw)


@pytest.mark.parametrize("wind", [BY_HEIGHT, LAYERS, BY_RANGE], ids=["linear-by-height", "layers-by-height",
                                                                     "layers-by-downrange"])
def test_kernel_flies_the_profile_as_the_scipy_reference_does(wind):
    m101 = load_m101()
    s0 = initial_state(818.0, 35.0)
    m = PointMassModel(42.6, 0.155, m101, Atmosphere(wind=wind))
    ref = m.simulate((), s0, T_OUT, backend="scipy")
    ker = m.simulate((), s0, T_OUT)
    still = PointMassModel(42.6, 0.155, m101).simulate((), s0, T_OUT)
    assert np.abs(ker.state[:, :3] - ref.state[:, :3]).max() < KERNEL_VS_SCIPY_M
    assert np.abs(still.state[:, :3] - ref.state[:, :3]).max() > 100.0  # the wind moves the shell
    np.testing.assert_allclose(ker.mach, ref.mach, atol=1e-4)


def test_a_batch_flies_each_trajectorys_own_profile_and_the_constant_wind_adds():
    m = PointMassModel(42.6, 0.155, load_m101(), wind=(1.5, -2.0, 0.0))
    s0 = np.stack([initial_state(818.0, 35.0)] * 3)
    winds = [LAYERS, None, BY_HEIGHT]
    batch = m.simulate_batch(np.zeros((3, 0)), s0, T_OUT, winds=winds)
    for i, w in enumerate(winds):
        one = m.with_(atmosphere=Atmosphere(wind=w)).simulate((), s0[i], T_OUT)
        np.testing.assert_array_equal(batch.state[i], one.state)
    shifted = PointMassModel(42.6, 0.155, load_m101(), Atmosphere(wind=LAYERS.plus(
        WindProfile("altitude", (0.0,), (1.5,), (-2.0,))))).simulate((), s0[0], T_OUT, backend="scipy")
    assert np.abs(batch.state[0, :, :3] - shifted.state[:, :3]).max() < KERNEL_VS_SCIPY_M
    with pytest.raises(ValueError, match="one batch cannot fly winds by altitude and by downrange"):
        m.simulate_batch(np.zeros((2, 0)), s0[:2], T_OUT, winds=[LAYERS, BY_RANGE])


def test_wind_tables_share_one_grid_and_mark_the_axis():
    par = np.zeros((3, K.N_PAR))
    tabs, idx, w0, dw = wind_tables([LAYERS, None, LAYERS], 250.0, par)
    assert tabs.shape[0] == 2 and list(idx) == [1, 0, 1] and w0 == -250.0
    np.testing.assert_array_equal(tabs[0], 0.0)
    assert par[0, K.P_WIND_AX_Z] == 1.0 and par[1, K.P_WIND_AX_Z] == 0.0 and par[0, K.P_WIND_AX_X] == 0.0
    z = w0 + dw * np.arange(tabs.shape[1])
    np.testing.assert_allclose(tabs[1], LAYERS.at(z + 250.0))
    assert wind_tables([None, None], 0.0, np.zeros((2, K.N_PAR)))[0] is None


def test_a_met_profiles_winds_are_flown_by_height_above_sea_level():
    """A profile's altitudes are above sea level, trajectory heights above the gun: a gun at
    300 m meets the 1000 m level's wind 700 m up, in the kernel and in the scipy reference."""
    lev = (300.0, 1000.0, 2500.0)
    T, p = (286.2, 281.6, 271.9), (97773.0, 89875.0, 74682.0)
    prof = MetProfile(lev, T, p, wind_x=(0.0, -8.0, -8.0), wind_y=(0.0, 0.0, 0.0), gun_altitude=300.0)
    par = np.zeros((1, K.N_PAR))
    tabs, _, w0, dw = wind_tables([prof.wind], prof.gun_altitude, par)
    j = int(round((700.0 - w0) / dw))
    assert w0 + j * dw == pytest.approx(700.0) and tabs[1, j, 0] == pytest.approx(-8.0)
    m = PointMassModel(42.6, 0.155, load_m101(), prof)
    state = np.array([0.0, 0.0, 700.0, 300.0, 0.0, 0.0])
    a = prof.at_height(700.0).speed_of_sound
    assert m.mach_of(state) == pytest.approx(308.0 / a, rel=1e-12)


def test_the_6dof_flies_the_atmospheres_wind_profile():
    """A one-level profile is a constant wind: the 6-DOF flies it exactly as its ``wind=``
    argument (track frame, y right), and a wind by height moves the drift."""
    from bayesdrag.dynamics import shell as shells, sixdof

    sh = shells.table1_shell()
    t = np.arange(0.0, 20.0, 0.5)
    const = sixdof.simulate_6dof(sh, 818.0, 30.0, t_out=t, wind=(3.0, -4.0, 0.0))
    prof = sixdof.simulate_6dof(sh, 818.0, 30.0, t_out=t, atmosphere=Atmosphere(
        wind=WindProfile("altitude", (0.0,), (3.0,), (-4.0,))))
    np.testing.assert_allclose(prof.position, const.position, atol=1e-6)
    layered = sixdof.simulate_6dof(sh, 818.0, 30.0, t_out=t, atmosphere=Atmosphere(wind=LAYERS))
    still = sixdof.simulate_6dof(sh, 818.0, 30.0, t_out=t)
    assert abs(layered.position[-1, 1] - still.position[-1, 1]) > 5.0


@pytest.mark.parametrize("k", [1, 2, 4, 7])
def test_layered_profiles_equal_the_ones_the_constructor_checks(k):
    # the layered constructor skips the checks it cannot fail and memoises the steps' geometry:
    # the profile must be the constructor's, to the last bit, winds and smoothed steps alike
    rng = np.random.default_rng(k)
    edges = np.cumsum(rng.uniform(20.0, 3000.0, k + 1))
    wx, wy = rng.normal(0.0, 8.0, k), rng.normal(0.0, 8.0, k)
    wy[0] = -0.0
    fast = WindProfile.layered("downrange", edges, wx, wy)
    slow = WindProfile("downrange", tuple(np.repeat(edges, 2)[1:-1]), tuple(np.repeat(wx, 2)), tuple(np.repeat(wy, 2)))
    assert fast == slow and hash(fast) == hash(slow)
    s = np.linspace(edges[0] - 200.0, edges[-1] + 200.0, 2001)
    np.testing.assert_array_equal(fast.at(s), slow.at(s))
    assert [fast.at_scalar(v) for v in s[::50]] == [slow.at_scalar(v) for v in s[::50]]


@pytest.mark.parametrize("wx, match", [((200.0, 1.0), "wind_x = 200 m/s .* exceeds"),
                                       ((float("nan"), 1.0), "wind_x")])
def test_layered_profiles_refuse_implausible_winds_as_the_constructor_does(wx, match):
    with pytest.raises(ValueError, match=match):
        WindProfile.layered("altitude", (0.0, 1000.0, 2000.0), wx, (0.0, 0.0))
