"""Catalogue of input edges (issue 44, items 7, 8 and 12): inputs that passed validation and then
ended in an internal error, a wrong reason or a file the program's own reader refuses. Each must
now end with exit status 2 and one line on stderr naming the file, key or option, what was found
and what is allowed (docs/formats.md, the command line's contract), or with a correct answer.
"""
import json
import logging
import math
import re
import shutil
import warnings
from importlib.resources import files
from pathlib import Path

import numpy as np
import pytest

from bayesdrag.cli import main
from bayesdrag.errors import InputError
from bayesdrag.io.rounds import read_round
from bayesdrag.io.tracks import read_track, write_track
from bayesdrag.round import RADAR_SITE_MAX, SIGMA_BOUNDS, Radar
from bayesdrag.synthetic import simulate_round
from bayesdrag.track import RadarTrack, SAMPLE_SIGMA_FLOOR

ROOT = Path(__file__).resolve().parents[2]

GUN_ROUND = """\
[projectile]
name = "155 mm"
mass = 42.6
diameter = 0.155
reference_drag = "cd.csv"

[launch]
elevation = 15.0
velocity = 818.0

[radar]
sigma = {x = 1.0, y = 1.0, z = 1.0, v = 0.3}
"""

#: a tracking radar recording its own channels; ``{site}`` is a ``position = ...`` line or empty
NATIVE_ROUND = """\
[projectile]
name = "155 mm M101"
mass = 42.6
diameter = 0.155
reference_drag = "cd.csv"

[launch]
elevation = 45.0
velocity = 818.0
azimuth = 90.0

[radar]
{site}
sigma = {{range = 2.0, azimuth = 0.03, elevation = 0.03, range_rate = 0.1}}
"""
#: radar sample interval of the planned cases [s] (coarse: the plans here test their inputs)
PLAN_DT = 0.1


@pytest.fixture
def folder(tmp_path):
    shutil.copy(files("bayesdrag") / "data" / "cd_m101.csv", tmp_path / "cd.csv")
    return tmp_path


def _error_line(capsys, code, pattern):
    """The run ended with exit 2 and exactly one line on stderr matching ``pattern``."""
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2, f"exit {code}: {err}"
    assert len(lines) == 1, lines
    assert lines[0].startswith("bayesdrag: error: ") and "Traceback" not in err
    assert re.search(pattern, lines[0]), f"{lines[0]!r} does not match {pattern!r}"
    return lines[0]


def _round(folder, text, name="round.toml"):
    (folder / name).write_text(text)
    return folder / name


# --- 7: a noise sd that passes as a number must be a plausible one --------------------------------

@pytest.mark.parametrize("line, pattern", [
    ("x = 1e308, y = 1.0, z = 1.0, v = 0.3", r"\[radar\] sigma\.x = 1e\+308 m is above the plausible 1000 m"),
    ("x = 1.0, y = 1.0, z = 1.0, v = 1e200", r"\[radar\] sigma\.v = 1e\+200 m/s is above the plausible 100 m/s"),
    ("x = 1e-9, y = 1.0, z = 1.0, v = 0.3", r"\[radar\] sigma\.x = 1e-09 m is below 0\.0001"),
])
@pytest.mark.parametrize("command", ["fit", "simulate"])
def test_an_implausible_round_sigma_exits_2_naming_it(folder, capsys, line, pattern, command):
    rnd = _round(folder, GUN_ROUND.replace("x = 1.0, y = 1.0, z = 1.0, v = 0.3", line))
    if command == "fit":
        write_track(folder / "track.csv", simulate_round(read_round(_round(folder, GUN_ROUND, "good.toml")), dt=0.5))
        argv = ["fit", str(folder / "track.csv"), str(rnd), "-o", str(folder / "out"), "--no-mcmc"]
    else:
        argv = ["simulate", str(rnd), "-o", str(folder / "sim.csv"), "--noise", "--seed", "1", "--dt", "0.5"]
    _error_line(capsys, main(argv), r"round\.toml: " + pattern)
    assert not (folder / "sim.csv").exists()


def test_an_implausible_angle_sigma_is_named_in_degrees(folder, capsys):
    rnd = _round(folder, NATIVE_ROUND.format(site="position = {x = -40.0, y = 25.0, z = 2.0}")
                 .replace("azimuth = 0.03,", "azimuth = 20.0,"))
    code = main(["simulate", str(rnd), "-o", str(folder / "sim.csv"), "--radar", "native", "--noise"])
    _error_line(capsys, code, r"\[radar\] sigma\.azimuth = 20 deg is above the plausible 10 deg")


def test_the_radar_refuses_an_implausible_sigma_from_python():
    lo, hi = SIGMA_BOUNDS["m"]
    with pytest.raises(ValueError, match=r"sigma\.x = 1e\+308 m is outside the plausible"):
        Radar({"x": 1e308})
    with pytest.raises(ValueError, match=r"sigma\.azimuth = 1 rad \(57\.2958 deg\) is outside"):
        Radar({"azimuth": 1.0})
    assert Radar({"x": lo, "v": SIGMA_BOUNDS["m/s"][1]}).sigma == {"x": lo, "v": 100.0}
    assert hi == 1000.0


