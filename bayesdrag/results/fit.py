"""What a fit found, as a value: :class:`FitResult`, its paragraph and printable summary (from
``result.json``'s content, so a loaded result reads the same), and :func:`load_result` to read
a written fit folder back into one."""
from __future__ import annotations

import json
import os
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import BayesdragWarning, FitWarning, InputError, MissingDataError, as_warning
from .words import determined_words, effect_lines
from ..io.hdf5_guard import Hdf5Limits
from ..track import MAX_FIT_SAMPLES
from .cd import CdTable, band_z
from .document import REWRITE, RESULT_SCHEMA, jsonable, read_document
from .summary import Summary

if TYPE_CHECKING:
    import arviz
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from ..estimate.model.ml import MLResult
    from ..estimate.bayes.posterior import LogPosterior
    from ..estimate.bayes.sampler import BayesResult
    from ..estimate.scheme1.fit import Scheme1Fit
    from ..estimate.scheme2 import Scheme2Result
    from ..io.outputs import OutputRun
    from ..round import Round
    from ..track import RadarTrack

__all__ = ["FitResult", "load_result", "fit_paragraph", "fit_summary", "BAND_KINDS", "LOG_LIKELIHOOD_DRAWS",
           "PARTIAL", "CHAIN"]

#: the sampler's chain while it runs, and once the run has finished
PARTIAL = "chain.partial.h5"
CHAIN = "chain.h5"
#: the kinds of :meth:`FitResult.band`
BAND_KINDS = ("total", "statistical", "posterior")
#: posterior draws (over all chains, evenly thinned) whose pointwise log-likelihood
#: ``to_inference_data`` holds and ``posterior.nc`` keeps (float32): every draw times every
#: observation would outweigh the rest of the file many times, and fewer than ~2 000 leave
#: ``arviz.loo``'s Pareto tails too short without ``reff=1.0`` (docs/bayes.md)
LOG_LIKELIHOOD_DRAWS = 2048
#: rows of the Cd table a summary shows
SUMMARY_ROWS = 7
#: most bytes of values a posterior.nc may declare, whatever result.json records [bytes] (the
#: demo's holds 12 MB; 16 walkers x 20 000 steps x 200 values per draw take 0.5 GB)
MAX_POSTERIOR_BYTES = 4 << 30
#: bytes of one value as the posterior bound counts it (float64) [bytes]
POSTERIOR_VALUE_BYTES = 8
#: the posterior bound's margin over its count of the file's values [-]
POSTERIOR_MARGIN = 2
#: posterior predictive draws per chain a posterior.nc may hold (fit_arrays keeps 5)
PREDICTIVE_DRAWS = 16
#: copies of the constants (observed and constant data, coordinates) a posterior.nc may hold
CONSTANT_COPIES = 8
#: sampled parameters beyond result.json's ml.params and ml.fixed (noise sd per channel, nu)
EXTRA_PARAMETERS = 8
#: chains of a Scheme 2 window (options.MAX_WALKERS: result.json does not record them)
SCHEME2_MAX_CHAINS = 1024
#: channels counted when result.json records no samples per channel (x, y, z, v)
UNRECORDED_CHANNELS = 4
#: what to do about a refused posterior.nc
POSTERIOR_FIX = ("write the folder again with bayesdrag fit -o DIR (or res.write(DIR)), or move posterior.nc away to "
                 "read the result without its draws")


