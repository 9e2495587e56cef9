"""Deprecated: moved to :mod:`bayesdrag.estimate.build.launch`; this re-export is removed in release 0.3."""
from ..build import launch as _moved
from ..build.launch import *  # noqa: F401,F403


def __getattr__(name):
    return getattr(_moved, name)
