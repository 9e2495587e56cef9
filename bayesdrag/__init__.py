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
only reads a track does not load the compiled kernel. Importing changes nothing outside the
package: no environment variable, no folder; numba's settings are made where the kernel is first
needed (:mod:`bayesdrag._runtime.numba_setup`).
"""
from __future__ import annotations

import importlib

__version__ = "0.1.0"


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
    "Atmosphere": "bayesdrag.air.atmosphere",
    "MetProfile": "bayesdrag.air.atmosphere",
    "ReferenceTable": "bayesdrag.drag",
    # the work
    "fit": "bayesdrag.pipeline",
    "simulate": "bayesdrag.pipeline",
    "diagnose": "bayesdrag.pipeline",
    "plan": "bayesdrag.pipeline",
    "FitOptions": "bayesdrag.options",
    "PlanOptions": "bayesdrag.options",
    "SimulateOptions": "bayesdrag.options",
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
    # warnings
    "BayesdragWarning": "bayesdrag.errors",
    "FitWarning": "bayesdrag.errors",
}

__all__ = sorted(_API) + ["__version__"]

# what type checkers and editors see: the names of _API, typed where they are defined (the
# package itself imports them on first use); tests/unit/test_typing.py keeps the two lists equal
from typing import TYPE_CHECKING, Any  # noqa: E402  (here, beside the names it types)

if TYPE_CHECKING:
    from .air.atmosphere import Atmosphere, MetProfile
    from .pipeline import diagnose
    from .pipeline import fit
    from .options import FitOptions, PlanOptions, SimulateOptions
    from .pipeline import plan, simulate
    from .drag import ReferenceTable
    from .errors import BayesdragWarning, FitError, FitWarning, InputError, MissingDataError
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
