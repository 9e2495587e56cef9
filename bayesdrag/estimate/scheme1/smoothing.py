"""Deprecated: moved to :mod:`bayesdrag.estimate.build.smoothing`; this re-export is removed in release 0.3."""
from ..build import smoothing as _moved
from ..build.smoothing import *  # noqa: F401,F403


def __getattr__(name):
    return getattr(_moved, name)
