"""Where numba keeps bayesdrag's compiled functions: a folder named by the module's place in
the package and the hash of its source, not by the folder it is installed in.

numba's own locator names a cache folder after the source file's absolute path, so the kernel
was compiled again (most of a first run's time) for every new installation of the same code: a new virtual environment, a fresh clone, a reinstall into another prefix. With
:class:`PackageCacheLocator` the cache is keyed by what numba's index checks anyway (the
source's content hash, numba's version, the CPU), so the same source compiles once per user and
machine. bayesdrag registers it through numba's documented ``NUMBA_CACHE_LOCATOR_CLASSES``
setting (``bayesdrag/__init__.py``), ahead of numba's own locators, which still serve every
other file; a user's own setting of that variable is respected.
"""
from __future__ import annotations

import hashlib
import os

from numba.core import caching, config

#: the folder holding the ``bayesdrag`` package
_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
_PKG = os.path.join(_ROOT, "bayesdrag")

class PackageCacheLocator(caching.UserProvidedCacheLocator):
    """numba cache locator for the files of the bayesdrag package (others: ``None``, so numba's
    locators take them): ``CACHE_DIR/bayesdrag_<module path>_<source hash>``."""

    def __init__(self, py_func, py_file):
        super().__init__(py_func, py_file)
        rel = os.path.splitext(os.path.relpath(os.path.abspath(py_file), _ROOT))[0].replace(os.sep, "_")
        with open(py_file, "rb") as f:
            digest = hashlib.sha256(f.read()).hexdigest()[:16]
        self._cache_path = os.path.join(config.CACHE_DIR, f"{rel}_{digest}")

    @classmethod
    def from_function(cls, py_func, py_file):
        if not config.CACHE_DIR or not os.path.abspath(py_file).startswith(_PKG + os.sep):
            return None
        return super().from_function(py_func, py_file)


def compile_record():
    """What this process compiled of bayesdrag's cached numba functions, and what it loaded.

    Looks at the dispatchers of the bayesdrag modules already imported (none is imported
    here): an overload missing from the cache was compiled, and numba's timers say how long.

    Returns
    -------
    dict
        ``compiled`` (names of the functions compiled here), ``compile_seconds`` (their
        compiler time [s]), ``loaded`` (how many overloads came from the cache) and
        ``cache_dir``.
    """
    import sys

    from numba.core.dispatcher import Dispatcher

    compiled, seconds, loaded = [], 0.0, 0
    for name, mod in list(sys.modules.items()):
        if not name.startswith("bayesdrag.") or mod is None:
            continue
        for attr, fn in list(vars(mod).items()):
            if (not isinstance(fn, Dispatcher) or getattr(fn, "__module__", name) != name
                    or type(getattr(fn, "_cache", None)).__name__ == "NullCache"):
                continue            # not bayesdrag's, or not cached (compiled inside a cached one)
            stats = fn.stats
            loaded += sum(stats.cache_hits.values())
            if sum(stats.cache_misses.values()):
                compiled.append(f"{name.split('.', 1)[1]}.{attr}")
                for cres in fn.overloads.values():
                    timers = (getattr(cres, "metadata", None) or {}).get("timers", {})
                    seconds += float(timers.get("compiler_lock", 0.0))
    return {"compiled": sorted(compiled), "compile_seconds": round(seconds, 2), "loaded": loaded,
            "cache_dir": config.CACHE_DIR or None}
