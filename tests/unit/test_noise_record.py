"""``ml.noise`` holds the final fit's noise, and the report prints the total sd it holds."""
import math
from types import SimpleNamespace

import pytest

from bayesdrag.estimate.scheme1.fit import noise_record
from bayesdrag.report.fit import noise_used

#: relative tolerance of a total sd rebuilt from its parts [-]
REL = 1e-12


def _res(sigma, ar, model):
    return SimpleNamespace(sigma=sigma, ar=ar, noise_model=model)


def test_the_total_sd_of_an_ar1_channel_adds_its_model_error_part_to_the_white_part():
    # the demo's z channel: nearly all the scatter (1.03 m) in the AR(1) part, 1.3e-4 m white
    res = _res({"z": 1.2663e-4, "v": 0.29}, {"z": (0.0138, 6.566e7)}, {"z": "ar1", "v": "white"})
    stale = {"requested": "auto", "model": {"z": "ar1", "v": "white"}, "ar": {"z": {"rho": 0.9995, "q": 7.33}}}
    rec = noise_record(stale, res)
    assert rec["sd"]["z"] == pytest.approx(1.2663e-4 * math.sqrt(1 + 6.566e7), rel=REL)
    assert 1.0 < rec["sd"]["z"] < 1.1
    assert rec["sd"]["v"] == 0.29
    # the AR(1) parameters are the final fit's, not those of the fit before effects were added
    assert rec["ar"] == {"z": {"rho": 0.0138, "q": 6.566e7}}
    assert stale["ar"]["z"]["rho"] == 0.9995, "the record it starts from is not changed"


def test_a_white_fit_keeps_its_sd_and_has_no_ar_part():
    rec = noise_record({"requested": "white", "model": {"x": "white"}}, _res({"x": 1.5}, {}, {"x": "white"}))
    assert rec["sd"] == {"x": 1.5} and "ar" not in rec


def test_the_report_prints_the_total_sd_and_the_correlation_it_holds():
    noise = {"sd": {"z": 1.0252, "elevation": math.radians(0.01)}, "ar": {"z": {"rho": 0.0138, "q": 6.6e7}}}
    text = noise_used(noise, {"z": 1.27e-4, "elevation": math.radians(0.01)})
    assert text == "z 1.03 m (AR(1), rho 0.0138), elevation 0.01 deg"
    assert "0.000127" not in text
    # an older result.json without ``sd`` falls back to the white sd it holds
    assert noise_used({}, {"x": 2.0}) == "x 2 m"
