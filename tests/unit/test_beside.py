"""Work computed in a forked process beside the caller (bayesdrag._runtime.beside): the same answer
forked or not, nothing lost when the child fails, the child killed when the caller fails."""
import os
import time

import numpy as np
import pytest

from bayesdrag._runtime import beside as _beside
from bayesdrag._runtime.beside import computed_beside, plain_json, started_beside

forks = pytest.mark.skipif(not hasattr(os, "fork") or not os.sys.platform.startswith("linux"),
                           reason="fork on Linux only")


def _answer():
    rng = np.random.default_rng(7)
    x = rng.normal(size=5)
    return {"x": x, "sum": np.float64(x.sum()), "n": np.int64(5), "flag": np.bool_(True), "none": None,
            "nan": float("nan"), "text": "été"}


def _expected():
    import json

    return json.loads(json.dumps(_answer(), default=plain_json))


@forks
def test_forked_answer_equals_the_answer_computed_here(monkeypatch):
    monkeypatch.setattr(_beside, "free_core", lambda: True)
    with computed_beside(_answer) as box:
        pass
    here = _expected()
    assert box.forked
    assert box.value["x"] == here["x"]          # floats exact through the JSON text
    assert box.value["sum"] == here["sum"] and box.value["n"] == 5 and box.value["flag"] is True
    assert box.value["none"] is None and np.isnan(box.value["nan"]) and box.value["text"] == "été"


@forks
def test_a_large_answer_comes_through_the_pipe_whole(monkeypatch):
    monkeypatch.setattr(_beside, "free_core", lambda: True)
    n = 300_000                                  # several MB: more than a pipe holds while the body runs
    with computed_beside(lambda: list(range(n))) as box:
        time.sleep(0.05)
    assert box.forked and len(box.value) == n and box.value[-1] == n - 1


def test_without_a_free_core_it_runs_here_after_the_body(monkeypatch):
    monkeypatch.setattr(_beside, "free_core", lambda: False)
    order = []
    with computed_beside(lambda: order.append("fn") or 3) as box:
        order.append("body")
    assert order == ["body", "fn"] and box.value == 3 and not box.forked


@forks
def test_a_child_that_fails_is_replaced_by_the_work_done_here(monkeypatch):
    monkeypatch.setattr(_beside, "free_core", lambda: True)
    parent = os.getpid()

    def fn():
        if os.getpid() != parent:
            raise RuntimeError("the child fails")
        return "here"

    with computed_beside(fn) as box:
        pass
    assert box.value == "here" and not box.forked


@forks
def test_an_answer_json_cannot_carry_is_computed_here(monkeypatch):
    monkeypatch.setattr(_beside, "free_core", lambda: True)
    with computed_beside(lambda: {"s": {1, 2}}) as box:      # a set: the child cannot write it
        pass
    assert box.value == {"s": {1, 2}} and not box.forked


def test_the_work_s_own_error_reaches_the_caller(monkeypatch):
    monkeypatch.setattr(_beside, "free_core", lambda: False)

    def fn():
        raise ValueError("bad input to the check")

    with pytest.raises(ValueError, match="bad input to the check"):
        with computed_beside(fn):
            pass


@forks
def test_when_the_body_fails_the_child_is_killed_and_reaped(monkeypatch, tmp_path):
    monkeypatch.setattr(_beside, "free_core", lambda: True)
    marker = tmp_path / "done"

    def slow():
        time.sleep(5)
        marker.write_text("finished")
        return 1

    pid = None
    with pytest.raises(KeyboardInterrupt):
        with started_beside(slow) as job:
            pid = job.pid
            raise KeyboardInterrupt
    assert pid is not None
    assert not marker.exists()                  # killed, not waited for
    with pytest.raises(ChildProcessError):      # reaped: no zombie left behind
        os.waitpid(pid, os.WNOHANG)


@forks
def test_a_started_job_is_collected_once(monkeypatch):
    monkeypatch.setattr(_beside, "free_core", lambda: True)
    with started_beside(lambda: [1, 2]) as job:
        assert job.pid is not None
        assert job.result() == [1, 2] and job.forked
        assert job.pid is None and job.result() == [1, 2]


def test_plain_json_refuses_what_it_cannot_write():
    with pytest.raises(TypeError, match="set is not JSON serialisable"):
        plain_json({1})


@forks
def test_running_says_whether_the_child_still_works(monkeypatch):
    monkeypatch.setattr(_beside, "free_core", lambda: True)

    def slow():
        time.sleep(0.5)
        return 7

    with started_beside(slow) as job:
        assert job.running()                   # asked at once: the child sleeps
        deadline = time.monotonic() + 30.0
        while job.running() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not job.running()               # its answer waits in the pipe
        # exited and still waitable: running() reaped nothing (WNOWAIT leaves it for result())
        assert os.waitid(os.P_PID, job.pid, os.WEXITED | os.WNOHANG | os.WNOWAIT) is not None
        assert job.result() == 7 and job.forked
        assert not job.running()
    with started_beside(lambda: 1, fork=False) as here:
        assert not here.running()              # no child: nothing runs beside


@forks
def test_running_holds_for_a_pipe_above_descriptor_1023(monkeypatch):
    """A long-lived process (a campaign's worker) may hold the child's pipe on a high descriptor,
    where ``select`` refuses: running() must still answer."""
    import resource

    soft, _ = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft <= 1100:
        pytest.skip(f"descriptor limit {soft}")
    monkeypatch.setattr(_beside, "free_core", lambda: True)
    with started_beside(lambda: time.sleep(0.3) or 5) as job:
        pid, fd = job._child
        high = os.dup2(fd, 1100)
        os.close(fd)
        job._child = (pid, high)
        assert job.running()
        assert job.result() == 5


@forks
def test_the_next_diagnosis_child_inherits_the_diagnosis_package():
    """While the child works the parent imports the diagnosis package (the wait it has anyway),
    so the child a later fit forks does not import it again (0.4-0.7 s). A fresh interpreter: this
    test process has imported the package long ago."""
    import subprocess
    import sys

    code = (
        "import sys, time\n"
        "from bayesdrag._runtime import beside\n"
        "from bayesdrag.pipeline.check import collected\n"
        "beside.free_core = lambda: True\n"
        "assert 'bayesdrag.diagnosis' not in sys.modules\n"
        "def work():\n"
        "    time.sleep(1.0)\n"
        "    return sorted(m for m in sys.modules if m == 'bayesdrag.diagnosis')\n"
        "with beside.started_beside(work) as job:\n"
        "    value = collected(job)\n"
        "assert job.forked and value == [], value\n"
        "assert 'bayesdrag.diagnosis' in sys.modules\n"
        "with beside.started_beside(work) as job:\n"
        "    value = collected(job)\n"
        "assert value == ['bayesdrag.diagnosis'], value\n"
        "print('ok')\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr[-2000:]
