"""Deprecated: moved to :mod:`bayesdrag.pipeline.model_check`; this re-export is removed in release 0.3."""
from .pipeline.model_check import *  # noqa: F401,F403
from .pipeline.model_check import __all__  # noqa: F401
