"""The diagnosis as a command: ``bayesdrag diagnose TRACK ROUND -o DIR`` (:func:`run_diagnose`)."""
from __future__ import annotations

import sys
from pathlib import Path

from ..errors import InputError

__all__ = ["run_diagnose"]


def run_diagnose(track_path, round_path, out, *, quiet=False, echo=print):
    """Read a track and a round, diagnose the gap between them and the nominal simulation, write
    ``DIR/diagnosis.json``, the figures and ``diagnosis.html``.

    Returns
    -------
    Diagnosis
    """
    from ..diagnose import MIN_DIAGNOSIS_SAMPLES, diagnose
    from ..diagnose_report import write_diagnosis
    from ..io.rounds import read_round
    from ..io.tracks import read_track

    track = read_track(track_path)
    rnd = read_round(round_path)
    if not quiet:
        for note in track.notes:
            print(f"bayesdrag: note: {note}", file=sys.stderr)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: output path exists and is not a folder")
    if track.n < MIN_DIAGNOSIS_SAMPLES:
        raise InputError(f"{track_path}: {track.n} samples are too few for a diagnosis "
                         f"(need >= {MIN_DIAGNOSIS_SAMPLES})")
    d = diagnose(track, rnd)
    paragraph = write_diagnosis(out, d, track_name=str(track_path), round_name=str(round_path))
    if not quiet:
        print(f"bayesdrag: diagnosis: {paragraph}", file=sys.stderr)
    echo(f"diagnose: verdict {d.summary['verdict'] or 'none'}; wrote {out / 'diagnosis.json'}, diagnosis.html, "
         f"diagnosis_*.png")
    return d
