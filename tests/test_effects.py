"""Each effect moves the trajectory the way physics says (issue 6, item 1)."""
import numpy as np
import pytest

from bayesdrag.atmosphere import Atmosphere
from bayesdrag.io.drag_tables import load_m101
from bayesdrag.dynamics.pointmass import PointMassModel
from bayesdrag.dynamics.trajectory import initial_state
from bayesdrag.effects import EFFECTS, K_YAW, EffectContext, get_effect, simulate_with_effects

V0, EL = 818.0, 30.0
T = np.linspace(0.0, 40.0, 401)
#: a deflection smaller than this [m] counts as "no change" (kernel rounding is ~1e-6 m)
TINY_M = 1e-3


@pytest.fixture(scope="module")
def model():
    return PointMassModel(42.6, 0.155, load_m101(), Atmosphere())


def _run(model, effects=(), values=(), ctx=None):
    st, _ = simulate_with_effects(model, (), initial_state(V0, EL), T, effects, values,
                                  ctx or EffectContext(v0=V0))
    return st


def test_library_has_the_design_names_and_parameters():
    assert set(EFFECTS) >= {"wind", "temperature", "density", "coriolis", "yaw_drag", "lift",
                            "radar_time", "drag_scale"}
    assert [p.name for p in EFFECTS["wind"].params] == ["wx", "wy"]
    assert EFFECTS["coriolis"].k == 0
    for e in EFFECTS.values():
        assert e.explanation and all(p.lower < p.start < p.upper or p.name == "yaw_amp" for p in e.params)
    with pytest.raises(ValueError, match="unknown effect 'fog'"):
        get_effect("fog")


def test_null_values_leave_the_trajectory_unchanged(model):
    base = _run(model)
    for e in EFFECTS.values():
        if e.k and e.name != "radar_time":
            st = _run(model, [e], e.null)
            assert np.max(np.abs(st - base)) < TINY_M, e.name


def test_headwind_shortens_range_and_crosswind_drifts_downwind(model):
    base = _run(model)
    head = _run(model, ["wind"], [-8.0, 0.0])
    cross = _run(model, ["wind"], [0.0, 5.0])
    assert head[-1, 0] < base[-1, 0] - 50.0
    assert cross[-1, 1] > 20.0  # blows toward +y


def test_warm_day_and_thin_air_extend_range(model):
    base = _run(model)
    assert _run(model, ["temperature"], [20.0])[-1, 0] > base[-1, 0] + 50.0
    assert _run(model, ["density"], [0.95])[-1, 0] > base[-1, 0] + 50.0
    assert _run(model, ["drag_scale"], [1.05])[-1, 0] < base[-1, 0] - 50.0


def test_density_and_drag_scale_are_the_same_trajectory(model):
    a = _run(model, ["density"], [1.04])
    b = _run(model, ["drag_scale"], [1.04])
    assert np.max(np.abs(a - b)) < TINY_M


def test_coriolis_deflects_right_in_the_north_and_left_in_the_south(model):
    north = _run(model, ["coriolis"], [], EffectContext(latitude_deg=50.0, azimuth_deg=90.0))
    south = _run(model, ["coriolis"], [], EffectContext(latitude_deg=-50.0, azimuth_deg=90.0))
    assert north[-1, 1] > 1.0 and south[-1, 1] < -1.0
    with pytest.raises(ValueError, match="latitude"):
        _run(model, ["coriolis"], [], EffectContext())


def test_yaw_drag_costs_range_early_and_lift_drifts_right(model):
    base = _run(model)
    yaw = _run(model, ["yaw_drag"], [K_YAW * 0.1**2, 0.3])
    assert yaw[-1, 0] < base[-1, 0] - 10.0
    lift = _run(model, ["lift"], [1.0])
    assert lift[-1, 1] > 10.0 and _run(model, ["lift"], [-1.0])[-1, 1] < -10.0
    assert EFFECTS["yaw_drag"].report_params([K_YAW * 0.1**2, 0.3])["delta0"] == pytest.approx(0.1)


def test_late_radar_clock_shows_the_shell_further_along(model):
    base = _run(model)
    late = _run(model, ["radar_time"], [0.05])
    # recorded time t shows the state at true time t + dt: x ahead by ~ v dt
    assert late[0, 0] == pytest.approx(V0 * np.cos(np.radians(EL)) * 0.05, rel=0.01)
    assert np.all(late[1:, 0] > base[1:, 0])


def test_early_clock_extrapolates_backwards_within_millimetres(model):
    """An early radar clock (dt < 0) puts the first samples before the state at launch; the
    output-error problem extrapolates them to second order. Reference: the exact equations
    integrated backwards with solve_ivp."""
    from scipy.integrate import solve_ivp

    from bayesdrag.effects import EffectContext, effect_fn, extra_params
    from bayesdrag.estimate.problem import OutputErrorProblem
    from bayesdrag.track import RadarTrack

    BACK_TOL_M = 2e-3
    dt = -0.08
    t = np.arange(0.0, 3.0, 0.02)
    s0 = initial_state(V0, EL)
    e = EFFECTS["radar_time"]
    tr = RadarTrack(t, {"x": t * 0 + np.arange(t.size), "z": t * 0 + np.arange(t.size) * 2.0}, {})
    prob = OutputErrorProblem(model, tr, np.concatenate([s0, [dt]]), channels=("x", "z"),
                              extras=extra_params([e]), effect_fn=effect_fn([e], EffectContext()), t_ic=0.0)
    y, _ = prob.predict(np.concatenate([s0, [dt]])[None])
    back = t[t + dt < 0] + dt
    sol = solve_ivp(model._rhs((), 0.0), (0.0, back.min()), s0, method="DOP853", rtol=1e-11, atol=1e-9,
                    dense_output=True)
    ref = sol.sol(back)
    assert np.max(np.abs(y[0, :back.size, 0] - ref[0])) < BACK_TOL_M
    assert np.max(np.abs(y[0, :back.size, 1] - ref[2])) < BACK_TOL_M
