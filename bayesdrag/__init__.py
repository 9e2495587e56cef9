"""bayesdrag: drag coefficient Cd(M) from radar-tracked trajectories, with honest uncertainty.

The public API (everything else is internal and may move):

>>> import bayesdrag                                                  # doctest: +SKIP
>>> track = bayesdrag.read_track("track.csv")                         # doctest: +SKIP
>>> rnd = bayesdrag.read_round("round.toml")                          # doctest: +SKIP
>>> res = bayesdrag.fit(track, rnd, mcmc=False)                       # doctest: +SKIP
>>> res.to_dict()["ml"]["quality"]["ok"]                              # doctest: +SKIP
True

Names are imported on first use (PEP 562), so ``import bayesdrag`` is fast and a script that
only reads a track does not load the compiled kernel. Importing changes nothing outside the
package: no environment variable, no folder; numba's settings are made where the kernel is first
needed (:mod:`bayesdrag._numba_setup`).
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
    "Atmosphere": "bayesdrag.atmosphere",
    "MetProfile": "bayesdrag.atmosphere",
    "ReferenceTable": "bayesdrag.drag",
    # the work
    "fit": "bayesdrag.commands.fit",
    "simulate": "bayesdrag.commands.simulate",
    "FitResult": "bayesdrag.results",
    "diagnose": "bayesdrag.commands.diagnose",
    "DiagnosisResult": "bayesdrag.results",
    "FitOptions": "bayesdrag.commands.options",
    "plan": "bayesdrag.commands.plan",
    "PlanResult": "bayesdrag.commands.plan",
    "PlanOptions": "bayesdrag.commands.options",
    "SimulateOptions": "bayesdrag.commands.options",
    # errors
    "InputError": "bayesdrag.errors",
    "FitError": "bayesdrag.errors",
}

__all__ = sorted(_API) + ["__version__"]


def __getattr__(name):
    mod = _API.get(name)
    if mod is None:
        raise AttributeError(f"module 'bayesdrag' has no attribute {name!r}")
    value = getattr(importlib.import_module(mod), name)
    globals()[name] = value
    return value


def __dir__():
    return __all__
