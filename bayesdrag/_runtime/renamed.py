"""Old names kept for one release: a module's ``__getattr__`` that answers a renamed name with
the object under its new name and a :class:`DeprecationWarning` (docs/architecture.md,
"Deprecated import paths")."""
from __future__ import annotations

import warnings
from typing import Any, Callable, Mapping

__all__ = ["renamed_getattr", "REMOVED_IN"]

#: the release that removes the old names
REMOVED_IN = "0.3"


def renamed_getattr(module: str, renamed: Mapping[str, str], namespace: Mapping[str, Any]) -> Callable[[str], Any]:
    """A module-level ``__getattr__`` for ``module`` (its ``__name__``): each old name of
    ``renamed`` (old -> new) gives ``namespace[new]`` (the module's ``globals()``) with a
    warning; any other name is an :class:`AttributeError` as without it."""
    def __getattr__(name: str) -> Any:
        if name in renamed:
            warnings.warn(f"{module}.{name} is now {renamed[name]} (the old name is removed in release {REMOVED_IN})",
                          DeprecationWarning, stacklevel=2)
            return namespace[renamed[name]]
        raise AttributeError(f"module {module!r} has no attribute {name!r}")
    return __getattr__
