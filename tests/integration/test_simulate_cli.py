"""Synthetic data and the command line: exit codes, one-line errors, files left untouched."""
import subprocess
import sys

import numpy as np
import pytest

from bayesdrag.cli import main
from bayesdrag.synthetic import add_noise, add_outliers, ar1_noise, drop_samples, simulate_round
from bayesdrag.io.rounds import read_round
from bayesdrag.io.tracks import read_track

ROUND = """
[projectile]
name = "155 mm"
mass = 42.6
diameter = 0.155
reference_drag = "{ref}"

[launch]
elevation = 15.0
velocity = 818.0

[radar]
sigma = {{x = 1.0, y = 1.0, z = 1.0, v = 0.3}}
"""


@pytest.fixture
def round_file(tmp_path):
    from importlib.resources import files

    ref = files("bayesdrag") / "data" / "cd_m101.csv"
    f = tmp_path / "r.toml"
    f.write_text(ROUND.format(ref=str(ref)))
    return f


def test_simulate_pointmass_to_impact(round_file):
    tr = simulate_round(read_round(round_file), dt=0.027)
    assert tr.names == ("x", "y", "z", "v")
    assert tr.t[0] == 0.0 and np.allclose(np.diff(tr.t[:-1]), 0.027)
    assert tr.z[-1] == pytest.approx(0.0, abs=1e-6) and np.all(tr.z[1:-1] > 0)
    assert tr.x[-1] == pytest.approx(14043, abs=5)      # 155 mm M101 at 818 m/s, QE 15 deg
    assert tr.v[0] == pytest.approx(818.0)


def test_clock_offset_shifts_samples(round_file):
    rnd = read_round(round_file)
    a = simulate_round(rnd, dt=0.027)
    b = simulate_round(rnd, dt=0.027, clock_offset=0.05)
    # radar time t_rec sees the state of true time t_rec + 0.05
    i = 100
    assert b.t[i] == pytest.approx(a.t[i])
    assert b.x[i] > a.x[i] + 0.04 * a.v[i] * 0.9


def test_noise_statistics(round_file, rng):
    rnd = read_round(round_file)
    clean = simulate_round(rnd, dt=0.027)
    noisy = add_noise(clean, {"x": 2.0, "v": 0.5}, rng)
    d = noisy.x - clean.x
    # sample sd of ~1200 draws: within 4 standard errors (sd/sqrt(2n))
    assert np.std(d) == pytest.approx(2.0, abs=4 * 2.0 / np.sqrt(2 * d.size))
    assert np.array_equal(noisy.z, clean.z)  # no sigma given for z -> unchanged


def test_ar1_noise_correlation(rng):
    e = ar1_noise(20000, 1.5, 0.9, rng)
    assert np.std(e) == pytest.approx(1.5, rel=0.1)
    assert np.corrcoef(e[:-1], e[1:])[0, 1] == pytest.approx(0.9, abs=0.02)


def test_outliers_and_dropouts(round_file, rng):
    clean = simulate_round(read_round(round_file), dt=0.027)
    bad, idx = add_outliers(clean, 0.02, 50.0, {"x": 1.0, "z": 1.0, "y": 1.0, "v": 0.3}, rng)
    assert idx.size == round(0.02 * clean.n)
    assert np.allclose(np.abs(bad.x[idx] - clean.x[idx]), 50.0)
    gapped = drop_samples(clean, fraction=0.1, gaps=[(5.0, 7.0)], rng=rng)
    assert gapped.n < 0.92 * clean.n
    assert not np.any((gapped.t >= 5.0) & (gapped.t <= 7.0))
    with pytest.raises(ValueError, match="needs an rng"):
        drop_samples(clean, fraction=0.1)


def test_cli_simulate_writes_track(round_file, tmp_path, capsys):
    out = tmp_path / "t.csv"
    assert main(["simulate", str(round_file), "-o", str(out), "--noise", "--seed", "3"]) == 0
    tr = read_track(out)
    assert tr.n > 1000 and tr.names == ("x", "y", "z", "v")
    # same seed -> same file; --model 6dof lands too
    out2 = tmp_path / "t2.csv"
    assert main(["simulate", str(round_file), "-o", str(out2), "--noise", "--seed", "3"]) == 0
    assert out.read_text() == out2.read_text()
    out3 = tmp_path / "t6.csv"
    assert main(["simulate", str(round_file), "-o", str(out3), "--model", "6dof"]) == 0
    t6 = read_track(out3)
    assert t6.z[-1] == pytest.approx(0.0, abs=1e-3)
    assert t6.y[-1] > 10.0  # right-hand spin drifts right


@pytest.mark.parametrize("args, match", [
    (["simulate", "{round}", "-o", "{out}", "--model", "3dof"], "invalid choice"),
    (["simulate", "{round}", "-o", "{out}", "--dt", "abc"], "expected a number, got 'abc'"),
    (["simulate", "{missing}", "-o", "{out}"], "not found"),
    (["simulate", "{round}", "-o", "{out}", "--seed", "4"], "--seed only makes sense with --noise"),
    (["simulate", "{round}", "-o", "{nodir}"], "does not exist"),
    (["frobnicate"], "invalid choice"),
])
def test_cli_bad_input_exit_2_one_line(args, match, round_file, tmp_path, capsys):
    keep = tmp_path / "out.csv"
    keep.write_text("precious")
    subs = {"round": str(round_file), "out": str(keep), "missing": str(tmp_path / "nope.toml"),
            "nodir": str(tmp_path / "no" / "such" / "t.csv")}
    code = main([a.format(**subs) for a in args])
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and match in err
    assert "Traceback" not in err
    assert keep.read_text() == "precious"  # a failed run leaves earlier files alone


def test_cli_round_without_reference_drag(tmp_path, capsys):
    f = tmp_path / "r.toml"
    f.write_text("[projectile]\nmass = 42.6\ndiameter = 0.155\n[launch]\nelevation = 10.0\nvelocity = 500.0\n")
    assert main(["simulate", str(f), "-o", str(tmp_path / "t.csv")]) == 2
    assert "reference_drag" in capsys.readouterr().err


def test_cli_subprocess_exit_code_and_no_traceback(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_bytes(b"\x00\xff\xfe garbage [[[")
    p = subprocess.run([sys.executable, "-m", "bayesdrag.cli", "simulate", str(bad), "-o",
                        str(tmp_path / "t.csv")], capture_output=True, text=True)
    assert p.returncode == 2
    assert "Traceback" not in p.stderr and len(p.stderr.strip().splitlines()) == 1
    assert str(bad) in p.stderr


def test_demo_runs(tmp_path, capsys):
    assert main(["demo", "-o", str(tmp_path / "demo")]) == 0
    for f in ("track_vs_pointmass.png", "differences.png", "reference_cd.png", "cd_ml.png", "residuals_ml.png"):
        assert (tmp_path / "demo" / f).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    import json
    summary = json.loads((tmp_path / "demo" / "summary.json").read_text())
    # the 6-DOF shell drifts right (yaw of repose): tens of metres rms in y, < 5 m in x
    assert summary["rms_track_minus_pointmass"]["y"] > 20
    assert summary["rms_track_minus_pointmass"]["x"] < 5
    # the ML fit of the 6-DOF track stays within 2 % of the firing table where Cd is determined
    assert summary["ml_fit"]["max_rel_diff_to_reference_in_determined_range"] < 0.02
    assert str((tmp_path / "demo").resolve()) in capsys.readouterr().out
