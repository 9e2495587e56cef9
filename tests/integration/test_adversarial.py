"""The adversarial cases of issue 16, end to end through the command line: every one ends with
exit status 2 and one line on stderr (or 1 and one line for a full disk, 130 for Ctrl-C), or
with a correct result; never a traceback, never code from a file run, never earlier outputs
lost or left looking current (the contract (docs/formats.md), command line).

Classes: planted pickles in every file the program reads; the chain checked before a resume;
the output folder as one consistent set (manifest, superseded files, kill, lock, umask, disk
full, unwritable folder, simulate's own inputs, numba's cache); inputs (devices, pipes, bounds,
dense tracks, bad values, misleading cases); Ctrl-C; Dask's log lines. The bad-input catalogue
itself is ``test_bad_input.py``.
"""
import errno
import json
import os
import pickle
import re
import shutil
import signal
import stat
import subprocess
import sys
import time
from importlib.resources import files
from pathlib import Path

import h5py
import numpy as np
import pytest

from bayesdrag.cli import main
from bayesdrag.io.rounds import read_round
from bayesdrag.io.tracks import read_track, write_track
from bayesdrag.synthetic import add_noise, simulate_round

ROUND = """\
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
SIGMA = {"x": 1.0, "y": 1.0, "z": 1.0, "v": 0.3}
#: quick fit options: one drag factor and the initial state
QUICK = ["--drag", "reference-scale", "--seed", "1"]
#: seconds a subprocess may take to reach the state a test waits for
PATIENCE = 240.0
ENV = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))


class _Payload:
    """Unpickling this creates ``marker``: proof that a file's content was unpickled."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def _pickle(marker):
    return pickle.dumps(_Payload(marker))


# ------------------------------------------------------------------ fixtures and helpers
@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """round.toml, its table cd.csv and track.csv: the round's point-mass track every 0.5 s
    with radar noise (65 samples, launch to impact)."""
    d = tmp_path_factory.mktemp("adversarial")
    shutil.copy(files("bayesdrag") / "data" / "cd_m101.csv", d / "cd.csv")
    (d / "round.toml").write_text(ROUND)
    clean = simulate_round(read_round(d / "round.toml"), dt=0.5)
    write_track(d / "track.csv", add_noise(clean, SIGMA, np.random.default_rng(5)))
    return d


@pytest.fixture
def case(base, tmp_path, monkeypatch):
    """A copy of ``base`` as the working folder."""
    d = tmp_path / "case"
    shutil.copytree(base, d)
    monkeypatch.chdir(d)
    return d


def _cli(argv, capsys):
    """(exit status, stderr lines) of ``bayesdrag ARGV`` run in this process."""
    capsys.readouterr()
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return code, err.strip().splitlines()


def _one_line(code, lines, status, pattern):
    assert code == status, f"exit {code}: {lines}"
    assert len(lines) == 1, lines
    assert re.search(pattern, lines[0]), f"{lines[0]!r} does not match {pattern!r}"


def _tree(folder):
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(Path(folder).rglob("*"))
            if p.is_file()}


def _popen(argv, **kw):
    return subprocess.Popen([sys.executable, "-m", "bayesdrag", *map(str, argv)], env=ENV, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **kw)


def _interruptible(argv, **kw):
    """:func:`_popen` with SIGINT at its default in the child, as a terminal's Ctrl-C finds it: a
    test run started in the background (``cmd &`` without job control) ignores SIGINT, the child
    inherits that, and the Ctrl-C tests then saw the fit run to its end (exit 0, and a skip)."""
    return _popen(argv, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL), **kw)


def _wait_for(cond, proc, what):
    t0 = time.monotonic()
    while not cond():
        if proc.poll() is not None:
            raise AssertionError(f"the run ended ({proc.returncode}) before {what}: {proc.communicate()}")
        if time.monotonic() - t0 > PATIENCE:
            proc.kill()
            raise AssertionError(f"no {what} within {PATIENCE} s")
        time.sleep(0.05)


def _staging(out):
    return [p for p in Path(out).glob(".staging-*")]


def _earlier_run(out):
    """An output folder holding an earlier run's files."""
    out.mkdir()
    for name, data in (("result.json", b'{"earlier": true}'), ("posterior.nc", b"earlier netcdf"),
                       ("chain.h5", b"earlier chain"), ("cd.png", b"\x89PNG earlier")):
        (out / name).write_bytes(data)
    return _tree(out)


# ================================================================== security
PLANTED = ["track", "round", "reference_drag", "campaign", "manifest", "commit_plan", "done_marker",
           "pooling"]


@pytest.mark.parametrize("where", PLANTED)
def test_a_planted_pickle_in_a_file_the_program_reads_never_runs(where, case, capsys):
    marker = case / "PWNED"
    payload = _pickle(marker)
    out = case / "out"
    argv = ["fit", "track.csv", "round.toml", "-o", out, "--no-mcmc", "--quiet", *QUICK]
    if where == "track":
        (case / "track.csv").write_bytes(payload)
    elif where == "round":
        (case / "round.toml").write_bytes(payload)
    elif where == "reference_drag":
        (case / "cd.csv").write_bytes(payload)
    elif where == "campaign":
        (case / "camp.toml").write_bytes(payload)
        argv = ["fit", "camp.toml", "-o", out, "--no-mcmc", "--quiet"]
    elif where == "manifest":
        out.mkdir()
        (out / "manifest.json").write_bytes(payload)
    elif where == "commit_plan":
        (out / ".staging-20260101T000000Z-1-abcd").mkdir(parents=True)
        (out / ".staging-20260101T000000Z-1-abcd" / ".commit.json").write_bytes(payload)
    else:
        (case / "camp.toml").write_text('[campaign]\nname = "c"\n[[rounds]]\nname = "a"\ntrack = "track.csv"\n'
                                         'round = "round.toml"\n')
        (out / "a").mkdir(parents=True)
        (out / "a" / ("done.fit.json" if where == "done_marker" else "pooling.json")).write_bytes(payload)
        argv = ["fit", "camp.toml", "-o", out, "--no-mcmc", "--quiet"]
    code, lines = _cli(argv, capsys)
    assert not marker.exists(), "a planted pickle was executed"
    assert code in (0, 2), lines
    if code == 2:
        assert len(lines) == 1 and lines[0].startswith("bayesdrag: error: "), lines


