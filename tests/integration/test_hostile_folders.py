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


# ================================================================== 3. chain files on --resume
@pytest.fixture(scope="module")
def finished(demo, tmp_path_factory):
    """A finished quick sampled run of the demo inputs (100 steps): its output folder."""
    out = tmp_path_factory.mktemp("finished") / "out"
    code = main(["fit", str(demo / "track.csv"), str(demo / "round.toml"), "-o", str(out), "--max-steps", "100",
                 "--quiet", "--drag", "reference-scale", "--seed", "1"])
    assert code == 0
    return out


RESUME = ["fit", "track.csv", "round.toml", "-o", "out", "--resume", "--max-steps", "100", "--quiet", "--drag",
          "reference-scale", "--seed", "1"]


def _planted_chain(case, finished, damage, outside):
    out = case / "out"
    out.mkdir()
    p = out / "chain.partial.h5"
    shutil.copy(finished / "chain.h5", p)
    import h5py

    with h5py.File(p, "a") as f:
        g = f["mcmc"]
        S, W = g["log_prob"].shape
        if damage == "external storage":
            secret = outside / "secret.bin"
            secret.write_bytes((b"the user's secret " * 10_000)[: S * W * 8])
            del g["log_prob"]
            g.create_dataset("log_prob", (S, W), dtype="f8", external=[(str(secret), 0, S * W * 8)])
        elif damage == "virtual dataset":
            layout = h5py.VirtualLayout(shape=(S, W), dtype="f8")
            layout[:] = h5py.VirtualSource(str(outside / "other.h5"), "x", shape=(S, W))
            with h5py.File(outside / "other.h5", "w") as o:
                o.create_dataset("x", data=g["log_prob"][()])
            del g["log_prob"]
            g.create_virtual_dataset("log_prob", layout)
        elif damage == "sparse 600 000-row resize":
            for name in ("chain", "log_prob", "blobs"):
                g[name].resize(600_000, axis=0)
            g.attrs["iteration"] = 600_000
            g["random_state"].attrs["step"] = 600_000
        else:                                          # the posterior moved by 5 %: positions forged
            g["chain"][...] = g["chain"][()] * 1.05
    return out


@pytest.mark.parametrize("damage, pattern", [
    ("external storage", r"dataset 'log_prob' is stored in external files"),
    ("virtual dataset", r"dataset 'log_prob' is a virtual dataset"),
    ("sparse 600 000-row resize", r"it holds 600000 steps, more than this run's --max-steps 100"),
    ("forged positions", r"the stored log posterior at step \d+, walker \d+ is .*not a chain this run made"),
])
def test_resume_refuses_a_planted_chain_before_using_it(case, tmp_path, finished, capsys, damage, pattern):
    """Reproducer 3: a chain whose fingerprint matches (copied from a real run) but that holds
    another file's bytes, other numbers or a sparse giant: one line, exit 2, nothing written."""
    out = _planted_chain(case, finished, damage, tmp_path / "outside")
    before = _state(tmp_path / "outside")
    code, lines, _ = _cli(RESUME, capsys)
    _one_line(code, lines, rf"chain\.partial\.h5: {pattern}.*; delete it to start the chain afresh")
    assert not (out / "posterior.nc").exists() and not (out / "result.json").exists()
    assert _state(tmp_path / "outside") == before
    assert not any(b"the user's secret" in data for data, _ in _state(out).values())


def test_a_genuine_chain_still_resumes(case, finished, capsys):
    out = case / "out"
    out.mkdir()
    shutil.copy(finished / "chain.h5", out / "chain.partial.h5")
    code, lines, _ = _cli(RESUME, capsys)
    assert code == 0, lines
    assert (out / "chain.h5").is_file() and (out / "posterior.nc").is_file()


