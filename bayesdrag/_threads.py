"""One BLAS thread while the compiled kernel runs its own threads.

The point-mass kernel runs on numba's threads (OpenMP); the estimators alternate kernel calls
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
