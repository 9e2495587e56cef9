"""Result types of the public API: frozen, self-describing, and able to write themselves.

A :class:`FitResult` (lmfit's ``MinimizerResult`` and py-ballisticcalc's ``HitResult`` are the
models) carries everything a fit found and chose: ``to_dict()`` is the content of
``result.json``, ``to_inference_data()`` the ArviZ posterior, ``write(DIR)`` the folder the
command line writes (``result.json``, ``posterior.nc``, figures, ``report.html``).
"""
from __future__ import annotations

import copy
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._gc import paused_gc
from .io.outputs import atomic_write, ensure_space, write_json

__all__ = ["FitResult", "DiagnosisResult", "PARTIAL", "CHAIN"]

#: the sampler's chain while it runs, and once the run has finished
PARTIAL = "chain.partial.h5"
CHAIN = "chain.h5"


def _jsonable(o):
    """Plain JSON types (numpy scalars and arrays converted, non-finite floats to None)."""
    if isinstance(o, dict):
        return {str(k): _jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_jsonable(v) for v in o]
    if isinstance(o, np.ndarray):
        return [_jsonable(v) for v in o.tolist()]
    if isinstance(o, (bool, np.bool_)):
        return bool(o)
    if isinstance(o, (int, np.integer)):
        return int(o)
    if isinstance(o, (float, np.floating)):
        return float(o) if np.isfinite(o) else None
    return o


@dataclass(frozen=True, eq=False)
class FitResult:
    """What a fit found (:func:`bayesdrag.fit`).

    Attributes
    ----------
    summary : dict
        The content of ``result.json``: ``scheme``, ``drag_model``, ``ml`` (with
        ``quality``), ``cd`` rows (each with ``determined`` and ``band_sd``), ``posterior`` and
        ``mcmc`` after sampling, ``windows`` for Scheme 2.
    track : RadarTrack
    round : Round
    options : FitOptions
    scheme1 : Scheme1Fit or None
        The Scheme 1 maximum-likelihood fit (its ML result, problem, start, smoothing, launch
        check, rejected samples).
    posterior : BayesResult or None
        The emcee run (Scheme 1 with sampling).
    log_posterior : LogPosterior or None
    scheme2 : Scheme2Result or None
    window_draws : dict or None
        Scheme 2: window index -> Cd draws (chains, draws).
    windows_ok : tuple of int
        Scheme 2: the windows whose fit converged.
    grid : ndarray
        The Mach grid of ``cd``.
    warnings : tuple of str
        Everything the user should read (misfits, undetermined ranges, launch conflicts, sampler
        problems); the command prints them on stderr.
    seconds : float
        Wall-clock time of the fit [s].
    """

    summary: dict
    track: object
    round: object
    options: object
    scheme1: object = None
    posterior: object = None
    log_posterior: object = None
    scheme2: object = None
    window_draws: dict | None = None
    windows_ok: tuple = ()
    grid: np.ndarray = None
    warnings: tuple = ()
    seconds: float = 0.0
    _cache: dict = field(default_factory=dict, repr=False)

    # -- what a reader asks first -------------------------------------------------------------
    @property
    def success(self):
        """True when the fit converged and its residuals look like the noise."""
        ml = self.summary["ml"]
        return bool(ml.get("converged", False) and ml.get("quality", {}).get("ok", False))

    @property
    def message(self):
        ml = self.summary["ml"]
        return ml.get("message") or f"{ml.get('windows_converged')} of {ml.get('windows')} windows converged"

    @property
    def cd(self):
        """The ``cd`` rows (list of dict: mach, ml, crb_sd, band_sd, determined, ...)."""
        return copy.deepcopy(self.summary["cd"])

    @property
    def ml(self):
        """The Scheme 1 :class:`~bayesdrag.estimate.ml.MLResult` (None for Scheme 2)."""
        return None if self.scheme1 is None else self.scheme1.ml

    def to_dict(self):
        """The content of ``result.json``: plain JSON types, a fresh copy."""
        return json.loads(json.dumps(_jsonable(self.summary), allow_nan=False))

    def to_inference_data(self):
        """The posterior as ArviZ InferenceData (``cd`` over a ``mach`` dim, the drag coefficients as
        one vector, noise and initial state by name); None without sampling."""
        if "idata" not in self._cache:
            self._cache["idata"] = self._inference_data()
        return self._cache["idata"]

    def _inference_data(self):
        if self.posterior is not None:
            from .estimate.inference import to_inference_data
            from .estimate.sampler import cd_draws

            f1 = self.scheme1
            cd = cd_draws(self.posterior, f1.drag_model, self.grid, f1.problem.P)
            if any("model_error_floor" in r for r in self.summary.get("cd", [])):
                from .estimate.sampler import widen_to_floor  # the same widening as result.json

                cd = widen_to_floor(cd, [dict(r) for r in self.summary["cd"]])
            return to_inference_data(self.posterior, self.log_posterior, self.grid, cd,
                                     self.round.reference_drag, seed=self.options.seed)
        if self.window_draws:
            from .estimate.inference import windows_inference_data

            return windows_inference_data(self.summary["windows"], self.windows_ok, self.window_draws, self.track,
                                          self.options.channels or self.track.names)
        return None

    # -- the output folder --------------------------------------------------------------------
    def write(self, directory, *, sources=None):
        """Write the folder the command line writes: ``result.json``, ``posterior.nc`` (after
        sampling), the figures and ``report.html``; a finished chain ``chain.partial.h5`` in it
        becomes ``chain.h5``. The folder is written as one consistent set
        (:class:`~bayesdrag.io.outputs.OutputRun`): ``manifest.json`` lists the files, an earlier
        run's files are moved to ``superseded/``.

        Parameters
        ----------
        directory : path
            Created if needed.
        sources : dict, optional
            ``{"track": ..., "round": ...}`` file names shown in the report (and, when they are
            files, recorded with their SHA-256 in the manifest).

        Returns
        -------
        list of Path
            The files written.
        """
        from .io.outputs import OutputRun

        files = {k: v for k, v in (sources or {}).items() if v is not None and Path(v).is_file()}
        with OutputRun(directory, "fit", inputs=files) as run:
            self.write_into(run, sources=sources)
        return [run.folder / f["name"] for f in run.manifest["files"]]

    def write_into(self, run, *, sources=None):
        """Write the outputs into an open :class:`~bayesdrag.io.outputs.OutputRun` (its staging
        folder) and hand it the finished chain; the run commits them."""
        self.write_files(run.staging, sources=sources)
        if self.posterior is not None:
            run.adopt(PARTIAL, CHAIN)

    def write_files(self, directory, *, sources=None):
        """Write ``result.json``, ``posterior.nc`` (after sampling), the figures and
        ``report.html`` into ``directory`` as plain files (no manifest, nothing moved).

        Returns
        -------
        list of Path
        """
        from .report.fit import write_fit_report

        out = Path(directory)
        written = [out / "result.json"]
        with paused_gc():       # thousands of figure artists: no collections over the fit's objects
            write_json(out / "result.json", self.to_dict())
            idata = self.to_inference_data()
            if idata is not None:
                # HDF5 crashes the process (segfault) when the disk fills up inside a write: refuse first
                ensure_space(out, _netcdf_bytes(idata) + (256 << 10), "posterior.nc")   # uncompressed: an upper bound
                atomic_write(out / "posterior.nc", lambda tmp: idata.to_netcdf(tmp))
                written.append(out / "posterior.nc")
            written += write_fit_report(out, self, sources=sources or {})
        return written


