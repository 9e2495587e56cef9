"""The README's Python tour runs as written (docs with runnable examples)."""
import re
import subprocess
import sys
from pathlib import Path

README = Path(__file__).resolve().parents[2] / "README.md"


def _blocks(lang):
    return [b for l, b in re.findall(r"```(bash|python)\n(.*?)```", README.read_text(), re.S) if l == lang]


def test_readme_python_tour_runs(tmp_path):
    code = _blocks("python")[0]
    p = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    err, shape = p.stdout.split("\n")[:2]
    assert float(err) < 1e-3            # kernel vs scipy, m
    assert shape.startswith("(64, ")


def test_readme_shell_tour_runs(tmp_path):
    tour = [b for b in _blocks("bash") if "bayesdrag simulate" in b][0]
    p = subprocess.run(["bash", "-e", "-c", tour], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "track.csv").exists() and (tmp_path / "track6.csv").exists()
    for out in ("fit/result.json", "fit2/result.json", "fitb/report.html", "fitb/posterior.nc", "diag/diagnosis.json",
                "session/campaign.json", "session/Shot0001/shot.json"):
        assert (tmp_path / out).exists(), out


def test_readme_setup_commands_match_ci():
    text = README.read_text()
    ci = (README.parent / ".ci" / "run").read_text()
    test_cmd = [b for b in _blocks("bash") if "pytest" in b][0].strip()
    assert test_cmd in ci
    assert "bayesdrag demo" in _blocks("bash")[0]
