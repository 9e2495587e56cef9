"""Deprecated: moved to :mod:`bayesdrag.effects.inputs`; this re-export is removed in release 0.3."""
from .effects.inputs import ExtraParam, SimInputs  # noqa: F401

__all__ = ["ExtraParam", "SimInputs"]
