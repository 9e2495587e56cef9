"""One BLAS thread while the compiled kernel runs its own threads.

The point-mass kernel runs on several threads (:mod:`bayesdrag.dynamics.threads`); the estimators
alternate kernel calls with small dense linear algebra (84 x 4000 products, 84 x 84 solves). With
OpenBLAS also threaded, each library's idle threads spin while the other works and the two
oversubscribe the cores, and the matrices are far too small for BLAS threads to help
(docs/measurements.md, "One BLAS thread").
:func:`single_blas` limits BLAS to one thread inside a ``with`` block (threadpoolctl, at run time,
so it works whatever imported numpy first) and restores it on leaving. It is a context manager,
not a decorator, so this low layer never calls back into the code that uses it.
"""
from __future__ import annotations

import contextlib
from typing import Iterator


@contextlib.contextmanager
def single_blas() -> Iterator[None]:
    """BLAS limited to one thread inside the block (restored on leaving it, also on an error)."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - a declared dependency
        yield
        return
    with threadpool_limits(limits=1, user_api="blas"):
        yield
