"""bayesdrag: drag coefficient Cd(M) from radar-tracked trajectories, with honest uncertainty.

The public API (everything else is internal and may move):

>>> import bayesdrag                                                  # doctest: +SKIP
>>> track = bayesdrag.read_track("track.csv")                         # doctest: +SKIP
>>> rnd = bayesdrag.read_round("round.toml")                          # doctest: +SKIP
>>> res = bayesdrag.fit(track, rnd, mcmc=False)                       # doctest: +SKIP
>>> print(res.summary())                                              # doctest: +SKIP
>>> res.cd.to_dataframe()                                             # doctest: +SKIP
>>> lo, hi = res.band(0.9)                                            # doctest: +SKIP
>>> res.write("out")                                                  # doctest: +SKIP
>>> bayesdrag.load_result("out") == res                               # doctest: +SKIP
True

The results (:class:`FitResult`, :class:`DiagnosisResult`, :class:`PlanResult`) are frozen values
with a short ``repr``, a printable ``summary()``, tables as arrays or data frames, ``to_dict()``
(the JSON file the command writes), figures (``plot_*``), ``write(DIR)``, and a ``load_*``
function that reads a written folder back into an equal value.

Names are imported on first use (PEP 562), so ``import bayesdrag`` is fast and a script that
only reads a track does not load the compiled kernel.
"""
from __future__ import annotations

import importlib
import os
import stat
import sys
import tempfile

__version__ = "0.1.0"


def _private_dir(path):
    """``path`` created 0700 when missing; returned when it is a real folder of this user that
    no one else may write, else None."""
    try:
        os.makedirs(path, mode=0o700, exist_ok=True)
        st = os.lstat(path)
    except OSError:
        return None
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid() or st.st_mode & 0o022:
        return None
    return path


