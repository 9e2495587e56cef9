"""The result values without a fit: the Cd table as arrays, bands, the printable summary, the
short repr, loading a folder back."""
import numpy as np
import pytest

from bayesdrag.errors import InputError, MissingDataError
from bayesdrag.results import CdTable, FitResult, Summary, load_diagnosis, load_plan, load_result
from bayesdrag.results.cd import band_z

#: a repr is one short paragraph [characters]
MAX_REPR = 2000
#: the 90 % Gaussian quantile
Z90 = 1.6448536269514722


def _rows(sampled=False, reference=True):
    """result.json-like ``cd`` rows on Mach 1.0-2.0: Cd 0.3 - 0.05 (M - 1), band sd 1e-3,
    undetermined below Mach 1.2."""
    rows = []
    for m in np.round(np.linspace(1.0, 2.0, 11), 4):
        r = {"mach": float(m), "ml": 0.3 - 0.05 * (m - 1), "crb_sd": 8e-4, "crb_sd_statistical": 6e-4,
             "band_sd": 1e-3, "determined": bool(m >= 1.2), "reference": 0.3 if reference else None}
        if sampled:
            r.update(mean=r["ml"], q05=r["ml"] - 0.0015, q95=r["ml"] + 0.0016)
        rows.append(r)
    return rows


def _record(sampled=False):
    q = {"ok": False, "problems": ["channel y: the model misses the track"],
         "channels": {"x": {"chi2_per_sample": 1.02}, "y": {"chi2_per_sample": 14.3}}}
    rec = {"scheme": 1, "drag_model": "spline",
           "ml": {"converged": True, "iterations": 7, "message": "converged", "mach_range_data": [1.0, 2.0],
                  "mach_range_determined": [1.2, 2.0], "warnings": [], "quality": q},
           "cd": _rows(sampled)}
    if sampled:
        rec["mcmc"] = {"converged": True, "walkers": 16, "steps": 300, "draws": 4000, "tau_max": 1.5}
    return rec


# ------------------------------------------------------------------------------------ CdTable
def test_cd_table_from_rows_holds_read_only_arrays():
    t = CdTable.from_rows(_rows(reference=False))
    assert len(t) == 11 and t.mach[0] == 1.0 and t.mach[-1] == 2.0
    assert t.determined.dtype == bool and not t.determined[0] and t.determined[-1]
    assert np.all(np.isnan(t.reference))                 # no reference drag: NaN, not None
    assert t.sd[3] == 1e-3 and t.statistical_sd[3] == 6e-4 and t.crb_sd[3] == 8e-4
    assert t.mean is None and not t.sampled
    with pytest.raises(ValueError, match="read-only"):
        t.ml[0] = 1.0
    assert t.determined_range == (1.2, 2.0)


def test_cd_table_dataframe_columns():
    df = CdTable.from_rows(_rows(sampled=True)).to_dataframe()
    assert list(df.columns)[:4] == ["mach", "ml", "sd", "determined"]
    assert {"reference", "crb_sd", "mean", "q05", "q95"} <= set(df.columns)
    assert len(df) == 11
    assert "mean" not in CdTable.from_rows(_rows()).to_dataframe().columns


def test_cd_table_at_interpolates_inside_and_refuses_outside():
    t = CdTable.from_rows(_rows(sampled=True))
    a = t.at([1.05, 1.5, 2.0])
    assert a.ml == pytest.approx(0.3 - 0.05 * (np.array([1.05, 1.5, 2.0]) - 1), abs=1e-12)
    assert list(a.determined) == [False, True, True]      # 1.05 lies between 1.0 and 1.1: undetermined
    assert t.at(1.15).determined[0] == False              # one neighbour undetermined  # noqa: E712
    assert t.at(1.2).determined[0]                        # on a determined row
    assert a.q95 == pytest.approx(a.ml + 0.0016, abs=1e-12)
    with pytest.raises(InputError, match=r"Mach 2\.5 is outside the table \(1 - 2\).*not extrapolated"):
        t.at([1.5, 2.5])
    with pytest.raises(InputError, match="outside the table"):
        t.at(float("nan"))


