"""The diagnosis as a command: :func:`diagnose` (Python API, ``bayesdrag.diagnose``) and
``bayesdrag diagnose TRACK ROUND -o DIR`` (:func:`run_diagnose`)."""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from ..diagnosis import MIN_DIAGNOSIS_SAMPLES
from ..diagnosis import diagnose as _analyse
from ..diagnosis.summary import summary_paragraph
from ..errors import InputError
from ..results import DiagnosisResult
from ..round import Round
from ..track import RadarTrack, thin_for_fit
from .options import DiagnoseOptions

__all__ = ["diagnose", "run_diagnose"]


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
    opts = options if options is not None else DiagnoseOptions()
    track = thin_for_fit(track)           # a very dense track: every k-th sample, with a note
    if kwargs:
        opts = DiagnoseOptions(**{**opts.__dict__, **kwargs})
    if track.n < MIN_DIAGNOSIS_SAMPLES:
        raise InputError(f"{track.source or 'track'}: {track.n} samples are too few for a diagnosis "
                         f"(need >= {MIN_DIAGNOSIS_SAMPLES})")
    from ..estimate.start import check_heights

    check_heights(track, rnd)
    d = _analyse(track, rnd, channels=opts.channels, alpha=opts.alpha, material_cd_shift=opts.material_cd_shift,
                 material_end_sd=opts.material_end_sd)
    record = dict(d.summary, summary=summary_paragraph(d.summary))     # what diagnosis.json holds
    return DiagnosisResult(record, d, track, rnd)


def run_diagnose(track_path, round_path, out, options=None, *, quiet=False, echo=print, also=None, columns=None):
    """Read a track and a round, diagnose them, write ``DIR/diagnosis.json``, the figures and
    ``diagnosis.html`` as one consistent set (``manifest.json``; an earlier diagnosis's files
    moved to ``DIR/superseded/``; the folder checked and locked before the work).

    ``also(result, folder)``, when given, writes further outputs of the run into ``folder``
    before it is committed (the batch's done marker). ``columns`` maps the track's header
    (``--columns``; :func:`bayesdrag.io.tracks.read_track`).

    Returns
    -------
    DiagnosisResult
    """
    from ..io.rounds import read_round
    from ..io.tracks import read_track
    from .runs import output_run

    track = thin_for_fit(read_track(track_path, columns=columns))
    rnd = read_round(round_path)
    if not quiet:
        for note in track.notes:
            print(f"bayesdrag: note: {note}", file=sys.stderr)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: output path exists and is not a folder")
    with output_run(out, "diagnose", track_path, round_path, rnd) as run:
        result = diagnose(track, rnd, options)
        result.write_files(run.staging, sources={"track": track_path, "round": round_path})
        if also is not None:
            also(result, run.staging)
    if not quiet:
        from ..diagnosis.summary import console_summary

        # from the file's content alone (every figure printed is one of diagnosis.json's)
        for line in console_summary(result.to_dict()):
            print(f"bayesdrag: diagnosis: {line}", file=sys.stderr)
    met = [n for n in ("diagnosis_met.csv", "diagnosis_wind_downrange.csv") if (out / n).is_file()]
    echo(f"diagnose: verdict {result.verdict or 'none'}; wrote {out / 'diagnosis.json'}, diagnosis.html, "
         f"diagnosis_*.png{''.join(', ' + n for n in met)}, manifest.json")
    return result