def _use_private_numba_cache():
    """numba's compilation cache is pickled by numba and loaded when the kernel is compiled: the
    one file bayesdrag lets be unpickled (DESIGN.md). It is kept in a per-user folder,
    ``$XDG_CACHE_HOME/bayesdrag/numba`` (default ``~/.cache/bayesdrag/numba``, or
    ``$TMPDIR/bayesdrag-<uid>/numba`` when the home folder cannot be written), created 0700 and
    used only when owned by the user and writable by no one else -- never beside the installed
    package (which other users may share) and never in an output folder. A ``NUMBA_CACHE_DIR``
    the user set is respected. Child processes (Dask workers) inherit the setting."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    home = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    for base in (os.path.join(home, "bayesdrag"), os.path.join(tempfile.gettempdir(), f"bayesdrag-{os.getuid()}")):
        if _private_dir(base) and _private_dir(os.path.join(base, "numba")):
            os.environ["NUMBA_CACHE_DIR"] = os.path.join(base, "numba")
            config = getattr(sys.modules.get("numba"), "config", None)
            if config is not None:       # numba imported before bayesdrag: it read the environment already
                config.CACHE_DIR = os.environ["NUMBA_CACHE_DIR"]
            return



def _passive_openmp_threads():
    """The compiled kernel's threads (numba's OpenMP layer) sleep when idle instead of spinning
    (``OMP_WAIT_POLICY=PASSIVE``, unless the user set it). A sampler calls the kernel a few
    thousand times with 16-64 trajectories each; with spinning threads every call's fork-join
    waited for a core the other processes held: measured on 2 cores at load 2.5, a
    16-trajectory batch of the demo track took 7.7 ms (480 us per trajectory) with the default
    policy and 0.30 ms (19 us) with passive threads; 256 trajectories 30 vs 27 us each. Only
    effective when set before the OpenMP runtime is loaded (numba loads it at the first
    threaded kernel call); child processes inherit it."""
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


def _package_numba_locator():
    """numba finds bayesdrag's compiled functions by the package's own locator
    (:mod:`bayesdrag._numba_cache`: one cache per source, wherever it is installed), then by its
    own locators; a ``NUMBA_CACHE_LOCATOR_CLASSES`` the user set is respected."""
    if os.environ.get("NUMBA_CACHE_LOCATOR_CLASSES"):
        return
    numba_locators = ("UserProvidedCacheLocator", "InTreeCacheLocator", "UserWideCacheLocator",
                      "IPythonCacheLocator", "ZipCacheLocator")
    os.environ["NUMBA_CACHE_LOCATOR_CLASSES"] = ",".join(
        ["bayesdrag._numba_cache.PackageCacheLocator"] + [f"numba.core.caching.{n}" for n in numba_locators])
    config = getattr(sys.modules.get("numba"), "config", None)
    if config is not None and hasattr(config, "CACHE_LOCATOR_CLASSES"):   # numba read the environment already
        config.CACHE_LOCATOR_CLASSES = os.environ["NUMBA_CACHE_LOCATOR_CLASSES"]


_use_private_numba_cache()
_package_numba_locator()
_passive_openmp_threads()

#: public name -> module that defines it
_API = {
    # files
    "read_track": "bayesdrag.io.tracks",
    "write_track": "bayesdrag.io.tracks",
    "read_round": "bayesdrag.io.rounds",
    "write_round": "bayesdrag.io.rounds",
    "read_drag_table": "bayesdrag.io.drag_tables",
    "load_m101": "bayesdrag.io.drag_tables",
    # values
    "RadarTrack": "bayesdrag.track",
    "Round": "bayesdrag.round",
    "Projectile": "bayesdrag.round",
    "Launch": "bayesdrag.round",
    "Radar": "bayesdrag.round",
    "Atmosphere": "bayesdrag.atmosphere",
    "MetProfile": "bayesdrag.atmosphere",
    "ReferenceTable": "bayesdrag.drag",
    # the work
    "fit": "bayesdrag.commands.fit",
    "simulate": "bayesdrag.commands.simulate",
    "diagnose": "bayesdrag.commands.diagnose",
    "plan": "bayesdrag.commands.plan",
    "FitOptions": "bayesdrag.commands.options",
    "PlanOptions": "bayesdrag.commands.options",
    "SimulateOptions": "bayesdrag.commands.options",
    # results
    "FitResult": "bayesdrag.results",
    "CdTable": "bayesdrag.results",
    "Summary": "bayesdrag.results",
    "DiagnosisResult": "bayesdrag.results",
    "PlanResult": "bayesdrag.results",
    "load_result": "bayesdrag.results",
    "load_diagnosis": "bayesdrag.results",
    "load_plan": "bayesdrag.results",
    # errors
    "InputError": "bayesdrag.errors",
    "FitError": "bayesdrag.errors",
    "MissingDataError": "bayesdrag.errors",
}

__all__ = sorted(_API) + ["__version__"]

# what type checkers and editors see: the names of _API, typed where they are defined (the
# package itself imports them on first use); tests/unit/test_typing.py keeps the two lists equal
from typing import TYPE_CHECKING, Any  # noqa: E402  (here, beside the names it types)

if TYPE_CHECKING:
    from .atmosphere import Atmosphere, MetProfile
    from .commands.diagnose import diagnose
    from .commands.fit import fit
    from .commands.options import FitOptions, PlanOptions, SimulateOptions
    from .commands.plan import plan
    from .commands.simulate import simulate
    from .drag import ReferenceTable
    from .errors import FitError, InputError, MissingDataError
    from .io.drag_tables import load_m101, read_drag_table
    from .io.rounds import read_round, write_round
    from .io.tracks import read_track, write_track
    from .results import (CdTable, DiagnosisResult, FitResult, PlanResult, Summary, load_diagnosis, load_plan,
                          load_result)
    from .round import Launch, Projectile, Radar, Round
    from .track import RadarTrack


def __getattr__(name: str) -> Any:
    mod = _API.get(name)
    if mod is None:
        raise AttributeError(f"module 'bayesdrag' has no attribute {name!r}")
    value = getattr(importlib.import_module(mod), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return __all__