def test_a_campaign_reads_an_unfinished_chain_only_with_resume(case, finished, capsys):
    """``batch`` (and ``fit CAMPAIGN``) continued any chain.partial.h5 it found."""
    _campaign(case, ["r1"])
    (case / "out" / "r1").mkdir(parents=True)
    shutil.copy(finished / "chain.h5", case / "out" / "r1" / "chain.partial.h5")
    argv = ["fit", "camp.toml", "-o", "out", "--max-steps", "100", "--quiet", "--drag", "reference-scale",
            "--seed", "1"]
    code, lines, _ = _cli(argv, capsys)
    assert code == 1 and any("round r1 (fit) failed: InputError: " in ln and "an unfinished chain of an earlier run "
                             "is there; continue it with --resume" in ln for ln in lines), lines
    assert not (case / "out" / "r1" / "result.json").exists()
    code, lines, _ = _cli(argv + ["--resume"], capsys)
    assert code == 0, lines
    assert (case / "out" / "r1" / "chain.h5").is_file() and (case / "out" / "campaign.json").is_file()


# ================================================================== 4. campaigns read only their own folder
SHADOW = "root:$6$planted$hash:19000:0:99999:7:::\n"


@pytest.fixture
def opened(monkeypatch):
    """Every file the readers open (the one opening function of bayesdrag.io.csv)."""
    from bayesdrag.io import csv as csv_module

    seen = []
    real = csv_module._open_regular

    def spy(path, what):
        seen.append(os.path.realpath(path))
        return real(path, what)

    monkeypatch.setattr(csv_module, "_open_regular", spy)
    return seen


@pytest.mark.parametrize("how", ["absolute", "relative escape", "link in the campaign folder",
                                 "round names a table outside", "round names metcm zones outside"])
def test_a_campaign_never_reads_a_file_outside_its_folder(case, tmp_path, capsys, opened, how):
    """Reproducer 4: ``track = "/etc/shadow"`` (or ``../../../etc/shadow``) printed the file's
    first line and saved it into campaign.json and campaign.html."""
    secret = tmp_path / "outside" / "shadow"
    secret.write_text(SHADOW)
    if how == "absolute":
        _campaign(case, ["r1"], track=str(secret))
    elif how == "relative escape":
        _campaign(case, ["r1"], track="../" * 12 + str(secret).lstrip("/"))
    elif how == "link in the campaign folder":
        (case / "r1.csv").symlink_to(secret)
        _campaign(case, ["r1"], track="r1.csv")
    elif how == "round names a table outside":
        (case / "round.toml").write_text((case / "round.toml").read_text().replace('"cd_m101.csv"', f'"{secret}"'))
        _campaign(case, ["r1"])
    else:       # issue 44 item 3: only reference_drag and profile were confined
        (case / "round.toml").write_text((case / "round.toml").read_text().replace(
            'model = "icao"', f'model = "icao"\nmetcm_zones = "{secret}"'))
        _campaign(case, ["r1"])
    code, lines, _ = _cli(["fit", "camp.toml", "-o", "out", *QUICK[:2]], capsys)
    _one_line(code, lines, r"(outside the campaign's folder .*: move the file there, or pass --allow-outside-inputs)")
    assert str(secret) not in opened
    assert "root:" not in "\n".join(lines)
    assert not (case / "out").exists()


def _secret_nowhere(case, lines, out):
    text = "\n".join(lines) + "".join(data.decode("utf-8", "replace") for data, _ in _state(out).values())
    assert "root:" not in text and "planted" not in text


def test_an_allowed_outside_track_is_never_quoted(case, tmp_path, capsys):
    """With --allow-outside-inputs the file is read, but an error never repeats its content (it
    would go into campaign.json)."""
    secret = tmp_path / "outside" / "shadow"
    secret.write_text(SHADOW)
    _campaign(case, ["r1"], track=str(secret))
    code, lines, _ = _cli(["fit", "camp.toml", "-o", "out", "--allow-outside-inputs", *QUICK[:2]], capsys)
    assert code == 1 and any("round r1 (fit) failed" in ln and "the line is not shown" in ln for ln in lines), lines
    _secret_nowhere(case, lines, case / "out")


