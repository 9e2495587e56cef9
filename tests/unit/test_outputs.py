"""The output folder as one consistent set (bayesdrag/io/outputs.py, the contract (docs/formats.md) command line):
manifest, superseded files moved aside (never deleted, never left looking current), staging and
a journalled swap that a later run completes, the folder lock, umask-respecting modes, a full
disk as one OutputError with nothing lost."""
import errno
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bayesdrag.errors import InputError, OutputError
from bayesdrag.io import outputs
from bayesdrag.io.outputs import MANIFEST, SUPERSEDED, DiskFullError, OutputRun, atomic_write, read_json


def _inputs(tmp_path, text="t,x\n0,0\n1,1\n"):
    p = tmp_path / "in" / "track.csv"
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(text)
    return {"track": p}


def _run(out, command, inputs, files, adopt=None):
    with OutputRun(out, command, inputs=inputs) as run:
        for name, text in files.items():
            (run.staging / name).write_text(text)
        for src, dst in (adopt or {}).items():
            run.adopt(src, dst)
    return run


def _tree(folder):
    return {p.relative_to(folder).as_posix(): p.read_text() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_first_run_writes_its_files_and_a_manifest(tmp_path):
    out = tmp_path / "out"
    ins = _inputs(tmp_path)
    run = _run(out, "fit", ins, {"result.json": "{}", "cd.png": "png"})
    assert sorted(p.name for p in out.iterdir()) == ["cd.png", "manifest.json", "result.json"]
    m = json.loads((out / MANIFEST).read_text())
    assert m["format"] == "bayesdrag-manifest/1" and m["command"] == "fit" and m["run"] == run.run_id
    assert [f["name"] for f in m["files"]] == ["cd.png", "result.json"]
    assert m["inputs"]["track"]["sha256"] == outputs.sha256_file(ins["track"])
    assert m["files"][1]["sha256"] == outputs.sha256_file(out / "result.json")
    assert m["superseded"] == [] and m["also_current"] == []


def test_a_rerun_moves_every_earlier_file_aside_also_those_it_does_not_rewrite(tmp_path):
    """The --no-mcmc case: the earlier posterior.nc and chain.h5 must not stay beside the new
    result.json; they go with the earlier manifest to superseded/<earlier run>/."""
    out = tmp_path / "out"
    ins = _inputs(tmp_path)
    first = _run(out, "fit", ins, {"result.json": "old", "posterior.nc": "old nc", "chain.h5": "old chain"})
    second = _run(out, "fit", ins, {"result.json": "new"})
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST, "result.json", SUPERSEDED]
    assert (out / "result.json").read_text() == "new"
    old = out / SUPERSEDED / first.run_id
    assert sorted(p.name for p in old.iterdir()) == ["chain.h5", MANIFEST, "posterior.nc", "result.json"]
    m = json.loads((out / MANIFEST).read_text())
    assert m["run"] == second.run_id
    assert m["superseded"] == [{"run": first.run_id, "command": "fit", "folder": f"{SUPERSEDED}/{first.run_id}",
                                "files": ["chain.h5", MANIFEST, "posterior.nc", "result.json"]}]


def test_another_command_on_the_same_inputs_keeps_the_earlier_run(tmp_path):
    out = tmp_path / "out"
    ins = _inputs(tmp_path)
    fit = _run(out, "fit", ins, {"result.json": "fit"})
    _run(out, "diagnose", ins, {"diagnosis.json": "diag"})
    assert (out / "result.json").read_text() == "fit" and not (out / SUPERSEDED).exists()
    m = json.loads((out / MANIFEST).read_text())
    assert [r["run"] for r in m["also_current"]] == [fit.run_id]
    # a fit of other inputs supersedes both the earlier fit and the diagnosis made beside it
    other = _inputs(tmp_path / "b", "t,x\n0,0\n2,2\n")
    _run(out, "fit", other, {"result.json": "fit 2"})
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST, "result.json", SUPERSEDED]
    m = json.loads((out / MANIFEST).read_text())
    assert m["also_current"] == [] and len(m["superseded"]) == 2


