"""The ``bayesdrag fit`` command (:func:`run_fit`): read the track and the round, call
:func:`bayesdrag.pipeline.fit` (the Python API ``bayesdrag.fit``), write the output folder and
print the outcome."""
from __future__ import annotations

import sys
import warnings
from pathlib import Path

from ..errors import BayesdragWarning, InputError
from ..options import FitOptions
from ..pipeline import fit, outcome_line
from ..results import PARTIAL
from ..results.words import effect_lines
from ..track import thin_for_fit

__all__ = ["run_fit"]

#: a track of at least this many samples gets a status line before its fit starts (the ML fit
#: alone then takes seconds to a minute)
PROGRESS_SAMPLES = 3000


def _echo_err(msg):
    print(msg, file=sys.stderr, flush=True)


def run_fit(track_path, round_path, out, options=None, *, resume=False, quiet=False, echo=print, run=None,
            also=None, verbosity=None, columns=None, track_format="auto", verbose=False):
    """The ``bayesdrag fit TRACK ROUND -o DIR`` command: read, fit, write ``DIR``.

    Outputs: ``result.json``, ``report.html`` and figures; with sampling also
    ``posterior.nc`` (ArviZ) and ``chain.h5`` (the emcee chain); ``manifest.json``. ``DIR`` is
    written as one consistent set (:class:`~bayesdrag.io.outputs.OutputRun`): checked and locked
    before the fit starts, the outputs staged and moved in at the end, an earlier run's files
    moved to ``DIR/superseded/``. While sampling, the chain is written to
    ``chain.partial.h5``; ``resume`` continues it after a kill, and it becomes ``chain.h5`` when
    the run finishes. A fresh run refuses to start over an unfinished chain (it would destroy
    it): resume it or delete it.

    Parameters
    ----------
    quiet : bool
        Nothing on stderr (the batch collects warnings itself); ``echo`` still receives the
        outcome line.
    verbosity : int, optional
        Overrides ``quiet``: 0 notes, progress and warnings on stderr; 1 (``-q``) warnings only;
        2 (``-qq``) nothing. The command line passes ``echo`` a no-op from 1 on.
    verbose : bool
        Also print the technical warnings (:data:`~bayesdrag.errors.QUIET_KINDS`: strong
        correlations, single coefficients' sds), which otherwise only ``result.json`` holds.
    columns : dict, optional
        ``{channel: header name}`` of the track file (``--columns``;
        :func:`bayesdrag.io.tracks.read_track`).
    track_format : str
        The track file's format (``--format``: ``"auto"`` sniffs it; :mod:`bayesdrag.io.formats`).
    run : OutputRun, optional
        An open run to write into (the demo's), instead of one of its own.
    also : callable, optional
        ``also(result, folder)`` writes further outputs of the run into ``folder`` (the batch's
        ``pooling.json``) before it is committed.

    Returns
    -------
    FitResult
    """
    from ..io.rounds import read_round
    from ..io.tracks import read_track
    from .runs import StageProgress, output_run, throttled

    level = (2 if quiet else 0) if verbosity is None else int(verbosity)
    talk, warn = level == 0, level <= 1
    opts = options if options is not None else FitOptions()
    track = thin_for_fit(read_track(track_path, columns=columns, format=track_format))
    rnd = read_round(round_path)
    if talk:
        for note in track.notes:
            _echo_err(f"bayesdrag: note: {note}")
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: output path exists and is not a folder")
    with output_run(out, "fit", track_path, round_path, rnd, opts, run=run) as run:
        partial = out / PARTIAL
        sampling = opts.mcmc and opts.scheme == 1
        if sampling and partial.exists() and not resume:
            raise InputError(f"{partial}: an unfinished chain from an earlier run is there; resume it (fit --resume) "
                             f"or delete the file to start afresh")
        if resume and sampling and not partial.exists() and talk:
            _echo_err(f"bayesdrag: note: --resume: no unfinished chain in {out}; starting afresh")
        show_bar = talk and sys.stderr.isatty()
        log = None if (not talk or show_bar) else throttled(_echo_err)
        if talk and track.n >= PROGRESS_SAMPLES:   # long work: say what is happening
            _echo_err(f"bayesdrag: fitting {track.n} samples: maximum likelihood"
                      + (", then the posterior (progress below)" if sampling else "") + " ...")
        chain = None
        if sampling:          # emcee and h5py: imported only by a fit that samples
            from ..io.chain import ChainFile

            chain = ChainFile(partial, inputs=run.inputs_digest, max_steps=opts.max_steps)
        ml_progress = StageProgress(_echo_err) if talk else None
        with warnings.catch_warnings():    # the command prints them itself, below, once
            warnings.simplefilter("ignore", BayesdragWarning)
            result = fit(track, rnd, opts, chain_path=chain, resume=resume, log=log, progress=show_bar,
                         ml_progress=ml_progress)
        result.write_into(run, sources={"track": str(track_path), "round": str(round_path)})
        if also is not None:
            also(result, run.staging)
    if warn:
        for w in result.warnings:
            if w.shown or verbose:
                _echo_err(f"bayesdrag: warning: {w}")
    quiet_ones = [w for w in result.warnings if not w.shown]
    if talk and quiet_ones and not verbose:
        _echo_err(f"bayesdrag: note: {len(quiet_ones)} technical warning{'s' if len(quiet_ones) != 1 else ''} "
                  f"({', '.join(sorted({w.kind for w in quiet_ones}))}: nothing to act on) in result.json; "
                  f"--verbose prints {'them' if len(quiet_ones) != 1 else 'it'}")
    if talk:
        for note in ((result.record.get("ml") or {}).get("quality") or {}).get("notes") or ():
            _echo_err(f"bayesdrag: note: {note}")
    echo(outcome_line(result))
    for line in effect_lines((result.record.get("ml") or {}).get("with_effects")):
        echo(line)            # what the fit added beside Cd is part of the answer
    if result.posterior is not None:
        b = result.posterior
        echo(f"mcmc: {b.message}; {b.steps} steps x {b.nwalkers} walkers in {b.elapsed:.1f} s")
    if run.manifest is not None:
        names = [f["name"] for f in run.manifest["files"] if f["name"] != "result.json"]
        echo(f"  wrote {out / 'result.json'}, " + ", ".join(names) + ", manifest.json")
    return result
