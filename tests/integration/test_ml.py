"""Output-error ML fit (Scheme 1): recovery of a known Cd, channel subsets, CRB sanity,
the `fit` command and its bad-input paths. (Monte Carlo CRB checks: issue 4, to come.)"""
import json

import numpy as np
import pytest

from bayesdrag.cli import main
from bayesdrag.drag import ReferenceTable, make_drag_model
from bayesdrag.dynamics.pointmass import PointMassModel
from bayesdrag.dynamics.trajectory import initial_state
from bayesdrag.errors import InputError
from bayesdrag.estimate.model.problem import OutputErrorProblem
from bayesdrag.estimate.cd.table import cd_table
from bayesdrag.estimate.scheme1.fit import fit_scheme1
from bayesdrag.synthetic import add_noise
from bayesdrag.round import Launch, Projectile, Radar, Round
from bayesdrag.track import RadarTrack

CD_RECOVERY_RTOL = 0.01     # issue 4: spline Cd within 1 % over Mach 1.2-2.3
Z_ORDER_ONE = 3.0           # |error| / CRB sd "of order 1"
SIX_DOF_RTOL = 0.02        # issue 4: from the 6-DOF track, Cd within 2 %
SIGMA = {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}


def test_spline_recovers_m101(noisy_track, round_, m101):
    f1 = fit_scheme1(noisy_track, round_, drag="spline")
    res, prob = f1.ml, f1.problem
    assert res.success and res.converged, res.message
    m = np.linspace(1.2, 2.3, 23)
    rows = cd_table(res, prob.model.drag, m, m101)
    err = np.array([r["ml"] / r["reference"] - 1 for r in rows])
    assert np.max(np.abs(err)) < CD_RECOVERY_RTOL
    # noise sd held at the round's values; residual rms matches them within 10 %
    for c, s in SIGMA.items():
        assert np.sqrt(np.mean(res.residuals[c] ** 2)) == pytest.approx(s, rel=0.1)


def test_error_over_crb_of_order_one(noisy_track, round_, m101):
    """The penalised spline's error is of the order of its own bound (its bounds include the
    smoothing prior), and the choice of smoothing is reported."""
    f1 = fit_scheme1(noisy_track, round_, drag="spline")
    res, prob = f1.ml, f1.problem
    rows = cd_table(res, prob.model.drag, np.linspace(1.2, 2.3, 23), m101)
    z = np.array([(r["ml"] - r["reference"]) / r["crb_sd"] for r in rows])
    assert np.max(np.abs(z)) < Z_ORDER_ONE, np.round(z, 2)
    sm = f1.smoothing
    assert 0 < sm["edf_drag"] < prob.model.drag.n_params
    assert not sm["at_grid_end"] or sm["sd"] == min(g["sd"] for g in sm["grid"])


def test_fixed_knots_leave_representation_error(noisy_track, round_, m101):
    """Why the default spline is penalised on fine knots: the plain spline on the sparse
    default knots misses M101 near Mach 1.25 by many of its own bounds."""
    f1 = fit_scheme1(noisy_track, round_, drag="spline", penalise=False)
    res, prob = f1.ml, f1.problem
    rows = cd_table(res, prob.model.drag, np.linspace(1.2, 2.3, 23), m101)
    z = np.array([(r["ml"] - r["reference"]) / r["crb_sd"] for r in rows])
    assert f1.smoothing is None
    assert np.max(np.abs(z)) > Z_ORDER_ONE


def test_spline_follows_a_moved_drag_rise(m101):
    """Truth differs from the round's firing table: the drag rise 3 % later in Mach and 4 %
    higher overall. The penalised spline (which shrinks toward the table's shape) still follows
    the truth to 1 % over Mach 1.2-2.3."""
    mm = np.linspace(0.5, 3.0, 251)
    truth_tab = ReferenceTable(tuple(mm), tuple(1.04 * m101.value(mm / 1.03)), source="moved rise")
    tr = PointMassModel(42.6, 0.155, truth_tab).simulate((), initial_state(818.0, 15.0), backend="scipy",
                                                          stop_at_impact=True, dt=0.027)
    clean = RadarTrack(tr.t, {c: tr.channel(c) for c in "xyzv"}, {})
    noisy = add_noise(clean, SIGMA, np.random.default_rng(11))
    rnd = Round(Projectile("155", 42.6, 0.155, m101, None), Launch(15.0, 818.0), radar=Radar(dict(SIGMA)),
                path="test.toml")
    f1 = fit_scheme1(noisy, rnd, drag="spline")
    res, prob = f1.ml, f1.problem
    rows = cd_table(res, prob.model.drag, np.linspace(1.2, 2.3, 23), truth_tab)
    err = np.array([r["ml"] / r["reference"] - 1 for r in rows])
    assert np.max(np.abs(err)) < CD_RECOVERY_RTOL, np.round(100 * err, 2)


def test_relaxation_estimates_noise(noisy_track, m101, round_):
    sp = make_drag_model("spline", mach_range=(0.92, 2.41))
    model = PointMassModel(42.6, 0.155, sp)
    th0 = np.concatenate([sp.initial_params(m101), initial_state(818.0, 15.0) + [1, 1, 1, 2, 0.5, -2]])
    res = OutputErrorProblem(model, noisy_track, th0).fit()
    assert res.converged
    for c, s in SIGMA.items():
        assert res.sigma[c] == pytest.approx(s, rel=0.08)
    # white noise: the colored-residual correction changes the bounds little
    P = sp.n_params
    assert np.allclose(res.crb_colored[:P], res.crb[:P], rtol=0.3)


