"""Chronograph sessions judged on synthetic series with a known truth and on the real LabRadar
series (slow: about three and four minutes on 2 cores; the runners print the figures)."""
import pytest

from acceptance import run_real_sessions, run_synthetic_sessions

pytestmark = pytest.mark.slow


def test_synthetic_series_no_determined_row_wrong_and_the_central_band_covers():
    s = run_synthetic_sessions.run(n=60, seed=49, log=lambda _: None)["summary"]
    assert s["wrong_rows"] == 0, s["series_with_wrong"]
    assert 0.85 <= s["central_coverage_90"] <= 0.95
    assert s["central_rms_err"] <= 0.01
    assert s["site_within_3sd"] >= 0.9


@pytest.mark.skipif(not run_real_sessions.DATA.is_dir(), reason="the real LabRadar data is not beside the repository")
def test_real_series_honest_without_a_truth():
    s = run_real_sessions.run(log=lambda _: None)["summary"]
    assert s["odd_even_max_abs_z"] <= 3 and s["odd_even_rms_z"] <= 1.3
    assert not s["odd_even_determined_over_3"]
    assert s["same_day_max_abs_z"] <= 3
    assert not s["negative_cd"] and not s["errors"]
