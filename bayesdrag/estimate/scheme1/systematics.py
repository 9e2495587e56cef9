"""Deprecated: moved to :mod:`bayesdrag.estimate.build.sources`; this re-export is removed in release 0.3."""
from ..build import sources as _moved
from ..build.sources import *  # noqa: F401,F403


def __getattr__(name):
    return getattr(_moved, name)
