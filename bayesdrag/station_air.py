"""Deprecated: moved to :mod:`bayesdrag.air.station`; this re-export is removed in release 0.3."""
from .air.station import *  # noqa: F401,F403
