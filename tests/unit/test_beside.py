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
