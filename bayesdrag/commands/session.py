"""``bayesdrag fit SERIES ROUND -o DIR`` for a chronograph session (:func:`run_session`): read the
shots and the round, fit them as one session, write ``DIR/campaign.json``, ``DIR/campaign.html``,
``DIR/session_cd.png`` and each shot's part of the fit in ``DIR/<shot>/``, print the outcome."""
from __future__ import annotations

import sys
from pathlib import Path

from .._runtime.renamed import renamed_getattr
from ..errors import InputError
from ..io.outputs import OutputRun
from .runs import round_files

__all__ = ["run_session", "session_lines"]


def _err(msg):
    print(msg, file=sys.stderr, flush=True)


def session_lines(record):
    """The console's lines for a session: its central row, form factors, muzzle speeds."""
    c, ff, bc, mv = record["central"], record["form_factor"], record["bc"], record["muzzle_velocity"]
    state = "determined" if c["determined"] else ("claimed, not determined" if c["claimed"] else "not determined")
    if c["mean"] <= 0 or ff["G7"]["value"] is None:
        return [f"session {record['name']}: {len(record['rounds'])} shots: no physical Cd (the shots do not determine "
                f"their deceleration; see campaign.json warnings)"]
    lines = [f"session {record['name']}: {len(record['rounds'])} shots, Cd {c['mean']:.4f} ± {c['sd']:.2g} "
             f"({100 * c['rel_sd']:.2g} %, {state}) at Mach {c['mach']:.3f}; "
             f"{record['determined']['rows']} of {record['determined']['of']} rows determined",
             f"  form factor G7 {ff['G7']['value']:.4f} ± {ff['G7']['sd']:.2g} (BC {bc['G7']['value']:.4g} lb/in^2), "
             f"G1 {ff['G1']['value']:.4f} ± {ff['G1']['sd']:.2g} (BC {bc['G1']['value']:.4g} lb/in^2)",
             f"  muzzle speed {mv['mean']:.1f} m/s, sd {mv['sd']:.2f}, extreme spread {mv['extreme_spread']:.1f}; "
             f"drag scatter between shots {100 * record['scatter']['mean']:.2g} %"]
    return lines


def run_session(tracks, round_path, out, *, verbosity=0, echo=print, figures=True):
    """Fit a chronograph session and write its folder.

    Parameters
    ----------
    tracks : list of path
        A LabRadar series folder, or shot files.
    round_path : path
        The round (one for all shots).
    out : path
        The output folder.
    verbosity : int
        0 notes and warnings on stderr; 1 warnings only; 2 nothing.
    figures : bool
        Write each shot's residual figure.

    Returns
    -------
    int
        0.
    """
    from ..campaign.session.run import fit_chronograph_session
    from ..io.rounds import read_round
    from ..io.sessions import read_session
    from ..report.session import write_drag_tables, write_session_report, write_shot

    talk, warn = verbosity == 0, verbosity <= 1
    files = read_session(tracks)
    rnd = read_round(round_path)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: output path exists and is not a folder")
    if talk:
        for n in files.notes:
            _err(f"bayesdrag: note: {n}")
    if warn:        # a shot left out is a warning: -q still says it
        for s in files.shots:
            if s.skipped:
                _err(f"bayesdrag: warning: shot {s.name} skipped: {s.skipped}")
    if talk:
        _err(f"bayesdrag: fitting {len(files.usable)} shots of {files.name} as one session ...")
    outcome = fit_chronograph_session(files, rnd, log=None)
    record = outcome.record
    # the manifest hashes the shots read (a skipped one may be a pipe, which must not be opened)
    inputs = {**round_files(round_path, rnd), **{f"shot {s.name}": s.path for s in files.usable}}
    with OutputRun(out, "session", inputs=inputs, echo=_err) as run:
        write_session_report(run.staging, record)
        if record["cd"]:
            write_drag_tables(run.staging, record, outcome.fit, rnd.projectile.mass, rnd.projectile.diameter,
                              outcome.reference)
        for i, shot in enumerate(outcome.fit.shots):
            with OutputRun(out / shot.name, "session-shot", inputs={"track": shot.source}, echo=_err) as srun:
                write_shot(srun.staging, record, outcome.fit, i, figures=figures)
    if warn:
        for w in record["warnings"]:
            _err(f"bayesdrag: warning: {w}")
        for w in record["conditional_on"]:
            _err(f"bayesdrag: note: Cd is conditional on {w}")
    for line in session_lines(record):
        echo(line)
    echo(f"  wrote {out / 'campaign.json'}, campaign.html, session_cd.png"
         + (", drag_table.json and .csv (py-ballisticcalc, mach,cd)" if record["cd"] else "")
         + f" and {len(outcome.fit.shots)} shot folders")
    return 0

#: old names, kept with a warning until release 0.3
__getattr__ = renamed_getattr(__name__, {"session_summary": "session_lines"}, globals())
