"""Point-mass model: fast kernel vs scipy reference, physics of wind and Coriolis, batch
consistency, and an independent cross-check against py-ballisticcalc 3.x."""
import numpy as np
import pytest

from bayesdrag.air.atmosphere import Atmosphere
from bayesdrag.drag import make_drag_model
from bayesdrag.dynamics import kernel as K
from bayesdrag.dynamics.forces import LIFT_REF_FRACTION, LIFT_VERTICAL_FRACTION, coriolis_matrix, lift_parameter
from bayesdrag.dynamics.pointmass import PointMassModel
from bayesdrag.dynamics.trajectory import initial_state, output_schedule

KERNEL_VS_SCIPY_M = 1e-3      # m, issue 3: kernel vs solve_ivp over a full 155 mm trajectory
PBC_M = 1.0                   # m, issue 3: vs py-ballisticcalc over the whole flight
MASS, DIAM = 42.6, 0.155      # paper Table 1 shell
LIFT_VS_6DOF_FACTOR = 2.0     # lift factor 1 vs the 6-DOF's drift: same order (generic L = 0.02 V0)


@pytest.fixture(scope="module")
def ref_traj(m101):
    model = PointMassModel(MASS, DIAM, m101)
    return model, model.simulate((), initial_state(818.0, 15.0), backend="scipy",
                                 stop_at_impact=True, dt=0.027)


def test_kernel_matches_scipy_full_flight(ref_traj):
    model, tr = ref_traj
    assert tr.success and tr.t_impact == pytest.approx(32.48, abs=0.05)
    tk = model.simulate((), tr.state[0], tr.t)
    assert np.max(np.abs(tk.state[:, :3] - tr.state[:, :3])) < KERNEL_VS_SCIPY_M
    assert np.max(np.abs(tk.speed - tr.speed)) < KERNEL_VS_SCIPY_M
    assert np.max(np.abs(tk.mach - tr.mach)) < 1e-6


@pytest.mark.parametrize("name", ["poly2", "spline"])
def test_kernel_matches_scipy_with_wind_coriolis_offsets(name, m101):
    drag = make_drag_model(name, mach_range=(0.6, 2.6))
    m = np.linspace(0.6, 2.6, 300)
    theta = drag.fit_curve(m, m101.value(m))[0] if name == "spline" else drag.initial_params(m101)
    model = PointMassModel(MASS, DIAM, drag, Atmosphere(temperature_offset=12.0, gun_altitude=400.0),
                           wind=(-6.0, 4.0, 0.0), coriolis=(50.0, 120.0), yaw_amp=0.05, yaw_decay=0.5)
    tr = model.simulate(theta, initial_state(818.0, 25.0), backend="scipy", stop_at_impact=True, dt=0.05)
    tk = model.simulate(theta, tr.state[0], tr.t)
    assert np.max(np.abs(tk.state[:, :3] - tr.state[:, :3])) < KERNEL_VS_SCIPY_M


def test_late_start_and_irregular_times(ref_traj, rng):
    model, tr = ref_traj
    i0 = 100
    t = np.sort(rng.choice(tr.t[i0:], 300, replace=False))
    t[0] = tr.t[i0]
    tk = model.simulate((), tr.state[i0], t, t_start=tr.t[i0])
    ts = model.simulate((), tr.state[i0], t, t_start=tr.t[i0], backend="scipy")
    assert np.max(np.abs(tk.state - ts.state)) < KERNEL_VS_SCIPY_M


def test_batch_equals_single_runs(m101):
    drag = make_drag_model("reference-scale", reference=m101)
    model = PointMassModel(MASS, DIAM, drag)
    t = np.arange(0, 20, 0.027)
    factors = np.array([[0.9], [1.0], [1.1], [1.0], [1.05]])
    s0 = np.stack([initial_state(800 + 10 * i, 10 + i) for i in range(5)])
    batch = model.simulate_batch(factors, s0, t)
    for i in range(5):
        single = model.simulate(factors[i], s0[i], t)
        assert np.array_equal(batch.state[i], single.state)
    # more drag -> shorter range
    assert batch.state[0, -1, 0] > batch.state[2, -1, 0]


