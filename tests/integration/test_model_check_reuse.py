"""The model check's fits with the diagnosis's effects are built on the plain fit's stages
(``bayesdrag.pipeline.model_check._from_plain``) instead of repeating them: the same numbers as
``fit_scheme1`` with the effects from the start, for the AR(1) fit and for its white-noise
check, and for a wind profile (fitted before the noise model, on the plain fit's smoothed white
state); and no shortcut where the effects change an earlier stage.

The flight is the honesty suite's point-mass track with a 5 m/s head wind the round does not
declare (its residuals are correlated, so the default noise model takes AR(1) and keeps the
white fit it started from)."""
import numpy as np
import pytest

from acceptance import honesty_suite as hs
from bayesdrag.estimate.scheme1.fit import fit_scheme1
from bayesdrag.pipeline.model_check import _from_plain
from bayesdrag.options import FitOptions

#: the same arithmetic in the same order: equal to rounding, relative [-]
SAME_REL = 1e-9


@pytest.fixture(scope="module")
def flight():
    track, rnd, _ = hs.make(hs.case_by_id("pm-wind-155-01"))
    opts = FitOptions(mcmc=False)
    plain = fit_scheme1(track, rnd, noise_model=opts.noise_model)
    return track, rnd, opts, plain


def _assert_same_fit(built, full):
    assert built.effects == full.effects
    assert built.noise["model"] == full.noise["model"]
    np.testing.assert_allclose(built.ml.theta, full.ml.theta, rtol=SAME_REL, atol=0)
    np.testing.assert_allclose(built.ml.crb, full.ml.crb, rtol=SAME_REL, atol=0)
    np.testing.assert_allclose(built.ml.cost, full.ml.cost, rtol=SAME_REL)
    assert built.ml.success == full.ml.success
    assert (built.white_ml is None) == (full.white_ml is None)


def test_the_effects_on_the_plain_stages_are_the_fit_with_them(flight):
    track, rnd, opts, plain = flight
    assert plain.white_ml is not None, "the flight's AR(1) choice is the premise of the white check below"
    built = _from_plain(plain, rnd, opts, with_effects=("wind",))
    full = fit_scheme1(track, rnd, noise_model=opts.noise_model, with_effects=("wind",), start=plain.start)
    assert built.effects == ("wind",)
    _assert_same_fit(built, full)


def test_the_white_check_adds_the_effects_to_the_white_fit(flight):
    track, rnd, opts, plain = flight
    built = _from_plain(plain, rnd, opts, with_effects=("wind",), noise_model="white")
    full = fit_scheme1(track, rnd, noise_model="white", with_effects=("wind",), start=plain.start)
    assert set(built.noise["model"].values()) == {"white"}
    _assert_same_fit(built, full)
    # the plain fit's own problem keeps its AR(1) noise model
    assert "ar1" in plain.problem.noise_model.values()


@pytest.mark.parametrize("noise_model", [None, "white"])
def test_a_wind_profile_starts_from_the_plain_fits_white_state(flight, noise_model):
    track, rnd, opts, plain = flight
    # the profile is fitted before the noise model: on the white fit the plain fit kept, then the
    # noise model chosen again with the profile in (the plain fit's AR(1) is no part of it)
    change = {} if noise_model is None else {"noise_model": noise_model}
    built = _from_plain(plain, rnd, opts, with_effects=("wind_profile",), wind_layers="altitude", **change)
    full = fit_scheme1(track, rnd, noise_model=noise_model or opts.noise_model, with_effects=("wind_profile",),
                       start=plain.start, wind_layers="altitude")
    assert built.effects == ("wind_profile",)
    _assert_same_fit(built, full)
    assert built.smoothing == full.smoothing
    np.testing.assert_allclose(built.ml_without_effects.theta, full.ml_without_effects.theta, rtol=SAME_REL, atol=0)