def _with_sample_sigma(folder, value, k=20):
    """The gun track with a ``sigma_v`` column: 0.3 m/s, and ``value`` at data row ``k``."""
    lines = (folder / "track.csv").read_text().splitlines()
    head = next(i for i, ln in enumerate(lines) if not ln.startswith("#"))
    rows = [ln + "," + (value if j == k else "0.3") for j, ln in enumerate(lines[head + 1:])]
    (folder / "sigma.csv").write_text("\n".join(lines[:head] + [lines[head] + ",sigma_v"] + rows) + "\n")
    return folder / "sigma.csv"


@pytest.mark.parametrize("value", ["1e-300", "1e-6"])
def test_a_sample_sigma_below_the_floor_exits_2_naming_the_sample(folder, capsys, value):
    rnd = _round(folder, GUN_ROUND)
    write_track(folder / "track.csv", simulate_round(read_round(rnd), dt=0.5))
    track = _with_sample_sigma(folder, value)
    code = main(["fit", str(track), str(rnd), "-o", str(folder / "out"), "--no-mcmc", "-q"])
    line = _error_line(capsys, code, r"sigma\.csv: sample 21 \(t = 10 s\): sigma_v = " + re.escape(f"{float(value):g}")
                       + r" m/s is below 0\.0001 m/s")
    assert "Mach" not in line


def test_the_track_refuses_a_sample_sigma_below_the_floor_from_python():
    t = np.arange(5.0)
    v = np.linspace(800.0, 700.0, 5)
    RadarTrack(t, {"v": v}, {"sigma_v": np.full(5, SAMPLE_SIGMA_FLOOR["m/s"])})    # at the floor: kept
    with pytest.raises(InputError, match=r"sample 3 \(t = 2 s\): sigma_elevation = 1e-06 deg is below 5e-05 deg"):
        RadarTrack(t, {"elevation": np.full(5, 0.3)},
                   {"sigma_elevation": np.radians([0.03, 0.03, 1e-6, 0.03, 0.03])})
    # a column of a channel the track lacks is not the fit's: kept, not checked
    RadarTrack(t, {"v": v}, {"sigma_x": np.zeros(5)})


# --- 8: plan --radar-sites --------------------------------------------------------------------

def test_radar_sites_led_by_a_minus_sign_are_one_value(folder, capsys):
    """The form the option's own message shows, as a shell passes it: two argv items."""
    rnd = _round(folder, NATIVE_ROUND.format(site="position = {x = -40.0, y = 25.0, z = 2.0}"))
    out = folder / "plan"
    assert main(["plan", str(rnd), "-o", str(out), "--dt", str(PLAN_DT), "--radar-sites", "-40,25,2;0,-30,1"]) == 0
    doc = json.loads((out / "plan.json").read_text())
    assert [c["radar"]["position"] for c in doc["cases"]] == [[-40.0, 25.0, 2.0], [0.0, -30.0, 1.0]]
    assert doc["best_site"]["position"] in ([-40.0, 25.0, 2.0], [0.0, -30.0, 1.0])
    # the angles' noise in the round file's unit, each case named by its site
    assert "azimuth 0.03 deg" in doc["summary"] and "from [0.0, -30.0, 1.0] m" in doc["summary"]
    # a value that is an option is still not taken for the sites
    _error_line(capsys, main(["plan", str(rnd), "-o", str(out), "--radar-sites", "-q"]),
                r"argument --radar-sites: expected one argument")


def test_the_radar_sites_limit_is_the_radars(folder, capsys):
    rnd = _round(folder, NATIVE_ROUND.format(site=""))
    far = 1.5 * RADAR_SITE_MAX
    code = main(["plan", str(rnd), "-o", str(folder / "plan"), f"--radar-sites=0,{far:g},0"])
    _error_line(capsys, code, rf"--radar-sites: .*is {far:.0f} m from the muzzle, more than a radar's plausible "
                              rf"{RADAR_SITE_MAX:g} m")
    assert not (folder / "plan").exists()


@pytest.mark.parametrize("site, words", [
    ("0,0,10", r"passes straight below it at t = 0 s \(the muzzle at launch\)"),
    ("0,0,-10", r"passes straight above it at t = 0 s"),
    ("0,0,0", r"is 0 m from it at t = 0 s \(the muzzle at launch\), nearer than 1 m"),
])
def test_a_site_on_the_guns_vertical_says_why(folder, capsys, site, words):
    rnd = _round(folder, NATIVE_ROUND.format(site=""))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        code = main(["plan", str(rnd), "-o", str(folder / "plan"), "--dt", str(PLAN_DT), f"--radar-sites={site}"])
    line = _error_line(capsys, code, r"radar site \[.*\] m: QE 45 deg, 818 m/s " + words
                       + r".*azimuth and elevation cannot be planned from there")
    assert "drag model" not in line
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)], [str(w.message) for w in caught]