def test_vacuum_parabola():
    """Cd = 0: the analytic parabola, to rounding."""
    model = PointMassModel(MASS, DIAM, make_drag_model("poly2"))
    s0 = initial_state(300.0, 30.0)
    t = np.linspace(0, 20, 101)
    tk = model.simulate([0.0, 0.0, 0.0], s0, t)
    assert np.allclose(tk.state[:, 0], s0[3] * t, atol=1e-9)
    assert np.allclose(tk.state[:, 2], s0[5] * t - 0.5 * 9.80665 * t**2, atol=1e-9)


@pytest.mark.parametrize("lift_factor", [0.0, 1.0])
def test_released_at_rest_falls_and_stays_finite(m101, lift_factor):
    """Zero airspeed at the start (a drop in still air): no 0/0 anywhere, the fall starts like
    free fall (drag ~ V^2 is negligible for the first second) and stays vertical."""
    model = PointMassModel(MASS, DIAM, m101, lift_factor=lift_factor, lift_v0=800.0)
    t = np.linspace(0.0, 1.0, 11)
    for backend in ("kernel", "scipy"):
        tr = model.simulate((), np.zeros(6), t, backend=backend)
        assert np.all(np.isfinite(tr.state)), backend
        assert tr.state[-1, 2] == pytest.approx(-0.5 * 9.80665, rel=1e-3)
        assert np.max(np.abs(tr.state[:, :2])) < 1e-9


def test_headwind_shortens_range_tailwind_lengthens(m101):
    s0 = initial_state(818.0, 15.0)
    ranges = {}
    for name, w in (("head", (-10.0, 0, 0)), ("none", (0, 0, 0)), ("tail", (10.0, 0, 0))):
        tr = PointMassModel(MASS, DIAM, m101, wind=w).simulate((), s0, backend="scipy",
                                                                stop_at_impact=True, dt=0.1)
        ranges[name] = tr.state[-1, 0]
    assert ranges["head"] < ranges["none"] < ranges["tail"]


def test_crosswind_drifts_downwind(m101):
    tr = PointMassModel(MASS, DIAM, m101, wind=(0, 5.0, 0)).simulate(
        (), initial_state(818.0, 15.0), backend="scipy", stop_at_impact=True, dt=0.1)
    assert tr.state[-1, 1] > 10.0


@pytest.mark.parametrize("lat, sign", [(50.0, 1.0), (-50.0, -1.0)])
def test_coriolis_deflects_right_in_north(m101, lat, sign):
    """Northern hemisphere: deflection to the right (y > 0) for any azimuth; southern: left."""
    for az in (0.0, 90.0, 225.0):
        tr = PointMassModel(MASS, DIAM, m101, coriolis=(lat, az)).simulate(
            (), initial_state(818.0, 15.0), backend="scipy", stop_at_impact=True, dt=0.1)
        # order of magnitude: 2 Omega sin(lat) * x * T / 3 ~ 6 m at 14 km, 32 s
        assert sign * tr.state[-1, 1] > 3.0


def test_coriolis_eastward_fire_goes_long():
    """Eotvos effect: firing east, the vertical Coriolis acceleration is upward (+2 Omega cos(lat) vx)."""
    C = coriolis_matrix(0.0, 90.0)
    a = C @ np.array([100.0, 0.0, 0.0])
    assert a[2] == pytest.approx(2 * 7.292115e-5 * 100.0, rel=1e-9)
    C = coriolis_matrix(50.0, 0.0)  # north: a_y = +2 Omega sin(lat) vx
    assert (C @ np.array([100.0, 0, 0]))[1] == pytest.approx(2 * 7.292115e-5 * np.sin(np.radians(50)) * 100, rel=1e-9)


