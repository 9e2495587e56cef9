"""Ctrl-C at a safe point.

A SIGINT raised as ``KeyboardInterrupt`` inside the compiled kernel surfaces as numba's
``SystemError`` ("returned a result with an exception set"), and inside emcee's likelihood
wrapper it first makes emcee print a traceback with the walkers' parameters. :func:`deferred_interrupt`
remembers a first Ctrl-C instead; the loop it wraps calls the checker it yields between two
blocks of work (the sampler: after each block of steps is written to the chain file) and the
interrupt is raised there, cleanly. A second Ctrl-C raises at once. Where the handler cannot be
installed (not the main thread, or SIGINT ignored as in a background job or a Dask worker) the
checker does nothing and SIGINT keeps its disposition.
"""
from __future__ import annotations

import contextlib
import signal
import threading

__all__ = ["deferred_interrupt", "caused_by_interrupt"]


@contextlib.contextmanager
def deferred_interrupt():
    """Context manager yielding ``check()``: raises ``KeyboardInterrupt`` when a Ctrl-C arrived
    since entering (see the module docstring)."""
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield lambda: None
        return
    pending = [False]

    def handler(signum, frame):
        if pending[0]:
            raise KeyboardInterrupt
        pending[0] = True

    def check():
        if pending[0]:
            pending[0] = False
            raise KeyboardInterrupt

    old = signal.signal(signal.SIGINT, handler)
    try:
        yield check
    finally:
        signal.signal(signal.SIGINT, old)
    if pending[0]:
        raise KeyboardInterrupt


def caused_by_interrupt(exc):
    """True when ``exc`` is, or was raised while handling, a ``KeyboardInterrupt`` (numba wraps
    one raised inside compiled code in a ``SystemError``)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False
