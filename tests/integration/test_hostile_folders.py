"""Hostile folders and files (issue 25): the reproducers of the attacker's report, each ending with
nothing outside the output folder changed or read, no code from a file run, and exit status 2
with one line naming the problem (or a correct result where the input is in fact fine).

The inputs are the shipped demo round and ``bayesdrag simulate round.toml -o track.csv --noise
--seed 1``. The attacker can write into the folder the user later runs bayesdrag on; the files
"outside" are the user's, elsewhere.
"""
import json
import os
import pickle
import re
import shutil
import stat
from importlib.resources import files
from pathlib import Path

import pytest

from bayesdrag.cli import main
from bayesdrag.io import outputs

#: quick fit options: one drag factor and the initial state
QUICK = ["--no-mcmc", "--quiet", "--drag", "reference-scale", "--seed", "1"]
#: a round folder or output folder name the attacker uses
STAGING = ".staging-20260101T000000Z-1-abcd"


class _Payload:
    """Unpickling this creates ``marker``: proof that a file's content was unpickled."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """The demo round (with its drag table) and its simulated noisy track."""
    d = tmp_path_factory.mktemp("demo")
    for name in ("demo_round.toml", "cd_m101.csv"):
        shutil.copy(files("bayesdrag") / "data" / name, d / name)
    (d / "round.toml").write_text((d / "demo_round.toml").read_text())
    assert main(["simulate", str(d / "round.toml"), "-o", str(d / "track.csv"), "--noise", "--seed", "1"]) == 0
    return d


@pytest.fixture
def case(demo, tmp_path, monkeypatch):
    """A copy of the demo inputs as the working folder, and the user's files elsewhere
    (``outside/``: a secret and a file the attacker wants overwritten)."""
    d = tmp_path / "case"
    shutil.copytree(demo, d)
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "secret.txt").write_text("the user's secret\n")
    (outside / "victim.txt").write_text("the user's file\n")
    monkeypatch.chdir(d)
    return d


def _cli(argv, capsys):
    capsys.readouterr()
    code = main([str(a) for a in argv])
    cap = capsys.readouterr()
    assert "Traceback" not in cap.err
    return code, cap.err.strip().splitlines(), cap.out


def _one_line(code, lines, pattern, status=2):
    assert code == status, f"exit {code}: {lines}"
    assert len(lines) == 1, lines
    assert lines[0].startswith("bayesdrag: error: "), lines
    assert re.search(pattern, lines[0]), f"{lines[0]!r} does not match {pattern!r}"


def _state(folder):
    """Every file under ``folder`` with its bytes and modification time (a write changes one)."""
    return {p.relative_to(folder).as_posix(): (p.read_bytes(), p.stat().st_mtime_ns)
            for p in sorted(Path(folder).rglob("*")) if p.is_file() and not p.is_symlink()}


def _fit(out):
    return ["fit", "track.csv", "round.toml", "-o", out, *QUICK]


def _plan(out, moves, signature=None):
    st = out / STAGING
    st.mkdir(parents=True, exist_ok=True)
    doc = {"format": "bayesdrag-commit/1", "run": "x", "moves": moves}
    if signature is not None:
        doc["signature"] = signature
    (st / ".commit.json").write_text(json.dumps(doc))


# ================================================================== 1. commit plans
@pytest.mark.parametrize("target", ["a folder of the user", "numba's cache"])
def test_a_planted_commit_plan_moves_nothing_through_a_link(case, tmp_path, capsys, target):
    """Reproducer 1: ``out/lnk`` -> a folder outside, ``out/payload.txt`` and a plan moving the
    payload over a file there and a secret from there into ``out``. Pointed at numba's cache, the
    payload is a pickle named like a kernel's index."""
    out = case / "out"
    out.mkdir()
    outside = tmp_path / "outside"
    marker = tmp_path / "PWNED"
    victim = "victim.txt"
    if target == "numba's cache":
        outside = tmp_path / "cache"
        (outside / "bayesdrag_dynamics_kernel_0").mkdir(parents=True)
        (outside / "secret.txt").write_text("secret")
        victim = "bayesdrag_dynamics_kernel_0/kernel.integrate_batch-1.py311.nbi"
    (out / "lnk").symlink_to(outside, target_is_directory=True)
    (out / "payload.txt").write_bytes(pickle.dumps(_Payload(marker)))
    _plan(out, [["payload.txt", f"lnk/{victim}", "in"], ["lnk/secret.txt", "stolen.txt", "in"]])
    before = _state(outside)
    code, lines, _ = _cli(_fit(out), capsys)
    _one_line(code, lines, r"\.commit\.json: an interrupted commit whose plan cannot be used \(a move a commit "
                           r"never makes: .*\); nothing was moved by it: move \.staging-\S+ out of")
    assert _state(outside) == before
    assert not (out / "stolen.txt").exists() and (out / "payload.txt").exists()
    assert not marker.exists()
    assert not (out / "result.json").exists()