def test_a_site_beside_the_guns_vertical_is_planned(folder):
    rnd = _round(folder, NATIVE_ROUND.format(site="position = {x = 0.0, y = 3.0, z = 10.0}"))
    assert main(["plan", str(rnd), "-o", str(folder / "plan"), "--dt", str(PLAN_DT), "-q"]) == 0


def test_the_docs_quote_every_radar_sites_list():
    """Unquoted, bash plans the first site and runs the others as commands."""
    for page in ("planning.md", "radar.md"):
        text = (ROOT / "docs" / page).read_text(encoding="utf-8")
        uses = re.findall(r"--radar-sites[ =](\S+)", text)
        assert uses, page
        for value in uses:
            if ";" in value:
                assert value[0] in "\"'", f"{page}: --radar-sites {value} is not quoted"


# --- 12: what the simulator writes, the keys the round names, the figures' chatter -----------------

@pytest.mark.parametrize("site, seed", [("", 4), ("position = {x = 0.0, y = 0.0, z = 10.0}", 1)])
def test_simulate_native_writes_only_what_the_reader_reads(folder, capsys, site, seed):
    """A radar at the muzzle (noise makes the first range negative) and one straight above it
    (noise takes the first elevation past -90 deg)."""
    rnd = _round(folder, NATIVE_ROUND.format(site=site))
    out = folder / "native.csv"
    assert main(["simulate", str(rnd), "-o", str(out), "--radar", "native", "--noise", "--seed", str(seed),
                 "--dt", "0.05"]) == 0
    said = capsys.readouterr().out
    track = read_track(out)
    clean = simulate_round(read_round(rnd), channels=("range",), dt=0.05)
    assert 0 < clean.n - track.n <= 3
    assert track.channels["range"].min() >= 0.0 and np.abs(track.channels["elevation"]).max() <= 0.5 * math.pi
    assert "left out that a radar does not record" in said
    assert "left out that a radar does not record" in out.read_text().splitlines()[0]


def test_a_non_finite_device_offset_is_named_as_itself(folder):
    for value in ("nan", "inf"):
        rnd = _round(folder, GUN_ROUND.replace("[radar]\n", f"[radar]\ndevice_offset = {value}\n"))
        with pytest.raises(InputError, match=rf"round\.toml: \[radar\] device_offset must be a finite number "
                                             rf"\(m\), got {value}") as info:
            read_round(rnd)
        assert "position" not in str(info.value)


def test_the_corner_figure_is_quiet(capfd, caplog):
    """corner logs "Too few points to create valid contours" through the root logger for a short
    chain (a resumed run printed it even with -q); the figure is drawn all the same, and nothing
    reaches a log handler or stderr."""
    from bayesdrag.plots.mcmc import plot_corner

    root = logging.getLogger()
    handlers = list(root.handlers)
    draws = np.random.default_rng(0).normal(size=(4, 2))
    with caplog.at_level(logging.WARNING):
        fig = plot_corner({"a": draws[:, 0], "b": draws[:, 1]})
    assert len(fig.axes) == 4
    assert not [r.getMessage() for r in caplog.records if "contours" in r.getMessage()]
    assert "Too few points" not in capfd.readouterr().err
    assert root.handlers == handlers and not root.filters


DOPPLER_ROUND = """\
[projectile]
name = "155 mm M101"
mass = 42.6
diameter = 0.155
reference_drag = "cd.csv"

[launch]
elevation = 45.0
velocity = 818.0
azimuth = 90.0

[radar]
{site}
sigma = {{range_rate = 0.1}}
"""


def test_a_native_track_without_its_site_does_not_understate(folder):
    """A Doppler radar 10 m behind the gun, the round without its site (the muzzle by default):
    the answer is not clean, and its reason must not size the missing site by the fitted site's own
    Cd shift (it said "moves Cd by up to 3.1e-07 %" while no row was determined)."""
    import bayesdrag

    truth = read_round(_round(folder, DOPPLER_ROUND.format(site="position = {x = -10.0, y = 0.0, z = 1.0}"), "t.toml"))
    rnd = read_round(_round(folder, DOPPLER_ROUND.format(site="")))
    clean = simulate_round(truth, channels=("range_rate",), dt=0.2)
    track = RadarTrack(clean.t, {"range_rate": clean.channels["range_rate"]
                                 + 0.1 * np.random.default_rng(3).standard_normal(clean.n)})
    reason = bayesdrag.fit(track, rnd, mcmc=False).to_dict()["headline"]["not_clean_because"]
    assert reason
    assert "radar_position" not in reason or "[radar] position" in reason, reason
    size = re.search(r"moves Cd by up to ([0-9.e+-]+) %", reason)
    assert size is None or float(size.group(1)) >= 1.0, reason