def _planted_chain(path, marker):
    """A chain file of the layout that stored the random state with pickle, its fingerprint
    copied from anywhere."""
    with h5py.File(path, "w") as f:
        g = f.create_group("mcmc")
        g.attrs["iteration"] = 50
        g.attrs["bayesdrag_fingerprint"] = "0123456789abcdef"
        g.attrs["random_state"] = np.void(_pickle(marker))
        g.create_dataset("chain", data=np.zeros((50, 16, 7)))


def test_fit_resume_on_a_planted_chain_exits_2_and_never_runs_it(case, capsys):
    out = case / "out"
    out.mkdir()
    _planted_chain(out / "chain.partial.h5", case / "PWNED")
    code, lines = _cli(["fit", "track.csv", "round.toml", "-o", out, "--resume", "--quiet", *QUICK], capsys)
    _one_line(code, lines, 2, r"chain\.partial\.h5: .*pickle, which is never loaded; delete it")
    assert not (case / "PWNED").exists()


def test_fit_campaign_on_a_planted_chain_reports_the_round_and_never_runs_it(case, capsys):
    (case / "camp.toml").write_text('[campaign]\nname = "c"\n[[rounds]]\nname = "a"\ntrack = "track.csv"\n'
                                     'round = "round.toml"\n')
    (case / "out" / "a").mkdir(parents=True)
    _planted_chain(case / "out" / "a" / "chain.partial.h5", case / "PWNED")
    code, lines = _cli(["fit", "camp.toml", "-o", case / "out", "--quiet", *QUICK[:2]], capsys)
    assert not (case / "PWNED").exists()
    assert code != 0 and any("an unfinished chain of an earlier run is there; continue it with --resume" in ln
                             for ln in lines), lines          # not read unless asked
    code, lines = _cli(["fit", "camp.toml", "-o", case / "out", "--quiet", "--resume", *QUICK[:2]], capsys)
    assert not (case / "PWNED").exists()
    assert code != 0 and any("never loaded" in ln for ln in lines), lines


@pytest.fixture(scope="module")
def finished(base, tmp_path_factory):
    """A finished quick MCMC run of ``base`` (100 steps): its output folder."""
    out = tmp_path_factory.mktemp("finished") / "out"
    code = main(["fit", str(base / "track.csv"), str(base / "round.toml"), "-o", str(out), "--max-steps", "100",
                 "--quiet", *QUICK])
    assert code == 0
    return out


def test_a_chain_made_from_other_input_bytes_is_refused_before_resuming(finished, case, capsys):
    """The fingerprint covers the inputs' bytes: the chain of a track that differs by one comment
    line is refused; the same chain beside the same inputs resumes."""
    out = case / "out"
    out.mkdir()
    shutil.copy(finished / "chain.h5", out / "chain.partial.h5")
    (case / "track.csv").write_text("# one more comment\n" + (case / "track.csv").read_text())
    code, lines = _cli(["fit", "track.csv", "round.toml", "-o", out, "--resume", "--max-steps", "100",
                        "--quiet", *QUICK], capsys)
    _one_line(code, lines, 2, r"chain\.partial\.h5: the stored chain was made with other inputs or settings.*"
                              r"delete it to start the chain afresh")
    assert (out / "chain.partial.h5").exists()


def test_a_chain_of_the_same_inputs_resumes(finished, base, case, capsys):
    out = case / "out"
    out.mkdir()
    shutil.copy(finished / "chain.h5", out / "chain.partial.h5")
    code, lines = _cli(["fit", "track.csv", "round.toml", "-o", out, "--resume", "--max-steps", "100",
                        "--quiet", *QUICK], capsys)
    assert code == 0, lines
    assert (out / "chain.h5").exists() and not (out / "chain.partial.h5").exists()


@pytest.mark.parametrize("damage, pattern", [
    ("nan", r"dataset 'chain' holds non-finite values"),
    ("shape", r"dataset 'chain' has shape .*this run needs"),
    ("symlink", r"the chain file is a symbolic link"),
])
def test_a_damaged_chain_exits_2_with_one_line(finished, case, capsys, damage, pattern):
    out = case / "out"
    out.mkdir()
    p = out / "chain.partial.h5"
    if damage == "symlink":
        p.symlink_to(finished / "chain.h5")
    else:
        shutil.copy(finished / "chain.h5", p)
        with h5py.File(p, "a") as f:
            c = f["mcmc/chain"]
            if damage == "nan":
                c[3, 2, 0] = np.nan
            else:
                data = c[()]
                del f["mcmc/chain"]
                f.create_dataset("mcmc/chain", data=data[:, :, :-1])
    code, lines = _cli(["fit", "track.csv", "round.toml", "-o", out, "--resume", "--max-steps", "100",
                        "--quiet", *QUICK], capsys)
    _one_line(code, lines, 2, pattern)


