"""Deprecated: moved to :mod:`bayesdrag.estimate.build.start`; this re-export is removed in release 0.3."""
from ..build import start as _moved
from ..build.start import *  # noqa: F401,F403


def __getattr__(name):
    return getattr(_moved, name)