@pytest.mark.parametrize("key", ["reference_drag", "metcm_zones"])
def test_a_named_file_is_never_quoted(case, tmp_path, capsys, key):
    """Issue 44 item 3: a token file named as the drag table (or, in a campaign allowed to read
    outside its folder, as the METCM zone table) had its first line quoted on stderr and into
    campaign.json / campaign.html ("header has sk-..."), though it reads like column names."""
    secret = tmp_path / "outside" / "token"
    secret.write_text("sk-planted-0123456789abcdef\n")
    text = (case / "round.toml").read_text()
    if key == "reference_drag":
        (case / "round.toml").write_text(text.replace('"cd_m101.csv"', f'"{secret}"'))
    else:
        (case / "met.txt").write_text("METCM1 345123 151200 0 000013\n00000000 28810013\n01000000 28780012\n")
        (case / "round.toml").write_text(text.replace('model = "icao"',
                                                      f'profile = "met.txt"\nmetcm_zones = "{secret}"'))
    _campaign(case, ["r1"])
    code, lines, _ = _cli(["fit", "camp.toml", "-o", "out", "--allow-outside-inputs", *QUICK[:2]], capsys)
    assert code in (1, 2), lines
    assert any(re.search(r"the (line|header) is not shown", ln) for ln in lines), lines
    _secret_nowhere(case, lines, case / "out")
    text = "\n".join(lines)
    assert "sk-planted" not in text


def test_an_allowed_outside_track_is_never_quoted_by_dask_workers(case, tmp_path):
    import subprocess
    import sys

    secret = tmp_path / "outside" / "shadow"
    secret.write_text(SHADOW)
    _campaign(case, ["r1", "r2"], track=str(secret))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    r = subprocess.run([sys.executable, "-m", "bayesdrag", "batch", "camp.toml", "-o", "out", "--workers", "1",
                        "--quiet", "--allow-outside-inputs", *QUICK[:2]], cwd=case, env=env, capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 1 and "the line is not shown" in r.stderr, r.stderr
    _secret_nowhere(case, [r.stdout, r.stderr], case / "out")


# ================================================================== 6. resources and faults
def test_a_file_size_limit_while_sampling_is_one_line_not_a_segfault(case):
    """EFBIG (``ulimit -f``) while the chain grows: exit 139 before; now the limit is checked
    before each block is written: one line, exit 1, the blocks written kept for --resume."""
    import resource
    import subprocess
    import sys

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (400_000, 400_000))

    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    r = subprocess.run([sys.executable, "-m", "bayesdrag", "fit", "track.csv", "round.toml", "-o", "out",
                        "--max-steps", "20000", "--quiet", "--drag", "reference-scale", "--seed", "1"], cwd=case,
                       env=env, capture_output=True, text=True, timeout=900, preexec_fn=limit)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1, r.stderr
    assert len(lines) == 1 and re.search(r"out: a file would pass the largest size allowed \(File too large: the "
                                         r"file size limit, ulimit -f.*; the unfinished chain stays in "
                                         r".*chain\.partial\.h5", lines[0]), lines
    assert (case / "out" / "chain.partial.h5").stat().st_size <= 400_000
    assert not list((case / "out").glob(".staging-*")) and not (case / "out" / "result.json").exists()


