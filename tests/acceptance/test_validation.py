"""Withheld-effect acceptance of the gap diagnosis (issue 6).

Default run: the SMALL subset (point mass, py-ballisticcalc, AR(1) noise, outliers, nulls).
``-m slow``: the full suite (38 withheld effects from 3 simulators and two shells, 20 null
seeds, two 6-DOF nulls)
with the acceptance numbers; ``python tests/acceptance/run_suite.py`` prints the same with a
confusion matrix.
"""
import pytest

from acceptance.cases import (EFFECT_CASES, NULL_CASES, PROFILE_CASES, PROFILE_HOLDOUT, SIXDOF_NULL, SMALL,
                              SMALL_PROFILE, run_case)
from acceptance.run_suite import summarise

#: acceptance (issue 6)
TOP1_MIN, MAG_MIN, SHRINK_MIN, FA_MAX = 0.90, 1.0, 0.9, 0.05


@pytest.mark.parametrize("case", SMALL + SMALL_PROFILE, ids=lambda c: c.id)
def test_small_suite_case(case):
    r = run_case(case)
    assert r["correct"], r
    # issue 26: the fit's origin check fires on the radar-clock case and on nothing else
    assert r["origin_alarm"] == (case.effect == "radar_time"), r
    assert r["text_numbers_not_in_json"] == [], r["paragraph"]
    if r["magnitude_ok"] is not None:
        assert r["magnitude_ok"], r
    if case.effect:
        assert r["shrink"] >= SHRINK_MIN, r
    if r["profile"] is not None:
        assert r["profile"]["ok"], r


#: an effect case whose shrink is below 0.9 beyond its noise, measured and open (docs/diagnosis.md):
#: a 20 ms clock at 7 deg with outliers, 0.54 +- 0.13 since the gross-outlier rule became local
KNOWN_SHRINK_MISSES = {"pm-radar_time-17"}


@pytest.mark.slow
def test_full_suite_meets_the_acceptance():
    results = [run_case(c) for c in EFFECT_CASES + NULL_CASES + SIXDOF_NULL]
    s = summarise(results)
    assert s["n_effect"] >= 30 and s["n_null"] >= 20
    assert s["top1_rate"] >= TOP1_MIN, s
    assert s["false_alarm_rate"] <= FA_MAX, s
    assert s["shrink_ge_0.9_rate"] >= 0.9, s
    # where shrink < 0.9 the effect's remaining gap is within one noise sd of the chi2, but for
    # the one open miss docs/diagnosis.md names ("The two misses"): any other fails
    missed = {r["id"] for r in results if r.get("profile") is None and r["truth"] != "none"
              and r["shrink"] is not None and r["shrink"] + (r.get("shrink_sd") or 0.0) < 0.9}
    assert missed <= KNOWN_SHRINK_MISSES, (missed, s)
    assert s["cases_with_extra_effects"] == 0, s
    assert s["magnitude_rate"] >= 0.9, s
    found, n_clock = (int(v) for v in s["radar_clock_origin_found"].split("/"))
    assert s["false_origin_alarms"] == 0 and found == n_clock > 0, s
    # every number the paragraph and the console lines print is one of diagnosis.json's
    assert all(r["text_numbers_not_in_json"] == [] for r in results), \
        [(r["id"], r["text_numbers_not_in_json"]) for r in results if r["text_numbers_not_in_json"]]


@pytest.mark.slow
@pytest.mark.parametrize("case", PROFILE_CASES + PROFILE_HOLDOUT, ids=lambda c: c.id)
def test_winds_that_change_along_the_flight_are_named_first(case):
    """Issue 29: the verdict names a wind first (never density or drag shape as the cause of the
    wind's signature), the wind named removes >= 90 % of the gap, a warm or cold day is found
    within 25 % of its size, and every number of the texts is the JSON's."""
    r = run_case(case)
    assert r["profile"]["ok"], r
    assert r["text_numbers_not_in_json"] == [], r["paragraph"]
