"""Python's cyclic garbage collector paused while figures and reports are built.

A fit leaves some 440 000 objects the collector tracks; building a report's figures allocates
matplotlib artists by the ten thousand, which triggers collections that traverse them all:
measured on the demo's fit, its figures took 0.9-1.6 s with the collector running and
0.56-1.04 s paused. :func:`paused_gc` pauses it for the duration of a block and restores the
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
