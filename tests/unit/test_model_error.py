"""The model-error term (bayesdrag.estimate.cd.model_error), the budget that adds up to the band,
the posterior widened to it, and the headline (issue 27)."""
import numpy as np
import pytest

from bayesdrag.estimate.bayes.draws import cd_posterior_rows, needs_widening, widen_to_floor
from bayesdrag.estimate.cd.headline import HEADLINE_LEVEL_Z, headline
from bayesdrag.estimate.cd.model_error import check_sd, combine, fold_into_budget, shift_sd
from bayesdrag.pipeline.model_check import level_shift

#: relative agreement of quantities written to 6 significant digits
SIX_DIGITS = 1e-5


def test_shift_sd_carries_the_better_fits_band():
    ml, band = np.array([0.30, 0.30]), np.array([0.001, 0.002])
    alt, band_alt = np.array([0.303, 0.30]), np.array([0.0015, 0.001])
    me = shift_sd(ml, band, alt, band_alt)
    # the plain Cd's error sd is sqrt(shift^2 + band_alt^2): its band plus me in squares gives it
    np.testing.assert_allclose(np.hypot(band, me), [np.hypot(0.003, 0.0015), 0.002], rtol=1e-12)
    np.testing.assert_allclose(shift_sd(ml, band, alt), [0.003, 0.0], atol=1e-15)


def test_check_sd_keeps_only_what_the_difference_noise_cannot_explain():
    ml, sd = np.array([0.30, 0.30, 0.30]), np.array([0.004, 0.004, 0.002])
    # a robust check twice as precise differs by 0.003: noise of variance 0.004^2 - 0.002^2 holds it
    alt, sd_alt = np.array([0.303, 0.310, 0.303]), np.array([0.002, 0.002, 0.002])
    me = check_sd(ml, sd, alt, sd_alt)
    assert me[0] == 0.0
    # a 0.010 shift against a difference noise of sd sqrt(1.2e-5): the excess is the bias
    np.testing.assert_allclose(me[1], np.sqrt(0.010**2 - (0.004**2 - 0.002**2)), rtol=1e-12)
    # equal precision: no noise in the difference is granted, the shift stands whole
    np.testing.assert_allclose(me[2], 0.003, rtol=1e-12)
    assert np.all(check_sd(ml, sd, np.array([np.nan] * 3), sd_alt) == np.inf)


def test_level_shift_follows_the_diagnosis_profile_in_squares():
    grid, ml = np.array([1.0, 1.5, 2.0, 2.5]), np.full(4, 0.3)
    profiles = {"yaw_drag": {"mach": [1.0, 2.0], "cd_relative": [0.0, -0.1]},
                "temperature": {"mach": [1.0, 2.0], "cd_relative": [0.02, 0.02]}}
    yaw = level_shift(grid, ml, profiles, ["yaw_drag"])
    # linear between the diagnosis's Mach numbers, |relative| times Cd, held beyond its range
    np.testing.assert_allclose(yaw, [0.0, 0.015, 0.03, 0.03], rtol=1e-12)
    both = level_shift(grid, ml, profiles, ["yaw_drag", "temperature"])
    np.testing.assert_allclose(both, np.hypot(yaw, 0.006), rtol=1e-12)
    assert level_shift(grid, ml, profiles, ["wind"]) is None


def test_combine_adds_in_squares_and_none_is_nothing():
    assert combine(None, None) is None
    np.testing.assert_allclose(combine(np.array([3.0]), None, np.array([4.0])), [5.0])


def test_budget_total_is_the_band_and_squares_add_up():
    budget = {"mach": [1.0, 2.0], "total_sd": [0.0010, 0.0020],
              "by_source": {"statistical": [0.0008, 0.0012], "density": [0.0006, 0.0016], "cross": [0.0, 0.0]}}
    rows = [{"band_sd": 0.0015, "model_error_sd": 0.0005}, {"band_sd": 0.0030, "model_error_sd": 0.0}]
    b = fold_into_budget(budget, rows)
    assert b["total_sd"] == [0.0015, 0.0030]
    assert b["linearised_total_sd"] == [0.0010, 0.0020]
    sq = sum(np.asarray(v) ** 2 for k, v in b["by_source"].items() if k != "cross")
    sq = sq + np.asarray(b["by_source"]["cross"])
    np.testing.assert_allclose(sq, np.square(b["total_sd"]), rtol=SIX_DIGITS)
    assert b["by_source"]["model_error"] == [0.0005, 0.0]


