"""The diagnosis as a command: :func:`diagnose` (Python API, ``bayesdrag.diagnose``) and
``bayesdrag diagnose TRACK ROUND -o DIR`` (:func:`run_diagnose`)."""
from __future__ import annotations

import sys
from pathlib import Path

from ..diagnosis import MIN_DIAGNOSIS_SAMPLES
from ..diagnosis import diagnose as _analyse
from ..errors import InputError
from ..results import DiagnosisResult
from .options import DiagnoseOptions

__all__ = ["diagnose", "run_diagnose"]


def diagnose(track, rnd, options=None, **kwargs):
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
        ``verdict``, ``paragraph``, ``to_dict()`` (``diagnosis.json``), ``write(DIR)``.
    """
    opts = options if options is not None else DiagnoseOptions()
    if kwargs:
        opts = DiagnoseOptions(**{**opts.__dict__, **kwargs})
    if track.n < MIN_DIAGNOSIS_SAMPLES:
        raise InputError(f"{track.source or 'track'}: {track.n} samples are too few for a diagnosis "
                         f"(need >= {MIN_DIAGNOSIS_SAMPLES})")
    d = _analyse(track, rnd, channels=opts.channels, alpha=opts.alpha, material_cd_shift=opts.material_cd_shift,
                 material_end_sd=opts.material_end_sd)
    return DiagnosisResult(d, track, rnd)


def run_diagnose(track_path, round_path, out, *, quiet=False, echo=print):
    """Read a track and a round, diagnose them, write ``DIR/diagnosis.json``, the figures and
    ``diagnosis.html``.

    Returns
    -------
    DiagnosisResult
    """
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
    result = diagnose(track, rnd)
    result.write(out, sources={"track": track_path, "round": round_path})
    if not quiet:
        print(f"bayesdrag: diagnosis: {result.paragraph}", file=sys.stderr)
    echo(f"diagnose: verdict {result.verdict or 'none'}; wrote {out / 'diagnosis.json'}, diagnosis.html, "
         f"diagnosis_*.png")
    return result