def test_output_schedule_places_outputs_in_uniform_steps(rng):
    t = np.sort(rng.uniform(0.5, 40.0, 200))
    h, n, step, theta = output_schedule(t, 0.5, 0.07)
    assert h <= 0.07 and n * h == pytest.approx(t[-1] - 0.5, rel=1e-12)
    assert np.all(np.diff(step) >= 0) and step.max() == n - 1
    assert np.all((theta >= 0.0) & (theta <= 1.0))
    assert np.allclose(0.5 + (step + theta) * h, t, rtol=0, atol=1e-12)
    # an output only at the initial state: zero-length step, the initial state comes back
    assert output_schedule(np.array([2.0]), 2.0, 0.1)[:2] == (0.0, 1)


def test_output_at_initial_state_only(m101):
    model = PointMassModel(MASS, DIAM, m101)
    s0 = initial_state(818.0, 15.0)
    tr = model.simulate((), s0, [3.0], t_start=3.0)
    assert np.array_equal(tr.state[0], s0)


def test_default_step_scales_with_drag_time(m101):
    """The default step (a fixed fraction of the drag time scale) keeps a rifle bullet, whose drag
    time scale is ~10x shorter than a shell's, within the kernel tolerance through Mach 1."""
    shell = PointMassModel(MASS, DIAM, m101)
    bullet = PointMassModel(0.0194, 0.0086, m101, wind=(2.0, -3.0, 0.0))   # .338, 300 gr
    assert bullet.kernel_step < shell.kernel_step / 5
    t = np.arange(0.0, 3.5, 0.01)  # 900 m/s -> Mach 1 at ~3 s
    ref = bullet.simulate((), initial_state(900.0, 2.0), t, backend="scipy")
    assert ref.mach[0] > 2.5 and ref.mach[-1] < 1.0
    tk = bullet.simulate((), ref.state[0], t)
    assert np.max(np.abs(tk.state[:, :3] - ref.state[:, :3])) < KERNEL_VS_SCIPY_M


