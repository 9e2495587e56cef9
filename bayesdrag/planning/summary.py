"""Deprecated: moved to :mod:`bayesdrag.planning.plan` (``summary_paragraph`` is now ``plan_paragraph``); this re-export is removed in release 0.3."""
from . import plan as _moved
from .plan import *  # noqa: F401,F403

_RENAMED = {"summary_paragraph": "plan_paragraph"}


def __getattr__(name):
    return getattr(_moved, _RENAMED.get(name, name))