def test_cd_tables_compare_by_their_arrays():
    a, b = CdTable.from_rows(_rows()), CdTable.from_rows(_rows())
    assert a == b                                          # NaN-free here; NaN equal to NaN too
    assert CdTable.from_rows(_rows(reference=False)) == CdTable.from_rows(_rows(reference=False))
    rows = _rows()
    rows[4]["ml"] += 1e-6
    assert CdTable.from_rows(rows) != a
    assert CdTable.from_rows(_rows(sampled=True)) != a


def test_band_level_must_be_a_probability():
    assert band_z(0.9) == pytest.approx(Z90, rel=1e-12)
    for bad in (0.0, 1.0, 1.5, -0.1, float("nan")):
        with pytest.raises(InputError, match="not a probability strictly between 0 and 1"):
            band_z(bad)


# ------------------------------------------------------------------------------ FitResult
def test_fit_result_bands_from_its_record():
    res = FitResult(_record())
    lo, hi = res.band(0.9)
    assert np.all(lo < res.cd.ml) and np.all(res.cd.ml < hi)
    assert hi - lo == pytest.approx(np.full(11, 2 * Z90 * 1e-3), rel=1e-9)
    lo5, hi5 = res.band(0.5)
    assert np.all(hi5 - lo5 < hi - lo)
    slo, shi = res.band(0.9, kind="statistical")
    assert shi - slo == pytest.approx(np.full(11, 2 * Z90 * 6e-4), rel=1e-9)
    with pytest.raises(InputError, match=r"band kind 'crb' is not known \(allowed: total, statistical, posterior\)"):
        res.band(0.9, kind="crb")
    with pytest.raises(MissingDataError, match="did not sample: fit with mcmc=True"):
        res.band(0.9, kind="posterior")


def test_fit_result_is_frozen_and_short_to_print():
    res = FitResult(_record(sampled=True), warnings=("channel y: the model misses the track",), seconds=1.5)
    with pytest.raises(AttributeError, match="frozen"):
        res.seconds = 2.0
    text = repr(res)
    assert len(text) <= MAX_REPR
    assert "NOT clean" in text and "determined Mach 1.20-2.00" in text and "1 warning" in text
    s = res.summary()
    assert isinstance(s, Summary)
    out = str(s)
    assert "spline" in out and "chi2 per sample" in out and "y 14.3" in out and "Mach 1.20-2.00" in out
    assert "post. mean" in out
    assert s._repr_html_().startswith("<div>") and "<table>" in s._repr_html_()
    assert FitResult(_record(sampled=True)) == res         # equal record, whatever the timing
    assert FitResult(_record()) != res


def test_fit_result_without_internals_names_what_is_missing():
    res = FitResult(_record())
    with pytest.raises(MissingDataError, match="plot_residuals needs the fit's scheme1, track"):
        res.plot_residuals()
    with pytest.raises(MissingDataError, match="fit with mcmc=True"):
        res.plot_sd_ratio()
    assert res.to_inference_data() is None


def test_fit_result_constructor_takes_the_record_once():
    with pytest.raises(TypeError, match="record="):
        FitResult()
    assert FitResult(summary=_record()) == FitResult(record=_record())


# ------------------------------------------------------------------------------ Summary
def test_summary_text_and_escaped_html():
    s = Summary("t <x>", (("a", "1 & 2"),), ("c1", "c2"), (("1", "<b>"),), ("note",))
    assert "a: 1 & 2" in str(s) and "<b>" in str(s)
    h = s._repr_html_()
    assert "&lt;b&gt;" in h and "1 &amp; 2" in h and "<b>" not in h


# ------------------------------------------------------------------------------ loading
def test_loaders_refuse_what_is_not_a_folder_of_theirs(tmp_path):
    with pytest.raises(InputError, match="no such folder"):
        load_result(tmp_path / "missing")
    with pytest.raises(InputError, match=r"no result\.json in the folder: not a fit result folder"):
        load_result(tmp_path)
    (tmp_path / "result.json").write_text("{")
    with pytest.raises(InputError, match=r"result\.json: not a valid result\.json"):
        load_result(tmp_path)
    (tmp_path / "result.json").write_text('{"scheme": 1}')
    with pytest.raises(InputError, match=r"key\(s\) drag_model, ml, cd missing"):
        load_result(tmp_path)
    with pytest.raises(InputError, match=r"no diagnosis\.json"):
        load_diagnosis(tmp_path)
    with pytest.raises(InputError, match=r"no plan\.json"):
        load_plan(tmp_path)