def test_a_folder_written_before_manifests_gets_its_outputs_moved_and_the_users_files_kept(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    for n in ("result.json", "posterior.nc", "chain.h5", "corner.png", "diagnosis_where.png"):
        (out / n).write_text("legacy")
    (out / "notes.txt").write_text("mine")
    (out / "chain.partial.h5").write_text("unfinished")
    _run(out, "fit", _inputs(tmp_path), {"result.json": "new"})
    left = sorted(p.name for p in out.iterdir())
    assert left == ["chain.partial.h5", MANIFEST, "notes.txt", "result.json", SUPERSEDED]
    (old,) = (out / SUPERSEDED).iterdir()
    assert sorted(p.name for p in old.iterdir()) == ["chain.h5", "corner.png", "diagnosis_where.png",
                                                     "posterior.nc", "result.json"]


def test_an_input_in_the_output_folder_is_never_moved(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    track = out / "summary.json"           # an input that happens to carry an output's name
    track.write_text("t,x\n0,0\n1,1\n")
    _run(out, "fit", {"track": track}, {"result.json": "new"})
    assert track.read_text() == "t,x\n0,0\n1,1\n"


def test_the_finished_chain_is_adopted(tmp_path):
    out = tmp_path / "out"
    ins = _inputs(tmp_path)
    _run(out, "fit", ins, {"result.json": "1"}, adopt={})
    (out / "chain.partial.h5").write_text("chain 2")
    _run(out, "fit", ins, {"result.json": "2"}, adopt={"chain.partial.h5": "chain.h5"})
    assert (out / "chain.h5").read_text() == "chain 2" and not (out / "chain.partial.h5").exists()
    m = json.loads((out / MANIFEST).read_text())
    assert "chain.h5" in [f["name"] for f in m["files"]]


def test_a_failed_run_changes_nothing(tmp_path):
    out = tmp_path / "out"
    ins = _inputs(tmp_path)
    _run(out, "fit", ins, {"result.json": "old", "cd.png": "old"})
    before = _tree(out)
    with pytest.raises(RuntimeError, match="boom"):
        with OutputRun(out, "fit", inputs=ins) as run:
            (run.staging / "result.json").write_text("half")
            raise RuntimeError("boom")
    assert _tree(out) == before
    assert not [p for p in out.iterdir() if p.name.startswith(".")]


def test_files_follow_the_umask(tmp_path):
    old = os.umask(0o022)
    try:
        out = tmp_path / "out"
        _run(out, "fit", _inputs(tmp_path), {"result.json": "x"})
        atomic_write(out / "track.csv", lambda tmp: Path(tmp).write_text("t,x\n"))
        os.umask(0o077)
        atomic_write(out / "private.csv", lambda tmp: Path(tmp).write_text("t,x\n"))
    finally:
        os.umask(old)
    mode = lambda p: p.stat().st_mode & 0o777  # noqa: E731
    assert mode(out / "result.json") == 0o644 and mode(out / MANIFEST) == 0o644
    assert mode(out / "track.csv") == 0o644
    assert mode(out / "private.csv") == 0o600


def test_a_second_run_on_the_folder_is_refused_and_a_killed_ones_lock_is_gone(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time; from bayesdrag.io.outputs import OutputRun\n"
         f"r = OutputRun({str(out)!r}, 'fit').__enter__(); print('locked', flush=True); time.sleep(60)"],
        stdout=subprocess.PIPE, text=True, env=dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path)))
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(InputError, match=rf"out is in use by another bayesdrag run \(pid {holder.pid}\)"):
            OutputRun(out, "fit").__enter__()
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait()
    # the killed holder left its staging folder behind but not the lock: the next run goes ahead
    assert [p.name for p in out.iterdir() if p.name.startswith(".staging-")]
    _run(out, "fit", {}, {"result.json": "after the kill"})
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST, "result.json"]