def test_a_planted_plan_of_the_right_shape_is_refused_unsigned(case, tmp_path, capsys):
    """A plan shaped like a real commit (a staged file into ``DIR``, an earlier file out to
    ``superseded/``) but not signed with this user's key: nothing moved."""
    out = case / "out"
    out.mkdir()
    (out / "result.json").write_text('{"the user": "result"}')
    _plan(out, [["result.json", "superseded/x/result.json", "out"], [f"{STAGING}/report.html", "report.html", "in"]])
    (out / STAGING / "report.html").write_text("<script>planted</script>")
    before = _state(out)
    code, lines, _ = _cli(_fit(out), capsys)
    _one_line(code, lines, r"cannot be used \(not signed by this user's bayesdrag for this folder\)")
    assert _state(out) == before


def test_a_signed_plan_copied_into_another_folder_is_refused(case, capsys, monkeypatch):
    """A genuine interrupted commit of folder A, copied into folder B: the signature is bound to
    A, so B refuses it; A itself completes it."""
    a, b = case / "a", case / "b"
    assert _cli(_fit(a), capsys)[0] == 0
    real_rename = os.rename
    calls = []

    def dying_rename(src, dst):
        calls.append(src)
        if len(calls) == 2:
            raise KeyboardInterrupt        # a kill half-way through the swap
        real_rename(src, dst)

    monkeypatch.setattr(outputs.os, "rename", dying_rename)
    assert _cli(_fit(a), capsys)[0] == 130
    monkeypatch.setattr(outputs.os, "rename", real_rename)
    (staging,) = a.glob(".staging-*")
    b.mkdir()
    shutil.copytree(staging, b / staging.name)
    shutil.copy(a / "result.json", b / "result.json") if (a / "result.json").exists() else None
    before = _state(b)
    code, lines, _ = _cli(_fit(b), capsys)
    _one_line(code, lines, r"not signed by this user's bayesdrag for this folder")
    assert _state(b) == before
    code, lines, _ = _cli(_fit(a), capsys)
    assert code == 0, lines
    assert not list(a.glob(".staging-*")) and (a / "result.json").exists()


def test_an_interrupted_commit_of_another_user_is_not_carried_out(case, capsys):
    if os.getuid() != 0:
        pytest.skip("needs root to give a folder to another user")
    out = case / "out"
    _plan(out, [["result.json", "superseded/x/result.json", "out"]])
    (out / "result.json").write_text("{}")
    os.chown(out / STAGING, 4242, 4242)
    code, lines, _ = _cli(_fit(out), capsys)
    _one_line(code, lines, r"interrupted commit in a folder of another user \(uid 4242\), never carried out")
    assert (out / "result.json").read_text() == "{}"


# ================================================================== 2. planted superseded/ and round folders
def test_a_superseded_link_is_refused_before_any_work(case, tmp_path, capsys):
    """Reproducer 2: ``out/superseded`` -> a folder outside; a rerun used to move the previous
    run's outputs there."""
    out = case / "out"
    assert _cli(_fit(out), capsys)[0] == 0
    first = _state(out)
    outside = tmp_path / "outside"
    (out / "superseded").symlink_to(outside, target_is_directory=True)
    before = _state(outside)
    code, lines, _ = _cli(_fit(out), capsys)
    _one_line(code, lines, r"out/superseded: is a symbolic link; bayesdrag makes this folder itself")
    assert _state(outside) == before and _state(out) == first


def test_a_superseded_folder_of_another_user_is_refused(case, capsys):
    if os.getuid() != 0:
        pytest.skip("needs root to give a folder to another user")
    out = case / "out"
    assert _cli(_fit(out), capsys)[0] == 0
    (out / "superseded").mkdir()
    os.chown(out / "superseded", 4242, 4242)
    first = _state(out)
    code, lines, _ = _cli(_fit(out), capsys)
    _one_line(code, lines, r"superseded: belongs to another user \(uid 4242\)")
    assert _state(out) == first