@pytest.mark.parametrize("change", [dict(with_effects=("radar_time",)),
                                    dict(with_effects=("wind",), likelihood="student-t"), dict(with_effects=())])
def test_no_shortcut_where_the_effects_change_an_earlier_stage(flight, change):
    _, rnd, opts, plain = flight
    # a clock offset changes the launch check, a Student-t fit reweights from the start: those
    # fits are made whole
    assert _from_plain(plain, rnd, opts, **change) is None


def test_no_shortcut_for_a_profile_once_ar1_is_asked_outright(flight):
    track, rnd, _, _ = flight
    # noise_model="ar1" keeps no white fit: the state the profile is fitted on is gone
    opts = FitOptions(mcmc=False, noise_model="ar1")
    plain = fit_scheme1(track, rnd, noise_model="ar1")
    assert plain.white_ml is None
    assert _from_plain(plain, rnd, opts, with_effects=("wind_profile",)) is None


def _check_with_profile(flight, monkeypatch, carries):
    """The model check of the plain fit against a diagnosis naming ``wind_profile`` on the
    altitude axis, its fits with Cd replaced by the plain fit carrying ``carries(call)``'s
    effects; returns (the record, the calls' keywords)."""
    from dataclasses import replace

    from bayesdrag.estimate.cd.table import cd_grid, cd_table
    from bayesdrag.pipeline import model_check as mc

    track, rnd, opts, plain = flight
    grid = cd_grid(0.9, 2.0)
    rows = cd_table(plain.ml, plain.drag_model, grid)
    calls = []

    def fake_alt(track_, rnd_, opts_, chans_, f1_, grid_, plain=None, **change):
        calls.append(change)
        fit = replace(f1_, effects=carries(len(calls)))
        if set(change["with_effects"]) - set(fit.effects):
            return None     # as _alt_rows answers a fit that dropped an effect asked for
        return np.array([r["ml"] for r in rows]), np.array([r["crb_sd"] for r in rows]), fit

    monkeypatch.setattr(mc, "_alt_rows", fake_alt)
    diagnosis = {"record": {"verdict": ["wind_profile"], "skipped": {},
                            "effects": [{"name": "wind_profile", "cd_shift_max": 0.02,
                                         "layers": {"axis": "altitude"}}]}}
    rec, fit = mc.model_error(track, rnd, opts, track.names, plain, grid, rows, diagnosis=diagnosis)
    return rec, fit, calls


def test_a_profile_is_fitted_on_the_diagnosis_axis_then_on_the_other_when_that_fails(flight, monkeypatch):
    rec, fit, calls = _check_with_profile(flight, monkeypatch, lambda k: ("wind_profile",) if k > 1 else ())
    # the diagnosis's axis first; its fit carried no profile, so the other axis was tried
    assert [c["wind_layers"] for c in calls] == ["altitude", "downrange"]
    assert fit.effects == ("wind_profile",) and rec["effects"] == ["wind_profile"]


def test_a_fit_that_drops_the_effect_sizes_it_by_the_diagnosis(flight, monkeypatch):
    rec, fit, _ = _check_with_profile(flight, monkeypatch, lambda k: ())
    # no fit carried the profile: its shift is not read off a fit without it (that shift is 0)
    assert fit is None
    assert rec["effects_from"].startswith("the diagnosis's Cd shift")
    assert min(rec["parts"]["effects"]) > 0


def test_a_check_fit_that_drops_an_effect_is_no_fit_of_it(flight, monkeypatch):
    from dataclasses import replace

    from bayesdrag.estimate.cd.table import cd_grid
    from bayesdrag.pipeline import model_check as mc

    track, rnd, opts, plain = flight
    # stage C could not add the effect (its fit failed): the plain fit comes back without it
    monkeypatch.setattr(mc, "_from_plain", lambda plain_, rnd_, opts_, **change: replace(plain_, effects=()))
    assert mc._alt_rows(track, rnd, opts, track.names, plain, cd_grid(0.9, 2.0), with_effects=("wind",)) is None
