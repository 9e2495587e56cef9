"""What a user sees while a fit runs (issue 26): ``--quiet`` levels as pip's and logging's, the
sampler's progress toward convergence (not toward ``--max-steps``), and the maximum-likelihood
stage's own progress when it is slow.
"""
import json
import re
import shutil
from importlib.resources import files

import numpy as np
import pytest

from bayesdrag.cli import main
from bayesdrag.commands.runs import PROGRESS_AFTER, StageProgress
from bayesdrag.estimate.bayes.sampler import TAU_FACTOR, steps_to_converge
from bayesdrag.estimate.scheme1.fit import fit_scheme1
from bayesdrag.io.rounds import read_round
from bayesdrag.io.tracks import write_track
from bayesdrag.synthetic import add_noise, simulate_round

ROUND = """\
[projectile]
name = "155 mm"
mass = 42.6
diameter = 0.155
reference_drag = "cd.csv"

[launch]
elevation = 15.0
velocity = {velocity}

[radar]
sigma = {{x = 1.0, y = 1.0, z = 1.0, v = 0.3}}
"""
#: the default --max-steps: the old bar's total
MAX_STEPS = 20000


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """A 66-sample point-mass track (0.5 s), its round, and a round whose launch speed is 25 sd
    off (its fit warns)."""
    d = tmp_path_factory.mktemp("progress")
    shutil.copy(files("bayesdrag") / "data" / "cd_m101.csv", d / "cd.csv")
    (d / "round.toml").write_text(ROUND.format(velocity=818.0))
    (d / "wrong.toml").write_text(ROUND.format(velocity=700.0))
    rnd = read_round(d / "round.toml")
    write_track(d / "track.csv", add_noise(simulate_round(rnd, dt=0.5), rnd.radar.sigma, np.random.default_rng(2)))
    return d


def _run(capsys, argv):
    capsys.readouterr()
    code = main([str(a) for a in argv])
    cap = capsys.readouterr()
    return code, cap.out.splitlines(), cap.err.splitlines()


@pytest.mark.parametrize("quiet, stdout, warnings, notes", [
    ([], True, True, True), (["-q"], False, True, False), (["-qq"], False, False, False)])
def test_quiet_levels(folder, tmp_path, capsys, quiet, stdout, warnings, notes):
    """Default: the summary on stdout, warnings and notes on stderr. ``-q``: nothing on stdout,
    warnings still on stderr. ``-qq``: nothing at all on success."""
    code, out, err = _run(capsys, ["fit", folder / "track.csv", folder / "wrong.toml", "-o", tmp_path / "o",
                                   "--no-mcmc", *quiet])
    assert code == 0
    assert bool(out) == stdout and (not out or out[0].startswith("fit: converged"))
    assert any(e.startswith("bayesdrag: warning: the round's launch speed 700") for e in err) == warnings
    assert all(e.startswith(("bayesdrag: warning:", "bayesdrag: note:")) for e in err), err
    if not notes:
        assert not any("note:" in e for e in err), err
    assert (tmp_path / "o" / "result.json").exists()


def test_quiet_applies_to_every_command(folder, tmp_path, capsys):
    code, out, err = _run(capsys, ["simulate", folder / "round.toml", "-o", tmp_path / "t.csv", "-q"])
    assert code == 0 and out == [] and err == []
    code, out, err = _run(capsys, ["diagnose", folder / "track.csv", folder / "round.toml", "-o", tmp_path / "d",
                                   "-qq"])
    assert code == 0 and out == [] and err == []
    # errors are never silenced
    code, out, err = _run(capsys, ["fit", folder / "track.csv", tmp_path / "none.toml", "-o", tmp_path / "e",
                                   "-qq"])
    assert code == 2 and len(err) == 1 and err[0].startswith("bayesdrag: error:")


def test_sampler_progress_counts_toward_convergence(folder, tmp_path, capsys):
    """The progress lines (stderr not a terminal) say how far the chain is from its
    convergence target, a few hundred steps here, not from --max-steps 20 000."""
    code, out, err = _run(capsys, ["fit", folder / "track.csv", folder / "round.toml", "-o", tmp_path / "s",
                                   "--seed", "1"])
    assert code == 0
    res = json.loads((tmp_path / "s" / "result.json").read_text())
    steps = res["mcmc"]["steps"]
    lines = [e for e in err if e.startswith("mcmc: ")]
    assert lines, err
    for ln in lines:
        m = re.match(r"mcmc: (\d+) of (at least )?~(\d+) steps", ln)
        assert m, ln
        done, target = int(m.group(1)), int(m.group(3))
        assert done <= target < MAX_STEPS / 10, ln
        assert target <= 4 * steps, (ln, steps)
    assert lines[0].startswith("mcmc: 100 of at least ~"), lines[0]     # the first tau is a lower bound


def test_steps_to_converge_is_the_tau_target():
    # 50 tau, or 3 tau of burn-in plus ESS 400 over 16 walkers (25 tau): the larger
    assert steps_to_converge(100, 10.0, 16, 25, MAX_STEPS) == int(TAU_FACTOR * 10.0)
    assert steps_to_converge(100, 10.0, 4, 25, MAX_STEPS) == int(3 * 10 + 400 * 10 / 4)
    assert steps_to_converge(600, 10.0, 16, 25, MAX_STEPS) == 625          # one more block at least
    assert steps_to_converge(100, 1e4, 16, 25, MAX_STEPS) == MAX_STEPS     # never beyond the limit
    assert steps_to_converge(100, float("nan"), 16, 25, MAX_STEPS) == 125


class _Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def test_stage_progress_speaks_only_when_the_stage_is_slow():
    lines, clock = [], _Clock()
    p = StageProgress(lines.append, clock=clock, every=10.0)
    p("stage A")
    clock.t = PROGRESS_AFTER - 0.1
    p("stage B")
    p.done()
    assert lines == []                                   # a quick fit says nothing
    clock.t = PROGRESS_AFTER + 1.0
    p("the whole curve")
    clock.t += 5.0
    p("smoothing fit 2")                                 # within 10 s of the last line: quiet
    clock.t += 6.0
    p("smoothing fit 3")
    clock.t = 60.0
    p.done()
    assert lines == ["bayesdrag: maximum likelihood (4 s): the whole curve",
                     "bayesdrag: maximum likelihood (15 s): smoothing fit 3",
                     "bayesdrag: maximum likelihood done in 60 s"]


def test_the_ml_fit_reports_its_steps(folder):
    from bayesdrag.io.tracks import read_track

    steps = []
    fit_scheme1(read_track(folder / "track.csv"), read_round(folder / "round.toml"), progress=steps.append)
    assert steps[0].startswith("the initial state") and steps[1].startswith("the whole curve")
    assert any(s.startswith("checking the round's launch values") for s in steps)
    assert any(s.startswith("choosing the smoothing by the evidence: fit 1") for s in steps)
