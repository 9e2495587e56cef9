"""Deprecated: moved to :mod:`bayesdrag.pipeline.sampling`; this re-export is removed in release 0.3."""
from .pipeline.sampling import *  # noqa: F401,F403
from .pipeline.sampling import __all__  # noqa: F401
