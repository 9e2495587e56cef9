"""``--sample-ar``: the AR(1) model-error coefficients sampled in the posterior (issue 15)."""
import numpy as np
import pytest

from bayesdrag.pipeline import fit
from bayesdrag.options import FitOptions
from bayesdrag.dynamics.pointmass import PointMassModel
from bayesdrag.dynamics.trajectory import initial_state
from bayesdrag.errors import InputError
from bayesdrag.io.drag_tables import load_m101
from bayesdrag.round import Launch, Projectile, Radar, Round
from bayesdrag.synthetic import add_noise
from bayesdrag.track import RadarTrack

SIGMA = {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}


#: AR(1) model error added to the x channel: lag-one correlation per sample and sd [m]
RHO_TRUE, AR_SD = 0.9, 3.0


def _ar1(n, rho, sd, rng):
    e = np.empty(n)
    e[0] = sd * rng.standard_normal()
    for k in range(1, n):
        e[k] = rho * e[k - 1] + sd * np.sqrt(1 - rho ** 2) * rng.standard_normal()
    return e


def test_sample_ar_puts_the_ar_coefficients_in_the_posterior():
    rng = np.random.default_rng(5)
    m101 = load_m101()
    tr = PointMassModel(42.6, 0.155, m101).simulate((), initial_state(818.0, 15.0), backend="scipy",
                                                     stop_at_impact=True, dt=0.25)
    ch = {c: tr.channel(c) for c in "xyzv"}
    ch["x"] = ch["x"] + _ar1(tr.t.size, RHO_TRUE, AR_SD, rng)
    track = add_noise(RadarTrack(tr.t, ch, {}), SIGMA, rng)
    rnd = Round(Projectile("155", 42.6, 0.155, None, None), Launch(15.0, 818.0), radar=Radar(dict(SIGMA)))
    res = fit(track, rnd, sample_ar=True, walkers=64, max_steps=400, seed=2)
    assert res.record["ml"]["noise"]["model"]["x"] == "ar1"
    post = res.record["posterior"]
    assert "log_1m_rho_x" in post["mean"] and "log_q_x" in post["mean"]
    # the sampled lag-one correlation of the x model error brackets the one put in (90 % interval
    # of rho = 1 - exp(log_1m_rho), widened by 0.05 for a short chain)
    rho_lo = 1 - np.exp(post["q95"]["log_1m_rho_x"])
    rho_hi = 1 - np.exp(post["q05"]["log_1m_rho_x"])
    assert rho_lo - 0.05 <= RHO_TRUE <= rho_hi + 0.05, (rho_lo, rho_hi)
    _check_pointwise_log_likelihood_uses_each_draws_ar(res)
    held = fit(track, rnd, walkers=64, max_steps=400, seed=2)
    assert not any(k.startswith("log_1m_rho") for k in held.record["posterior"]["mean"])


#: the summed float32 pointwise terms equal the draw's log-likelihood to this relative tolerance
TOL_LOGLIK_REL = 2e-6


def _check_pointwise_log_likelihood_uses_each_draws_ar(res):
    """The log_likelihood group's terms of a draw sum to its log-likelihood with the draw's own
    sampled rho and q of the x channel (the sampler's whitened sum of squares and log
    determinant) and its noise sd draws."""
    from bayesdrag.estimate.model import colored
    from bayesdrag.estimate.bayes.inference import LOG_LIKELIHOOD_VAR

    import xarray as xr

    from bayesdrag.estimate.bayes.posterior_groups import log_likelihood_group
    from bayesdrag.results import LOG_LIKELIHOOD_DRAWS

    b, post = res.posterior, res.log_posterior
    # the group as the file writes it (built directly: this short chain need not have converged,
    # and an unconverged posterior is written without it)
    g = log_likelihood_group(b, post, LOG_LIKELIHOOD_DRAWS)
    dims, values = g.data_vars[LOG_LIKELIHOOD_VAR]
    ll = xr.DataArray(values, dims=dims, coords={k: v[1] for k, v in g.coords.items() if v[0] == (k,)})
    for chain, k in ((0, 0), (5, ll.sizes["draw"] - 1)):
        draw = int(ll["draw"][k])
        d = b.draws[chain, draw]
        y, _ = post.problem.predict(b.thetas[chain, draw][None])
        r = post.problem.z - y[0]
        want = 0.0
        for j, c in enumerate(post.channels):
            s = np.exp(d[b.names.index(f"log_sigma_{c}")])
            if c in post.ar_sampled:
                rho, q = 1 - np.exp(d[b.names.index(f"log_1m_rho_{c}")]), np.exp(d[b.names.index(f"log_q_{c}")])
            elif c in post.ar_channels:
                rho, q = post.ar_ml[c]
            else:
                rho, q = 0.0, 0.0                     # white: the filter is the identity
            ss, ld = colored.whitened_ss(r[:, j][None], np.array([rho]), np.array([q]), post.problem.dt_ratio)
            want += -0.5 * ld[0] - post.N * (np.log(s) + 0.5 * np.log(2 * np.pi)) - 0.5 * ss[0] / s ** 2
        got = float(np.sum(ll.values[chain, k], dtype=np.float64))
        assert got == pytest.approx(want, rel=TOL_LOGLIK_REL)


def test_sample_ar_must_be_a_bool():
    with pytest.raises(InputError, match="sample_ar"):
        FitOptions(sample_ar="yes")
