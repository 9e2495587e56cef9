"""Every effect the fit adds is said where the answer is (issue 47, item 1): a head wind growing
with height, left out of the round, is found and fitted as layers of wind, and the console, the
report's answer and summary() say so with each layer's wind and band, in the numbers result.json
holds. The flight is made by the independent integrator of tests/fixtures/met_flight.py."""
from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from bayesdrag.cli import main
from bayesdrag.results import load_result
from fixtures import met_flight as M

#: the flights' quadrant elevation [deg] and sample interval [s]
QE, DT = 30.0, 0.1
#: a layer's fitted head wind holds the truth's mean over the layer within this many of its sd
LAYER_Z = 3.0


def _growing(alt):
    """A head wind growing smoothly from 2 m/s at the gun to 12 m/s at 3 km (then steady)."""
    h = min(max(alt - M.GUN_ALTITUDE, 0.0), 3000.0)
    return (-2.0 - 10.0 * (1.0 - math.cos(math.pi * h / 3000.0)) / 2.0, 0.0)


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    d = tmp_path_factory.mktemp("wind_told")
    t, pos, v, _, _ = M.fly(_growing, 0.0, qe=QE, dt=DT)
    M.write_track(d, t, pos, v, np.random.default_rng(11))
    (d / "round.toml").write_text(
        f'[projectile]\nmass = 42.6\ndiameter = 0.155\nreference_drag = "{M.REF}"\n[launch]\nelevation = {QE}\n'
        f'velocity = 818.0\nazimuth = 90.0\naltitude = {M.GUN_ALTITUDE}\n[atmosphere]\nmodel = "icao"\n'
        '[radar]\nsigma = {x = 1.0, y = 1.0, z = 1.0, v = 0.3}\n')
    return d


def test_the_wind_found_is_said_on_the_console_the_report_and_summary(fitted, capsys):
    out = fitted / "out"
    assert main(["fit", str(fitted / "track.csv"), str(fitted / "round.toml"), "-o", str(out), "--no-mcmc"]) == 0
    console = capsys.readouterr().out
    doc = json.loads((out / "result.json").read_text())
    we = doc["ml"]["with_effects"]
    assert "wind_profile" in we["effects"]
    layers = we["wind_layers"]["layers"]
    head = re.search(r"found and fitted: wind_profile \(a wind changing along the flight\), (\d+) layers by height", console)
    assert head and int(head.group(1)) == len(layers), console
    # every layer's line says the numbers result.json holds, and the wind it found is the truth's
    for lay in layers:
        line = (f"  {lay['from']:.0f}-{lay['to']:.0f}: wx {lay['wx']:+.1f} ± {lay['wx_sd']:.1f} m/s, "
                f"wy {lay['wy']:+.1f} ± {lay['wy_sd']:.1f} m/s")
        assert line in console, (line, console)
        hs = np.linspace(lay["from"], lay["to"], 21)
        truth = float(np.mean([_growing(h)[0] for h in hs]))
        if lay["wx_sd"] < 2.0:             # layers the flight crosses (the top ones it barely reaches)
            assert abs(lay["wx"] - truth) < LAYER_Z * lay["wx_sd"], (lay, truth)
    html = (out / "report.html").read_text()
    assert "Beside Cd the fit carries what the track shows" in html and "wind_profile" in html
    text = str(load_result(out).summary())
    assert re.search(r"effects fitted:\s+below the table", text) and head.group(0) in text


def test_the_wind_figure_shows_the_layers_beside_the_met(tmp_path):
    """``res.plot_wind()`` and the report's wind.png: the fitted layers with their bands, and the
    met message's wind dashed beside them (the wind given as a METCM, the layers fitted as its
    declared doubt)."""
    import bayesdrag

    t, pos, v, _, _ = M.fly(_growing, 0.0, qe=QE, dt=DT)
    M.write_track(tmp_path, t, pos, v, np.random.default_rng(12))
    profile = M.write_metcm(tmp_path, _growing, 0.0)
    rnd = bayesdrag.read_round(M.write_round(tmp_path, profile, qe=QE))
    res = bayesdrag.fit(bayesdrag.read_track(tmp_path / "track.csv"), rnd, mcmc=False)
    layers = res.record["ml"]["with_effects"]["wind_layers"]["layers"]
    ax = res.plot_wind()
    labels = [line.get_label() for line in ax.get_lines()]
    assert {"wx, met file", "wy, met file", "wx (tail +)", "wy (toward +y, right)"} <= set(labels)
    lo, hi = ax.get_ylim()
    assert lo <= layers[0]["from"] and hi >= layers[-1]["to"]           # every layer drawn
    res.write(tmp_path / "out")
    assert (tmp_path / "out" / "report.html").read_text().count("Wind found and fitted") >= 1