def test_the_resume_advice_never_loops(finished, case, capsys):
    """Without --resume the unfinished chain is refused with "resume it or delete it"; with
    --resume a chain that cannot be continued says "delete it" (never "rerun with --resume")."""
    out = case / "out"
    out.mkdir()
    shutil.copy(finished / "chain.h5", out / "chain.partial.h5")
    code, lines = _cli(["fit", "track.csv", "round.toml", "-o", out, "--quiet", *QUICK], capsys)
    _one_line(code, lines, 2, r"unfinished chain .*resume it \(fit --resume\) or delete the file")
    code, lines = _cli(["fit", "track.csv", "round.toml", "-o", out, "--resume", "--walkers", "20", "--quiet",
                        *QUICK], capsys)
    _one_line(code, lines, 2, r"delete it to start the chain afresh")
    assert "--resume" not in lines[0]


def test_resume_without_a_chain_starts_afresh_and_says_so(case, capsys):
    code, lines = _cli(["fit", "track.csv", "round.toml", "-o", case / "out", "--resume", "--max-steps", "100",
                        *QUICK], capsys)
    assert code == 0
    assert any("--resume: no unfinished chain" in ln and "starting afresh" in ln for ln in lines), lines


# ================================================================== the output folder
def test_a_no_mcmc_rerun_leaves_no_earlier_posterior_looking_current(finished, case, capsys):
    out = case / "out"
    shutil.copytree(finished, out)
    first = json.loads((out / "manifest.json").read_text())
    assert {"posterior.nc", "chain.h5"} <= {f["name"] for f in first["files"]}
    code, lines = _cli(["fit", "track.csv", "round.toml", "-o", out, "--no-mcmc", "--quiet", *QUICK], capsys)
    assert code == 0, lines
    m = json.loads((out / "manifest.json").read_text())
    now = {p.name for p in out.iterdir() if p.is_file()}
    assert now == {f["name"] for f in m["files"]} | {"manifest.json"}
    assert "posterior.nc" not in now and "chain.h5" not in now and "corner.png" not in now
    old = out / "superseded" / first["run"]
    assert (old / "posterior.nc").is_file() and (old / "chain.h5").is_file() and (old / "manifest.json").is_file()
    assert m["superseded"][0]["run"] == first["run"]
    assert m["inputs"]["track"]["sha256"] == first["inputs"]["track"]["sha256"]


def test_a_folder_written_before_manifests_is_cleaned_up_not_mixed(case, capsys):
    out = case / "out"
    before = _earlier_run(out)
    (out / "notes.txt").write_text("the user's own file")
    code, lines = _cli(["fit", "track.csv", "round.toml", "-o", out, "--no-mcmc", "--quiet", *QUICK], capsys)
    assert code == 0, lines
    assert not (out / "posterior.nc").exists() and not (out / "chain.h5").exists()
    assert (out / "notes.txt").read_text() == "the user's own file"
    moved = next((out / "superseded").iterdir())
    assert {k: v for k, v in _tree(moved).items()} == before


def test_a_run_killed_while_working_leaves_the_earlier_set_and_no_stray_file(case, capsys):
    out = case / "out"
    before = _earlier_run(out)
    # 1000 walkers: a step then takes tens of ms, so the run is still sampling a second after its
    # chain file appears (with 16 it converged within that second once the sampler got faster)
    proc = _interruptible(["fit", "track.csv", "round.toml", "-o", out, "--max-steps", "200000", "--walkers", "1000",
                           *QUICK], cwd=case)
    _wait_for(lambda: (out / "chain.partial.h5").exists(), proc, "sampling")
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert {k: v for k, v in _tree(out).items() if not k.startswith((".staging-", "chain.partial"))} == before
    # the next run removes the killed run's staging folder and leaves nothing half-written
    code, lines = _cli(["fit", "track.csv", "round.toml", "-o", out, "--no-mcmc", "--quiet", *QUICK], capsys)
    assert code == 0, lines
    assert not _staging(out) and not list(out.rglob("*.part"))


def test_two_runs_at_once_are_refused_and_a_killed_runs_lock_does_not_block_resume(case, capsys):
    out = case / "out"
    proc = _popen(["fit", "track.csv", "round.toml", "-o", out, "--max-steps", "200000", *QUICK], cwd=case)
    try:
        _wait_for(lambda: (out / "chain.partial.h5").exists(), proc, "sampling")
        code, lines = _cli(["fit", "track.csv", "round.toml", "-o", out, "--no-mcmc", *QUICK], capsys)
        _one_line(code, lines, 2, rf"out is in use by another bayesdrag run \(pid {proc.pid}\)")
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    # resumed with the killed run's own --max-steps: a smaller one is refused when the killed run
    # had already stored more steps (issue 25's bound), which depends on when the kill lands
    code, lines = _cli(["fit", "track.csv", "round.toml", "-o", out, "--resume", "--max-steps", "200000", "--quiet",
                        *QUICK], capsys)
    assert code == 0, lines
    m = json.loads((out / "manifest.json").read_text())
    assert "chain.h5" in {f["name"] for f in m["files"]}


def test_outputs_follow_the_umask(case, capsys):
    old = os.umask(0o027)
    try:
        code, lines = _cli(["fit", "track.csv", "round.toml", "-o", case / "out", "--no-mcmc", "--quiet", *QUICK],
                           capsys)
        code2, _ = _cli(["simulate", "round.toml", "-o", case / "sim.csv"], capsys)
    finally:
        os.umask(old)
    assert code == 0 and code2 == 0, lines
    modes = {p.name: stat.S_IMODE(p.stat().st_mode) for p in (case / "out").iterdir() if p.is_file()}
    assert modes and set(modes.values()) == {0o640}, modes
    assert stat.S_IMODE((case / "sim.csv").stat().st_mode) == 0o640


