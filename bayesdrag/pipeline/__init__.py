"""The four API verbs: what ``bayesdrag.fit``, ``bayesdrag.diagnose``, ``bayesdrag.plan`` and
``bayesdrag.simulate`` compute, values in, a frozen result out (:class:`~bayesdrag.results.FitResult`,
:class:`~bayesdrag.results.DiagnosisResult`, :class:`~bayesdrag.results.PlanResult`, a
:class:`~bayesdrag.track.RadarTrack`; ``plan`` and ``simulate`` are :mod:`.plans` and :mod:`.simulation`).

No file is read or written here (except the sampler's chain file when the caller names one) and
nothing is printed: the commands (:mod:`bayesdrag.commands`) read the files, call these functions
and write the output folder.

A Scheme 1 fit is six named stages, one module each, run in this order by :func:`scheme1_fit`:

1. :mod:`.preparation` -- the values checked once (channels, dense tracks, a chronograph's site);
2. :mod:`.ml` -- the maximum-likelihood fit and its :class:`~.ml.Answer` (rows, budget);
3. :mod:`.check` -- the model check (:mod:`.model_check`), which may replace the answer with
   its fit carrying the effects it finds; its diagnosis runs in a forked process beside stage 2;
4. :mod:`.sampling` -- the posterior (with ``mcmc``);
5. :mod:`.claim` -- each row's band and whether it is claimed;
6. :mod:`.result` -- the frozen result and the outcome line.

Scheme 2 (a constant Cd per window) is :mod:`.scheme2`.
"""
from __future__ import annotations

import contextlib
import time
import warnings as py_warnings
from typing import Any, Callable

from .._runtime.renamed import renamed_getattr
from .._runtime.threads import single_blas
from ..errors import BayesdragWarning, InputError
from ..options import DiagnoseOptions, FitOptions
from ..results import DiagnosisResult, FitResult
from ..round import Round
from ..track import RadarTrack, thin_for_fit
from .check import EFFECT_RESIDUAL_SHARE, check_stage, diagnosis_beside, residual_share
from .claim import claim_stage
from .ml import ml_stage
from ..results.words import why_not_clean
from .plans import plan
from .preparation import Prepared, prepare, watched
from .result import result_stage, outcome_line
from .sampling import sample_stage
from .scheme2 import scheme2_fit
from .simulation import simulate

__all__ = ["fit", "diagnose", "plan", "simulate", "outcome_line", "scheme1_fit", "scheme2_fit", "watched", "why_not_clean", "EFFECT_RESIDUAL_SHARE",
           "residual_share"]


def fit(track: RadarTrack, rnd: Round, options: FitOptions | None = None, *, chain_path: Any = None,
        resume: bool = False, log: Callable[[str], None] | None = None, progress: bool | None = None,
        ml_progress: Callable[[str], None] | None = None, **kwargs: Any) -> FitResult:
    """Estimate Cd(M) from a track.

    Parameters
    ----------
    track : RadarTrack
    rnd : Round
    options : FitOptions, optional
        Everything that changes the result (default :class:`FitOptions`); keyword arguments
        (``mcmc=False``, ``drag="poly2"``, ...) override single fields.
    chain_path : path, optional
        Scheme 1 with sampling: write the emcee chain to this HDF5 file as it runs (a killed run
        can then be resumed).
    resume : bool
        Continue the unfinished chain in ``chain_path``.
    log : callable, optional
        ``log(str)`` receives status lines of long work (the sampler's progress).
    progress : bool or None
        Show a progress bar (tqdm: a widget in a notebook, a line on stderr in a terminal) while
        sampling. None (default): when someone is watching, i.e. stderr is a terminal or the code
        runs in a Jupyter kernel; ``False`` never.
    ml_progress : callable, optional
        ``ml_progress(step)`` receives the step the maximum-likelihood fit is at
        (:class:`~bayesdrag.commands.runs.StageProgress` prints it when the fit is slow); its
        ``done()`` is called at the end when it has one.

    Returns
    -------
    FitResult
        Frozen; ``to_dict()`` is the content of ``result.json``.

    Warns
    -----
    BayesdragWarning
        Each of the result's ``warnings`` worth reading (misfits, undetermined ranges, sampler
        problems; not the strong correlations and single coefficients' sds, which stay in
        ``warnings``), after the fit; filter the category to silence them.

    Raises
    ------
    InputError
        Options or inputs that do not fit together (a channel the track lacks).
    FitError
        No solution: the message says why.
    """
    with single_blas():   # the kernel's threads use the cores, not BLAS's
        t_start = time.perf_counter()
        progress = watched() if progress is None else bool(progress)
        prep = prepare(track, rnd, options, **kwargs)
        if prep.opts.scheme == 2:
            return _emitted(scheme2_fit(prep, log, t_start))
        return _emitted(scheme1_fit(prep, chain_path, resume, log, progress, t_start, ml_progress))