def test_widening_holds_the_model_error_and_keeps_the_sampled_posterior():
    rng = np.random.default_rng(0)
    cd = 0.3 + 0.001 * rng.standard_normal((4, 2000, 2))
    rows = [{"mach": 1.0, "ml": 0.3, "crb_sd": 0.001, "model_error_sd": 0.002},
            {"mach": 2.0, "ml": 0.3, "crb_sd": 0.001}]
    assert needs_widening(rows) and not needs_widening([rows[1]])
    wide = widen_to_floor(cd, rows)
    out = cd_posterior_rows(rows, wide, cd)
    # the total sd is sqrt(sampled^2 + model error^2); the sampled keys are the sampler's
    assert out[0]["sd"] == pytest.approx(np.hypot(out[0]["sampled_sd"], 0.002), rel=1e-9)
    assert out[1]["sd"] == pytest.approx(out[1]["sampled_sd"], rel=1e-12)
    assert out[0]["sd_over_crb"] == pytest.approx(out[0]["sampled_sd"] / 0.001, rel=1e-12)
    assert out[0]["q05"] < out[0]["sampled_q05"] and out[0]["q95"] > out[0]["sampled_q95"]
    assert rows[0]["model_error_widening"] > 2.0 and rows[1]["model_error_widening"] == 1.0


def test_headline_takes_the_rows_numbers():
    rows = [{"mach": m, "ml": 0.3, "band_sd": 0.001, "determined": 1.0 <= m <= 2.0} for m in np.linspace(0.8, 2.4, 17)]
    h = headline(rows, (1.0, 2.0), False, "the model misses the track; next: bayesdrag diagnose")
    assert h["band"] == "ml" and h["clean"] is False and "next" in h["not_clean_because"]
    assert [p["mach"] for p in h["cd"]] == pytest.approx([1.0, 1.25, 1.5, 1.75, 2.0], abs=0.051)
    assert all(p["determined"] for p in h["cd"])
    assert h["cd"][0]["q95"] - h["cd"][0]["cd"] == pytest.approx(HEADLINE_LEVEL_Z * 0.001)
    assert headline(rows, None, True)["determined_range"] is None


def _residuals(**chans):
    from types import SimpleNamespace

    return SimpleNamespace(residuals={c: np.asarray(v, float) for c, v in chans.items()})


def test_residual_share_follows_the_structured_misfit_that_remains():
    from bayesdrag.pipeline import EFFECT_RESIDUAL_SHARE, residual_share

    rng = np.random.default_rng(7)
    n = 2000
    t = np.linspace(0.0, 1.0, n)
    noise = rng.normal(0.0, 1.0, n)
    # the plain fit leaves a smooth misfit of 5 noise sd, the effect's fit white noise only: the
    # share is white noise's detection limit, far below the cap
    plain = _residuals(x=noise + 5.0 * np.sin(3 * t))
    exact = _residuals(x=rng.normal(0.0, 1.0, n))
    share = residual_share(plain, exact, ("x",), {"x": 1.0})
    limit = np.sqrt(2.0 / np.sqrt(n) / np.mean((5.0 * np.sin(3 * t))**2))
    assert share < 0.5 * EFFECT_RESIDUAL_SHARE
    np.testing.assert_allclose(share, limit, rtol=0.25)
    # a fit that leaves a fifth of the smooth misfit keeps about a fifth of its correction
    part = _residuals(x=rng.normal(0.0, 1.0, n) + 1.0 * np.sin(3 * t))
    np.testing.assert_allclose(residual_share(plain, part, ("x",), {"x": 1.0}), 0.2, atol=0.05)
    # one that removes little is capped; a plain fit with no structure keeps the cap
    assert residual_share(plain, plain, ("x",), {"x": 1.0}) == EFFECT_RESIDUAL_SHARE
    assert residual_share(exact, exact, ("x",), None) == EFFECT_RESIDUAL_SHARE


class _Round:
    """A round with nothing declared: every effect is fittable (plan_effects)."""

    class systematics:
        @staticmethod
        def declared():
            return ()

    class radar:
        time_offset = None
        position_offset = None

    class launch:
        latitude_deg = 45.0


#: parameters of the effects in the close-alternative tests (a wind profile's ten layers, two winds each)
_K = {"wind": 2, "wind_profile": 20, "lift": 1, "coriolis": 1, "temperature": 1, "yaw_drag": 2, "radar_time": 1,
      "radar_position": 3}


def _rows(**shrinks):
    return {"effects": [{"name": n, "shrink": s, "significant": True, "material": True,
                         "params": {f"p{i}": 0.0 for i in range(_K[n])}} for n, s in shrinks.items()]}


