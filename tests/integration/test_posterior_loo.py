"""The written posterior serves arviz.loo and arviz.compare honestly (issue 47, item 5): the
log-likelihood keeps at least 2 000 draws (float32), so that loo's Pareto diagnostics hold
without ``reff``; an unconverged posterior is written without its log_likelihood group and
``to_inference_data()`` warns why, so that arviz.compare cannot rank it silently."""
from __future__ import annotations

import warnings

import arviz as az
import numpy as np
import pytest

import bayesdrag
from bayesdrag.results import LOG_LIKELIHOOD_DRAWS, load_result

#: the share of observations whose Pareto k may exceed 0.7 (ArviZ's "bad") with the stored draws
BAD_K_SHARE = 0.01


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """A 155 mm flight of the independent integrator (tests/fixtures/met_flight.py), calm ICAO
    air, the M101 table."""
    from fixtures import met_flight as M

    tp, rp = M.write_icao_case(tmp_path_factory.mktemp("loo"), seed=6)
    return bayesdrag.read_track(tp), bayesdrag.read_round(rp)


def test_the_stored_log_likelihood_keeps_2000_draws(demo, tmp_path):
    assert LOG_LIKELIHOOD_DRAWS >= 2000
    track, rnd = demo
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = bayesdrag.fit(track, rnd, seed=1)
    assert res.posterior.converged
    res.write(tmp_path / "out")
    idata = load_result(tmp_path / "out").to_inference_data()
    ll = idata.log_likelihood["track"]
    W, S = res.posterior.draws.shape[:2]
    assert ll.dtype == np.float32
    assert ll.sizes["chain"] * ll.sizes["draw"] >= min(2000, W * S)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        loo = az.loo(idata)                                   # no reff: as a user would call it
    assert float(np.mean(loo.pareto_k.values > 0.7)) <= BAD_K_SHARE


def test_an_unconverged_posterior_is_not_ranked_silently(demo, tmp_path):
    track, rnd = demo
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = bayesdrag.fit(track.subset(range(0, track.n, 3)), rnd, seed=2, max_steps=100, walkers=16)
    assert not res.posterior.converged
    with pytest.warns(bayesdrag.BayesdragWarning, match=r"did not converge .*log_likelihood group is left out"):
        idata = res.to_inference_data()
    assert "log_likelihood" not in idata.groups()
    res.write(tmp_path / "out")
    back = load_result(tmp_path / "out")
    with pytest.warns(bayesdrag.BayesdragWarning, match="cannot rank an unconverged posterior"):
        written = back.to_inference_data()
    assert "log_likelihood" not in written.groups() and "posterior" in written.groups()
    lo, hi = back.band(0.9, kind="posterior")                 # the draws themselves are still there
    assert np.all(lo <= hi)


def test_progress_is_shown_when_someone_watches(monkeypatch):
    """``bayesdrag.fit(progress=None)``: a bar when stderr is a terminal or in a Jupyter kernel."""
    import sys

    from bayesdrag.pipeline import watched

    class Tty:
        def isatty(self):
            return True

    class Pipe:
        def isatty(self):
            return False

    monkeypatch.setattr(sys, "stderr", Tty())
    assert watched()
    monkeypatch.setattr(sys, "stderr", Pipe())
    monkeypatch.delitem(sys.modules, "ipykernel", raising=False)
    assert not watched()
    monkeypatch.setitem(sys.modules, "ipykernel", object())
    assert watched()