@pytest.mark.parametrize("target", ["round.toml", "cd.csv"])
def test_simulate_refuses_to_overwrite_its_own_inputs(case, capsys, target):
    before = (case / target).read_bytes()
    code, lines = _cli(["simulate", "round.toml", "-o", target], capsys)
    _one_line(code, lines, 2, r"an input of this run; write the track to another file")
    assert (case / target).read_bytes() == before


def test_a_full_disk_while_writing_is_one_line_exit_1_and_nothing_lost(case, capsys, monkeypatch):
    from bayesdrag import results

    out = case / "out"
    before = _earlier_run(out)

    def full(self, directory, **kw):
        (Path(directory) / "result.json").write_text("{")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(results.FitResult, "write_files", full)
    code, lines = _cli(["fit", "track.csv", "round.toml", "-o", out, "--no-mcmc", *QUICK], capsys)
    _one_line(code, lines, 1, r"the disk is full .*earlier outputs are untouched")
    assert _tree(out) == before


def test_a_full_disk_while_sampling_keeps_the_chain_for_resume(case, capsys, monkeypatch):
    from bayesdrag.io import chain
    from bayesdrag.io.outputs import DiskFullError

    calls = []

    def filling(folder, nbytes, what):
        calls.append(what)
        if len(calls) > 2:
            raise DiskFullError(f"{folder}: the disk is full (0 bytes free) while writing {what}")

    monkeypatch.setattr(chain, "ensure_space", filling)
    out = case / "out"
    code, lines = _cli(["fit", "track.csv", "round.toml", "-o", out, "--max-steps", "100000", "--quiet", *QUICK],
                       capsys)
    _one_line(code, lines, 1, r"the disk is full.*unfinished chain stays in .*chain\.partial\.h5.*--resume")
    with h5py.File(out / "chain.partial.h5", "r") as f:
        assert f["mcmc"].attrs["iteration"] > 0
    assert not (out / "result.json").exists()


@pytest.fixture
def small_disk(tmp_path):
    """A 3 MB tmpfs (root only; skipped elsewhere), unmounted afterwards."""
    mnt = tmp_path / "small"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=3m", "tmpfs", str(mnt)], capture_output=True)
    if r.returncode != 0:
        pytest.skip("cannot mount a small tmpfs here (needs root)")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", str(mnt)], capture_output=True)


def test_a_really_full_disk_while_sampling_is_one_line_not_a_segfault(case, small_disk):
    """The issue's case on a real file system: 33 lines of h5py tracebacks and a segfault (exit
    139) became one line, exit 1, with the unfinished chain kept."""
    (small_disk / "filler").write_bytes(b"\0" * 1_500_000)
    out = small_disk / "out"
    r = subprocess.run([sys.executable, "-m", "bayesdrag", "fit", "track.csv", "round.toml", "-o", str(out),
                        "--max-steps", "400", "--quiet", "--seed", "1"], env=ENV, cwd=case, capture_output=True,
                       text=True, timeout=600)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1, r.stderr
    assert len(lines) == 1 and "the disk is full" in lines[0] and "Traceback" not in r.stderr, lines
    assert not (out / "result.json").exists() and not _staging(out)


@pytest.mark.parametrize("where", ["under a file", "is a file"])
def test_an_unusable_output_folder_is_refused_before_any_work(case, capsys, monkeypatch, where):
    from bayesdrag.commands import fit as fit_module

    def no_fit(*a, **k):
        raise AssertionError("the fit ran before the output folder was checked")

    monkeypatch.setattr(fit_module, "fit", no_fit)
    out = case / "track.csv" / "out" if where == "under a file" else case / "cd.csv"
    code, lines = _cli(["fit", "track.csv", "round.toml", "-o", out, "--no-mcmc", *QUICK], capsys)
    _one_line(code, lines, 2, r"(cannot create the output folder|output path exists and is not a folder)")


def _clean_env(tmp_path):
    """The environment of a new user: a fresh home and cache folder, no numba settings."""
    env = {k: v for k, v in ENV.items()
           if k not in ("NUMBA_CACHE_DIR", "NUMBA_CACHE_LOCATOR_CLASSES", "OMP_WAIT_POLICY")}
    (tmp_path / "home").mkdir(exist_ok=True)
    (tmp_path / "cache").mkdir(exist_ok=True)
    return dict(env, HOME=str(tmp_path / "home"), XDG_CACHE_HOME=str(tmp_path / "cache"))


def _files_under(folder):
    return sorted(p.relative_to(folder).as_posix() for p in Path(folder).rglob("*"))


#: a Python snippet: compile (or load) one cached function of the package and print the settings
_FIRST_USE = """
import json, os
import numpy as np
{first}
from bayesdrag.estimate.model import colored
colored.whitened_ss(np.zeros((2, 5)), 0.5, 1.0, np.ones(4))
print(json.dumps({{k: os.environ.get(k) for k in ("NUMBA_CACHE_DIR", "OMP_WAIT_POLICY", "NUMBA_CACHE_LOCATOR_CLASSES")}}))
"""


