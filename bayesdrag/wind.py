"""Deprecated: moved to :mod:`bayesdrag.air.wind`; this re-export is removed in release 0.3."""
from .air.wind import *  # noqa: F401,F403
