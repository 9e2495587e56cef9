"""Result values of the public API: frozen, compared by the document they write, short to print.

A :class:`FitResult` (lmfit's ``MinimizerResult``, statsmodels' results and py-ballisticcalc's
``HitResult`` are the models) carries everything a fit found and chose: ``res.cd`` the Cd table
as arrays (:class:`CdTable`), ``res.band(level)``, ``res.summary()`` a printable table,
``to_dict()`` the content of ``result.json``, ``to_inference_data()`` the ArviZ posterior,
``plot_cd()`` and the report's other figures, ``write(DIR)`` the folder the command line writes,
and :func:`load_result` reads such a folder back. :class:`DiagnosisResult` and
:class:`PlanResult` follow the same pattern.

This package sits low in the layers (above ``estimate/``, below ``diagnosis/`` and the
commands): values only. Its presentation methods (the figures, ``write``) import ``plots/`` and
``report/`` inside the method, the one upward edge the architecture test allows.
"""
from __future__ import annotations

from .cd import CdTable
from .diagnosis import DiagnosisResult, load_diagnosis
from .fit import BAND_KINDS, CHAIN, LOG_LIKELIHOOD_DRAWS, PARTIAL, FitResult, load_result
from .plan import PlanResult, load_plan
from .summary import Summary

__all__ = ["FitResult", "CdTable", "Summary", "DiagnosisResult", "PlanResult", "load_result", "load_diagnosis",
           "load_plan", "BAND_KINDS", "LOG_LIKELIHOOD_DRAWS", "PARTIAL", "CHAIN"]
