"""The kernel's helper threads (``bayesdrag.dynamics.threads.run_split``): every call runs once, errors
reach the caller, a second caller while the helpers are busy runs its calls itself, and nothing
shows up as a ``threading`` thread (the report forks its figure process only when none runs)."""
import threading
import time

import pytest

from bayesdrag.dynamics.threads import run_split


def test_every_call_runs_once_on_another_thread_than_the_first():
    seen = []

    def call(i):
        seen.append((i, threading.get_ident()))

    before = threading.active_count()      # other tests in the same process may have left threads
    run_split(call, [(0,), (1,), (2,)])
    assert sorted(i for i, _ in seen) == [0, 1, 2]
    idents = dict(seen)
    assert idents[0] == threading.get_ident() and len(set(idents.values())) == 3
    assert threading.active_count() == before


def test_an_error_on_a_helper_reaches_the_caller_and_the_helpers_stay_usable():
    def call(i):
        if i == 1:
            raise ValueError(f"lane {i} failed")

    with pytest.raises(ValueError, match="lane 1 failed"):
        run_split(call, [(0,), (1,)])
    done = []
    run_split(lambda i: done.append(i), [(0,), (1,)])
    assert sorted(done) == [0, 1]


def test_a_second_caller_while_the_helpers_are_busy_runs_its_calls_itself():
    inner = []
    gate = threading.Event()

    def slow(i):
        if i == 1:
            gate.wait(5.0)

    def other():
        run_split(lambda i: inner.append((i, threading.get_ident())), [(0,), (1,)])
        gate.set()

    t = threading.Thread(target=other)

    def first(i):
        if i == 0:
            time.sleep(0.05)       # the helper holds call 1 until ``other`` has run
            t.start()
            t.join(5.0)
        else:
            slow(i)

    run_split(first, [(0,), (1,)])
    assert sorted(i for i, _ in inner) == [0, 1]
    assert len({ident for _, ident in inner}) == 1      # both on the second caller's own thread


def _split_in_child(q):
    out = []
    run_split(lambda i: out.append(i), [(0,), (1,), (2,)])
    q.put(sorted(out))


@pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="fork only")
def test_a_forked_child_starts_its_own_helpers():
    """A forked child does not inherit the parent's helper threads (the report forks its figure
    process): its first split must start new ones rather than wait for threads that do not exist."""
    import multiprocessing

    run_split(lambda i: None, [(0,), (1,), (2,)])          # the parent's helpers exist
    ctx = multiprocessing.get_context("fork")
    q = ctx.Queue()
    p = ctx.Process(target=_split_in_child, args=(q,))
    p.start()
    p.join(30.0)
    if p.is_alive():
        p.kill()
    assert p.exitcode == 0 and q.get(timeout=5.0) == [0, 1, 2]


def test_scratch_is_one_set_per_slot_reused_by_the_next_call():
    """Each call slot gets its own scratch arrays (no two threads write the same array), and the
    next call with the same key gets the same ones again (a call allocates nothing)."""
    import numpy as np

    made = []

    def make(n, width):
        made.append((n, width))
        return (np.zeros((n, width)),)

    seen = []
    run_split(lambda i, a: seen.append((i, a)), [(0,), (1,)], (("probe", 3), lambda *_: make(3, 4)))
    first = dict(seen)
    assert len(made) == 2 and first[0] is not first[1]
    seen.clear()
    run_split(lambda i, a: seen.append((i, a)), [(0,), (1,)], (("probe", 3), lambda *_: make(3, 4)))
    assert len(made) == 2 and dict(seen)[0] is first[0] and dict(seen)[1] is first[1]


def test_a_second_caller_while_the_pool_is_busy_gets_fresh_scratch():
    """The pool's scratch belongs to the thread that holds the pool: a caller that finds it busy
    runs its calls itself with arrays of its own."""
    import numpy as np

    key = ("probe-busy", 1)
    own, other = [], []
    gate = threading.Event()

    def inner():
        run_split(lambda i, a: other.append(a), [(0,)], (key, lambda *_: (np.zeros(2),)))
        gate.set()

    t = threading.Thread(target=inner)

    def first(i, a):
        own.append(a)
        if i == 0:
            t.start()
            t.join(5.0)

    run_split(first, [(0,), (1,)], (key, lambda *_: (np.zeros(2),)))
    assert gate.is_set() and len(other) == 1 and all(other[0] is not a for a in own)
