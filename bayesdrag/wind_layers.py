"""Deprecated: moved to :mod:`bayesdrag.effects.wind_layers`; this re-export is removed in release 0.3."""
from .effects.wind_layers import *  # noqa: F401,F403
from .effects.wind_layers import __all__  # noqa: F401
