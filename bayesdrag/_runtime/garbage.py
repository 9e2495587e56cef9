"""Python's cyclic garbage collector paused while figures and reports are built.

A fit leaves some 440 000 objects the collector tracks; building a report's figures allocates
matplotlib artists by the ten thousand, which triggers collections that traverse them all
(docs/measurements.md, "Garbage collector"). :func:`paused_gc` pauses it for the duration of a block and restores the
previous state (the figures' reference cycles are collected later, as usual).
"""
from __future__ import annotations

import contextlib
import gc


@contextlib.contextmanager
def paused_gc():
    """Context manager: the cyclic collector disabled inside, its previous state restored."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()
