"""Deprecated: moved to :mod:`bayesdrag.air.atmosphere`; this re-export is removed in release 0.3."""
from .air.atmosphere import *  # noqa: F401,F403
