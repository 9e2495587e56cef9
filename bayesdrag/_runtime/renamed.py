"""Old names kept for one release: a module's ``__getattr__`` that answers a renamed name with
the object under its new name and a :class:`DeprecationWarning` (docs/architecture.md,
"Deprecated import paths")."""
from __future__ import annotations

import warnings
from typing import Any, Callable, Mapping

__all__ = ["renamed_getattr", "warn_renamed", "REMOVED_IN"]

#: the release that removes the old names
REMOVED_IN = "0.3"


def warn_renamed(old: str, new: str, stacklevel: int = 3) -> None:
    """Warn that ``old`` (a qualified name) is now ``new`` until :data:`REMOVED_IN`;
    ``stacklevel`` counts from the caller of this function's caller (a deprecated property or
    method: the user's line)."""
    warnings.warn(f"{old} is now {new} (the old name is removed in release {REMOVED_IN})", DeprecationWarning,
                  stacklevel=stacklevel)


def renamed_getattr(module: str, renamed: Mapping[str, str], namespace: Mapping[str, Any]) -> Callable[[str], Any]:
    """A module-level ``__getattr__`` for ``module`` (its ``__name__``): each old name of
    ``renamed`` (old -> new) gives ``namespace[new]`` (the module's ``globals()``) with a
    warning; any other name is an :class:`AttributeError` as without it."""
    def __getattr__(name: str) -> Any:
        if name in renamed:
            warn_renamed(f"{module}.{name}", renamed[name], stacklevel=3)
            return namespace[renamed[name]]
        raise AttributeError(f"module {module!r} has no attribute {name!r}")
    return __getattr__
