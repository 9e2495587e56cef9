"""``bayesdrag plan`` on the command line: exit codes, one-line errors, the files it writes and
their agreement with the Python API (``bayesdrag.plan``)."""
import json
import subprocess
import sys
from importlib.resources import files

import pytest

import bayesdrag
from bayesdrag.cli import main

ROUND = """
[projectile]
name = "155 mm"
mass = 42.6
diameter = 0.155
reference_drag = "{ref}"
mass_sd = 0.05

[launch]
elevation = 15.0
velocity = 818.0

[atmosphere]
density_sd = 0.003

[radar]
{radar}
"""
SIGMA = "sigma = {x = 1.0, y = 1.0, z = 1.0, v = 0.3}"


def _round(tmp_path, radar=SIGMA, name="r.toml"):
    f = tmp_path / name
    f.write_text(ROUND.format(ref=str(files("bayesdrag") / "data" / "cd_m101.csv"), radar=radar))
    return f


def test_plan_writes_json_html_and_figure(tmp_path, capsys):
    r = _round(tmp_path)
    out = tmp_path / "plan"
    code = main(["plan", str(r), "-o", str(out), "--elevations", "15,45", "--velocities", "684,818",
                 "--rounds", "3", "--scatter", "0.01", "--target", "0.005"])
    assert code == 0
    doc = json.loads((out / "plan.json").read_text())
    assert [(c["elevation"], c["velocity"]) for c in doc["cases"]] == [(15.0, 684.0), (15.0, 818.0), (45.0, 684.0),
                                                                       (45.0, 818.0)]
    for c in doc["cases"]:
        assert c["rounds"] == 3 and len(c["mach_range"]) == 2
        assert all(r["sd"] >= 0.003 * r["reference"] for r in c["cd"])  # the density floor
    assert doc["target"]["relative_sd"] == 0.005 and doc["target"]["paragraph"].startswith("Target 0.5 %")
    html = (out / "plan.html").read_text()
    assert "data:image/png;base64," in html and doc["target"]["paragraph"].split(":")[0] in html
    assert (out / "plan.png").stat().st_size > 10_000 and (out / "plan_budget.png").exists()
    assert "Target 0.5 %" in capsys.readouterr().out


def test_plan_output_folder_is_one_consistent_set(tmp_path):
    """Like every command's: a manifest naming the files and the round's bytes, and a second plan
    into the same folder moves the first one's files aside (its plan_budget.png is not left
    looking current when the second writes none)."""
    r = _round(tmp_path)
    out = tmp_path / "plan"
    assert main(["plan", str(r), "-o", str(out), "--elevations", "15"]) == 0
    man = json.loads((out / "manifest.json").read_text())
    assert man["command"] == "plan"
    assert {"plan.json", "plan.html", "plan.png"} <= {f["name"] for f in man["files"]}
    assert (out / "plan.json").exists()
    first = set(p.name for p in out.iterdir())
    r2 = tmp_path / "r2.toml"
    r2.write_text(r.read_text().replace("mass_sd = 0.05\n", "").replace("density_sd = 0.003\n", ""))
    assert main(["plan", str(r2), "-o", str(out), "--elevations", "30"]) == 0
    assert (out / "superseded").is_dir() and "plan_budget.png" in first
    names = {f["name"] for f in json.loads((out / "manifest.json").read_text())["files"]}
    assert (out / "plan_budget.png").exists() == ("plan_budget.png" in names)


def test_api_to_dict_is_plan_json(tmp_path):
    r = _round(tmp_path)
    res = bayesdrag.plan(bayesdrag.read_round(r), elevations=(30.0,), dt=0.05, lock_on=1.0)
    written = res.write(tmp_path / "api")
    assert tmp_path / "api" / "plan.json" in written
    assert json.loads((tmp_path / "api" / "plan.json").read_text()) == res.to_dict()
    assert res.to_dict()["radar"] == {"sigma": {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}, "dt": 0.05, "lock_on": 1.0,
                                      "loss": None}


@pytest.mark.parametrize("args, words", [
    (["--elevations", "5,x"], ["--elevations", "'x' is not a number", "(0, 90) deg"]),
    (["--elevations", "95"], ["--elevations", "95 is outside"]),
    (["--velocities", "0"], ["--velocities", "(0, 3000] m/s"]),
    (["--rounds", "0"], ["--rounds", "positive integer"]),
    (["--target", "2"], ["target", "(0, 1)"]),
    (["--lock-on", "300"], ["lock_on", "lands at"]),
    (["--lock-on", "20", "--loss", "10"], ["loss", "after the lock-on"]),
])
def test_bad_options_exit_2_with_one_line(tmp_path, capsys, args, words):
    r = _round(tmp_path)
    out = tmp_path / "bad"
    assert main(["plan", str(r), "-o", str(out)] + args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("bayesdrag: error:")
    for w in words:
        assert w in err, err
    assert not out.exists()  # nothing written by a refused run


def test_round_without_sigma_exits_2(tmp_path, capsys):
    r = _round(tmp_path, radar="")
    assert main(["plan", str(r), "-o", str(tmp_path / "o")]) == 2
    assert "[radar] sigma" in capsys.readouterr().err


def test_failed_run_leaves_earlier_files(tmp_path):
    r = _round(tmp_path)
    out = tmp_path / "o"
    out.mkdir()
    (out / "plan.json").write_text("{\"earlier\": true}")
    assert main(["plan", str(r), "-o", str(out), "--lock-on", "300"]) == 2
    assert json.loads((out / "plan.json").read_text()) == {"earlier": True}


def test_console_script_runs(tmp_path):
    r = _round(tmp_path)
    p = subprocess.run([sys.executable, "-m", "bayesdrag.cli", "plan", str(r), "-o", str(tmp_path / "o"),
                        "--dt", "0.1"], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "o" / "plan.html").exists()


def test_a_closed_stdout_is_not_an_internal_error(tmp_path):
    """``bayesdrag plan ... | head -c 1``: the reader goes away; the files are written and the
    command stops quietly with 141 (128 + SIGPIPE), no "internal error"."""
    r = _round(tmp_path)
    p = subprocess.Popen([sys.executable, "-m", "bayesdrag.cli", "plan", str(r), "-o", str(tmp_path / "o"),
                          "--dt", "0.1"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.close()                       # nobody reads stdout
    err = p.stderr.read().decode()
    assert p.wait(timeout=300) in (0, 141), err
    assert "internal error" not in err and "Traceback" not in err
    assert (tmp_path / "o" / "plan.json").exists()