def test_import_bayesdrag_changes_no_variable_and_creates_no_file(tmp_path, base):
    """``import bayesdrag`` and reading a track: the environment is as before, no file or folder
    appears in the home or cache folder, numba is not even imported."""
    env = _clean_env(tmp_path)
    code = ("import json, os, sys\nbefore = dict(os.environ)\nimport bayesdrag\n"
            f"tr = bayesdrag.read_track({str(base / 'track.csv')!r})\n"
            "print(json.dumps({'same': dict(os.environ) == before, 'numba': 'numba' in sys.modules, 'n': tr.n}))")
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    out = json.loads(r.stdout)
    assert out == {"same": True, "numba": False, "n": read_track(base / "track.csv").n}, out
    assert _files_under(tmp_path / "home") == [] and _files_under(tmp_path / "cache") == []


@pytest.mark.parametrize("first", ["from bayesdrag.dynamics import kernel", "from bayesdrag.estimate.bayes import posterior"])
def test_the_first_kernel_use_caches_in_the_private_folder(tmp_path, first):
    """Where the compiled functions are first needed the settings are made: the cache in the
    per-user folder (0700), numba's threads passive; also when a module that imports numba
    itself (the AR(1) filter) is imported before the dynamics."""
    env = _clean_env(tmp_path)
    r = subprocess.run([sys.executable, "-c", _FIRST_USE.format(first=first + "\nimport bayesdrag.dynamics")],
                       env=env, capture_output=True, text=True, check=True)
    settings = json.loads(r.stdout.strip().splitlines()[-1])
    cache = tmp_path / "cache" / "bayesdrag" / "numba"
    assert settings["NUMBA_CACHE_DIR"] == str(cache) and settings["OMP_WAIT_POLICY"] == "PASSIVE"
    assert settings["NUMBA_CACHE_LOCATOR_CLASSES"].split(",")[0] == "bayesdrag._runtime.numba_cache.PackageCacheLocator"
    assert stat.S_IMODE(cache.stat().st_mode) == 0o700 and stat.S_IMODE(cache.parent.stat().st_mode) == 0o700
    assert [p for p in cache.rglob("colored.*.nbi")], _files_under(cache)
    assert not r.stderr.strip(), r.stderr


def test_a_users_own_numba_settings_are_respected(tmp_path):
    env = dict(_clean_env(tmp_path), NUMBA_CACHE_DIR=str(tmp_path / "mine"), OMP_WAIT_POLICY="ACTIVE")
    r = subprocess.run([sys.executable, "-c", _FIRST_USE.format(first="import bayesdrag.dynamics")], env=env,
                       capture_output=True, text=True, check=True)
    settings = json.loads(r.stdout.strip().splitlines()[-1])
    assert settings["NUMBA_CACHE_DIR"] == str(tmp_path / "mine") and settings["OMP_WAIT_POLICY"] == "ACTIVE"
    assert [p for p in (tmp_path / "mine").rglob("colored.*.nbi")]
    assert _files_under(tmp_path / "cache") == []


@pytest.mark.parametrize("how", ["default folder writable by others", "NUMBA_CACHE_DIR writable by others",
                                 "default folder is a symbolic link"])
