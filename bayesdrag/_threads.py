"""One BLAS thread while the compiled kernel runs its own threads; the kernel's helper threads.

The point-mass kernel runs on several threads (:func:`run_split`); the estimators alternate kernel calls
with small dense linear algebra (84 x 4000 products, 84 x 84 solves). With OpenBLAS also
threaded, each library's idle threads spin while the other works and the two oversubscribe the
cores, and the matrices are far too small for BLAS threads to help (docs/measurements.md,
"One BLAS thread").
:func:`single_blas` limits BLAS to one thread for the duration of a call (threadpoolctl, at run
time, so it works whatever imported numpy first) and restores it afterwards.
"""
from __future__ import annotations

import functools
from typing import Any, Callable, TypeVar

_F = TypeVar("_F", bound=Callable[..., Any])


def single_blas(fn: _F) -> _F:
    """Decorator: run ``fn`` with BLAS limited to one thread (restored on return). Typed to keep
    ``fn``'s signature (``bayesdrag.fit`` is decorated)."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            from threadpoolctl import threadpool_limits
        except ImportError:  # pragma: no cover - a declared dependency
            return fn(*args, **kwargs)
        with threadpool_limits(limits=1, user_api="blas"):
            return fn(*args, **kwargs)

    return wrapper  # type: ignore[return-value]


class _Worker:
    """A helper thread that runs one call at a time for :func:`run_split` (a bare ``_thread``:
    it is not one of ``threading``'s threads, so code that forks only when no other Python thread
    runs, e.g. the report's figure process, still does)."""

    def __init__(self):
        import _thread

        self.go = _thread.allocate_lock()
        self.done = _thread.allocate_lock()
        self.go.acquire()
        self.done.acquire()
        self.task = None
        self.error = None
        _thread.start_new_thread(self._loop, ())

    def _loop(self):
        while True:
            self.go.acquire()
            fn, args = self.task
            self.task = None
            try:
                fn(*args)
            except BaseException as e:   # noqa: BLE001 - handed to the caller in run_split
                self.error = e
            del fn, args                 # the caller's arrays are not kept alive between calls
            self.done.release()


#: the helper threads of this process (``pid`` -> workers), started when first needed and kept
#: like numba's own thread pool: starting a thread per kernel call cost ~80 us, as much as
#: integrating a few trajectories; a forked child starts its own (threads are not inherited)
_POOL: dict = {}


def run_split(fn, arg_lists):
    """Call ``fn(*a)`` for every ``a`` of ``arg_lists`` side by side: the first in the calling
    thread, the others each on a helper thread (``fn`` must release the GIL, e.g. a numba
    function compiled with ``nogil=True``, and the calls must touch disjoint data). Re-raises the
    first exception a call raised. When another thread is using the helpers (or one failed to
    finish), the calls run one after the other in the calling thread instead."""
    import os
    import _thread

    if len(arg_lists) == 1:
        fn(*arg_lists[0])
        return
    pid = os.getpid()
    entry = _POOL.get(pid)
    if entry is None:
        entry = _POOL.setdefault(pid, (_thread.allocate_lock(), []))
    busy, workers = entry
    if not busy.acquire(blocking=False):
        for a in arg_lists:
            fn(*a)
        return
    ok = False
    try:
        while len(workers) < len(arg_lists) - 1:
            workers.append(_Worker())
        used = workers[:len(arg_lists) - 1]
        for w, a in zip(used, arg_lists[1:]):
            w.task = (fn, a)
            w.go.release()
        try:
            fn(*arg_lists[0])
        finally:
            for w in used:
                w.done.acquire()
        ok = True
        errors = [w.error for w in used if w.error is not None]
        for w in used:
            w.error = None
        if errors:
            raise errors[0]
    finally:
        if ok:
            busy.release()
        else:
            # interrupted while the helpers may still run: leave them, start afresh next time
            _POOL.pop(pid, None)
