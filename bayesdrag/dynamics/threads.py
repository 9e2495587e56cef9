"""The point-mass kernel's helper threads: :func:`run_split` runs the kernel's blocks side by side.

The kernel's own concern, so it lives beside the kernel: a low layer that ran the kernel's
functions handed to it would be a call back up the layers.
"""
from __future__ import annotations

import os


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


class _Pool:
    """This process's helper threads, and the scratch arrays of the calls run through them.

    ``busy`` is held by the one thread using the pool; only it touches ``workers`` and
    ``scratch``. ``scratch`` maps a key to the arrays made for the calls of each slot (slot 0:
    the calling thread's, slot i: helper i's), so that a thread reuses its own arrays
    call after call and no two threads ever write the same array (nor the same cache line):
    a kernel call of one trajectory then allocates nothing."""

    #: the most scratch keys kept (batch shapes seen); more, and the oldest are dropped
    MAX_KEYS = 8

    def __init__(self):
        import _thread

        self.busy = _thread.allocate_lock()
        self.workers = []
        self.scratch = {}
        self.keys = []

    def arrays(self, key, make, n):
        """The scratch arrays of the first ``n`` slots for ``key`` (a list, one tuple a slot;
        ``make(*key)`` for a slot that has none yet)."""
        found = self.scratch.get(key, [])
        if key not in self.scratch:
            self.keys.append(key)
            if len(self.keys) > self.MAX_KEYS:
                del self.scratch[self.keys.pop(0)]
        found = found + [make(*key) for _ in range(n - len(found))]
        self.scratch[key] = found
        return found


#: the pool of this process (``pid`` -> :class:`_Pool`), started when first needed and kept like
#: numba's own thread pool: starting a thread per kernel call cost ~80 us, as much as
#: integrating a few trajectories; a forked child starts its own (threads are not inherited)
_POOL: dict = {}


def run_split(fn, arg_lists, scratch=None):
    """Call ``fn(*a)`` for every ``a`` of ``arg_lists`` side by side: the first in the calling
    thread, the others each on a helper thread (``fn`` must release the GIL, e.g. a numba
    function compiled with ``nogil=True``, and the calls must touch disjoint data). Re-raises the
    first exception a call raised. When another thread is using the helpers (or one failed to
    finish), the calls run one after the other in the calling thread instead.

    ``scratch``: ``(key, make)``, optional: each call gets the arrays of the tuple ``make(*key)``
    appended to its arguments, its own set per slot, kept by the pool and reused by the next
    call with the same key (``fn`` must not rely on their contents from one call to the next);
    when the pool is busy, fresh ones."""
    pid = os.getpid()
    pool = _POOL.get(pid)
    if pool is None:
        pool = _POOL.setdefault(pid, _Pool())
    if not pool.busy.acquire(False):
        for a in arg_lists:
            fn(*(a if scratch is None else a + scratch[1](*scratch[0])))
        return
    ok = True                           # until a helper has a task: the pool stays usable
    try:
        if scratch is not None:
            key, make = scratch
            found = pool.scratch.get(key)
            if found is None or len(found) < len(arg_lists):
                found = pool.arrays(key, make, len(arg_lists))
            arg_lists = [a + s for a, s in zip(arg_lists, found)]
        if len(arg_lists) == 1:
            fn(*arg_lists[0])
            return
        workers = pool.workers
        while len(workers) < len(arg_lists) - 1:
            workers.append(_Worker())
        used = workers[:len(arg_lists) - 1]
        ok = False
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
            pool.busy.release()
        else:
            # interrupted while the helpers may still run: leave them (and their arrays), start
            # afresh next time
            _POOL.pop(pid, None)