@pytest.mark.parametrize("stdout", ["ascii", "/dev/full"])
def test_a_finished_runs_messages_never_fail_it(case, stdout):
    """An ASCII-only stdout (the plan's paragraph has a degree sign) or ``> /dev/full``: the run
    is finished and its files written; exit 0 (with one note on stderr when stdout is full)."""
    import subprocess
    import sys

    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p), PYTHONIOENCODING="ascii")
    sink = open("/dev/full", "w") if stdout == "/dev/full" else subprocess.PIPE
    try:
        r = subprocess.run([sys.executable, "-m", "bayesdrag", "plan", "round.toml", "-o", "out", "--elevations", "15"],
                           cwd=case, env=env, stdout=sink, stderr=subprocess.PIPE, text=True, timeout=300)
    finally:
        if sink is not subprocess.PIPE:
            sink.close()
    assert r.returncode == 0, r.stderr
    assert (case / "out" / "plan.json").is_file() and (case / "out" / "manifest.json").is_file()
    if stdout == "ascii":
        assert "QE 15\\xb0" in r.stdout and not r.stderr.strip()
    else:
        assert r.stderr.strip().splitlines() == ["bayesdrag: note: the messages of this run could not be written to "
                                                 "stdout (No space left on device); its files are written"]


def test_a_300_character_output_name_is_one_line(case, capsys):
    code, lines, _ = _cli(["fit", "track.csv", "round.toml", "-o", "x" * 300, *QUICK], capsys)
    _one_line(code, lines, r"x{40}\.\.\.x{30} \(300 characters\): the name is too long \(File name too long\)")


@pytest.mark.parametrize("how", ["read-only file", "read-only file system"])
def test_a_read_only_simulate_target_is_one_line(case, capsys, monkeypatch, how):
    target = case / "sim.csv"
    if how == "read-only file":
        target.write_text("t,x\n0,0\n")
        target.chmod(0o444)
        pattern = r"sim\.csv: the output file is read-only; bayesdrag does not replace it"
    else:
        import errno

        real_open = os.open

        def read_only(path, flags, *a, **k):
            if str(path).endswith(".part"):
                raise OSError(errno.EROFS, "Read-only file system", str(path))
            return real_open(path, flags, *a, **k)

        monkeypatch.setattr(outputs.os, "open", read_only)
        pattern = r"the output folder is not writable \(Read-only file system\)"
    code, lines, _ = _cli(["simulate", "round.toml", "-o", target], capsys)
    _one_line(code, lines, pattern)