@pytest.mark.parametrize("channels", [("x", "z"), ("v",), ("x", "v")])
def test_channel_subsets(noisy_track, round_, m101, channels):
    f1 = fit_scheme1(noisy_track, round_, drag="spline", channels=channels)
    res, prob = f1.ml, f1.problem
    assert res.converged, res.message
    rows = cd_table(res, prob.model.drag, np.linspace(1.3, 2.2, 10), m101)
    err = np.array([r["ml"] / r["reference"] - 1 for r in rows])
    tol = 0.03 if channels == ("v",) else CD_RECOVERY_RTOL
    assert np.max(np.abs(err)) < tol
    assert set(res.residuals) == set(channels)


def test_poly2_misfit_reported(noisy_track, round_):
    """The quadratic cannot follow the transonic rise: the fit says so by its residuals."""
    f1 = fit_scheme1(noisy_track, round_, drag="poly2")
    res = f1.ml
    rms_x = np.sqrt(np.mean(res.residuals["x"] ** 2))
    assert rms_x > 5 * SIGMA["x"]


def test_too_few_samples(noisy_track, round_):
    """Two speeds cannot determine even one factor on the table and the launch state: refused
    naming the smallest model; three can, and the too-large default spline gives way to that
    factor (issue 26: the model's size follows the data)."""
    with pytest.raises(InputError, match="are too few to determine Cd: even the smallest drag model"):
        fit_scheme1(noisy_track.subset(slice(0, 2)), round_, drag="spline", channels=("v",))
    f1 = fit_scheme1(noisy_track.subset(slice(0, 3)), round_, drag="spline", channels=("v",))
    assert f1.drag_model.name == "reference-scale" and "too few for the default spline" in f1.model_size["note"]


def test_cli_fit_writes_result(noisy_track, round_, tmp_path, capsys):
    from importlib.resources import files

    from bayesdrag.io.tracks import write_track

    tf = tmp_path / "t.csv"
    write_track(tf, noisy_track)
    rf = tmp_path / "r.toml"
    ref = files("bayesdrag") / "data" / "cd_m101.csv"
    rf.write_text(f'[projectile]\nmass = 42.6\ndiameter = 0.155\nreference_drag = "{ref}"\n'
                  f'[launch]\nelevation = 15.0\nvelocity = 818.0\n'
                  f'[radar]\nsigma = {{x = 1.0, y = 1.0, z = 1.0, v = 0.3}}\n')
    out = tmp_path / "out"
    assert main(["fit", str(tf), str(rf), "-o", str(out), "--no-mcmc"]) == 0
    r = json.loads((out / "result.json").read_text())
    assert r["scheme"] == 1 and r["drag_model"] == "spline"
    assert r["ml"]["converged"] is True and r["ml"]["iterations"] > 0
    assert set(r["ml"]["crb"]) <= set(r["ml"]["params"])
    mach = [row["mach"] for row in r["cd"]]
    assert min(mach) > 0.85 and max(mach) < 2.5
    assert all(abs(row["ml"] / row["reference"] - 1) < 0.02 for row in r["cd"] if 1.2 <= row["mach"] <= 2.3)
    assert "posterior" not in r
    for f in ("cd.png", "residuals.png"):
        assert (out / f).read_bytes()[:4] == b"\x89PNG"
    # bad channel subset -> exit 2, one line; earlier results untouched
    before = (out / "result.json").read_text()
    capsys.readouterr()
    assert main(["fit", str(tf), str(rf), "-o", str(out), "--channels", "x,q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--channels" in err[0]
    assert (out / "result.json").read_text() == before
    # a constant channel carries no information
    const = tmp_path / "c.csv"
    const.write_text("t,x,v\n" + "\n".join(f"{0.027 * i:.3f},{21.0 * i:.2f},818.0" for i in range(200)))
    assert main(["fit", str(const), str(rf), "-o", str(tmp_path / "o2"), "--no-mcmc"]) == 2
    assert "constant" in capsys.readouterr().err


def test_six_dof_track_within_two_percent():
    """The shipped 6-DOF track (paper Table 1 shell, QE 15 deg): the point-mass Scheme 1 fit
    gives Cd within 2 % of M101 over Mach 1.2-2.3 (issue 4). The 6-DOF's yaw-of-repose lift,
    absent from the point mass, shows up in the initial conditions instead: the fitted muzzle
    moves sideways by tens of metres against a 1 m launch prior (docs/ml.md explains)."""
    from bayesdrag.commands.demo import demo_inputs
    from bayesdrag.io.rounds import read_round
    from bayesdrag.io.tracks import read_track

    tp, rp = demo_inputs()
    track, rnd = read_track(tp), read_round(rp)
    f1 = fit_scheme1(track, rnd)
    res, prob = f1.ml, f1.problem
    assert res.converged, res.message
    rows = cd_table(res, prob.model.drag, np.linspace(1.2, 2.3, 23), rnd.reference_drag)
    err = np.array([r["ml"] / r["reference"] - 1 for r in rows])
    assert np.max(np.abs(err)) < SIX_DOF_RTOL
    assert abs(res.params["Y0"]) > 10 * rnd.launch.position_sd
