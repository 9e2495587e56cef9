"""Trajectory models: the point mass (numba kernel and scipy reference) and the 6-DOF simulator.

The modules here compile numba functions, so numba's settings (cache folder, cache locator,
idle threads) are made before any of them imports numba (:mod:`bayesdrag._runtime.numba_setup`): the
first place a process needs the compiled kernel, never ``import bayesdrag``.
"""
from .._runtime.numba_setup import ensure as _numba_settings

_numba_settings()
