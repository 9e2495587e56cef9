"""The result values on real fits (issue 24): the demo track fitted with and without sampling,
a diagnosis and a plan. A short repr, the Cd table as arrays and a data frame, bands at any
level, a printable summary, figures from the result, a written folder read back into an equal
value, and the pointwise log-likelihood that ``arviz.loo`` and ``arviz.compare`` need."""
import math
import warnings

import numpy as np
import pytest

import bayesdrag
from bayesdrag.commands.demo import demo_inputs
from bayesdrag.errors import MissingDataError
from bayesdrag.estimate.model import colored
from bayesdrag.estimate.bayes.inference import LOG_LIKELIHOOD_VAR
from bayesdrag.results import LOG_LIKELIHOOD_DRAWS

#: a repr is one short paragraph [characters] (issue 24: 93 126 and 161 447 before)
MAX_REPR = 2000
#: the summed pointwise terms equal the draw's log-likelihood to this relative tolerance (the
#: group is stored as float32: ~1e-7 per term, summed over ~5 000 terms)
TOL_LOGLIK_REL = 2e-6
#: bands recomputed from the same draws agree to rounding [-]
TOL_CD = 1e-12


@pytest.fixture(scope="module")
def demo():
    track_path, round_path = demo_inputs()
    return bayesdrag.read_track(track_path), bayesdrag.read_round(round_path)


@pytest.fixture(scope="module")
def ml(demo):
    return bayesdrag.fit(*demo, mcmc=False)


@pytest.fixture(scope="module")
def sampled(demo):
    return bayesdrag.fit(*demo, seed=0)


@pytest.fixture(scope="module")
def written(sampled, tmp_path_factory):
    out = tmp_path_factory.mktemp("fit")
    sampled.write(out)
    return out


def test_repr_is_one_short_paragraph(ml, sampled):
    for res in (ml, sampled):
        text = repr(res)
        assert len(text) <= MAX_REPR, len(text)
        assert "\n" not in text and "spline" in text and "determined Mach" in text
    assert "posterior converged" in repr(sampled) and "not sampled" in repr(ml)