class FitResult:
    """What a fit found (:func:`bayesdrag.fit`), as a value: frozen, compared by what
    ``result.json`` holds, printable in one short paragraph.

    Attributes
    ----------
    record : dict
        The content of ``result.json`` (read it, do not change it; :meth:`to_dict` gives a copy).
    cd : CdTable
        Cd(M) as arrays: ``mach``, ``ml``, ``sd`` (the total band sd), ``determined``,
        ``reference``, ``crb_sd``, ``statistical_sd`` and, when sampled, ``mean``, ``q05``,
        ``q95``.
    track : RadarTrack or None
        The track as fitted (thinned when very dense); None for a result read from a folder.
    round : Round or None
        None for a result read from a folder.
    options : FitOptions or None
        The options of the fit; None for a result read from a folder.
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
    warnings : tuple of FitWarning
        Everything the user should read (misfits, undetermined ranges, launch conflicts, sampler
        problems; :class:`~bayesdrag.errors.FitWarning`, tested by ``kind``, ``str()`` its
        sentence); the command prints them on stderr, :func:`bayesdrag.fit` also emits them as
        :class:`~bayesdrag.errors.BayesdragWarning`. Read back from a folder, their kind is
        ``recorded``.
    seconds : float
        Wall-clock time of the fit [s].
    folder : Path or None
        The folder a loaded result was read from (None for a fresh fit).

    Notes
    -----
    A result read back by :func:`load_result` holds what the folder holds (``result.json``,
    ``posterior.nc``): its Cd table, bands, summary, ``to_dict()``, ``to_inference_data()`` and
    the figures drawn from ``result.json`` are those of the fit; what needs the fit's objects
    (the residual, corner and trace figures, writing the folder again) raises
    :class:`~bayesdrag.errors.MissingDataError` naming what is missing. Two results are equal
    when their ``to_dict()`` are.
    """

    record: dict[str, Any]
    cd: CdTable
    track: RadarTrack | None
    round: Round | None
    options: Any
    scheme1: Scheme1Fit | None
    posterior: BayesResult | None
    log_posterior: LogPosterior | None
    scheme2: Scheme2Result | None
    window_draws: dict[int, np.ndarray] | None
    windows_ok: tuple[int, ...]
    grid: np.ndarray
    warnings: tuple[FitWarning, ...]
    seconds: float
    folder: Path | None
    _cache: dict[Any, Any]

    def __init__(self, record: dict[str, Any] | None = None, track: RadarTrack | None = None,
                 round: Round | None = None, options: Any = None, scheme1: Scheme1Fit | None = None,
                 posterior: BayesResult | None = None, log_posterior: LogPosterior | None = None,
                 scheme2: Scheme2Result | None = None, window_draws: dict[int, np.ndarray] | None = None,
                 windows_ok: tuple[int, ...] | None = None, grid: np.ndarray | None = None,
                 warnings: tuple[FitWarning, ...] = (), seconds: float = 0.0, *, summary: dict[str, Any] | None = None,
                 inference_data: arviz.InferenceData | None = None, folder: Path | None = None,
                 cd_draws: np.ndarray | None = None) -> None:
        if (record is None) == (summary is None):
            raise TypeError("FitResult: give the result.json content as record= (summary= is its older name)")
        rec = record if record is not None else summary
        assert rec is not None
        if windows_ok is None:
            windows_ok = tuple(k for k, w in enumerate(rec.get("windows") or []) if w.get("converged"))
        table = CdTable.from_rows(rec["cd"], statistical_sd=_scheme2_statistical_sd(rec, windows_ok))
        values = dict(record=rec, cd=table, track=track, round=round, options=options, scheme1=scheme1,
                      posterior=posterior, log_posterior=log_posterior, scheme2=scheme2, window_draws=window_draws,
                      windows_ok=tuple(int(k) for k in windows_ok),
                      grid=np.asarray(grid if grid is not None else table.mach, float),
                      warnings=tuple(as_warning(w) for w in warnings),
                      seconds=float(seconds), folder=None if folder is None else Path(folder),
                      _cache={} if inference_data is None else {(
                          "idata", 0 if (rec.get("mcmc") or {}).get("converged") is False and rec.get("scheme") == 1
                          else LOG_LIKELIHOOD_DRAWS): inference_data})
        if cd_draws is not None:   # the draws result.json's rows were made of: one set for rows, idata and report
            values["_cache"]["cd_draws"] = np.asarray(cd_draws, dtype=np.float64)
        for k, v in values.items():
            object.__setattr__(self, k, v)

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"FitResult is frozen: cannot set {name!r}")

    def __delattr__(self, name: str) -> None:
        raise AttributeError(f"FitResult is frozen: cannot delete {name!r}")

    # -- what a reader asks first -------------------------------------------------------------
    @property
    def success(self) -> bool:
        """True when the fit converged and its residuals look like the noise."""
        ml = self.record["ml"]
        return bool(ml.get("converged", False) and (ml.get("quality") or {}).get("ok", False))

    @property
    def message(self) -> str:
        """The ML fit's outcome in words (Scheme 2: how many windows converged)."""
        ml = self.record["ml"]
        return str(ml.get("message") or f"{ml.get('windows_converged')} of {ml.get('windows')} windows converged")

    @property
    def scheme(self) -> int:
        """1 (Cd(M) over the whole flight) or 2 (a constant Cd per window)."""
        return int(self.record["scheme"])

    @property
    def drag_model(self) -> str:
        """The drag model's name (``spline``, ``poly2``, ...; Scheme 2: ``constant per window``)."""
        return str(self.record["drag_model"])

    @property
    def sampled(self) -> bool:
        """True when the fit sampled the posterior (``mcmc`` in ``result.json``)."""
        return "mcmc" in self.record

    @property
    def loaded(self) -> bool:
        """True for a result read back from a folder (:func:`load_result`)."""
        return self.folder is not None

    @property
    def ml(self) -> MLResult | None:
        """The Scheme 1 :class:`~bayesdrag.estimate.model.ml.MLResult` (None for Scheme 2 and for a
        result read from a folder)."""
        return None if self.scheme1 is None else self.scheme1.ml

    def band(self, level: float = 0.9, kind: str = "total") -> tuple[np.ndarray, np.ndarray]:
        """A central band of Cd on the grid ``cd.mach``.

        Parameters
        ----------
        level : float
            Its probability, strictly between 0 and 1.
        kind : {"total", "statistical", "posterior"}
            ``total``: ``ml ± z sd`` with ``sd`` each row's band sd (what the fit stands by);
            ``statistical``: ``ml ± z statistical_sd`` (the Cramér-Rao sd with every declared
            source held); ``posterior``: the quantiles of the posterior Cd draws (after sampling;
            Scheme 2: each window's quantiles of the draws ``posterior.nc`` holds, interpolated
            onto the grid as its Cd is).

        Returns
        -------
        lo, hi : (M,) ndarray
            Cd [-].

        Raises
        ------
        InputError
            An unknown kind or a level outside (0, 1).
        MissingDataError
            ``kind="posterior"`` for a fit that did not sample.
        """
        if kind not in BAND_KINDS:
            raise InputError(f"band kind {kind!r} is not known (allowed: {', '.join(BAND_KINDS)})")
        z = band_z(level)
        if kind == "posterior":
            return self._posterior_band(float(level))
        sd = self.cd.sd if kind == "total" else self.cd.statistical_sd
        return self.cd.ml - z * sd, self.cd.ml + z * sd

    def _posterior_band(self, level: float) -> tuple[np.ndarray, np.ndarray]:
        if not self.sampled:
            raise MissingDataError("band(kind='posterior') needs the posterior draws and this fit did not sample: "
                                   "fit with mcmc=True (the default), or ask for kind='total'")
        idata = self._posterior_idata()
        if idata is None:
            raise MissingDataError(f"band(kind='posterior'): no posterior.nc in {self.folder}")
        p = ((1.0 - level) / 2.0, (1.0 + level) / 2.0)
        cd = np.asarray(idata["posterior"]["cd"], dtype=np.float64)
        q = np.quantile(cd.reshape(-1, cd.shape[-1]), p, axis=0)
        if self.scheme == 1:
            return q[0], q[1]
        mach = np.asarray(idata["constant_data"]["mach"], dtype=np.float64)   # Scheme 2: per window, onto the grid
        order = np.argsort(mach)
        return (np.interp(self.cd.mach, mach[order], q[0][order]), np.interp(self.cd.mach, mach[order], q[1][order]))

    def summary(self) -> Summary:
        """A printable summary (``print(res.summary())``; HTML in a notebook): drag model,
        scheme, convergence, chi2 per channel, determined Mach range, whether the answer is
        clean, and Cd at a handful of Mach numbers of the determined range."""
        return fit_summary(self, SUMMARY_ROWS)

    def __repr__(self) -> str:
        return f"<FitResult: {fit_paragraph(self)}>"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, FitResult):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]   # a value holding mutable arrays

    def to_dict(self) -> dict[str, Any]:
        """The content of ``result.json``: plain JSON types, a fresh copy."""
        return json.loads(json.dumps(jsonable(self.record), allow_nan=False))

    # -- the posterior --------------------------------------------------------------------------
    def to_inference_data(self, *, log_likelihood_draws: int | None = LOG_LIKELIHOOD_DRAWS
                          ) -> arviz.InferenceData | None:
        """The posterior as ArviZ ``InferenceData`` (what ``posterior.nc`` holds); None without
        sampling.

        Scheme 1: ``posterior`` (``cd`` over a ``mach`` dim, the drag coefficients as one vector,
        noise and initial state by name), ``log_likelihood`` (one variable ``track`` over an
        ``observation`` dim: every sample of every channel, for ``arviz.loo`` and
        ``arviz.compare``), ``posterior_predictive``, ``sample_stats``, ``observed_data``,
        ``constant_data``. Scheme 2: ``cd`` per window (no ``log_likelihood``: its windows
        overlap).

        Parameters
        ----------
        log_likelihood_draws : int or None, keyword-only
            Posterior draws (over all chains, evenly thinned) of the ``log_likelihood`` group;
            None for every draw (memory: draws x observations x 4 bytes, ~200 MB on the demo
            track); 0 leaves the group out. ``posterior.nc`` keeps :data:`LOG_LIKELIHOOD_DRAWS`;
            its draws are a thinned subset, nearly independent: ``arviz.loo(idata, reff=1.0)``.
        """
        if log_likelihood_draws != 0 and self._unconverged():
            warnings.warn(f"the posterior's chain did not converge ({self.record['mcmc'].get('message')}): its "
                          f"log_likelihood group is left out, so that arviz.loo and arviz.compare cannot rank an "
                          f"unconverged posterior (sample longer: max_steps)", BayesdragWarning, stacklevel=2)
            log_likelihood_draws = 0
        key = ("idata", log_likelihood_draws)
        if key not in self._cache:
            if self.loaded:
                if ("idata", LOG_LIKELIHOOD_DRAWS) in self._cache:
                    raise MissingDataError(f"{self.folder}: posterior.nc holds the log-likelihood of "
                                           f"{LOG_LIKELIHOOD_DRAWS} draws; other draws need the fit itself")
                return None
            self._cache[key] = self._inference_data(log_likelihood_draws)
        return self._cache[key]

    def _posterior_idata(self) -> arviz.InferenceData | None:
        """The InferenceData to read posterior draws from: the one held (a loaded folder's, or one
        made already), else one made without the log-likelihood, which reading draws does not need."""
        for key, value in self._cache.items():
            if isinstance(key, tuple) and key[0] == "idata" and value is not None:
                return value
        return self.to_inference_data(log_likelihood_draws=0)

    def _unconverged(self) -> bool:
        """A Scheme 1 posterior whose chain did not converge (``mcmc.converged`` false)."""
        return self.scheme == 1 and (self.record.get("mcmc") or {}).get("converged") is False

    def _inference_data(self, log_likelihood_draws: int | None) -> arviz.InferenceData | None:
        arrays = self._posterior_arrays(log_likelihood_draws)
        if arrays is not None:
            from ..estimate.bayes.inference import as_inference_data

            return as_inference_data(arrays)
        if self.window_draws and self.track is not None:
            from ..estimate.bayes.inference import windows_inference_data

            chans = getattr(self.options, "channels", None) or self.track.names
            return windows_inference_data(self.record["windows"], self.windows_ok, self.window_draws, self.track,
                                          chans)
        return None

    def _posterior_arrays(self, log_likelihood_draws: int | None = LOG_LIKELIHOOD_DRAWS):
        """The arrays of the Scheme 1 posterior (:func:`~bayesdrag.estimate.bayes.posterior_groups.fit_arrays`,
        computed once: InferenceData and ``posterior.nc`` are made from them), or None (no
        sampled fit in this process)."""
        if self.posterior is None or self.scheme1 is None or self.log_posterior is None:
            return None
        if self._unconverged():
            log_likelihood_draws = 0      # posterior.nc of an unconverged chain: no log_likelihood to rank by
        key = ("arrays", log_likelihood_draws)
        if key not in self._cache:
            from ..estimate.bayes.posterior_groups import fit_arrays

            ref = self.round.reference_drag if self.round is not None else None
            self._cache[key] = fit_arrays(self.posterior, self.log_posterior, self.grid, self.cd_draws(), ref,
                                          seed=getattr(self.options, "seed", None),
                                          log_likelihood_draws=log_likelihood_draws)
        return self._cache[key]

    def cd_draws(self) -> np.ndarray:
        """Posterior Cd draws on the grid, (chains, draws, M), widened to the model-error floor
        and model-error term where ``result.json``'s rows are (Scheme 1 after sampling): the
        draws whose quantiles are the rows' ``q05``/``q95``."""
        if "cd_draws" not in self._cache:
            if self.posterior is None or self.scheme1 is None:
                idata = self._posterior_idata() if self.sampled and self.scheme == 1 else None
                if idata is None:
                    raise MissingDataError("cd_draws() needs the Scheme 1 posterior: fit with mcmc=True (the default)")
                self._cache["cd_draws"] = np.asarray(idata["posterior"]["cd"], dtype=np.float64)
            else:
                from ..estimate.bayes.draws import cd_draws, needs_widening, widen_to_floor

                f1 = self.scheme1
                cd = cd_draws(self.posterior, f1.drag_model, self.grid, f1.problem.P)
                if needs_widening(self.record.get("cd", [])):
                    cd = widen_to_floor(cd, [dict(r) for r in self.record["cd"]])   # as result.json's rows
                self._cache["cd_draws"] = cd
        return self._cache["cd_draws"]

    # -- figures (the report's, one at a time) ----------------------------------------------------
    def plot_cd(self, ax: Axes | None = None) -> Axes:
        """Cd(M) with its band and the reference (the report's ``cd.png``): the ML curve and its
        90 % band, after sampling the posterior's 50 % and 90 % bands; Scheme 2 its windows."""
        from ..report.fit import cd_figure

        return cd_figure(self, ax=ax)

    def plot_cd_relative(self, ax: Axes | None = None) -> Axes:
        """Cd in percent of the reference curve (``cd_relative.png``): after sampling the
        posterior bands (with a reference drag); after an ML fit its curve and band (relative to
        the curve itself without a reference), where a 0.1 % band is visible."""
        from ..report.fit import cd_relative_figure

        return cd_relative_figure(self, ax=ax)

    def plot_sd_ratio(self, ax: Axes | None = None) -> Axes:
        """Posterior sd over the Cramér-Rao sd against Mach (``cd_sd_ratio.png``; after sampling)."""
        from ..report.fit import sd_ratio_figure

        return sd_ratio_figure(self, ax=ax)

    def plot_budget(self, ax: Axes | None = None) -> Axes:
        """The Cd sd by source against Mach (``cd_budget.png``; Scheme 1)."""
        from ..report.fit import budget_figure

        return budget_figure(self, ax=ax)

    def plot_wind(self, ax: Axes | None = None) -> Axes:
        """The layers of wind the fit found and fitted, with +-1 sd, beside the met file's wind
        (``wind.png``; a fit that added a wind profile)."""
        from ..report.fit import wind_figure

        return wind_figure(self, ax=ax)

    def plot_residuals(self, fig: Figure | None = None) -> Figure:
        """Residuals with their noise band (``residuals.png``; after sampling also their
        autocorrelation). Needs the fit's objects (not a loaded result)."""
        from ..report.fit import residuals_figure

        return residuals_figure(self, fig=fig)

    def plot_corner(self, fig: Figure | None = None) -> Figure:
        """Corner plot of Cd at three Mach numbers and the initial state (``corner.png``; after
        sampling; needs the fit's objects)."""
        from ..report.fit import corner_figure

        return corner_figure(self, fig=fig)

    def plot_traces(self, fig: Figure | None = None) -> Figure:
        """Walkers against step with the burn-in marked (``traces.png``; after sampling; needs
        the fit's objects)."""
        from ..report.fit import traces_figure

        return traces_figure(self, fig=fig)

    def require(self, what: str, *names: str) -> None:
        """Raise :class:`~bayesdrag.errors.MissingDataError` when an attribute ``names`` is None:
        ``what`` needs the fit's objects, which a written folder does not hold."""
        missing = [n for n in names if getattr(self, n) is None]
        if missing:
            where = f"read from {self.folder}" if self.loaded else "without them"
            raise MissingDataError(f"{what} needs the fit's {', '.join(missing)}, and this result was {where} "
                                   f"(a folder holds result.json and posterior.nc only): run bayesdrag.fit to get them")

    # -- the output folder --------------------------------------------------------------------
    def write(self, directory: str | Path, *, sources: dict[str, Any] | None = None) -> list[Path]:
        """Write the folder the command line writes: ``result.json``, ``posterior.nc`` (after
        sampling), the figures and ``report.html`` (:func:`bayesdrag.report.fit.write_fit`); a
        finished chain ``chain.partial.h5`` in it becomes ``chain.h5``. The folder is written as
        one consistent set (:class:`~bayesdrag.io.outputs.OutputRun`): ``manifest.json`` lists
        the files, an earlier run's files are moved to ``superseded/``.

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
        from ..report.fit import write_fit

        return write_fit(self, directory, sources=sources)

    def write_into(self, run: OutputRun, *, sources: dict[str, Any] | None = None) -> None:
        """Write the outputs into an open :class:`~bayesdrag.io.outputs.OutputRun` (its staging
        folder) and hand it the finished chain; the run commits them."""
        self.write_files(run.staging, sources=sources)
        if self.posterior is not None:
            run.adopt(PARTIAL, CHAIN)

    def write_files(self, directory: str | Path, *, sources: dict[str, Any] | None = None) -> list[Path]:
        """Write ``result.json``, ``posterior.nc`` (after sampling), the figures and
        ``report.html`` into ``directory`` as plain files (no manifest, nothing moved).

        Returns
        -------
        list of Path
        """
        from ..report.fit import write_fit_files

        self.require("writing the report", "track", "round")
        return write_fit_files(self, directory, sources=sources)


def _scheme2_statistical_sd(record: dict[str, Any], windows_ok: tuple[int, ...]) -> np.ndarray | None:
    """Scheme 2's statistical sd on the grid: the converged windows' ``crb_sd_statistical``
    interpolated as their Cd is (None for Scheme 1, whose rows carry it)."""
    if record.get("scheme") != 2 or not windows_ok:
        return None
    w = [record["windows"][k] for k in windows_ok]
    mach = np.array([r["mach"] for r in w], float)
    stat = np.array([np.nan if r.get("crb_sd_statistical") is None else r["crb_sd_statistical"] for r in w], float)
    order = np.argsort(mach)
    return np.interp([r["mach"] for r in record["cd"]], mach[order], stat[order])


# -- the fit in words (from result.json's content, so a loaded result reads the same) ----------------
#: the central probability of the band the summary's table shows
SUMMARY_BAND = 0.9


def _fmt(v: float | None, spec: str = ".5f") -> str:
    return "—" if v is None or not np.isfinite(v) else format(float(v), spec)


def _determined(res: FitResult) -> str:
    det = res.cd.determined_range
    return determined_words(det, ((res.record.get("ml") or {}).get("quality") or {}).get("undetermined") or ())


def _warning_count(res: FitResult) -> str:
    """``"2 warnings"``, with the technical ones (quiet kinds) counted apart."""
    shown = sum(w.shown for w in res.warnings)
    quiet = len(res.warnings) - shown
    return (f"{shown} warning{'s' if shown != 1 else ''}"
            + (f" (+{quiet} technical, in .warnings)" if quiet else ""))


def _clean(rec: dict[str, Any]) -> tuple[bool, int]:
    q = rec["ml"].get("quality") or {}
    return bool(q.get("ok", False)), len(q.get("problems") or [])


def _posterior_line(rec: dict[str, Any]) -> str:
    m = rec.get("mcmc")
    if not m:
        return "not sampled (maximum likelihood only)"
    if rec.get("scheme") == 2:
        return f"{m.get('windows_converged')} window(s) converged, max r_hat {_fmt(m.get('r_hat_max'), '.3f')}"
    state = "converged" if m.get("converged") else "NOT converged"
    return (f"{state}: {m.get('walkers')} walkers x {m.get('steps')} steps, {m.get('draws')} draws kept "
            f"(tau max {_fmt(m.get('tau_max'), '.1f')} steps)")


def fit_paragraph(res: FitResult) -> str:
    """One short paragraph: scheme, drag model, convergence, determined range, cleanliness, the
    posterior, warnings (what ``repr`` shows; no arrays)."""
    rec = res.record
    ok, n_prob = _clean(rec)
    lo, hi = float(res.cd.mach[0]), float(res.cd.mach[-1])
    parts = [f"Scheme {res.scheme}, {res.drag_model} drag", f"ML {res.message}",
             f"Cd over Mach {lo:.2f}-{hi:.2f} ({len(res.cd)} rows), determined {_determined(res)}",
             "clean" if ok else f"NOT clean ({n_prob} quality problem{'s' if n_prob != 1 else ''})",
             f"posterior {_posterior_line(rec)}" if res.sampled else "not sampled",
             _warning_count(res)]
    if res.loaded:
        parts.append(f"read from {res.folder}")
    else:
        parts.append(f"{res.seconds:.1f} s")
    return "; ".join(parts) + ". See .summary(), .cd, .band(), .plot_cd(), .to_dict()"


def fit_summary(res: FitResult, rows: int) -> Summary:
    """The summary of a fit: a header block and Cd at ``rows`` Mach numbers of the determined
    range (the whole range when nothing is determined)."""
    rec = res.record
    ml = rec["ml"]
    ok, n_prob = _clean(rec)
    q = ml.get("quality") or {}
    chi2 = ", ".join(f"{c} {v['chi2_per_sample']:.3g}" for c, v in (q.get("channels") or {}).items()
                     if v.get("chi2_per_sample") is not None)
    if res.scheme == 2:
        conv = f"{ml.get('windows_converged')} of {ml.get('windows')} windows converged"
    else:
        conv = f"{'yes' if ml.get('converged') else 'NO'} in {ml.get('iterations')} iterations ({ml.get('message')})"
    data = ml.get("mach_range_data") or [float(res.cd.mach[0]), float(res.cd.mach[-1])]
    header = [("drag model", res.drag_model), ("scheme", str(res.scheme)), ("ML converged", conv)]
    if chi2:
        header.append(("chi2 per sample", chi2))
    header += [("Mach range of the data", f"{data[0]:.3f} - {data[1]:.3f}"),
               ("Cd determined", _determined(res)),
               ("clean answer", "yes" if ok else f"NO: {n_prob} quality problem(s), see the warnings"),
               ("posterior", _posterior_line(rec)), ("warnings", _warning_count(res))]
    lo, hi = res.band(SUMMARY_BAND)
    cols = ["Mach", "Cd (ML)", "band sd", f"{SUMMARY_BAND:.0%} band", "determined", "reference"]
    post = res.cd.sampled
    if post:
        cols += ["post. mean", "q05", "q95"]
    table = []
    c = res.cd
    for i in c.rows_at(rows):
        row = [f"{c.mach[i]:.3f}", _fmt(c.ml[i]), _fmt(c.sd[i], ".2e"), f"{_fmt(lo[i])} - {_fmt(hi[i])}",
               "yes" if c.determined[i] else "no", _fmt(c.reference[i])]
        if post:
            assert c.mean is not None and c.q05 is not None and c.q95 is not None
            row += [_fmt(c.mean[i]), _fmt(c.q05[i]), _fmt(c.q95[i])]
        table.append(tuple(row))
    notes: tuple[str, ...] = (f"{SUMMARY_BAND:.0%} band: Cd (ML) ± {band_z(SUMMARY_BAND):.3f} x the row's total band "
                              f"sd; all {len(c)} rows in res.cd (res.cd.to_dataframe()).",)
    found = effect_lines(ml.get("with_effects"))
    if found:      # what the fit added beside Cd is part of the answer: said above the table
        header.append(("effects fitted", found[0].split(": ", 1)[1] if len(found) == 1 else "below the table"))
        notes = ("\n".join(found),) + tuple(notes)
    return Summary(title=f"bayesdrag fit: Scheme {res.scheme}, {res.drag_model} drag", header=tuple(header),
                   columns=tuple(cols), rows=tuple(table), notes=notes)


def load_result(directory: str | Path) -> FitResult:
    """The :class:`FitResult` of a folder ``bayesdrag fit`` (or ``res.write``) wrote.

    Parameters
    ----------
    directory : path
        Holds ``result.json`` and, after sampling, ``posterior.nc``.

    Returns
    -------
    FitResult
        Equal to the result that wrote the folder (the same ``to_dict()`` and Cd table); it
        holds what the files hold (no track, round or fit objects).

    Raises
    ------
    InputError
        No ``result.json`` in the folder, or not a valid one (:func:`~.document.read_document`:
        every key the result reads of its type, every number finite); a ``posterior.nc`` that
        is a link or not a regular file, not HDF5, stored partly outside itself, or declaring
        more values than ``result.json``'s sampler made (:func:`_posterior_limits`), checked
        before any of its values is read (:func:`bayesdrag.io.netcdf.read_inference_data`).
    """
    folder = Path(directory)
    record = read_document(folder, "result.json", "fit result", required=("scheme", "drag_model", "ml", "cd"),
                           schema=RESULT_SCHEMA)
    idata = None
    nc = folder / "posterior.nc"
    if os.path.lexists(nc):      # a link too: refused by the reader, never followed
        from ..io.netcdf import read_inference_data

        idata = read_inference_data(nc, _posterior_limits(record, folder))
    return FitResult(record, inference_data=idata, folder=folder, warnings=_recorded_warnings(record))


def _posterior_limits(record: dict[str, Any], folder: Path) -> Hdf5Limits:
    """What ``posterior.nc`` may declare, from ``result.json``'s (checked) record.

    The values a posterior file holds: every kept draw of Cd on the M Mach rows and of the Q
    parameters (W walkers x at most S steps), the predictive tracks and log-likelihood of a
    few draws over the O observations, and constants; counted as float64 with a margin of
    :data:`POSTERIOR_MARGIN`, and at most :data:`MAX_POSTERIOR_BYTES` whatever the record says.
    Every dimension is at most the largest of W, S, M, Q and O.

    Raises
    ------
    InputError
        The record says the fit did not sample, or does not record its sampler's size.
    """
    doc, nc = folder / "result.json", folder / "posterior.nc"
    mc = record.get("mcmc")
    if not mc:
        raise InputError(f"{nc}: result.json records no sampling ('mcmc' missing), so the folder holds no posterior; "
                         f"{POSTERIOR_FIX}")
    ml, m_rows = record["ml"], len(record["cd"])
    if record["scheme"] == 1:
        missing = [k for k in ("walkers", "steps") if mc.get(k) is None]
        if missing:
            raise InputError(f"{doc}: mcmc.{missing[0]} is missing: it bounds posterior.nc; {REWRITE}")
        w, s = mc["walkers"], mc["steps"]
        q = len(ml.get("params") or {}) + len(ml.get("fixed") or []) + EXTRA_PARAMETERS
        o = _observations([ml.get("quality")])
        # an unconverged posterior is written without its log-likelihood draws
        ll_draws = LOG_LIKELIHOOD_DRAWS if mc.get("converged") is not False else 0
        values = (w * s * (m_rows + q + 1) + (w * PREDICTIVE_DRAWS + max(ll_draws, w)) * (m_rows + o)
                  + CONSTANT_COPIES * (m_rows + q + o) + w + s)
    else:
        windows = record.get("windows") or []
        w, s, q = SCHEME2_MAX_CHAINS, max([r.get("steps") or 0 for r in windows], default=0), 1
        m_rows += len(windows)
        o = _observations([r.get("quality") for r in windows])
        values = w * s * m_rows + CONSTANT_COPIES * (m_rows + o) + w + s
    max_bytes = min(MAX_POSTERIOR_BYTES, POSTERIOR_MARGIN * POSTERIOR_VALUE_BYTES * values)
    why = (f"that result.json's sampler allows ({w} walkers x {s} steps, {m_rows} Mach rows, {q} parameters, {o} "
           f"observations; at most {MAX_POSTERIOR_BYTES} bytes)")
    return Hdf5Limits(max_bytes=max_bytes, max_length=max(w, s, m_rows, q, o), why=why, fix=POSTERIOR_FIX,
                      what="posterior file")


def _observations(qualities: list[Any]) -> int:
    """Samples over all channels that the ``quality`` records give (``channels.<c>.n``), or
    :data:`~bayesdrag.track.MAX_FIT_SAMPLES` per channel for :data:`UNRECORDED_CHANNELS` when
    none is recorded."""
    counts = [c.get("n") for q in qualities for c in ((q or {}).get("channels") or {}).values()]
    counts = [n for n in counts if n is not None]
    return sum(counts) if counts else MAX_FIT_SAMPLES * UNRECORDED_CHANNELS


def _recorded_warnings(record: dict[str, Any]) -> tuple[FitWarning, ...]:
    """The warnings ``result.json`` records: the quality gate's problems, the ML fit's notes and
    the sampler's message when it did not converge."""
    ml = record.get("ml", {})
    out = list((ml.get("quality") or {}).get("problems") or [])
    out += [w for w in ml.get("warnings") or [] if w not in out]
    mc = record.get("mcmc") or {}
    if mc and mc.get("converged") is False and mc.get("message"):
        out.append(str(mc["message"]))
    return tuple(as_warning(w) for w in out)
