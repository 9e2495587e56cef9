"""`bayesdrag demo`: the shipped 6-DOF track through ML + emcee to report.html (slow: the
whole pipeline on 1209 samples and ~54 parameters; tests/test_simulate_cli.py runs it too)."""
import json

import pytest

from bayesdrag.cli import main


@pytest.mark.slow
def test_demo_writes_a_converged_report(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert f"report: {(out / 'report.html').resolve()}" in printed
    r = json.loads((out / "result.json").read_text())
    assert r["mcmc"]["converged"] and max(r["posterior"]["r_hat"].values()) < 1.01
    s = json.loads((out / "summary.json").read_text())
    # the posterior mean of the 6-DOF track's Cd stays within 2 % of M101 where determined
    assert s["max_rel_diff_posterior_mean_to_reference_in_determined_range"] < 0.02
    html = (out / "report.html").read_text()
    assert html.count("data:image/png;base64,") >= 6
    for f in ("posterior.nc", "chain.h5", "cd.png", "corner.png", "traces.png"):
        assert (out / f).exists(), f
    assert not (out / "chain.partial.h5").exists()
