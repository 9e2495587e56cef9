"""Each effect moves the trajectory the way physics says (issue 6, item 1)."""
import numpy as np
import pytest

from bayesdrag.air.atmosphere import Atmosphere
from bayesdrag.io.drag_tables import load_m101
from bayesdrag.dynamics.pointmass import PointMassModel
from bayesdrag.dynamics.trajectory import initial_state
from bayesdrag.effects import (DRAG_SHAPE_MAX, EFFECTS, K_YAW, EffectContext, ShapedTable, drag_shape_knots,
                               drag_shape_model, get_effect, level_free_offsets, simulate_with_effects)
from bayesdrag.air.wind import WindProfile
from bayesdrag.effects.wind_layers import WIND_LAYERS_MAX, WindLayers

V0, EL = 818.0, 30.0
T = np.linspace(0.0, 40.0, 401)
#: a deflection smaller than this [m] counts as "no change" (kernel rounding is ~1e-6 m)
TINY_M = 1e-3
#: Mach span the 818 m/s, 30 deg flight of T covers (for drag_shape's knots)
SPAN = (0.85, 2.45)


@pytest.fixture(scope="module")
def model():
    return PointMassModel(42.6, 0.155, load_m101(), Atmosphere())


LAYERS = WindLayers("altitude", (0.0, 2000.0, 4000.0, 8000.0))


def _ctx(**kw):
    """The effect context of the test flight (drag_shape needs the table's shaped drag,
    wind_profile its layers)."""
    kw.setdefault("wind_layers", LAYERS)
    return EffectContext(v0=V0, drag_shape=drag_shape_model(load_m101(), SPAN), **kw)


def _run(model, effects=(), values=(), ctx=None):
    st, _ = simulate_with_effects(model, (), initial_state(V0, EL), T, effects, values, ctx or _ctx())
    return st


def test_library_has_the_design_names_and_parameters():
    assert set(EFFECTS) >= {"wind", "temperature", "density", "coriolis", "yaw_drag", "lift",
                            "radar_time", "drag_scale", "drag_shape"}
    assert [p.name for p in EFFECTS["drag_shape"].params] == [f"s{i + 1}" for i in range(DRAG_SHAPE_MAX)]
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
    from bayesdrag.estimate.model.problem import OutputErrorProblem
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


# --- drag_shape: the table times a smooth correction without a level ---------------------------
#: relative tolerance of a Mach mean computed on 801 points
MEAN_TOL = 1e-3


def test_drag_shape_knots_are_denser_where_the_table_rises():
    knots = drag_shape_knots(load_m101(), 0.7, 2.4)
    assert knots[0] <= 0.7 and knots[-1] >= 2.4 and len(knots) - 1 <= DRAG_SHAPE_MAX - 2
    width = np.diff(knots)
    mid = 0.5 * (knots[:-1] + knots[1:])
    # the M101 rise (Mach 0.9-1.05) gets the narrowest intervals
    assert width[np.argmin(np.abs(mid - 1.0))] < 0.5 * width.max()
    with pytest.raises(ValueError, match="mach_max > mach_min"):
        drag_shape_knots(load_m101(), 1.2, 1.2)


def test_drag_shape_correction_has_no_level_and_changes_drag_where_it_is_put(model):
    shape = drag_shape_model(load_m101(), SPAN)
    K = shape.n_shape
    m = np.linspace(shape.knots[0], shape.knots[-1], 801)
    for k in range(K):  # every shape function has zero Mach mean (default offsets)
        c = np.zeros(K)
        c[k] = 1.0
        assert abs(np.mean(shape.correction(c, m))) < MEAN_TOL
    base = _run(model)
    # coefficients beyond the span's count are unused: all zero is the table itself
    assert np.max(np.abs(_run(model, ["drag_shape"], np.zeros(DRAG_SHAPE_MAX)) - base)) < TINY_M
    # +10 % carried by the top three B-splines: more drag at high Mach (the first part of the
    # flight), less at low Mach (the zero mean), a shorter range
    up = np.zeros(DRAG_SHAPE_MAX)
    up[K - 3:K] = 0.1
    table = load_m101().value(np.array([1.0, 2.3]))
    cd = shape.cd(np.r_[1.0, up[:K]], np.array([1.0, 2.3]))
    assert cd[1] > table[1] * 1.05 and cd[0] < table[0]
    assert _run(model, ["drag_shape"], up)[-1, 0] < base[-1, 0] - 10.0
    with pytest.raises(ValueError, match="reference drag table"):
        _run(model, ["drag_shape"], up, EffectContext(v0=V0))


def test_level_free_offsets_make_the_shape_orthogonal_to_a_constant_factor():
    """Synthetic sensitivities: after the offsets each shape column is orthogonal to the level
    column once the nuisance columns are projected out."""
    rng = np.random.default_rng(3)
    shape = drag_shape_model(load_m101(), SPAN)
    K = shape.n_shape
    S = rng.standard_normal((200, K + 1))
    A = rng.standard_normal((200, 3))
    off = level_free_offsets(shape, S, A)
    # moving the offsets by b subtracts b times the level column from each shape column
    S2 = S.copy()
    S2[:, 1:] -= np.outer(S[:, 0], off - np.asarray(shape.offsets))
    Q, _ = np.linalg.qr(A)
    P = S2 - Q @ (Q.T @ S2)
    assert np.max(np.abs(P[:, 1:].T @ P[:, 0])) < 1e-9 * np.linalg.norm(P[:, 0]) ** 2
    with pytest.raises(ValueError, match="offsets must be"):
        ShapedTable(load_m101(), shape.knots, offsets=(0.1,))


def test_wind_profile_flies_its_layers_as_a_wind_profile_of_the_atmosphere(model):
    """The effect's layer winds (wx_1, wy_1, wx_2, ...) are a layered WindProfile added to the
    round's own wind, by height or by downrange distance; unused layers are ignored."""
    vals = np.zeros(2 * WIND_LAYERS_MAX)
    vals[:6] = [4.0, -1.0, -3.0, 2.0, -9.0, 5.0]
    assert [p.name for p in EFFECTS["wind_profile"].params][:4] == ["wx_1", "wy_1", "wx_2", "wy_2"]
    got = _run(model, ["wind_profile"], vals)
    want = WindProfile.layered("altitude", LAYERS.edges, (4.0, -3.0, -9.0), (-1.0, 2.0, 5.0))
    st, _ = simulate_with_effects(model.with_(atmosphere=Atmosphere(wind=want)), (), initial_state(V0, EL), T)
    assert np.max(np.abs(got - st)) < TINY_M
    base = WindProfile("downrange", (0.0, 20000.0), (1.0, 1.0), (0.0, 2.0))
    by_x = WindLayers("downrange", (0.0, 6000.0, 12000.0, 18000.0), base=base)
    got = _run(model, ["wind_profile"], vals, _ctx(wind_layers=by_x))
    want = WindProfile.layered("downrange", by_x.edges, (4.0, -3.0, -9.0), (-1.0, 2.0, 5.0)).plus(base)
    st, _ = simulate_with_effects(model.with_(atmosphere=Atmosphere(wind=want)), (), initial_state(V0, EL), T)
    assert np.max(np.abs(got - st)) < TINY_M and np.max(np.abs(got - _run(model))) > 10.0
    with pytest.raises(ValueError, match="needs its layers"):
        _run(model, ["wind_profile"], vals, _ctx(wind_layers=None))
    with pytest.raises(ValueError, match="the base wind is by altitude, the layers by downrange"):
        WindLayers("downrange", (0.0, 1.0), base=WindProfile("altitude", (0.0,), (1.0,), (0.0,)))