@pytest.mark.parametrize("B", [21, 64])
def test_vector_lanes_match_single_runs(m101, B, rng):
    """Batches run in vector lanes (and padded blocks); every trajectory with its own drag,
    wind, yaw drag and lift must equal its single (scalar-path) run to rounding."""
    drag = make_drag_model("reference-scale", reference=m101)
    model = PointMassModel(MASS, DIAM, drag)
    t = np.arange(0.0, 30.0, 0.027)
    factors = rng.uniform(0.9, 1.1, (B, 1))
    s0 = np.stack([initial_state(v, e) for v, e in zip(rng.uniform(780, 830, B), rng.uniform(10, 40, B))])
    wy = rng.uniform(-5, 5, B)
    yaw = np.where(np.arange(B) % 3 == 0, 0.05, 0.0)
    lift = lift_parameter(rng.uniform(0, 2, B), 818.0)
    over = {K.P_WY: wy, K.P_YAW_AMP: yaw, K.P_YAW_DECAY: np.full(B, 0.4), K.P_LIFT: lift}
    batch = model.simulate_batch(factors, s0, t, overrides=over)
    for i in (0, 1, B // 2, B - 1):
        single = model.with_(wind=(0.0, wy[i], 0.0), yaw_amp=yaw[i], yaw_decay=0.4).simulate_batch(
            factors[i:i + 1], s0[i:i + 1], t, overrides={K.P_LIFT: lift[i:i + 1]})
        assert np.allclose(batch.state[i], single.state[0], rtol=0, atol=1e-9)
        assert np.allclose(batch.mach[i], single.mach[0], rtol=0, atol=1e-12)


@pytest.mark.parametrize("t, t0, match", [
    ([0.0, 0.1, 0.1], 0.0, "increase strictly"),
    ([0.5, 1.0], 1.0, "before the initial state"),
    ([], 0.0, "non-empty"),
])
def test_output_schedule_errors(t, t0, match):
    with pytest.raises(ValueError, match=match):
        output_schedule(np.array(t), t0, 0.03)


def test_bad_backend(ref_traj):
    model, tr = ref_traj
    with pytest.raises(ValueError, match="allowed: 'kernel', 'scipy'"):
        model.simulate((), tr.state[0], tr.t, backend="euler")


# --- independent cross-check: py-ballisticcalc 3.x -------------------------------------------
@pytest.mark.parametrize("wind", [(0.0, 0.0), (0.0, 10.0)], ids=["no-wind", "crosswind"])
def test_against_py_ballisticcalc(m101, wind):
    """Same shell, drag table and launch; py-ballisticcalc with ITS OWN atmosphere (not ours).

    Conventions matched (tests/support/pbc_reference.py): BC = 8 m K/(0.3048 pi d^2 rho_ref) so the
    table is the projectile's own Cd; its real-gas sea-level density (ratio 1.000426) folded
    into BC; a dense resampling of our PCHIP so both interpolate alike; barrel elevation set
    directly (sight height 0); gravity 9.80665; Coriolis and spin drift off; wind
    direction_from = atan2(wy, wx). Remaining difference: its geometric-altitude, no-isothermal
    atmosphere (cm at a 3.3 km apex)."""
    pbc = pytest.importorskip("py_ballisticcalc")
    from support.pbc_reference import pbc_trajectory

    mach, cd = np.array(m101.mach), np.array(m101.cd_values)
    ref = pbc_trajectory(mach, cd, MASS, DIAM, 818.0, 15.0, wind=wind, exact_atmosphere=False)
    model = PointMassModel(MASS, DIAM, m101, wind=(wind[0], wind[1], 0.0))
    t = ref["t"]
    ours = model.simulate((), initial_state(818.0, 15.0), t, backend="kernel")
    for k, c in (("x", 0), ("y", 1), ("z", 2)):
        assert np.max(np.abs(ours.state[:, c] - ref[k])) < PBC_M, k
    assert np.max(np.abs(ours.speed - ref["v"])) < 0.1


# --- lift on the yaw of repose (effect ``lift``) --------------------------------------------
def test_lift_kernel_matches_scipy(m101):
    """Lift on, together with wind (the lift follows the airspeed) and Coriolis."""
    model = PointMassModel(MASS, DIAM, m101, wind=(3.0, -5.0, 0.0), coriolis=(45.0, 30.0),
                           lift_factor=1.5)
    tr = model.simulate((), initial_state(818.0, 30.0), backend="scipy", stop_at_impact=True, dt=0.027)
    tk = model.simulate((), tr.state[0], tr.t)
    assert np.max(np.abs(tk.state[:, :3] - tr.state[:, :3])) < KERNEL_VS_SCIPY_M
    # and the lift really acted: without it y differs by far more than the tolerance
    plain = model.with_(lift_factor=0.0).simulate((), tr.state[0], tr.t)
    assert np.max(np.abs(plain.state[:, 1] - tk.state[:, 1])) > 10.0


def test_lift_drifts_right_growing_and_mirrors(m101):
    """factor > 0 (right-hand spin), no wind: y > 0 and growing with time of flight; factor < 0
    mirrors it exactly. The vertical part (Magnus force and lift on the vertical yaw of repose)
    is up for either spin direction, so x and z are the same for both."""
    s0 = initial_state(818.0, 15.0)
    t = np.arange(0.0, 32.0, 0.027)
    right = PointMassModel(MASS, DIAM, m101, lift_factor=1.0).simulate((), s0, t)
    left = PointMassModel(MASS, DIAM, m101, lift_factor=-1.0).simulate((), s0, t)
    none = PointMassModel(MASS, DIAM, m101).simulate((), s0, t)
    y = right.state[:, 1]
    assert np.all(y[1:] > 0.0)
    assert np.all(np.diff(y) > 0.0)
    assert y[-1] > 50.0
    assert np.allclose(left.state[:, 1], -y, rtol=1e-9, atol=1e-9)
    assert np.max(np.abs(none.state[:, 1])) == 0.0
    assert np.allclose(left.state[:, [0, 2]], right.state[:, [0, 2]], rtol=1e-9, atol=1e-9)
    # the vertical force lifts the shell: ~11 % of the drift after 32 s (6-DOF: test below)
    dz = right.state[:, 2] - none.state[:, 2]
    assert 0.05 * y[-1] < dz[-1] < 0.2 * y[-1]
    flat = PointMassModel(MASS, DIAM, m101, lift_factor=1.0, lift_vertical_fraction=0.0).simulate((), s0, t)
    # without it the lift keeps x, z to second order in the drift angle (1 - cos ~ (y / x)^2 / 2)
    assert np.max(np.abs(flat.state[:, 2] - none.state[:, 2])) < 0.5


def test_lift_matches_6dof_drift_order():
    """factor 1 with the Table 1 shell at 818 m/s, QE 15 deg: drift of the order of the full
    6-DOF's (which has Ix, spin, C_La and C_Ma of its own)."""
    from bayesdrag.dynamics.sixdof import simulate_6dof
    from bayesdrag.dynamics.shell import table1_shell
    shell = table1_shell()
    six = simulate_6dof(shell, 818.0, 15.0)
    model = PointMassModel(shell.mass, shell.diameter, shell.cd0, lift_factor=1.0)
    pm = model.simulate((), initial_state(818.0, 15.0), backend="scipy", stop_at_impact=True, dt=0.05)
    ratio = pm.state[-1, 1] / six.impact_drift
    assert 1.0 / LIFT_VS_6DOF_FACTOR < ratio < LIFT_VS_6DOF_FACTOR, (
        f"point-mass lift drift {pm.state[-1, 1]:.1f} m vs 6-DOF {six.impact_drift:.1f} m: ratio {ratio:.3f}")


#: the modified-point-mass lift vs the 6-DOF's drift and rise (Table 1 shell, QE 15 deg, 32 s)
LIFT_6DOF_Y_REL, LIFT_6DOF_DZ_REL = 0.03, 0.10


def test_lift_shape_follows_the_6dof_drift_and_rise():
    """The lift factor and a lateral aerodynamic jump (a heading change of the launch, as the
    diagnosis fits it with the initial state) reproduce the 6-DOF's whole drift history y(t)
    to within LIFT_6DOF_Y_REL of its size at every time after 8 s, and the rise z(t) over the
    point mass (Magnus force and lift on the vertical yaw of repose) to LIFT_6DOF_DZ_REL, with
    the factor near 1 (Table 1 shell, 818 m/s, QE 15 deg). The constant-L model of session 2
    (no Mach shape, no spin decay, no vertical part) misses the drift shape by more."""
    from bayesdrag.dynamics.sixdof import simulate_6dof
    from bayesdrag.dynamics.shell import table1_shell
    shell = table1_shell()
    t = np.arange(0.0, 32.01, 2.0)
    six = simulate_6dof(shell, 818.0, 15.0, t_out=t, stop_at_impact=False)
    s0 = initial_state(818.0, 15.0)
    model = PointMassModel(shell.mass, shell.diameter, shell.cd0)
    none = model.simulate((), s0, t).state
    late = t >= 8.0
    y6, dz6 = six.position[late, 1], six.position[late, 2] - none[late, 2]

    def fit(m):
        st = m.with_(lift_factor=1.0).simulate((), s0, t).state
        A = np.column_stack([st[:, 1], t])  # drift per unit factor, jump
        coef, *_ = np.linalg.lstsq(A, six.position[:, 1], rcond=None)
        return coef[0], np.max(np.abs((A @ coef)[late] - y6) / y6), st

    f, err, st = fit(model)
    assert 0.9 < f < 1.1 and err < LIFT_6DOF_Y_REL
    dz = f * (st[late, 2] - none[late, 2])  # linear in the factor to first order
    assert np.max(np.abs(dz - dz6) / dz6) < LIFT_6DOF_DZ_REL
    _, err_const, _ = fit(model.with_(lift_mach_rise=0.0, lift_mach_sat=0.0, spin_decay=0.0,
                                      lift_vertical_fraction=0.0))
    assert err_const > 3 * err


def test_lift_parameter_and_overrides(m101):
    """L = factor * 0.02 * V0; per-trajectory overrides of P_LIFT (and the vertical-force
    speed P_LIFT_VERT = LIFT_VERTICAL_FRACTION * V0) equal models with lift_v0."""
    assert lift_parameter(1.0, 818.0) == pytest.approx(LIFT_REF_FRACTION * 818.0)
    assert np.allclose(lift_parameter([0.5, -1.0], [800.0, 700.0]), [8.0, -14.0])
    s0 = np.stack([initial_state(818.0, 15.0)] * 3)
    t = np.arange(0.0, 10.0, 0.1)
    factors = np.array([0.0, 0.7, 1.3])
    base = PointMassModel(MASS, DIAM, m101)
    batch = base.simulate_batch(np.zeros((3, 0)), s0, t,
                                overrides={K.P_LIFT: lift_parameter(factors, 818.0),
                                           K.P_LIFT_VERT: np.full(3, LIFT_VERTICAL_FRACTION * 818.0)})
    for i, f in enumerate(factors):
        single = base.with_(lift_factor=f, lift_v0=818.0).simulate((), s0[i], t)
        assert np.array_equal(batch.state[i], single.state)
    # default V0 is the initial state's speed
    m = base.with_(lift_factor=1.0)
    assert m.par_row(s0[0])[K.P_LIFT] == pytest.approx(0.02 * 818.0)
    assert m.par_row(s0[0])[K.P_LIFT_VERT] == pytest.approx(LIFT_VERTICAL_FRACTION * 818.0)
    with pytest.raises(ValueError, match="needs the initial states"):
        m.kernel_inputs(np.zeros((1, 0)))


def test_vector_and_scalar_kernels_have_separate_disk_caches():
    """numba keys its on-disk cache by the function's qualified name and line, not by its
    compile options: the scalar copy of the block integrator must carry its own name, or
    whichever variant is compiled first is loaded for both (the vectorised one then ran scalar)."""
    assert K.integrate_blocks_scalar.py_func.__qualname__ == "integrate_blocks_scalar"
    assert K.integrate_blocks.py_func.__qualname__ == "integrate_blocks"
    assert K.integrate_blocks._compiler.pipeline_class is K._NoAliasCompiler
    assert K.integrate_blocks_scalar._compiler.pipeline_class is not K._NoAliasCompiler
    assert K.integrate_blocks.targetoptions.get("nogil") and K.integrate_blocks_scalar.targetoptions.get("nogil")


@pytest.mark.parametrize("B", [1, 7, 8, 9, 21, 40])
def test_threads_split_blocks_without_changing_a_bit(B, m101):
    """The helper threads integrate disjoint blocks with the same code: 1, 2 and 3 threads give
    identical states and Mach numbers (calm and with a wind by height)."""
    from bayesdrag.air.wind import WindProfile

    base = PointMassModel(42.6, 0.155, m101)
    windy = base.with_(atmosphere=Atmosphere(wind=WindProfile.layered(
        "altitude", (0.0, 500.0, 1500.0), (-3.0, -6.0), (1.0, 2.0))))
    t = np.linspace(0.0, 20.0, 201)
    s0 = np.stack([initial_state(800.0 + 2.0 * i, 15.0 + 0.1 * i) for i in range(B)])
    for model in (base, windy):
        h, n_steps, out_step, out_theta = output_schedule(t, 0.0, model.kernel_step)
        par, cd_tabs, cd_idx, grid, atm_tabs, atm_idx, z0, dz, wind = model.kernel_inputs(
            np.zeros((B, 0)), None, None, s0, None)
        w_tabs, w_idx, w0, dw = wind
        runs = []
        for n_threads in (1, 2, 3):
            out, mach = np.full((B, t.size, 6), np.nan), np.full((B, t.size), np.nan)
            K.integrate_batch(s0, 0.0, h, n_steps, out_step, out_theta, par, cd_tabs.reshape(-1), cd_tabs.shape[1],
                              cd_idx, grid.m0, grid.dm, atm_tabs.reshape(-1), atm_tabs.shape[1], atm_idx, z0, dz,
                              None if w_tabs is None else w_tabs.reshape(-1), 2 if w_tabs is None else w_tabs.shape[1],
                              w_idx, w0, dw, K.lanes_per_block(B, 2), out, mach, n_threads)
            runs.append((out, mach))
        assert np.all(np.isfinite(runs[0][0])) and np.all(np.isfinite(runs[0][1]))
        for out, mach in runs[1:]:
            assert np.array_equal(out, runs[0][0]) and np.array_equal(mach, runs[0][1])
