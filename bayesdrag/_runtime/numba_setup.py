"""numba's settings for bayesdrag's compiled functions, made where they are first needed.

:func:`ensure` runs once per process, called by the modules that compile numba functions
(``bayesdrag.dynamics``) before they import numba, and by ``batch`` before it starts Dask
workers (which inherit the environment). ``import bayesdrag`` changes nothing: a script that
only reads a track sets no variable and creates no folder.

What it sets, each only when the user has not (a user's own value is respected):

* ``NUMBA_CACHE_DIR``: the per-user private folder ``<user cache>/numba``
  (:func:`bayesdrag._runtime.user_cache.user_cache_dir`). numba pickles its cache and loads it when a
  function is compiled: the one file bayesdrag lets be unpickled, so it is kept where only the
  user can write, never beside the installed package (which other users may share) and never
  in an output folder. When that folder, or a ``NUMBA_CACHE_DIR`` the user set, is writable by
  others, not owned by the user or a symbolic link, it is not used: this process (and its
  workers) compile into a fresh private temporary folder removed at exit, and one note on the
  ``bayesdrag`` logger says why.
* ``NUMBA_CACHE_LOCATOR_CLASSES``: bayesdrag's locator first
  (:class:`bayesdrag._runtime.numba_cache.PackageCacheLocator`: one cache per source, wherever it is
  installed), then numba's own.
* ``OMP_WAIT_POLICY=PASSIVE``: the kernel's threads sleep when idle instead of spinning. A
  sampler calls the kernel a few thousand times with 16-64 trajectories each; with spinning
  threads every call's fork-join waited for a core the other processes held (figures in
  ``docs/bayes.md``). Effective because the OpenMP runtime is loaded at the first
  threaded kernel call, after this.

numba reads its settings when it is imported; when something imported numba before (the user's
code), ``numba.config`` is updated too. Functions decorated before the settings were made (a
bayesdrag module that imports numba itself, imported first) get their cache re-enabled under
them, before any of them is compiled or loaded.
"""
from __future__ import annotations

import atexit
import logging
import os
import shutil
import sys
import tempfile

from .user_cache import checked_folder, user_cache_dir

__all__ = ["ensure", "cache_note"]

_LOCATOR = "bayesdrag._runtime.numba_cache.PackageCacheLocator"
_NUMBA_LOCATORS = ("UserProvidedCacheLocator", "InTreeCacheLocator", "UserWideCacheLocator",
                   "IPythonCacheLocator", "ZipCacheLocator")
_state = {"done": False, "note": None}


def cache_note():
    """Why the cache folder was not used in this process (one line), or None."""
    return _state["note"]


def ensure():
    """Make numba's settings for bayesdrag (module docstring); once per process."""
    if _state["done"]:
        return
    _state["done"] = True
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    _cache_dir()
    _locators()
    _recache_early_dispatchers()


def _cache_dir():
    user = os.environ.get("NUMBA_CACHE_DIR")
    if user:
        why = checked_folder(user)
        if why is None:
            return
        why = f"NUMBA_CACHE_DIR {why}"
    else:
        folder, why = user_cache_dir("numba")
        if folder is not None:
            _set_cache_dir(folder)
            return
    fresh = tempfile.mkdtemp(prefix="bayesdrag-numba-")        # 0700, this process's own
    atexit.register(shutil.rmtree, fresh, True)
    _set_cache_dir(fresh)
    _state["note"] = (f"bayesdrag: note: numba's cache folder is not used: {why}; the compiled kernel is "
                      f"kept in {fresh} for this run only (compiling takes ~10 s)")
    logging.getLogger("bayesdrag").warning(_state["note"])


def _set_cache_dir(folder):
    os.environ["NUMBA_CACHE_DIR"] = folder
    config = getattr(sys.modules.get("numba"), "config", None)
    if config is not None:            # numba imported already: it read the environment before
        config.CACHE_DIR = folder


def _locators():
    if os.environ.get("NUMBA_CACHE_LOCATOR_CLASSES"):
        return
    value = ",".join([_LOCATOR] + [f"numba.core.caching.{n}" for n in _NUMBA_LOCATORS])
    os.environ["NUMBA_CACHE_LOCATOR_CLASSES"] = value
    config = getattr(sys.modules.get("numba"), "config", None)
    if config is not None and hasattr(config, "CACHE_LOCATOR_CLASSES"):
        config.CACHE_LOCATOR_CLASSES = value


def _recache_early_dispatchers():
    """Cached functions of bayesdrag modules decorated before the settings: their cache is made
    again under them (they have compiled and loaded nothing yet)."""
    if "numba" not in sys.modules:
        return
    from numba.core.dispatcher import Dispatcher

    for name, mod in list(sys.modules.items()):
        if not name.startswith("bayesdrag.") or mod is None:
            continue
        for fn in list(vars(mod).values()):
            cache = getattr(fn, "_cache", None)
            if (isinstance(fn, Dispatcher) and type(cache).__name__ == "FunctionCache" and not fn.overloads
                    and type(cache._impl.locator).__name__ != "PackageCacheLocator"):
                fn.enable_caching()