def test_a_cache_folder_others_can_write_is_never_loaded(tmp_path, how):
    """Reproducer 1's end: a pickle moved over a kernel's cache index ran in the next fit. A cache
    folder others can write (or a link to one) is not used: the functions are compiled into a
    private folder for this run, one note says why, the planted index never runs."""
    env = _clean_env(tmp_path)
    snippet = _FIRST_USE.format(first="import bayesdrag.dynamics")
    # the names numba gives the cache files, from a clean run
    clean = tmp_path / "clean"
    subprocess.run([sys.executable, "-c", snippet], env=dict(env, NUMBA_CACHE_DIR=str(clean)), check=True,
                   capture_output=True)
    names = [p.relative_to(clean) for p in clean.rglob("*.nbi")]
    assert names
    marker = tmp_path / "PWNED"
    shared = tmp_path / "shared"
    for rel in names:
        (shared / rel).parent.mkdir(parents=True, exist_ok=True)
        (shared / rel).write_bytes(_pickle(marker))
    for d in [shared, *shared.rglob("*")]:
        if d.is_dir():
            d.chmod(0o777)
    if how == "NUMBA_CACHE_DIR writable by others":
        env["NUMBA_CACHE_DIR"] = str(shared)
    elif how == "default folder writable by others":
        (tmp_path / "cache" / "bayesdrag").mkdir(mode=0o700)
        shared.rename(tmp_path / "cache" / "bayesdrag" / "numba")
        shared = tmp_path / "cache" / "bayesdrag" / "numba"
    else:
        (tmp_path / "evil").mkdir(mode=0o777)
        shared.rename(tmp_path / "evil" / "numba")
        shared = tmp_path / "evil" / "numba"
        (tmp_path / "cache" / "bayesdrag").symlink_to(tmp_path / "evil", target_is_directory=True)
    before = _tree(shared)
    r = subprocess.run([sys.executable, "-c", snippet], env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert not marker.exists(), "a planted cache index was unpickled"
    assert _tree(shared) == before
    notes = r.stderr.strip().splitlines()
    assert len(notes) == 1 and re.search(r"numba's cache folder is not used: .*(written by others|symbolic link)",
                                         notes[0]), notes
    used = json.loads(r.stdout.strip().splitlines()[-1])["NUMBA_CACHE_DIR"]
    assert not Path(used).exists(), "the run's own cache folder was not removed at exit"


# ================================================================== inputs
@pytest.mark.parametrize("role", ["track", "reference_drag"])
def test_a_device_is_refused_not_read(case, capsys, role):
    if role == "track":
        argv = ["fit", "/dev/zero", "round.toml", "-o", "out", "--no-mcmc"]
    else:
        (case / "round.toml").write_text(ROUND.replace('"cd.csv"', '"/dev/zero"'))
        argv = ["fit", "track.csv", "round.toml", "-o", "out", "--no-mcmc"]
    code, lines = _cli(argv, capsys)
    _one_line(code, lines, 2, r"/dev/zero: (track|drag table) is a device, not a regular file")


def test_a_pipe_is_refused_without_waiting_for_a_writer(case):
    os.mkfifo(case / "pipe.csv")
    r = subprocess.run([sys.executable, "-m", "bayesdrag", "fit", "pipe.csv", "round.toml", "-o", "out", "--no-mcmc"],
                       env=ENV, cwd=case, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "pipe.csv: track is a pipe, not a regular file" in r.stderr, r.stderr


def test_a_track_larger_than_the_bound_is_refused_by_its_size(case, capsys, monkeypatch):
    from bayesdrag.io import csv as csv_module

    monkeypatch.setitem(csv_module.MAX_BYTES, "track", 1000)
    code, lines = _cli(["fit", "track.csv", "round.toml", "-o", "out", "--no-mcmc"], capsys)
    _one_line(code, lines, 2, r"track\.csv: track is \d+ bytes, more than the 1000 allowed; thin it")


def test_a_very_dense_track_is_decimated_with_a_note_and_fitted(case, capsys):
    """A 50 000-sample track (0.65 ms apart): thinned to at most 10 000 samples, with a note
    that says so, and fitted in reasonable time (a 325 000-row one did not finish in 5 min)."""
    tr = read_track(case / "track.csv")
    t = np.linspace(tr.t[0], tr.t[-1], 50_000)
    dense = type(tr)(t, {c: np.interp(t, tr.t, a) for c, a in tr.channels.items()}, {})
    write_track(case / "dense.csv", dense)
    t0 = time.perf_counter()
    code, lines = _cli(["fit", "dense.csv", "round.toml", "-o", "out", "--no-mcmc", *QUICK], capsys)
    assert code == 0, lines
    assert any(re.search(r"50000 samples .* using every 5th \(10001 samples\)", ln) for ln in lines), lines
    assert time.perf_counter() - t0 < 120


@pytest.mark.parametrize("argv_tail, pattern", [
    (["--clock-offset", "nan"], r"--clock-offset: expected a finite number, got 'nan'"),
    (["--clock-offset", "inf"], r"--clock-offset: expected a finite number, got 'inf'"),
    (["--clock-offset", "1000"], r"clock_offset = 1000.0 is not allowed; use a finite offset within \+-1 s"),
], ids=["nan", "inf", "1000"])
def test_bad_clock_offsets_exit_2(case, capsys, argv_tail, pattern):
    code, lines = _cli(["simulate", "round.toml", "-o", "sim.csv", *argv_tail], capsys)
    _one_line(code, lines, 2, pattern)
    assert not (case / "sim.csv").exists()


def test_max_steps_1_exits_2_and_leaves_no_chain(case, capsys):
    code, lines = _cli(["fit", "track.csv", "round.toml", "-o", "out", "--max-steps", "1", *QUICK], capsys)
    _one_line(code, lines, 2, r"max_steps \(--max-steps\) = 1 is not allowed; use an integer >= 100")
    assert not (case / "out").exists() or not list((case / "out").iterdir())


def test_a_density_ratio_of_1e_12_exits_2(case, capsys):
    (case / "round.toml").write_text(ROUND + "\n[atmosphere]\ndensity_ratio = 1e-12\n")
    code, lines = _cli(["fit", "track.csv", "round.toml", "-o", "out", "--no-mcmc"], capsys)
    _one_line(code, lines, 2, r"round\.toml: \[atmosphere\] density_ratio = 1e-12 is outside 0\.5 \.\. 2")


@pytest.mark.parametrize("which", ["round", "campaign"])
def test_a_5000_deep_nested_toml_array_exits_2(case, capsys, which):
    deep = "a = " + "[" * 5000 + "]" * 5000 + "\n"
    if which == "round":
        (case / "round.toml").write_text(ROUND + "\n[extra]\n" + deep)
        argv = ["fit", "track.csv", "round.toml", "-o", "out", "--no-mcmc"]
    else:
        (case / "campaign.toml").write_text('[campaign]\nname = "c"\n' + deep)
        argv = ["fit", "campaign.toml", "-o", "out", "--no-mcmc"]
    code, lines = _cli(argv, capsys)
    _one_line(code, lines, 2, rf"{which}\.toml: not a {which} file: arrays or tables nested too deeply")


def _edit_track(d, fn):
    tr = read_track(d / "track.csv")
    write_track(d / "bad.csv", fn(tr))


def test_a_track_flying_toward_minus_x_is_fitted_correctly_with_a_note(case, capsys):
    _edit_track(case, lambda tr: type(tr)(tr.t, dict(tr.channels, x=-tr.channels["x"]), {}))
    code, lines = _cli(["fit", "bad.csv", "round.toml", "-o", "out", "--no-mcmc", *QUICK], capsys)
    assert code == 0, lines
    assert any("flies toward -x" in ln for ln in lines), lines
    res = json.loads((case / "out" / "result.json").read_text())
    assert res["ml"]["converged"]
    assert abs(res["ml"]["params"]["scale"] - 1.0) < 0.01 if "scale" in res["ml"]["params"] else True
    for row in res["cd"]:
        assert row["ml"] == pytest.approx(row["reference"], rel=0.02)


def test_a_stray_sample_long_after_impact_is_named(case, capsys):
    text = (case / "track.csv").read_text().rstrip("\n").splitlines()
    last = text[-1].split(",")
    (case / "bad.csv").write_text("\n".join(text + [",".join(["1000.0"] + last[1:])]) + "\n")
    code, lines = _cli(["fit", "bad.csv", "round.toml", "-o", "out", "--no-mcmc"], capsys)
    _one_line(code, lines, 2, r"bad\.csv: line \d+: t = 1000 s comes .* after the previous sample.*stray sample")


def test_a_tiny_sigma_is_named(case, capsys):
    (case / "round.toml").write_text(ROUND.replace("x = 1.0", "x = 1e-9"))
    code, lines = _cli(["fit", "track.csv", "round.toml", "-o", "out", "--no-mcmc"], capsys)
    _one_line(code, lines, 2, r"\[radar\] sigma\.x = 1e-09 m is below 0\.0001")


def test_a_two_row_track_is_not_blamed_on_spline_knots(case, capsys):
    _edit_track(case, lambda tr: tr.subset(np.arange(2)))
    code, lines = _cli(["fit", "bad.csv", "round.toml", "-o", "out", "--no-mcmc"], capsys)
    _one_line(code, lines, 2, r"bad\.csv: 2 samples .* too few")
    assert "knot" not in lines[0]


def test_a_1e300_value_is_one_line_naming_the_row(case, capsys):
    text = (case / "track.csv").read_text().splitlines()
    row = text[10].split(",")
    row[2] = "1e300"
    text[10] = ",".join(row)
    (case / "bad.csv").write_text("\n".join(text) + "\n")
    code, lines = _cli(["fit", "bad.csv", "round.toml", "-o", "out", "--no-mcmc"], capsys)
    _one_line(code, lines, 2, r"bad\.csv: line 11, column 'y': 1e\+300 is out of range")


def test_a_reference_drag_pointing_at_any_file_never_echoes_it(case, capsys):
    secret = case / "secret.txt"
    secret.write_text("root:$6$hash-that-must-not-be-shown:0:0\nmore\n")
    (case / "round.toml").write_text(ROUND.replace('"cd.csv"', f'"{secret}"'))
    code, lines = _cli(["fit", "track.csv", "round.toml", "-o", "out", "--no-mcmc"], capsys)
    _one_line(code, lines, 2, r"secret\.txt: line 1: not a drag table: .*header naming the columns mach,cd")
    assert "hash-that-must-not-be-shown" not in lines[0] and "root:" not in lines[0]


def test_ctrl_c_while_sampling_exits_130_without_a_traceback(case):
    out = case / "out"
    # 1000 walkers: a step then takes tens of ms, so the run is still sampling a second after its
    # chain file appears (with 16 it converged within that second once the sampler got faster)
    proc = _interruptible(["fit", "track.csv", "round.toml", "-o", out, "--max-steps", "200000", "--walkers", "1000",
                           *QUICK], cwd=case)
    _wait_for(lambda: (out / "chain.partial.h5").exists(), proc, "sampling")
    time.sleep(1.0)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=PATIENCE)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "emcee" not in err
    assert err.strip().splitlines()[-1] == "bayesdrag: interrupted"
    assert "continue it with --resume" in err
    assert (out / "chain.partial.h5").exists() and not (out / "result.json").exists()


def test_ctrl_c_during_the_ml_fit_exits_130_without_a_traceback(case):
    tr = read_track(case / "track.csv")
    t = np.linspace(tr.t[0], tr.t[-1], 9000)
    write_track(case / "dense.csv", type(tr)(t, {c: np.interp(t, tr.t, a) for c, a in tr.channels.items()}, {}))
    proc = _interruptible(["fit", "dense.csv", "round.toml", "-o", "out", "--no-mcmc"], cwd=case)
    _wait_for(lambda: _staging(case / "out"), proc, "the fit")
    time.sleep(1.5)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=PATIENCE)
    if proc.returncode == 0:
        pytest.skip("the fit finished before the interrupt")
    assert proc.returncode == 130, err
    assert "Traceback" not in err


