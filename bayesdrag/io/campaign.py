"""Campaign files (TOML): many rounds of one shell.

A campaign TOML lists rounds (paths relative to the campaign file)::

    [campaign]
    name = "130 mm cargo shell, trial 5"

    [[rounds]]
    name = "r1"          # folder name of the round's outputs: letters, digits, '.', '_', '-'
    track = "r1.csv"
    round = "r1.toml"
"""
from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError
from .csv import read_text, read_toml

__all__ = ["CampaignRound", "Campaign", "is_campaign_file", "read_campaign", "write_campaign"]


_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$")


_CAMPAIGN_KEYS = ("name", "description")


_ROUND_KEYS = ("name", "track", "round")


@dataclass(frozen=True)
class CampaignRound:
    """One round of a campaign: its name (output folder) and resolved input paths."""

    name: str
    track: Path
    round: Path


@dataclass(frozen=True)
class Campaign:
    """A campaign file: ``name`` and the ``rounds`` in file order; ``path`` the TOML file."""

    name: str
    rounds: tuple
    path: Path
    description: str = ""

    @property
    def names(self):
        return [r.name for r in self.rounds]


def is_campaign_file(path):
    """True if ``path`` is a TOML file with a ``[campaign]`` table or ``[[rounds]]`` array (so
    ``bayesdrag fit`` treats it as a campaign rather than a track)."""
    p = Path(path)
    if p.suffix.lower() != ".toml" or not p.is_file():
        return False
    try:
        doc = tomllib.loads(read_text(p, "campaign file"))
    except (tomllib.TOMLDecodeError, InputError, RecursionError):
        return True     # read_campaign says what is wrong with it
    return "campaign" in doc or "rounds" in doc


def read_campaign(path, allow_outside=False):
    """Read and validate a campaign TOML.

    The tracks and round files must be inside the campaign file's folder (after following
    links), checked before anything in them is read: a campaign is often in a folder others
    can write, and one pointing at ``/etc/shadow`` would have the user read it.

    Parameters
    ----------
    path : str or os.PathLike
    allow_outside : bool
        Accept files outside the campaign's folder (``--allow-outside-inputs``).

    Returns
    -------
    Campaign

    Raises
    ------
    InputError
        Naming the file and the key: unreadable TOML, unknown keys, a round without ``track``
        or ``round``, a name that is not a safe folder name or is the name of an output,
        duplicate names, files outside the campaign's folder, missing files, fewer than one
        round.
    """
    path = Path(path)
    doc = read_toml(path, "campaign file", "a campaign lists [[rounds]] of name, track and round")
    unknown = [k for k in doc if k not in ("campaign", "rounds")]
    if unknown:
        raise InputError(f"{path}: unknown top-level key {unknown[0]!r}; allowed: [campaign], [[rounds]]")
    camp = doc.get("campaign", {})
    if not isinstance(camp, dict):
        raise InputError(f"{path}: [campaign] must be a table with name = \"...\"")
    bad = [k for k in camp if k not in _CAMPAIGN_KEYS]
    if bad:
        raise InputError(f"{path}: unknown key campaign.{bad[0]}; allowed: {', '.join(_CAMPAIGN_KEYS)}")
    name = camp.get("name", path.stem)
    if not isinstance(name, str):
        raise InputError(f"{path}: campaign.name must be text, got {type(name).__name__}")
    rounds = doc.get("rounds")
    if not isinstance(rounds, list) or not rounds:
        raise InputError(f"{path}: a campaign needs at least one [[rounds]] entry with name, track and round")
    out, seen = [], set()
    root = path.resolve().parent
    for i, r in enumerate(rounds, 1):
        where = f"{path}: rounds entry {i}"
        if not isinstance(r, dict):
            raise InputError(f"{where}: must be a table with name, track and round")
        bad = [k for k in r if k not in _ROUND_KEYS]
        if bad:
            raise InputError(f"{where}: unknown key {bad[0]!r}; allowed: {', '.join(_ROUND_KEYS)}")
        for k in ("track", "round"):
            if k not in r:
                raise InputError(f"{where}: missing key {k!r} (a path relative to the campaign file)")
            if not isinstance(r[k], str) or not r[k]:
                raise InputError(f"{where}: {k} must be a non-empty path, got {r[k]!r}")
        nm = r.get("name", Path(r["track"]).stem)
        if not isinstance(nm, str) or not _NAME_RE.match(nm):
            raise InputError(f"{where}: name {nm!r} is not allowed; use 1-64 letters, digits, '.', '_', '-' "
                             f"(it names the output folder)")
        if _output_name(nm):
            raise InputError(f"{where}: name {nm!r} is not allowed; it is the name of a file or folder bayesdrag "
                             f"writes into the output folder (the round's outputs would be moved or overwritten): "
                             f"choose another name")
        if nm in seen:
            raise InputError(f"{where}: duplicate round name {nm!r}; names must be unique")
        seen.add(nm)
        files = {}
        for k in ("track", "round"):
            p = (path.parent / r[k]).resolve()
            if not allow_outside and not p.is_relative_to(root):
                raise InputError(f"{where} ({nm}): {k} {r[k]!r} is outside the campaign's folder {root}; a campaign "
                                 f"reads only files in its own folder: move the file there, or pass "
                                 f"--allow-outside-inputs")
            if not p.is_file():
                raise InputError(f"{where} ({nm}): {k} file {r[k]!r} not found (looked at {p})")
            files[k] = p
        out.append(CampaignRound(nm, files["track"], files["round"]))
    return Campaign(name, tuple(out), path.resolve(), str(camp.get("description", "")))


def _output_name(name):
    """True when a round folder called ``name`` would collide with what bayesdrag writes into a
    campaign's output folder (its outputs, ``superseded/``, the unfinished chain, the lock)."""
    from fnmatch import fnmatch

    from .outputs import KNOWN_OUTPUTS, LOCK_NAME, PARTIAL_CHAIN, SUPERSEDED

    return name in (SUPERSEDED, PARTIAL_CHAIN, LOCK_NAME) or any(fnmatch(name, p) for p in KNOWN_OUTPUTS)


def write_campaign(path, name, rounds):
    """Write a campaign TOML. ``rounds``: iterable of (name, track path, round path); paths are
    written relative to the campaign file's folder when possible."""
    import os

    path = Path(path)
    lines = [f"[campaign]\nname = {_toml_str(name)}\n"]
    for nm, tr, ro in rounds:
        rel = [Path(os.path.relpath(Path(p).resolve(), path.resolve().parent)).as_posix() for p in (tr, ro)]
        lines.append(f"\n[[rounds]]\nname = {_toml_str(nm)}\ntrack = {_toml_str(rel[0])}\n"
                     f"round = {_toml_str(rel[1])}\n")
    path.write_text("".join(lines), encoding="utf-8")
    return path


def _toml_str(s):
    return '"' + str(s).replace("\\", "\\\\").replace('"', '\\"') + '"'
