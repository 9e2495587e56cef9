"""Numerical robustness (issue 7): what cannot be computed ends with a clear message and the
the contract (docs/formats.md) exit status, never a hang or a silent wrong answer."""
import numpy as np
import pytest

from bayesdrag.drag import Poly2
from bayesdrag.dynamics.pointmass import PointMassModel
from bayesdrag.dynamics.trajectory import initial_state
from bayesdrag.errors import FitError, InputError
from bayesdrag.estimate.model.problem import OutputErrorProblem
from bayesdrag.synthetic import add_noise, simulate_round
from bayesdrag.round import Launch, Projectile, Round
from bayesdrag.track import RadarTrack

SIGMA = {"x": 1.0, "z": 1.0, "v": 0.3}


@pytest.fixture(scope="module")
def track(m101):
    tr = PointMassModel(42.6, 0.155, m101).simulate((), initial_state(818.0, 15.0), np.arange(0, 20, 0.027),
                                                    backend="scipy")
    return add_noise(RadarTrack(tr.t, {c: tr.channel(c) for c in "xzv"}, {}, source="t.csv"), SIGMA,
                     np.random.default_rng(1))


def test_round_that_never_lands_is_refused(m101):
    """A near-vertical 1500 m/s shot does not come down within the time limit: a clear error,
    not an endless integration."""
    rnd = Round(Projectile("p", 42.6, 0.155, m101, None), Launch(89.0, 1500.0), path="steep.toml")
    with pytest.raises(InputError, match=r"steep.toml: the simulated round does not land within 20 s"):
        simulate_round(rnd, max_time=20.0)


def test_negative_drag_start_is_a_fit_error(track):
    """Cd = -50 at the start makes the shell accelerate without bound: FitError (exit 1) that
    says what to check, never NaN results."""
    model = PointMassModel(42.6, 0.155, Poly2())
    th0 = np.r_[-50.0, 0.0, 0.0, initial_state(818.0, 15.0)]
    with pytest.raises(FitError, match="not finite"):
        OutputErrorProblem(model, track, th0, sigma=SIGMA).fit()


def test_iteration_limit_is_reported(track, m101):
    """A fit stopped by its iteration limit says so and is not marked a success."""
    model = PointMassModel(42.6, 0.155, Poly2())
    th0 = np.r_[0.6, -0.2, 0.03, initial_state(790.0, 14.0)]
    free = np.array([1, 1, 1, 1, 0, 1, 1, 0, 1], bool)  # no y channel: Y0, Uy0 fixed
    res = OutputErrorProblem(model, track, th0, free=free, sigma=SIGMA).fit(max_iter=1)
    assert not res.converged and not res.success
    assert res.message == "not converged after 1 iterations"


def test_inconsistent_track_does_not_pass_silently(track):
    """A track of a different projectile (drag 10x the model's reach) cannot be fitted within the
    drag model's bounds: the result is marked, with warnings, rather than a confident answer."""
    fake = RadarTrack(track.t, {"x": track.x * 0.2, "z": track.channels["z"] * 0.2, "v": track.v * 0.2}, {},
                      source="fake.csv")
    model = PointMassModel(42.6, 0.155, Poly2())
    th0 = np.r_[0.6, -0.2, 0.03, initial_state(818.0, 15.0)]
    res = OutputErrorProblem(model, fake, th0, sigma=SIGMA).fit(max_iter=15)
    rms = {c: np.sqrt(np.mean(r**2)) / SIGMA[c] for c, r in res.residuals.items()}
    assert (not res.success) or res.warnings or max(rms.values()) > 5.0


def test_blind_parameter_is_named(track):
    """Free Y0, Uy0 without a y channel: no crash in the bounds, a warning that names them."""
    model = PointMassModel(42.6, 0.155, Poly2())
    th0 = np.r_[0.6, -0.2, 0.03, initial_state(818.0, 15.0)]
    res = OutputErrorProblem(model, track, th0, sigma=SIGMA).fit(max_iter=3)
    assert not res.success
    assert any(w.kind == "no_information" and "Y0" in w.params for w in res.warnings)


def test_cli_unfittable_track_exit_2(tmp_path, capsys, m101):
    """A 'track' standing still in x while v says 500 m/s: refused as bad input (exit 2, one
    line naming the file), not fitted."""
    from bayesdrag.cli import main

    t = np.arange(0, 5, 0.027)
    (tmp_path / "t.csv").write_text("t,x,v\n" + "\n".join(f"{a:.3f},100.0,500.0" for a in t))
    ref = tmp_path / "cd.csv"
    ref.write_text("mach,cd\n" + "\n".join(f"{m:.2f},{c:.4f}" for m, c in zip(m101.mach, m101.cd_values)))
    (tmp_path / "r.toml").write_text('[projectile]\nmass = 42.6\ndiameter = 0.155\nreference_drag = "cd.csv"\n'
                                     '[launch]\nelevation = 15.0\nvelocity = 818.0\n')
    code = main(["fit", str(tmp_path / "t.csv"), str(tmp_path / "r.toml"), "-o", str(tmp_path / "out"),
                 "--no-mcmc"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "t.csv" in err[0]