def test_batch_quiet_prints_no_dask_log_lines_and_never_runs_a_planted_chain(case):
    (case / "camp.toml").write_text('[campaign]\nname = "c"\n[[rounds]]\nname = "a"\ntrack = "track.csv"\n'
                                     'round = "round.toml"\n')
    (case / "out" / "a").mkdir(parents=True)
    _planted_chain(case / "out" / "a" / "chain.partial.h5", case / "PWNED")
    r = subprocess.run([sys.executable, "-m", "bayesdrag", "batch", "camp.toml", "-o", "out", "--workers", "1",
                        "--quiet", "--resume", *QUICK[:2]], env=ENV, cwd=case, capture_output=True, text=True,
                       timeout=600)
    assert not (case / "PWNED").exists()
    assert "INFO" not in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert r.returncode != 0 and "never loaded" in r.stdout + r.stderr


# ================================================================== what a new user stumbled on
def test_the_corner_plot_labels_are_readable():
    """Labels at CORNER_LABEL_PT with units, ticks without "+2.126e2" offsets, one short title per
    quantity (the issue: 8 pt labels in an 18 in figure shown 9 in wide)."""
    from bayesdrag.plots.mcmc import CORNER_LABEL_PT, plot_corner

    rng = np.random.default_rng(0)
    fig = plot_corner({"Cd(M1.07)": 0.386 + 1e-4 * rng.standard_normal(2000),
                       "Ux0": 789.8 + 0.05 * rng.standard_normal(2000),
                       "Uz0": 212.66 + 0.02 * rng.standard_normal(2000)})
    fig.canvas.draw()
    labels = [ax.xaxis.label for ax in fig.axes if ax.xaxis.label.get_text()]
    assert [lb.get_text() for lb in labels] == ["Cd(M1.07)", "Ux0 [m/s]", "Uz0 [m/s]"]
    assert all(lb.get_fontsize() >= CORNER_LABEL_PT >= 14 for lb in labels)
    assert not [ax for ax in fig.axes for a in (ax.xaxis, ax.yaxis) if a.get_offset_text().get_text()]
    titles = [ax.get_title() for ax in fig.axes if ax.get_title()]
    assert len(titles) == 3 and all(" ± " in t for t in titles)


