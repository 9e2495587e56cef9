"""The report says what result.json says (issue 27): the budget's total is the band the rows
report and its squares add up to it, the posterior figure shows the posterior as sampled with
the model-error widening as its own term, the page opens with the headline (before any figure),
and the summary line names the next step."""
import json
import math
from html.parser import HTMLParser

import numpy as np
import pytest

from bayesdrag.cli import main
from fixtures.shell155 import write_shell155_inputs

#: the budget is written to 6 significant digits: relative agreement with the rows' band_sd
BUDGET_REL = 1e-5
#: the report's tables print 3 significant digits
TABLE_REL = 5e-3


@pytest.fixture(scope="module")
def fitted(tmp_path_factory, m101):
    """A sampled fit of a 14 s point-mass track with AR(1) noise (rho 0.9): the noise check runs
    and the rows carry a model-error term."""
    d = tmp_path_factory.mktemp("consistency")
    write_shell155_inputs(d, m101, elevation=20.0, seconds=14.0, seed=3, rho=0.9)
    out = d / "out"
    code = main(["fit", str(d / "track.csv"), str(d / "round.toml"), "-o", str(out), "--drag", "reference-scale",
                 "--seed", "2", "--quiet"])
    assert code == 0
    return out, json.loads((out / "result.json").read_text())


def test_budget_total_is_the_band_and_adds_up(fitted):
    _, r = fitted
    b = r["uncertainty_budget"]
    band = np.array([row["band_sd"] for row in r["cd"]])
    np.testing.assert_allclose(b["total_sd"], band, rtol=BUDGET_REL)
    sq = sum(np.asarray(v, float) ** 2 for k, v in b["by_source"].items() if k != "cross")
    np.testing.assert_allclose(sq + np.asarray(b["by_source"]["cross"]), band ** 2, rtol=5 * BUDGET_REL)
    me = np.array([row.get("model_error_sd", 0.0) for row in r["cd"]])
    if np.any(me > 0):
        np.testing.assert_allclose(b["by_source"]["model_error"], me, rtol=BUDGET_REL)


def test_posterior_keys_as_sampled_and_total(fitted):
    _, r = fitted
    for row in r["cd"]:
        assert row["q05"] <= row["sampled_q05"] + 1e-12 and row["sampled_q95"] <= row["q95"] + 1e-12
        assert row["total_sd_over_crb"] >= row["sd_over_crb"] - 1e-12
        assert math.isclose(row["sd_over_crb"], row["sampled_sd"] / row["crb_sd"], rel_tol=1e-9)


def test_sd_ratio_figure_draws_the_json(fitted):
    from bayesdrag.plots.cd import plot_cd_relative

    _, r = fitted
    ax = plot_cd_relative(r["cd"])
    lines = {ln.get_label(): np.asarray(ln.get_ydata(), float) for ln in ax.lines}
    np.testing.assert_allclose(lines["posterior as sampled"], [row["sd_over_crb"] for row in r["cd"]])
    widened = any(row["model_error_widening"] > 1 + 1e-9 for row in r["cd"])
    assert ("total band (with the model-error widening)" in lines) == widened
    if widened:
        np.testing.assert_allclose(lines["total band (with the model-error widening)"],
                                   [row["total_sd_over_crb"] for row in r["cd"]])


def test_budget_table_total_is_the_row_band(fitted):
    from bayesdrag.report.fit import budget_context

    _, r = fitted
    ctx = budget_context(r)
    by_mach = {round(row["mach"], 4): row for row in r["cd"]}
    for row in ctx["rows"]:
        cd_row = by_mach[round(row["mach"], 4)]
        assert math.isclose(row["total"], 100 * cd_row["band_sd"] / cd_row["ml"], rel_tol=TABLE_REL)


def test_headline_matches_the_rows(fitted):
    _, r = fitted
    h = r["headline"]
    assert h["clean"] == r["ml"]["quality"]["ok"]
    assert h["determined_range"] == r["ml"]["mach_range_determined"]
    by_mach = {row["mach"]: row for row in r["cd"]}
    for p in h["cd"]:
        row = by_mach[p["mach"]]
        assert (p["cd"], p["band_sd"], p["q05"], p["q95"]) == (row["ml"], row["band_sd"], row["q05"], row["q95"])
    if not h["clean"]:
        assert "next" in h["not_clean_because"]


class _Order(HTMLParser):
    """Document order of the headline section and the first figure image."""

    def __init__(self):
        super().__init__()
        self.events = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "section" and a.get("id") == "headline":
            self.events.append("headline")
        elif tag in ("figure", "img"):
            self.events.append("figure")


def test_headline_precedes_the_first_figure(fitted):
    out, r = fitted
    p = _Order()
    p.feed((out / "report.html").read_text(encoding="utf-8"))
    assert "headline" in p.events and "figure" in p.events
    assert p.events.index("headline") < p.events.index("figure")


def test_outcome_line_names_the_next_step(fitted, capsys):
    from bayesdrag.pipeline import why_not_clean

    _, r = fitted
    q = r["ml"]["quality"]
    if not q["ok"]:
        assert "next:" in why_not_clean(q)
    noisy_free = {"channels": {"x": {"chi2_per_sample": 50.0, "lag1": 0.9, "n": 100, "rms": 2e-4,
                                     "noise_sd": 1e-5, "noise_source": "estimated"}}}
    msg = why_not_clean(noisy_free)
    assert "misses" not in msg and "noise-free" in msg
    missed = {"channels": {"x": {"chi2_per_sample": 50.0, "lag1": 0.9, "n": 100, "rms": 7.0,
                                 "noise_sd": 1.0, "noise_source": "round"}}}
    assert "bayesdrag diagnose" in why_not_clean(missed)