@dataclass(frozen=True, eq=False)
class DiagnosisResult:
    """What a diagnosis found (:func:`bayesdrag.diagnose`).

    Attributes
    ----------
    diagnosis : Diagnosis
        The analysis (:func:`bayesdrag.diagnosis.diagnose`): its ``summary`` and the residuals
        the figures show.
    track : RadarTrack
    round : Round
    """

    diagnosis: object
    track: object
    round: object

    @property
    def verdict(self):
        """The material effects found, best first (``[]``: the nominal model explains the track)."""
        return list(self.diagnosis.summary["verdict"])

    @property
    def summary(self):
        """The content of ``diagnosis.json`` (a fresh copy; :meth:`to_dict`)."""
        return self.to_dict()

    @property
    def paragraph(self):
        """The diagnosis in one paragraph of words."""
        from .diagnosis.summary import summary_paragraph

        return summary_paragraph(self.diagnosis.summary)

    def to_dict(self):
        """The content of ``diagnosis.json``: plain JSON types, a fresh copy (with ``summary``, the
        paragraph)."""
        s = dict(self.diagnosis.summary, summary=self.paragraph)
        return json.loads(json.dumps(_jsonable(s), allow_nan=False))

    def write(self, directory, *, sources=None):
        """Write ``diagnosis.json``, the figures and ``diagnosis.html`` into ``directory`` as one
        consistent set (:class:`~bayesdrag.io.outputs.OutputRun`, as :meth:`FitResult.write`).

        Returns
        -------
        list of Path
        """
        from .io.outputs import OutputRun

        files = {k: v for k, v in (sources or {}).items() if v is not None and Path(v).is_file()}
        with OutputRun(directory, "diagnose", inputs=files) as run:
            self.write_files(run.staging, sources=sources)
        return [run.folder / f["name"] for f in run.manifest["files"]]

    def write_files(self, directory, *, sources=None):
        """Write ``diagnosis.json``, the figures and ``diagnosis.html`` into ``directory`` as
        plain files. Returns the paths."""
        from .report.diagnosis import write_diagnosis

        sources = sources or {}
        out = Path(directory)
        write_diagnosis(out, self.diagnosis, track_name=str(sources.get("track", self.track.source)),
                        round_name=str(sources.get("round", self.round.path)))
        return [out / "diagnosis.json", out / "diagnosis.html"] + sorted(out.glob("diagnosis_*.png"))


def _netcdf_bytes(idata):
    """Bytes of the arrays of an InferenceData (what its NetCDF file holds, before overhead)."""
    total = 0
    for name in idata.groups():
        ds = getattr(idata, name.lstrip("/"), None)
        if ds is not None:
            total += sum(int(v.nbytes) for v in ds.variables.values())
    return total