def test_cd_table_is_arrays_and_a_data_frame(ml):
    cd = ml.cd
    rows = ml.to_dict()["cd"]
    assert np.array_equal(cd.mach, [r["mach"] for r in rows])
    assert np.array_equal(cd.sd, [r["band_sd"] for r in rows])
    assert np.array_equal(cd.determined, [r["determined"] for r in rows])
    df = cd.to_dataframe()
    assert list(df.columns[:4]) == ["mach", "ml", "sd", "determined"]
    assert len(df) == len(rows)
    mid = float(cd.mach[len(cd) // 2] + 0.003)
    assert cd.at(mid).ml[0] == pytest.approx(np.interp(mid, cd.mach, cd.ml), abs=TOL_CD)


def test_bands_hold_the_ml_curve_and_grow_with_the_level(ml, sampled):
    for res in (ml, sampled):
        lo9, hi9 = res.band(0.9)
        lo5, hi5 = res.band(0.5)
        assert np.all((lo9 <= res.cd.ml) & (res.cd.ml <= hi9))
        assert np.all(hi9 - lo9 > hi5 - lo5)
        slo, shi = res.band(0.9, kind="statistical")
        assert np.all(shi - slo <= hi9 - lo9 + TOL_CD)         # the total band holds the sources and model error
    with pytest.raises(MissingDataError, match="mcmc=True"):
        ml.band(0.9, kind="posterior")
    # the posterior band at 90 % is result.json's q05 / q95 (the same draws, the same quantiles)
    plo, phi = sampled.band(0.9, kind="posterior")
    assert np.max(np.abs(plo - sampled.cd.q05)) < TOL_CD and np.max(np.abs(phi - sampled.cd.q95)) < TOL_CD


def test_summary_prints_and_renders_in_a_notebook(ml, sampled):
    for res in (ml, sampled):
        s = res.summary()
        text = str(s)
        assert "chi2 per sample" in text and "Cd determined" in text and "clean answer" in text
        html = s._repr_html_()
        assert "<table>" in html and "spline" in html
    assert "post. mean" in str(sampled.summary()) and "post. mean" not in str(ml.summary())


def test_figures_come_from_the_result(ml, sampled):
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    assert isinstance(ml.plot_cd(), Axes)
    assert isinstance(ml.plot_budget(), Axes)
    assert isinstance(ml.plot_residuals(), Figure)
    for fn in (sampled.plot_cd, sampled.plot_cd_relative, sampled.plot_sd_ratio):
        assert isinstance(fn(), Axes)
    for fn in (sampled.plot_residuals, sampled.plot_corner, sampled.plot_traces):
        assert isinstance(fn(), Figure)
    fig = Figure()
    ax = fig.add_subplot()
    assert sampled.plot_cd(ax=ax) is ax


def test_a_written_folder_loads_back_equal(sampled, written):
    back = bayesdrag.load_result(written)
    assert back == sampled
    assert back.to_dict() == sampled.to_dict()
    assert back.cd == sampled.cd
    assert np.array_equal(back.cd.ml, sampled.cd.ml) and np.array_equal(back.cd.q95, sampled.cd.q95)
    assert len(repr(back)) <= MAX_REPR and str(written) in repr(back)
    plo, phi = back.band(0.8, kind="posterior")
    wlo, whi = sampled.band(0.8, kind="posterior")
    assert np.max(np.abs(plo - wlo)) < TOL_CD and np.max(np.abs(phi - whi)) < TOL_CD
    assert back.plot_cd() is not None                       # from result.json alone
    with pytest.raises(MissingDataError, match=r"plot_corner needs the fit's scheme1, posterior.*read from"):
        back.plot_corner()
    with pytest.raises(MissingDataError, match="writing the report needs the fit's track, round"):
        back.write(written / "again")


def test_an_ml_folder_loads_back_without_a_posterior(ml, tmp_path):
    ml.write(tmp_path)
    back = bayesdrag.load_result(tmp_path)
    assert back == ml and back.cd == ml.cd and back.to_inference_data() is None and not back.sampled


def _conditional_loglik(res, chain, draw):
    """log p(z | theta, sigma) of one retained draw by the sampler's own functions: per channel
    the whitened sum of squares and log determinant (colored.whitened_ss), the draw's sigma."""
    b, post = res.posterior, res.log_posterior
    y, _ = post.problem.predict(b.thetas[chain, draw][None])
    r = post.problem.z - y[0]
    total = 0.0
    for j, c in enumerate(post.channels):
        s = math.exp(b.draws[chain, draw, b.names.index(f"log_sigma_{c}")])
        if c in post.ar_channels:
            rho, q = post.ar_ml[c]
            ss, ld = colored.whitened_ss(r[:, j][None], np.array([rho]), np.array([q]), post.problem.dt_ratio)
            ss, ld = float(ss[0]), float(ld[0])
        else:
            ss, ld = float(np.sum(r[:, j] ** 2)), 0.0
        total += -0.5 * ld - post.N * (math.log(s) + 0.5 * math.log(2 * math.pi)) - 0.5 * ss / s ** 2
    return total


def test_log_likelihood_terms_sum_to_the_draws_log_likelihood(sampled):
    idata = sampled.to_inference_data()
    ll = idata.log_likelihood[LOG_LIKELIHOOD_VAR]
    n_obs = sampled.log_posterior.N * len(sampled.log_posterior.channels)
    assert ll.dims == ("chain", "draw", "observation") and ll.sizes["observation"] == n_obs
    assert ll.sizes["chain"] * ll.sizes["draw"] <= LOG_LIKELIHOOD_DRAWS
    assert idata.log_likelihood.attrs["thinned"] == 1
    assert sampled.log_posterior.ar_channels                 # the demo's channels are ar1: the Kalman path
    for chain, k in ((0, 0), (7, 3), (15, ll.sizes["draw"] - 1)):
        draw = int(ll["draw"][k])
        want = _conditional_loglik(sampled, chain, draw)
        got = float(np.sum(ll.values[chain, k], dtype=np.float64))
        assert got == pytest.approx(want, rel=TOL_LOGLIK_REL)


def test_loo_runs_on_the_result_and_on_the_written_file(sampled, written):
    import arviz as az

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")                      # Pareto-k notes on a thinned subset
        loo = az.loo(sampled.to_inference_data())
        back = az.loo(bayesdrag.load_result(written).to_inference_data())
    assert np.isfinite(loo.elpd_loo) and loo.n_data_points == sampled.log_posterior.N * 4
    assert back.elpd_loo == pytest.approx(loo.elpd_loo, rel=1e-12)


def test_compare_ranks_two_drag_models(m101):
    """On a point-mass track flown with the M101 table, the table scaled by one factor (the true
    shape) is ranked above one quadratic over the whole flight (which cannot follow it)."""
    import arviz as az

    from bayesdrag.dynamics.pointmass import PointMassModel
    from bayesdrag.dynamics.trajectory import initial_state
    from bayesdrag.synthetic import add_noise

    sigma = {"x": 1.0, "z": 1.0, "v": 0.3}
    tr = PointMassModel(42.6, 0.155, m101).simulate((), initial_state(818.0, 15.0), backend="scipy",
                                                     stop_at_impact=True, dt=0.2)
    track = add_noise(bayesdrag.RadarTrack(tr.t, {c: tr.channel(c) for c in sigma}, {}), sigma,
                      np.random.default_rng(4))
    rnd = bayesdrag.Round(bayesdrag.Projectile("155", 42.6, 0.155, m101, None), bayesdrag.Launch(15.0, 818.0),
                          radar=bayesdrag.Radar(dict(sigma)))
    fits = {d: bayesdrag.fit(track, rnd, drag=d, noise_model="white", walkers=32, max_steps=1500, seed=3)
            for d in ("reference-scale", "poly2")}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = az.compare({d: r.to_inference_data() for d, r in fits.items()})
    assert list(table.index) == ["reference-scale", "poly2"]
    assert table.loc["poly2", "elpd_diff"] > 4 * table.loc["poly2", "dse"]


# ----------------------------------------------------------------------------- diagnosis, plan
@pytest.fixture(scope="module")
def diagnosis(demo):
    _, rnd = demo
    track = bayesdrag.simulate(rnd, noise=True, seed=3, dt=0.1, clock_offset=0.02)
    return bayesdrag.diagnose(track, rnd)


def test_diagnosis_result_is_a_value_like_a_fit(diagnosis, tmp_path):
    d = diagnosis
    assert len(repr(d)) <= MAX_REPR and "verdict" in repr(d)
    text = str(d.summary())
    assert "verdict" in text and " ".join(d.paragraph.split()) in " ".join(text.split())
    assert "<table>" in d.summary()._repr_html_()
    df = d.to_dataframe()
    assert list(df["name"]) == [e["name"] for e in d.to_dict()["effects"]]
    assert {"significant", "shrink", "delta_loglik", "verdict", "params"} <= set(df.columns)
    assert df["verdict"].sum() == len(d.verdict)
    d.write(tmp_path)
    back = bayesdrag.load_diagnosis(tmp_path)
    assert back == d and back.to_dict() == d.to_dict() and back.verdict == d.verdict
    assert back.plot_ranking() is not None
    with pytest.raises(MissingDataError, match="plot_where needs the diagnosis's residual arrays"):
        back.plot_where()


def test_plan_result_is_a_value_like_a_fit(demo, tmp_path):
    _, rnd = demo
    p = bayesdrag.plan(rnd, elevations=(15.0, 45.0), dt=0.1, target=0.002)
    assert len(repr(p)) <= MAX_REPR and "2 case(s) planned" in repr(p)
    text = str(p.summary())
    assert "target relative sd" in text and " ".join(p.paragraph.split()) in " ".join(text.split())
    df = p.to_dataframe()
    assert list(df["elevation"]) == [15.0, 45.0] and {"mach_min", "mach_max", "best_relative_sd"} <= set(df.columns)
    assert list(df["best_relative_sd"]) == [c["best_relative_sd"] for c in p.to_dict()["cases"]]
    p.write(tmp_path)
    back = bayesdrag.load_plan(tmp_path)
    assert back == p and back.to_dict() == p.to_dict() and back.paragraph == p.paragraph
    with pytest.raises(MissingDataError, match="plot_plan needs the plan's objects"):
        back.plot_plan()