def test_a_run_killed_during_its_swap_is_completed_by_the_next_run(tmp_path, monkeypatch):
    out = tmp_path / "out"
    ins = _inputs(tmp_path)
    first = _run(out, "fit", ins, {"result.json": "old", "posterior.nc": "old", "cd.png": "old"})
    real_rename = os.rename
    calls = []

    def dying_rename(a, b):
        calls.append(a)
        if len(calls) == 3:
            raise KeyboardInterrupt        # a kill half-way through the plan
        real_rename(a, b)

    monkeypatch.setattr(outputs.os, "rename", dying_rename)
    with pytest.raises(KeyboardInterrupt):
        _run(out, "fit", ins, {"result.json": "new", "cd.png": "new"})
    monkeypatch.setattr(outputs.os, "rename", real_rename)
    assert (out / "posterior.nc").exists() or (out / SUPERSEDED).exists()   # mixed: the swap stopped
    notes = []
    with OutputRun(out, "diagnose", inputs=ins, echo=notes.append) as run:
        (run.staging / "diagnosis.json").write_text("d")
    assert any("completed the interrupted commit" in n for n in notes)
    assert (out / "result.json").read_text() == "new" and (out / "cd.png").read_text() == "new"
    assert not (out / "posterior.nc").exists()
    assert (out / SUPERSEDED / first.run_id / "posterior.nc").read_text() == "old"
    assert not [p for p in out.iterdir() if p.name.startswith(".staging-")]


def test_a_plan_that_leaves_the_folder_is_refused(tmp_path):
    out = tmp_path / "out"
    staging = out / ".staging-20260101T000000Z-1-abcd"
    staging.mkdir(parents=True)
    (tmp_path / "victim").write_text("keep")
    (staging / ".commit.json").write_text(json.dumps({"format": "bayesdrag-commit/1", "run": "x",
                                                   "moves": [["../victim", "stolen", "out"]]}))
    with pytest.raises(InputError, match="an interrupted commit whose plan cannot be used"):
        OutputRun(out, "fit").__enter__()
    assert (tmp_path / "victim").read_text() == "keep"


def test_disk_full_while_writing_keeps_the_earlier_outputs(tmp_path):
    out = tmp_path / "out"
    ins = _inputs(tmp_path)
    _run(out, "fit", ins, {"result.json": "old"})
    before = _tree(out)
    with pytest.raises(DiskFullError, match=r"the disk is full .*earlier outputs are untouched"):
        with OutputRun(out, "fit", inputs=ins) as run:
            raise OSError(errno.ENOSPC, "No space left on device")
    assert _tree(out) == before
    # a library's wrapped message counts too (h5py, netCDF)
    assert outputs.is_disk_full(RuntimeError("file write failed: errno = 28, error message = 'No space'"))
    assert not outputs.is_disk_full(RuntimeError("something else"))


def test_unwritable_folder_is_refused_before_any_work(tmp_path, monkeypatch):
    out = tmp_path / "out"
    out.mkdir()
    real_mkdir = Path.mkdir

    def no_mkdir(self, *a, **k):
        if self.name.startswith(".staging-"):
            raise PermissionError(errno.EACCES, "Permission denied")
        return real_mkdir(self, *a, **k)

    monkeypatch.setattr(Path, "mkdir", no_mkdir)
    with pytest.raises(InputError, match=r"out: the output folder is not writable \(Permission denied\)"):
        OutputRun(out, "fit").__enter__()


def test_read_json_is_bounded_and_never_evaluates(tmp_path):
    p = tmp_path / "m.json"
    p.write_text("[" * 100000 + "]" * 100000)
    with pytest.raises(InputError, match="nested too deeply"):
        read_json(p)
    p.write_text(" " * 100)
    with pytest.raises(InputError, match="larger than 10 bytes"):
        read_json(p, max_bytes=10)
    with pytest.raises(InputError, match="not a regular file"):
        read_json("/dev/zero")


def test_a_manifest_naming_files_outside_the_folder_is_ignored(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (tmp_path / "victim").write_text("keep")
    (out / MANIFEST).write_text(json.dumps({"format": "bayesdrag-manifest/1", "run": "evil", "command": "fit",
                                            "files": [{"name": "../victim"}]}))
    _run(out, "fit", {}, {"result.json": "new"})
    assert (tmp_path / "victim").read_text() == "keep"


def test_stale_temporary_files_of_a_killed_write_are_removed(tmp_path):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f".track.csv.{dead.pid}.abcd1234.part"
    stale.write_text("half")
    time.sleep(0.01)
    atomic_write(tmp_path / "track.csv", lambda tmp: Path(tmp).write_text("t,x\n"))
    assert not stale.exists() and (tmp_path / "track.csv").read_text() == "t,x\n"


def test_output_error_is_not_an_input_error():
    assert issubclass(DiskFullError, OutputError) and not issubclass(OutputError, InputError)