def test_a_sampled_noise_sd_far_above_the_stated_one_is_explained():
    """The demo's noise sd of y reads 20.2 m against the stated 1 m: the report says why."""
    from bayesdrag.report.fit import noise_explanation

    rows = noise_explanation({"x": {"median": 1.06}, "y": {"median": 20.2}}, {"x": 1.0, "y": 1.0},
                             {"x": "round", "y": "round"})
    assert len(rows) == 1 and rows[0][0] == "why the noise sd of y is large"
    assert rows[0][1].startswith("20.2 against the 1 the round states") and "model error" in rows[0][1]


def test_a_segment_over_the_whole_flight_is_named_so():
    from bayesdrag.diagnosis.where import where_segments

    t = np.linspace(0.5, 36.2, 400)
    z = 3000 * np.sin(np.pi * (t - 0.5) / 36.0)
    resid = np.full((400, 1), 5.0)
    segs = where_segments(t, resid, np.ones((400, 1)), np.linspace(2.3, 0.9, 400), z, ("v",))
    assert segs[0]["phase"] == "whole flight" and segs[0]["phases"] == ["ascent", "apex", "descent"]


def test_a_launch_misfit_below_2_sd_is_not_called_inconsistent():
    from bayesdrag.diagnosis.where import with_launch_misfit

    assert with_launch_misfit([], 0.5, {"X_muzzle": 0.1, "heading": -0.1}, 100.0) == []
    assert with_launch_misfit([], 0.5, {"X_muzzle": 3.0}, 100.0)[0]["channel"] == "launch"


def test_a_cross_drift_absorbed_into_the_launch_heading_is_explained(base):
    """A 5 m/s cross wind: the baseline turns its launch heading and the where-ranking sees only
    what is left; the paragraph says how much was absorbed, in metres."""
    from bayesdrag import diagnose

    rnd = read_round(base / "round.toml")
    track = add_noise(simulate_round(rnd, dt=0.25, wind=(0.0, 5.0, 0.0)), SIGMA, np.random.default_rng(3))
    d = diagnose(track, rnd)
    a = d.to_dict()["absorbed"]
    assert [r["name"] for r in a] == ["heading"] and a[0]["drift_m"] > 30.0
    assert "Absorbed: the fit turned the launch heading by" in d.paragraph
    assert "inconsistent with the muzzle" not in d.paragraph
    assert d.verdict == ["wind"]


def test_the_materiality_threshold_is_set_on_the_command_line(case, capsys):
    code, lines = _cli(["diagnose", "track.csv", "round.toml", "-o", "out", "--material-cd", "5",
                        "--material-end-sd", "10", "--quiet"], capsys)
    assert code == 0, lines
    s = json.loads((case / "out" / "diagnosis.json").read_text())
    assert s["materiality"]["cd_shift"] == pytest.approx(0.05) and s["materiality"]["end_sd"] == 10.0
    code, lines = _cli(["diagnose", "track.csv", "round.toml", "-o", "out", "--material-cd", "-1"], capsys)
    _one_line(code, lines, 2, r"--material-cd: expected a positive finite number")


def test_every_figure_of_the_paragraph_comes_from_the_verdicts_joint_fit():
    """The paragraph printed the joint fit's wind, then the Cd shift of the wind-only fit (where the
    wind stood in for a hot day): the values and the impact of a verdict effect are its joint
    fit's; a lone fit's tailwind of 7.9 m/s appears nowhere."""
    from bayesdrag.results.words import diagnosis_paragraph

    row = {"name": "wind", "params": {"wx": 7.9, "wy": 0.1}, "sd": {"wx": 0.2, "wy": 0.3},
           "params_joint": {"wx": -0.52, "wy": 0.08}, "sd_joint": {"wx": 0.05, "wy": 0.04},
           "shrink": 0.9, "shrink_given_others": 0.1, "confounded_with": [], "cd_shift_max": 0.004,
           "end_shift_sd": 4.2, "remaining_gap_fraction": 0.0}
    temp = dict(row, name="temperature", params={"dT": 18.0}, sd={"dT": 0.5}, params_joint={"dT": 15.1},
                sd_joint={"dT": 0.4}, shrink_given_others=0.95, cd_shift_max=0.19)
    s = {"baseline": {"chi2_per_sample": 40.0, "gap": 5000.0}, "reference_drag": True,
         "effects": [row, temp], "verdict": ["temperature", "wind"], "immaterial": [],
         "joint": {"effects": ["temperature", "wind"], "shrink": 0.99, "strongly_correlated": []},
         "materiality": {"cd_shift": 0.001, "end_sd": 3.0}, "where": [], "absorbed": []}
    text = diagnosis_paragraph(s)
    assert "wx = -0.52" in text and "dT = 15.1" in text
    assert "7.9" not in text and "dT = 18" not in text
    assert "shift by up to 0.004 (relative)" in text and "shift by up to 0.19 (relative)" in text
