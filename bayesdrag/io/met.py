"""Met profile files (CSV): the air a round flew through, level by level (altitude, temperature,
pressure, optional wind), read into :class:`bayesdrag.atmosphere.MetProfile`."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..atmosphere import MetProfile
from ..errors import InputError
from .csv import read_table

__all__ = ["read_met_profile", "write_met_profile", "PROFILE_COLUMNS", "PROFILE_OPTIONAL_COLUMNS"]


#: columns of a met profile CSV: required, then optional
PROFILE_COLUMNS = ("altitude", "temperature", "pressure")
PROFILE_OPTIONAL_COLUMNS = ("wind_x", "wind_y")


def read_met_profile(path, gun_altitude=0.0, **offsets):
    """Read a met profile CSV into a :class:`MetProfile`.

    Format (the track CSV rules: ``#`` comments, a header row, one row of numbers per level):
    columns ``altitude`` [m above sea level, geometric], ``temperature`` [K], ``pressure`` [Pa],
    optional ``wind_x``, ``wind_y`` [m/s, track frame]; rows in increasing altitude.

    Parameters
    ----------
    path : str or os.PathLike
    gun_altitude : float, m
    **offsets
        ``temperature_offset``, ``pressure_ratio``, ``density_ratio`` as in :class:`MetProfile`.

    Raises
    ------
    bayesdrag.errors.InputError
        Everything the CSV reader rejects, unknown columns, and every :class:`MetProfile`
        validation failure (the message names the file and, where it concerns one level, its
        line).
    """
    path, names, data, line_no = read_table(
        path, "met profile", required=PROFILE_COLUMNS,
        allowed=PROFILE_COLUMNS + PROFILE_OPTIONAL_COLUMNS, quote=False)
    cols = {n: data[:, k] for k, n in enumerate(names)}
    try:
        return MetProfile(tuple(cols["altitude"]), tuple(cols["temperature"]), tuple(cols["pressure"]),
                          None if "wind_x" not in cols else tuple(cols["wind_x"]),
                          None if "wind_y" not in cols else tuple(cols["wind_y"]),
                          gun_altitude=gun_altitude, source=str(Path(path)), **offsets)
    except ValueError as exc:
        msg = str(exc)
        # name the file line of the level the message quotes, when it quotes one
        m = re.search(r"altitude (-?[0-9.e+]+) m", msg)
        where = ""
        if m:
            try:
                hit = np.flatnonzero(np.isclose(cols["altitude"], float(m.group(1)), rtol=1e-5, atol=0.5))
            except ValueError:
                hit = []
            if len(hit):
                where = f"line {line_no[hit[-1] if 'repeats' in msg or 'below the previous' in msg else hit[0]]}: "
        raise InputError(f"{path}: {where}{msg}") from None


def write_met_profile(path, profile, comment=None):
    """Write a :class:`MetProfile`'s levels as CSV that :func:`read_met_profile` reads back."""
    cols = [("altitude", profile.altitude), ("temperature", profile.temperature),
            ("pressure", profile.pressure)]
    for k in ("wind_x", "wind_y"):
        if getattr(profile, k) is not None:
            cols.append((k, getattr(profile, k)))
    head = "".join(f"# {ln}".rstrip() + "\n" for ln in str(comment).splitlines()) if comment else ""
    head += "# units: m above sea level, K, Pa, m/s\n" + ",".join(k for k, _ in cols) + "\n"
    body = "".join(",".join(repr(float(c[i])) for _, c in cols) + "\n" for i in range(len(profile.altitude)))
    Path(path).write_text(head + body, encoding="utf-8")