@pytest.mark.parametrize("name", ["result.json", "report.html", "chain.partial.h5"])
def test_a_link_where_an_output_goes_is_refused(case, tmp_path, capsys, name):
    out = case / "out"
    out.mkdir()
    (out / name).symlink_to(tmp_path / "outside" / "victim.txt")
    before = _state(tmp_path / "outside")
    argv = _fit(out)
    if name == "chain.partial.h5":        # read only when sampling and resuming
        argv = [a for a in argv if a != "--no-mcmc"] + ["--resume", "--max-steps", "100"]
    code, lines, _ = _cli(argv, capsys)
    assert code == 2 and len(lines) == 1, lines
    assert re.search(r"(a symbolic link where bayesdrag writes an output|the chain file is a symbolic link)",
                     lines[0]), lines
    assert _state(tmp_path / "outside") == before


def _campaign(case, names, **paths):
    text = '[campaign]\nname = "c"\n'
    for n in names:
        text += f'[[rounds]]\nname = "{n}"\ntrack = "{paths.get("track", "track.csv")}"\n' \
                f'round = "{paths.get("round", "round.toml")}"\n'
    (case / "camp.toml").write_text(text)
    return case / "camp.toml"


def test_a_planted_round_folder_link_is_refused(case, tmp_path, capsys):
    """Reproducer 2, campaigns: ``out/r1`` -> a folder outside; the round's outputs went there."""
    _campaign(case, ["r1"])
    out = case / "out"
    out.mkdir()
    (out / "r1").symlink_to(tmp_path / "outside", target_is_directory=True)
    before = _state(tmp_path / "outside")
    code, lines, _ = _cli(["fit", "camp.toml", "-o", out, *QUICK[:2]], capsys)
    _one_line(code, lines, r"out/r1: the folder of round r1 is a symbolic link; bayesdrag makes these folders "
                           r"itself: remove it")
    assert _state(tmp_path / "outside") == before


# ================================================================== 5. names that collide
@pytest.mark.parametrize("name", ["campaign.json", "superseded", "manifest.json", "campaign_cd.png", "done.fit.json",
                                  "chain.partial.h5"])
def test_a_round_named_like_an_output_is_refused(case, capsys, name):
    _campaign(case, [name])
    code, lines, _ = _cli(["fit", "camp.toml", "-o", case / "out", *QUICK[:2]], capsys)
    _one_line(code, lines, rf"camp\.toml: rounds entry 1: name '{re.escape(name)}' is not allowed; .*the name of "
                           rf"a file or folder bayesdrag writes")
    assert not (case / "out").exists()


def test_an_input_named_like_an_output_is_never_moved(case, capsys):
    """Reproducer 5: the track named ``result.json`` in ``-o .``: moved away although inputs
    never are. Now the run refuses to write over it; the input stays."""
    os.rename("track.csv", "result.json")
    before = Path("result.json").read_bytes()
    code, lines, _ = _cli(["fit", "result.json", "round.toml", "-o", ".", *QUICK], capsys)
    _one_line(code, lines, r"result\.json: an input of this run has the name of an output it writes into .*inputs "
                           r"are never moved")
    assert Path("result.json").read_bytes() == before
    assert not Path("superseded").exists() and not Path("manifest.json").exists()


def test_an_input_named_like_the_manifest_is_refused_before_any_work(case, capsys):
    os.rename("round.toml", "manifest.json")
    code, lines, _ = _cli(["fit", "track.csv", "manifest.json", "-o", ".", *QUICK], capsys)
    _one_line(code, lines, r"manifest\.json: the round is named like the manifest bayesdrag writes")


@pytest.mark.parametrize("command", ["fit", "simulate", "plan", "diagnose", "batch"])
def test_an_empty_output_name_is_refused(case, capsys, command):
    """Reproducer 5: ``-o ""`` wrote into the current folder."""
    before = _state(case)
    argv = {"fit": ["fit", "track.csv", "round.toml"], "simulate": ["simulate", "round.toml"],
            "plan": ["plan", "round.toml"], "diagnose": ["diagnose", "track.csv", "round.toml"],
            "batch": ["batch", str(_campaign(case, ["r1"]))]}[command]
    before = _state(case)
    code, lines, _ = _cli(argv + ["-o", ""], capsys)
    _one_line(code, lines, r"command line: -o is empty; give a folder or file name \(\. for the current folder\)")
    assert _state(case) == before


def test_the_user_s_own_link_above_the_folder_is_followed_once(case, tmp_path, capsys):
    """A user's ``-o`` may pass a symbolic link (their own): the run writes where it points."""
    real = tmp_path / "real"
    real.mkdir()
    (case / "results").symlink_to(real, target_is_directory=True)
    code, lines, _ = _cli(_fit(case / "results" / "out"), capsys)
    assert code == 0, lines
    assert (real / "out" / "result.json").is_file() and (real / "out" / "manifest.json").is_file()
    assert stat.S_ISLNK(os.lstat(case / "results").st_mode)
