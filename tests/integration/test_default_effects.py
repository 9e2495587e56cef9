"""The default fit fits the cause: when the model check's diagnosis names material effects the
round does not declare, the answer is the fit with them as nuisance parameters
(``ml.with_effects``, ``ml_without_effects`` per row); a track the model fits gets nothing added;
``with_effects="none"`` keeps the plain fit (its bands widened by the shift); Scheme 2 skips the
search with a note.

The flights are the honesty suite's (``tests/acceptance/honesty_suite.py``): a point-mass track
flown by an independent scipy integrator with a wind the round does not declare, and a flight
with no unmodelled effect. Judged as the suite judges (a row right within 2 % of the truth or 3
of its band sd)."""
import numpy as np
import pytest

import bayesdrag
from acceptance import honesty_suite as hs

#: the fitted wind must lie within this many of its CRB sd of the truth [-]
EFFECT_K = 3.0
#: least share of the flown Mach span that stays determined once the effect is fitted
MIN_DETERMINED = 0.6
#: linear interpolation between rows 0.01 Mach apart, relative [-]
INTERP_REL = 2e-3


@pytest.fixture(scope="module")
def demo_inputs_paths():
    from bayesdrag.commands.demo import demo_inputs

    return demo_inputs()


@pytest.mark.parametrize("case_id, wind", [("pm-wind-155-01", (-5.0, 0.0)), ("pm-wind-s105-03", (4.0, -6.0))])
def test_an_undeclared_wind_is_found_fitted_and_the_rows_claimed_are_right(case_id, wind):
    r = hs.run_case(hs.case_by_id(case_id))
    assert "error" not in r, r.get("error")
    assert r["effects_added"] == ["wind"], r
    for name, truth in zip(("wind.wx", "wind.wy"), wind):
        value, sd = r["effect_params"][name]
        assert abs(value - truth) <= EFFECT_K * sd + 1e-9, f"{name} {value:.3f} +- {sd:.3f} for {truth}"
    assert r["determined_wrong"] == 0, r
    assert r["determined_fraction"] >= MIN_DETERMINED, r


#: a fitted clock offset's sd must be below this to count as measured [s] (a flight of tens of
#: seconds at 0.05 s samples sizes it to milliseconds once the launch priors hold)
CLOCK_SD_MAX = 0.005


def test_a_late_radar_clock_is_fitted_and_sized_with_the_launch_priors_kept():
    case = hs.case_by_id("w-pm-radar_time-15")
    r = hs.run_case(case)
    assert "error" not in r, r.get("error")
    assert r["effects_added"] == ["radar_time"], r
    value, sd = r["effect_params"]["radar_time.dt"]
    truth = case.withheld.params["dt"]
    assert sd < CLOCK_SD_MAX, f"radar_time.dt {value:.4g} +- {sd:.3g} s: the clock offset is not sized"
    assert abs(value - truth) <= EFFECT_K * sd, f"radar_time.dt {value:.4g} +- {sd:.3g} s for {truth}"
    assert r["determined_wrong"] == 0, r


def test_a_track_the_model_fits_gets_nothing_added_and_the_same_cd():
    case = hs.case_by_id("w-pm-null-100")
    track, rnd, _ = hs.make(case)
    default = bayesdrag.fit(track, rnd, mcmc=False)
    none = bayesdrag.fit(track, rnd, mcmc=False, with_effects="none")
    assert default.to_dict()["ml"]["quality"]["ok"]
    assert "with_effects" not in default.to_dict()["ml"]
    np.testing.assert_array_equal(default.cd.ml, none.cd.ml)
    np.testing.assert_array_equal(default.cd.sd, none.cd.sd)


def test_the_demo_adds_lift_and_keeps_the_plain_cd(demo_inputs_paths):
    track, rnd = (bayesdrag.read_track(demo_inputs_paths[0]), bayesdrag.read_round(demo_inputs_paths[1]))
    d = bayesdrag.fit(track, rnd, mcmc=False).to_dict()
    we = d["ml"]["with_effects"]
    assert we["added_by"] == "default" and we["effects"] == ["lift"], we
    assert "names lift" in we["reason"]
    assert all("ml_without_effects" in r for r in d["cd"])
    assert {"ml", "model_check", "refit", "total"} <= set(d["timing"])
    plain = bayesdrag.fit(track, rnd, mcmc=False, with_effects="none").to_dict()
    assert "with_effects" not in plain["ml"] and "refit" not in plain["timing"]
    assert plain["ml"]["quality"]["model_error"]["effects"] == ["lift"]      # widened instead
    # the plain Cd kept beside the corrected one is the plain fit's (the two grids differ by the
    # refit's Mach span: compared where both reach, by linear interpolation between 0.01-Mach rows)
    m = np.array([r["mach"] for r in d["cd"]])
    mp = np.array([r["mach"] for r in plain["cd"]])
    inside = (m >= mp[0]) & (m <= mp[-1])
    np.testing.assert_allclose(np.array([r["ml_without_effects"] for r in d["cd"]])[inside],
                               np.interp(m[inside], mp, [r["ml"] for r in plain["cd"]]), rtol=INTERP_REL)


def test_scheme2_skips_the_search_with_a_note(demo_inputs_paths):
    track, rnd = (bayesdrag.read_track(demo_inputs_paths[0]), bayesdrag.read_round(demo_inputs_paths[1]))
    d = bayesdrag.fit(track, rnd, mcmc=False, scheme=2, window=100).to_dict()
    if not d["ml"]["quality"]["ok"]:
        assert any("Scheme 2 fits no effects" in n for n in d["ml"]["notes"])


def test_with_none_and_default_are_options_and_scheme2_refuses_named_effects():
    from bayesdrag.options import FitOptions

    assert FitOptions().with_effects == "default"
    assert FitOptions(with_effects="none").with_effects == ()
    assert FitOptions(with_effects="none", scheme=2).with_effects == ()
    with pytest.raises(bayesdrag.InputError, match="with_effects.*Scheme 1 curve"):
        FitOptions(with_effects="wind", scheme=2)
    with pytest.raises(bayesdrag.InputError, match="use default, none, auto or effects among"):
        FitOptions(with_effects="windd")


def test_an_effect_the_user_names_is_not_reported_as_missing():
    """``--with wind`` on a track with an undeclared wind: the model check's diagnosis of the
    plain track names the wind, which the fit already carries. Before, the fit said "NOT a clean
    answer ... `--with wind` fits the cause" with a 0 % shift; the check now leaves the carried
    effect out of its model error and its advice."""
    track, rnd, truth = hs.make(hs.case_by_id("pm-wind-155-01"))
    res = bayesdrag.fit(track, rnd, mcmc=False, with_effects=("wind",))
    q = res.to_dict()["ml"]["quality"]
    assert q["model_error"]["effects_fitted"] == ["wind"]
    assert "wind" not in q["model_error"]["effects"]
    assert not any("--with wind" in p for p in q["problems"]), q["problems"]
    assert q["ok"], q["problems"]
    assert hs.judge(res.to_dict(), truth)["determined_wrong"] == 0
