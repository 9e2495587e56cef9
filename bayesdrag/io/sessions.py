"""Chronograph sessions as the device writes them: a LabRadar series folder, a list of shot files,
or one shot file (docs/radar.md, "Chronograph sessions").

A series folder ``SR0047/`` holds ``TRK/Shot#### Track.csv`` (one track per shot, read by
:mod:`bayesdrag.io.formats.labradar`) and ``SR0047 Report.csv`` (the device's shot list). The
report is read for the record only: each shot's muzzle speed as the device extrapolated it, its
date and time. Its ``Proj. Weight`` is a stale device setting and is not read (the round gives
the mass). Reports and track folders do not always agree (a report lists shots 1-8 while the
tracks are Shot0008-0015; a report with one row more or fewer than the tracks): a report row is
matched to a track by its shot number, and the mismatch is a note, never a reason to drop a
track. A report saved again by a spreadsheet (comma separated, no ``sep=;``) is read too.

A shot that cannot be read is skipped with its reason (one line naming the file); the session
goes on with the others.
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InputError
from .csv import read_bytes
from .formats.labradar import VELOCITY_UNITS, read_labradar

__all__ = ["SessionFiles", "ShotFile", "read_session", "is_session_path", "MAX_SHOTS", "MIN_SHOT_SAMPLES"]

#: most shots in one session: a LabRadar series holds at most a few hundred
MAX_SHOTS = 1000
#: a shot with fewer measured samples than this is skipped: a speed, a deceleration and a time
#: origin leave no degree of freedom for the noise below it
MIN_SHOT_SAMPLES = 8
#: largest report file read [bytes]
MAX_REPORT_BYTES = 1 << 20
_SHOT_RE = re.compile(r"shot\s*0*(\d+)", re.I)


@dataclass(frozen=True)
class ShotFile:
    """One shot of a session as read.

    Attributes
    ----------
    name : str
        ``Shot0001`` (the file's stem up to its first space).
    path : str
    track : RadarTrack or None
        None when the shot was skipped.
    skipped : str or None
        Why it was skipped.
    report : dict
        The report's row for this shot (``v0`` [m/s], ``date``, ``time``), empty without one.
    """

    name: str
    path: str
    track: object = field(default=None, repr=False)
    skipped: str | None = None
    report: dict = field(default_factory=dict)


@dataclass(frozen=True)
class SessionFiles:
    """A session's shots as read, and notes on what was read."""

    name: str
    shots: tuple
    notes: tuple = ()

    @property
    def usable(self):
        """The shots that were read."""
        return tuple(s for s in self.shots if s.track is not None)


def is_session_path(paths) -> bool:
    """Whether the track argument(s) name a session: a folder, or more than one file."""
    paths = [paths] if isinstance(paths, (str, os.PathLike)) else list(paths)
    return len(paths) > 1 or (len(paths) == 1 and Path(paths[0]).is_dir())


def _shot_number(name):
    m = _SHOT_RE.search(name)
    return int(m.group(1)) if m else None


def _track_files(folder):
    trk = folder / "TRK"
    where = trk if trk.is_dir() else folder
    # every .csv entry but the report, regular file or not: a pipe or a device named like a shot
    # is read through the guarded reader, which refuses it, and is listed as a skipped shot
    files = sorted(p for p in where.iterdir() if not p.is_dir() and p.suffix.lower() == ".csv"
                   and "report" not in p.name.lower())
    if not files:
        raise InputError(f"{folder}: track expected, found a directory without shot files (TRK/Shot#### Track.csv): "
                         f"a folder is read as a LabRadar series; give a track file or a series folder")
    return files


def _report(folder):
    """``({shot number: row dict}, notes)`` from the series' report, if there is one."""
    found = sorted(p for p in folder.iterdir() if p.is_file() and p.name.lower().endswith("report.csv"))
    if not found:
        return {}, ()
    path = found[0]
    try:
        raw = read_bytes(path, "LabRadar report", MAX_REPORT_BYTES)
    except InputError as exc:
        return {}, (f"{path}: report not read ({exc}); the tracks are fitted without it",)
    text = raw.replace(b"\x00", b"").decode("utf-8-sig", "replace")
    lines = [ln.strip() for ln in text.replace("\r", "\n").split("\n")]
    rows, header, sep, unit = {}, None, ";", "fps"   # the device's default unit
    for ln in lines:
        if not ln:
            continue
        line_sep = ";" if ln.count(";") >= ln.count(",") else ","
        cells = [c.strip() for c in ln.split(line_sep)]
        if header is None:
            if cells and cells[0].lower() == "units velocity" and len(cells) > 1:
                unit = cells[1].lower()
            if cells and cells[0].lower() == "shot id":
                header = [c.lower() for c in cells]
                sep = line_sep
            continue
        if not cells[0].isdigit():
            continue
        row = dict(zip(header, cells))
        rec = {}
        try:
            v0 = float(row.get("v0", "nan"))
            rec["v0_reported"] = v0 if v0 > 0 else None
        except ValueError:
            rec["v0_reported"] = None
        rec["date"], rec["time"] = row.get("date", ""), row.get("time", "")
        rows[int(cells[0])] = rec
    factor = VELOCITY_UNITS.get(unit)
    for rec in rows.values():     # the report's speeds in m/s, as the tracks'
        if rec["v0_reported"] is not None:
            rec["v0_reported"] = rec["v0_reported"] * factor if factor else None
    notes = () if sep == ";" else (f"{path}: a comma-separated report (saved again by a spreadsheet); read",)
    return rows, notes


def read_session(paths, *, name=None) -> SessionFiles:
    """Read a session: a LabRadar series folder, or a list of shot files.

    Parameters
    ----------
    paths : str, os.PathLike or sequence of them
        A folder (with ``TRK/`` and a report, or shot files directly), or shot files.
    name : str, optional
        The session's name (default: the folder's name, or the first file's folder's).

    Returns
    -------
    SessionFiles
        Every shot file found, read or skipped with its reason.

    Raises
    ------
    bayesdrag.errors.InputError
        A path that does not exist, a folder without shot files, more than :data:`MAX_SHOTS`
        shots, or two files of one shot name.
    """
    paths = [paths] if isinstance(paths, (str, os.PathLike)) else list(paths)
    notes = []
    report = {}
    if len(paths) == 1 and Path(paths[0]).is_dir():
        folder = Path(paths[0])
        files = _track_files(folder)
        report, rnotes = _report(folder)
        notes.extend(rnotes)
        name = name or folder.name
    else:
        files = []
        for p in paths:
            p = Path(p)
            if not p.exists():
                raise InputError(f"{p}: no such shot file")
            if p.is_dir():
                raise InputError(f"{p}: a folder in a list of shot files; give the series folder alone")
            files.append(p)
        name = name or (files[0].parent.parent.name if files[0].parent.name.upper() == "TRK" else files[0].parent.name)
    if len(files) > MAX_SHOTS:
        raise InputError(f"{paths[0]}: {len(files)} shot files; a session holds at most {MAX_SHOTS}")
    shots, seen = [], {}
    for f in files:
        shot = f.name.split(" ")[0].split(".")[0] or f.stem
        if shot in seen:
            raise InputError(f"{f}: shot {shot} appears twice (also {seen[shot]}); a session's shots have one file "
                             f"each")
        seen[shot] = f
        number = _shot_number(f.name)
        rep = report.get(number, {}) if number is not None else {}
        try:
            tr = read_labradar(f)
        except InputError as exc:
            shots.append(ShotFile(shot, str(f), None, f"not read: {exc}", rep))
            continue
        if tr.n < MIN_SHOT_SAMPLES:
            shots.append(ShotFile(shot, str(f), None, f"{tr.n} measured samples, fewer than {MIN_SHOT_SAMPLES}", rep))
            continue
        shots.append(ShotFile(shot, str(f), tr, None, rep))
    if report:
        numbers = {_shot_number(Path(s.path).name) for s in shots}
        missing = sorted(set(report) - numbers)
        extra = sorted(n for n in numbers if n is not None and n not in report)
        if missing or extra:
            notes.append(f"{name}: the report lists {len(report)} shots and the folder holds {len(shots)} tracks"
                         + (f"; report rows without a track: {', '.join(map(str, missing[:8]))}" if missing else "")
                         + (f"; tracks without a report row: {', '.join(map(str, extra[:8]))}" if extra else "")
                         + " (every track is fitted; the report is for the record)")
    return SessionFiles(str(name), tuple(shots), tuple(notes))
