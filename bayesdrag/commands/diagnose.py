"""The ``bayesdrag diagnose TRACK ROUND -o DIR`` command (:func:`run_diagnose`) around
:func:`bayesdrag.pipeline.diagnose` (the Python API ``bayesdrag.diagnose``)."""
from __future__ import annotations

import sys
from pathlib import Path

from ..errors import InputError
from ..pipeline import diagnose
from ..track import thin_for_fit

__all__ = ["run_diagnose"]


def run_diagnose(track_path, round_path, out, options=None, *, quiet=False, echo=print, also=None, columns=None,
                 track_format="auto"):
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

    track = thin_for_fit(read_track(track_path, columns=columns, format=track_format))
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
        from ..results.words import diagnosis_lines

        # from the file's content alone (every figure printed is one of diagnosis.json's)
        for line in diagnosis_lines(result.to_dict()):
            print(f"bayesdrag: diagnosis: {line}", file=sys.stderr)
    met = [n for n in ("diagnosis_met.csv", "diagnosis_wind_downrange.csv") if (out / n).is_file()]
    echo(f"diagnose: verdict {result.verdict or 'none'}; wrote {out / 'diagnosis.json'}, diagnosis.html, "
         f"diagnosis_*.png{''.join(', ' + n for n in met)}, manifest.json")
    return result
