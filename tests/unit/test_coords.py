"""The drift coordinates of the posterior (bayesdrag.estimate.bayes.coords): an exact change of variables."""
import numpy as np
import pytest

from bayesdrag.dynamics.pointmass import PointMassModel
from bayesdrag.dynamics.trajectory import initial_state
from bayesdrag.estimate.bayes.coords import DENSITY, MASS, TEMPERATURE
from bayesdrag.estimate.bayes.posterior import LogPosterior
from bayesdrag.estimate.scheme1.fit import fit_scheme1
from bayesdrag.io.drag_tables import load_m101
from bayesdrag.round import Launch, Projectile, Radar, Round, Systematics
from bayesdrag.synthetic import add_noise
from bayesdrag.track import RadarTrack

SIGMA = {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}
#: round trip tolerance [Laplace sd] and log-determinant tolerance (the map is evaluated in float64)
ROUND_TRIP_TOL_SD = 1e-6
LOGDET_TOL = 1e-5


@pytest.fixture(scope="module")
def post():
    m101 = load_m101()
    tr = PointMassModel(42.6, 0.155, m101).simulate((), initial_state(818.0, 15.0), backend="scipy",
                                                     stop_at_impact=True, dt=0.2)
    track = add_noise(RadarTrack(tr.t, {c: tr.channel(c) for c in "xyzv"}, {}), SIGMA, np.random.default_rng(3))
    rnd = Round(Projectile("155", 42.6, 0.155, None, None), Launch(15.0, 818.0), radar=Radar(dict(SIGMA)),
                systematics=Systematics(density=0.002, temperature=0.5, mass=0.1))
    f1 = fit_scheme1(track, rnd)
    return LogPosterior(f1.problem, f1.ml)


def test_declared_air_and_mass_sources_switch_the_coordinates_on(post):
    assert post.coords is not None
    assert set(post.coords.pos) == {DENSITY, TEMPERATURE, MASS}


def test_the_map_round_trips(post):
    rng = np.random.default_rng(0)
    L = np.linalg.cholesky(post.laplace_cov)
    X = (post.laplace_mean + 3 * rng.standard_normal((20, post.ndim)) @ L.T)[:, :post.n_theta]
    back = post.coords.from_theta(post.coords.to_theta(X))
    sd = np.sqrt(np.diag(post.laplace_cov))[:post.n_theta]
    assert np.max(np.abs(back - X) / sd) < ROUND_TRIP_TOL_SD


def test_log_jacobian_is_the_log_determinant_of_the_map(post):
    x = post.laplace_mean[:post.n_theta].copy()
    x[post.coords.pos[TEMPERATURE]] = 1.5          # 3 sd: delta and f well away from their nominal 0, 1
    x[post.coords.pos[DENSITY]] = 1.006
    _, logdet = np.linalg.slogdet(post.coords.jacobian(x))
    assert abs(post.coords.log_jacobian(x[None])[0] - logdet) < LOGDET_TOL * max(1.0, abs(logdet))


def test_laplace_covariance_maps_back_to_the_parameters_one(post):
    """J cov_X J^T in the parameters' units is the Fisher inverse the ML fit's CRB comes from."""
    n = post.n_theta
    J = post.coords.jacobian(post.laplace_mean[:n])
    cov_theta = J @ post.laplace_cov[:n, :n] @ J.T
    sd = np.sqrt(np.diag(cov_theta))
    assert np.allclose(sd, post.crb_rms[:n], rtol=1e-4)


def test_reported_draws_are_in_the_parameters_units(post):
    x = post.laplace_mean[None].copy()
    x[0, post.coords.pos[DENSITY]] = 1.004           # f = 1.004: sampled c~ = 1.004 c
    rep = post.reported(x)[0]
    drag = post.coords.drag
    assert np.allclose(rep[drag], post.full_theta(x)[0, post.idx][drag])
    assert not np.allclose(rep[drag], x[0, drag], rtol=1e-4)


def test_default_walkers_follow_the_sampled_temperature(post):
    from types import SimpleNamespace

    from bayesdrag.estimate.bayes.sampler import DEFAULT_WALKERS, SOURCE_WALKERS, default_walkers

    assert default_walkers(post) == SOURCE_WALKERS == 128
    assert default_walkers(post, "de") == 2 * post.ndim + 2
    assert default_walkers(SimpleNamespace(ndim=41, coords=None)) == DEFAULT_WALKERS == 16


def test_the_map_stays_a_bijection_over_the_whole_temperature_bound(post):
    """Beyond its well-conditioned range the temperature term is held, so the map inverts even
    at the parameter's bounds (20 declared sd) where its Taylor terms alone would be singular."""
    j = post.coords.pos[TEMPERATURE]
    lo, hi = post.coords.dT_range
    assert lo < 0 < hi
    for d in (post.lower[j], lo - 1.0, hi + 1.0, post.upper[j]):
        x = post.laplace_mean[:post.n_theta].copy()
        x[j] = d
        assert np.isfinite(post.coords.log_jacobian(x[None])[0])
        back = post.coords.from_theta(post.coords.to_theta(x[None]))[0]
        sd = np.sqrt(np.diag(post.laplace_cov))[:post.n_theta]
        assert np.max(np.abs(back - x) / sd) < ROUND_TRIP_TOL_SD