def _emitted(result):
    """``result``, each of its warnings worth reading (``shown``: not one of
    :data:`~bayesdrag.errors.QUIET_KINDS`) emitted through :mod:`warnings` as a
    :class:`~bayesdrag.errors.BayesdragWarning` (attributed to the caller of :func:`fit`)."""
    for w in result.warnings:
        if w.shown:
            py_warnings.warn(w.message, BayesdragWarning, stacklevel=3)
    return result


def scheme1_fit(prep: Prepared, chain_path, resume, log, progress, t_start, ml_progress=None):
    """A Scheme 1 fit of prepared values, stage by stage (the module's docstring names them)."""
    opts = prep.opts
    check = opts.model_check and opts.with_effects != "auto"
    with diagnosis_beside(prep, fork=check) as diag, contextlib.ExitStack() as later:
        diag = diag if check else None
        timing = {"beside": []}
        ans, with_note = ml_stage(prep, log, ml_progress)
        timing["ml"] = round(time.perf_counter() - t_start, 3)
        chk = check_stage(prep, ans, diag, timing, ml_progress, with_note, later)
        bayes, post, chk = sample_stage(prep, chk, chain_path, resume, log, progress, diag, timing, ml_progress)
        quality, placement = claim_stage(prep, chk, ml_progress)
        return result_stage(prep, chk, quality, placement, bayes, post, timing, t_start)


def diagnose(track: RadarTrack, rnd: Round, options: DiagnoseOptions | None = None, **kwargs: Any) -> DiagnosisResult:
    """Diagnose the gap between a track and the nominal simulation of its round: where the
    simulation misses, which unmodelled effect explains it, how large it is and whether it
    matters (material).

    Parameters
    ----------
    track : RadarTrack
    rnd : Round
    options : DiagnoseOptions, optional
        Keyword arguments (``channels=("x", "z", "v")``, ``material_cd_shift=0.002``) override
        single fields.

    Returns
    -------
    DiagnosisResult
        ``verdict``, ``paragraph``, ``summary()``, ``to_dataframe()`` (the candidate effects),
        ``to_dict()`` (``diagnosis.json``), ``write(DIR)``.
    """
    from ..diagnosis import MIN_DIAGNOSIS_SAMPLES
    from ..diagnosis import diagnose as analyse
    from ..results.words import diagnosis_paragraph
    from ..estimate.build.model_size import check_constant_channels
    from ..estimate.build.start import check_heights

    opts = options if options is not None else DiagnoseOptions()
    track = thin_for_fit(track)           # a very dense track: every k-th sample, with a note
    if kwargs:
        opts = DiagnoseOptions(**{**opts.__dict__, **kwargs})
    if track.n < MIN_DIAGNOSIS_SAMPLES:
        raise InputError(f"{track.source or 'track'}: {track.n} samples are too few for a diagnosis "
                         f"(need >= {MIN_DIAGNOSIS_SAMPLES})")
    check_heights(track, rnd)
    check_constant_channels(track, tuple(opts.channels) if opts.channels else track.names)
    d = analyse(track, rnd, channels=opts.channels, alpha=opts.alpha, material_cd_shift=opts.material_cd_shift,
                material_end_sd=opts.material_end_sd)
    record = dict(d.record, summary=diagnosis_paragraph(d.record))     # what diagnosis.json holds
    return DiagnosisResult(record, d, track, rnd)

#: old names, kept with a warning until release 0.3
__getattr__ = renamed_getattr(__name__, {"summary_line": "outcome_line"}, globals())
