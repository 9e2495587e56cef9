"""Deprecated: moved to :mod:`bayesdrag.estimate.build.basis`; this re-export is removed in release 0.3."""
from ..build import basis as _moved
from ..build.basis import *  # noqa: F401,F403


def __getattr__(name):
    return getattr(_moved, name)