def test_a_nonsense_mplbackend_is_one_line_before_any_work(case):
    import subprocess
    import sys

    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p), MPLBACKEND="nonsense")
    r = subprocess.run([sys.executable, "-m", "bayesdrag", "fit", "track.csv", "round.toml", "-o", "out", *QUICK],
                       cwd=case, env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and r.stderr.strip().splitlines() == [
        "bayesdrag: error: environment: MPLBACKEND='nonsense' is not a matplotlib backend; unset it (bayesdrag draws "
        "its figures without one) or use e.g. Agg"], r.stderr
    assert not (case / "out").exists()


def test_a_garbage_scheduler_address_is_one_line(case, capsys):
    _campaign(case, ["r1"])
    code, lines, _ = _cli(["batch", "camp.toml", "-o", "out", "--scheduler", "garbage:://x"], capsys)
    _one_line(code, lines, r"option scheduler \(--scheduler\) = 'garbage:://x' is not allowed; give a Dask scheduler "
                           r"address such as tcp://host:8786")
    assert not (case / "out").exists()


@pytest.mark.parametrize("argv, pattern", [
    (["--walkers", "100000"], r"walkers \(--walkers\) = 100000 is not allowed; use at most 1024"),
    (["--max-steps", "100000000"], r"max_steps \(--max-steps\) = 100000000 is not allowed; use at most 1000000"),
    (["--scheme", "2", "--window", "15", "--overlap", "14"],
     r"window \(--window\) = 15 is not allowed; with overlap 14 it makes 1\d{3} Scheme 2 windows of this \d+-sample "
     r"track, and one run fits at most 200"),
])
def test_caps_are_checked_before_anything_is_allocated(case, capsys, monkeypatch, argv, pattern):
    from bayesdrag import pipeline as fit_module

    def no_work(*a, **k):
        raise AssertionError("the fit started before the cap was checked")

    monkeypatch.setattr(fit_module, "scheme1_fit", no_work)
    monkeypatch.setattr(fit_module, "scheme2_fit", no_work)
    code, lines, _ = _cli(["fit", "track.csv", "round.toml", "-o", "out", "--quiet", *argv], capsys)
    _one_line(code, lines, pattern)


def test_more_workers_than_the_cap_are_refused(case, capsys):
    _campaign(case, ["r1"])
    code, lines, _ = _cli(["batch", "camp.toml", "-o", "out", "--workers", "1000"], capsys)
    _one_line(code, lines, r"workers \(--workers\) = 1000 is not allowed; use at most 64")


@pytest.mark.parametrize("craft", ["negative cd", "not a covariance", "nodes off the lattice", "no name",
                                   "reference of another length"])
def test_a_crafted_pooling_input_leaves_its_round_out(case, capsys, craft):
    """A round's pooling.json edited in the folder: the campaign pools the other rounds and
    names the one left out; before, the campaign crashed."""
    _campaign(case, ["r1", "r2"])
    argv = ["fit", "camp.toml", "-o", "out", *QUICK[:2], "--no-mcmc", "--quiet"]
    assert _cli(argv, capsys)[0] == 0
    p = case / "out" / "r2" / "pooling.json"
    doc = json.loads(p.read_text())
    if craft == "negative cd":
        doc["cd"][0] = -0.3
    elif craft == "not a covariance":
        doc["cov"] = [[-1.0 if i == j else 0.0 for j in range(len(doc["cd"]))] for i in range(len(doc["cd"]))]
    elif craft == "nodes off the lattice":
        doc["mach"] = [m + 0.013 for m in doc["mach"]]
    elif craft == "no name":
        del doc["name"]
    else:
        doc["reference"] = [0.3]
    p.write_text(json.dumps(doc))
    (case / "out" / "campaign.json").unlink()
    (case / "out" / "manifest.json").unlink()
    code, lines, _ = _cli(argv, capsys)
    assert code == 1, lines
    assert any(re.search(r"round r2 \(pool\) failed: left out of the pooling: .*pooling\.json: not a pooling input "
                         r"of this version", ln) for ln in lines), lines
    camp = json.loads((case / "out" / "campaign.json").read_text())
    assert camp["rounds"] == ["r1"] and [f["name"] for f in camp["failed"]] == ["r2"]


def test_batch_quiet_prints_nothing(case):
    """``batch --quiet`` printed Dask's "Connection ... has been closed" from the workers. Since
    issue 26 ``-q`` prints nothing on stdout on success either (pip's and logging's levels)."""
    import subprocess
    import sys

    _campaign(case, ["r1", "r2"])
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    r = subprocess.run([sys.executable, "-m", "bayesdrag", "batch", "camp.toml", "-o", "out", "--workers", "2",
                        "--quiet", *QUICK], cwd=case, env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0 and r.stderr == "", r.stderr
    assert r.stdout == "", r.stdout
    assert (case / "out" / "campaign.json").is_file()


def test_batch_quiet_beside_another_cluster(case):
    """Two batches at once: the second's Dask scheduler found its HTTP server's default port
    (8787) taken and warned on stderr although ``--quiet``. Here the port is held by this test
    (or already by something else) while the batch runs."""
    import socket
    import subprocess
    import sys

    _campaign(case, ["r1"])
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    holder = socket.socket()
    try:
        try:
            holder.bind(("", 8787))
            holder.listen(1)
        except OSError:
            pass            # taken already: the condition under test holds
        r = subprocess.run([sys.executable, "-m", "bayesdrag", "batch", "camp.toml", "-o", "out", "--workers", "1",
                            "--quiet", *QUICK], cwd=case, env=env, capture_output=True, text=True, timeout=600)
    finally:
        holder.close()
    assert r.returncode == 0 and r.stderr == "", r.stderr
    assert (case / "out" / "campaign.json").is_file()