def test_close_alternative_is_the_single_effect_the_data_barely_tell_from_the_verdict():
    from bayesdrag.pipeline.model_check import ALTERNATIVE_GAP_RATIO, close_alternative

    # a 6-DOF flight in a head wind: the profile leaves 0.17 % of the gap, a constant wind 0.19 %
    names, instead_of, ratio = close_alternative(_rows(wind_profile=0.9983, wind=0.9981, lift=0.16),
                                                 ("wind_profile",), _Round)
    assert names == ("wind",) and instead_of == "wind_profile" and ratio == pytest.approx(0.0019 / 0.0017)
    # one that leaves ten times the misfit is no alternative (the demo: lift against a wind profile)
    assert close_alternative(_rows(lift=0.99975, wind_profile=0.98457), ("lift",), _Round) is None
    # at the ratio it is, beyond it not
    edge = 1.0 - ALTERNATIVE_GAP_RATIO * 0.01
    assert close_alternative(_rows(lift=0.99, coriolis=edge + 1e-9), ("lift",), _Round)[0] == ("coriolis",)
    assert close_alternative(_rows(lift=0.99, coriolis=edge - 1e-6), ("lift",), _Round) is None
    # the air and the Cd-level effects are never the alternative; a member stays in a two-member verdict
    assert close_alternative(_rows(wind=0.99, temperature=0.995, yaw_drag=0.995), ("wind",), _Round) is None
    names, instead_of, _ = close_alternative(_rows(wind=0.99, lift=0.5, coriolis=0.992), ("wind", "lift"), _Round)
    assert names == ("coriolis", "lift") and instead_of == "wind"
    # a larger explanation the diagnosis passed over is none, however close (a profile beside a
    # constant wind; a radar site beside its clock)
    assert close_alternative(_rows(wind=0.99, wind_profile=0.995), ("wind",), _Round) is None
    assert close_alternative(_rows(radar_time=0.99, radar_position=0.99), ("radar_time",), _Round) is None


def test_alternative_error_adds_the_shift_on_the_answer_s_grid():
    from bayesdrag.pipeline.model_check import alternative_error

    rows = [{"mach": m, "ml": 0.30, "crb_sd": 0.001, "model_error_sd": 0.002} for m in (0.9, 1.0, 1.1)]
    gap = {"alternative": {"mach": [0.8, 1.0, 1.2], "cd": [0.31, 0.33, 0.35], "band_sd": [0.001, 0.001, 0.001]}}
    alternative_error(rows, gap)
    # the alternative's Cd interpolated to 0.32, 0.33, 0.34: shifts 0.02, 0.03, 0.04 added in squares
    np.testing.assert_allclose([r["model_error_sd"] for r in rows], np.hypot(0.002, [0.02, 0.03, 0.04]), rtol=1e-12)
    np.testing.assert_allclose(gap["parts"]["alternative"], [0.02, 0.03, 0.04], rtol=1e-3)


def test_a_yaw_behind_the_verdict_s_drag_shape_is_named_when_it_explains_nearly_as_much():
    from bayesdrag.pipeline.model_check import ALTERNATIVE_GAP_RATIO, shape_confounded

    def dsum(yaw_shrink, shape_shrink=0.77, **yaw):
        row = dict(name="yaw_drag", shrink=yaw_shrink, significant=True, material=True,
                   confounded_with=["drag_shape"], params={"delta0": 0.13, "decay": 0.24})
        row.update(yaw)
        return {"effects": [dict(name="drag_shape", shrink=shape_shrink, significant=True, material=True,
                                 confounded_with=["yaw_drag"]), row]}

    # the measured flight: yaw removes the whole gap alone, the table's shape 77 %
    assert shape_confounded(dsum(1.0), ["drag_shape", "density"]) == ["yaw_drag"]
    # at the ratio's edge and just beyond it (what each leaves alone)
    edge = 1.0 - ALTERNATIVE_GAP_RATIO * (1.0 - 0.77)
    assert shape_confounded(dsum(edge + 1e-9), ["drag_shape"]) == ["yaw_drag"]
    assert shape_confounded(dsum(edge - 1e-3), ["drag_shape"]) == []
    # no drag_shape in the verdict, the yaw in it already, or not significant / material: nothing
    assert shape_confounded(dsum(1.0), ["wind"]) == []
    assert shape_confounded(dsum(1.0), ["drag_shape", "yaw_drag"]) == []
    assert shape_confounded(dsum(1.0, significant=False), ["drag_shape"]) == []
    assert shape_confounded(dsum(1.0, material=False), ["drag_shape"]) == []
    # not confounded with the shape (either row may say so): a distinct effect, not this rule's
    assert shape_confounded(dsum(1.0, confounded_with=[]), ["drag_shape"]) == ["yaw_drag"]
    d = dsum(1.0, confounded_with=[])
    d["effects"][0]["confounded_with"] = []
    assert shape_confounded(d, ["drag_shape"]) == []
    # a yaw pinned at the effect's bounds stands for another shell's table (the robustness
    # suite's G1 bullet with a G7 table: 0.288 rad never damping), not for a launch yaw
    assert shape_confounded(dsum(1.0, params={"delta0": 0.288, "decay": 0.1}), ["drag_shape"]) == []
    assert shape_confounded(dsum(1.0, params={"delta0": 0.3, "decay": 0.5}), ["drag_shape"]) == []
    assert shape_confounded(dsum(1.0, params={"delta0": 0.13, "decay": 0.14}), ["drag_shape"]) == []
