"""The commit plan of an output folder: the journal of renames that swaps a run's staged files
into ``DIR`` (:class:`bayesdrag.io.outputs.OutputRun`), and what makes one safe to carry out
again after a kill.

A plan is written into the run's staging folder before its first rename (the commit point) and
replayed by the next run when the swap was interrupted. ``DIR`` may be a folder others can write
(a planted plan moved files through a symbolic link out of ``DIR`` and a pickle over a compiled
kernel's cache index), so a plan is carried out only when:

* every move has a shape a commit makes (:func:`plan_moves`): an earlier file of ``DIR`` out to
  ``superseded/<run>/<the same name>``, a staged file of *this plan's* staging folder in to the
  same name, or one name of ``DIR`` to another (the finished chain adopted);
* it is signed (:func:`signature`, HMAC-SHA256) with the user's key kept in the private cache
  folder (:func:`bayesdrag._runtime.user_cache.user_key`), bound to the folder's device and inode and to
  the staging folder's name: a plan written by someone else, or copied from another folder, does
  not verify. Where the user has no private folder, plans are unsigned and only their shapes and
  files are checked;
* each rename moves a regular file of the user, over nothing or a regular file, through folders
  that are real folders of the user (:func:`execute`): no symbolic link is followed.
"""
from __future__ import annotations

import hashlib
import hmac
import json
import os
import re
import stat

__all__ = ["PLAN", "PLAN_FORMAT", "STAGING_PREFIX", "SUPERSEDED", "safe_rel", "plan_moves", "signature",
           "check_signature", "execute", "not_own_folder"]

#: the commit journal inside a staging folder (hidden: `bayesdrag plan` writes a `plan.json` output)
PLAN = ".commit.json"
PLAN_FORMAT = "bayesdrag-commit/1"
STAGING_PREFIX = ".staging-"
#: earlier runs' files, one folder per run
SUPERSEDED = "superseded"
NAME_RE = re.compile(r"^\.?[A-Za-z0-9][A-Za-z0-9._-]{0,200}$")


def safe_rel(rel):
    """A relative path from a plan or manifest, checked to be plain names (no '..', no '/'
    at the start): a tuple of its parts."""
    if not isinstance(rel, str) or not rel or rel.startswith("/"):
        raise ValueError(f"not a relative path: {rel!r}")
    parts = tuple(rel.split("/"))
    if not all(NAME_RE.match(p) and p not in (".", "..") for p in parts):
        raise ValueError(f"not a plain relative path: {rel!r}")
    return parts


def plan_moves(doc, staging):
    """The moves ``(src parts, dst parts, "in" | "out")`` of a plan read from the staging folder
    ``staging`` (its name), each checked to have a shape a commit makes (module docstring).

    Raises
    ------
    ValueError
        Not a plan of this version, or a move of another shape.
    """
    if not isinstance(doc, dict) or doc.get("format") != PLAN_FORMAT or not isinstance(doc.get("moves"), list):
        raise ValueError("not a commit plan of this version")
    moves = []
    for m in doc["moves"]:
        if not (isinstance(m, list) and len(m) == 3 and m[2] in ("in", "out")):
            raise ValueError("malformed move")
        src, dst, kind = safe_rel(m[0]), safe_rel(m[1]), m[2]
        if kind == "out":
            ok = len(src) == 1 and len(dst) == 3 and dst[0] == SUPERSEDED and dst[2] == src[0] != SUPERSEDED
        else:
            ok = len(dst) == 1 and ((len(src) == 2 and src[0] == staging and src[1] == dst[0])
                                    or (len(src) == 1 and src[0] != dst[0]))
        if not ok or any(p.startswith(STAGING_PREFIX) for p in dst):
            raise ValueError(f"a move a commit never makes: {m[0]!r} -> {m[1]!r}")
        moves.append((src, dst, kind))
    return moves


def signature(key, folder, staging, run, moves):
    """HMAC-SHA256 (hex) of a plan with the user's ``key``, bound to the output folder (its device
    and inode) and to its staging folder's name ``staging``."""
    st = os.stat(folder)
    body = json.dumps({"folder": [st.st_dev, st.st_ino], "staging": staging, "run": run, "moves": moves},
                      sort_keys=True)
    return hmac.new(key, body.encode(), hashlib.sha256).hexdigest()


def check_signature(key, doc, folder, staging):
    """Raise :class:`ValueError` unless the plan ``doc`` carries the signature ``key`` gives it
    for ``folder`` and ``staging`` (nothing is checked when ``key`` is None: no private folder)."""
    if key is None:
        return
    want = signature(key, folder, staging, doc.get("run"), doc["moves"])
    if not isinstance(doc.get("signature"), str) or not hmac.compare_digest(doc["signature"], want):
        raise ValueError("not signed by this user's bayesdrag for this folder")


def execute(folder, moves):
    """Do the renames of a plan inside ``folder`` (``DIR``, resolved); replaying a plan after a
    kill completes it. An ``out`` move (an earlier file to ``superseded/``) is done when its
    source exists and its target does not (the source's name is taken by the new file
    afterwards); an ``in`` move (a new file into ``DIR``) whenever its source, which belongs to
    this run alone, still exists.

    Every folder on the way is a real folder of this user (``superseded/`` and
    ``superseded/<run>/`` are made here when missing), the source a regular file of this user
    and the target absent or a regular file: a symbolic link planted anywhere is never followed.

    Raises
    ------
    ValueError
        Something else on the way (nothing further is moved).
    """
    for src, dst, kind in moves:
        s, d = folder.joinpath(*src), folder.joinpath(*dst)
        _own_folders(folder, src[:-1], create=False)
        try:
            st = os.lstat(s)
        except FileNotFoundError:
            continue
        if not stat.S_ISREG(st.st_mode) or st.st_uid != os.getuid():
            raise ValueError(f"{'/'.join(src)} is not a regular file of this user")
        if kind == "in":
            if os.path.lexists(d) and not stat.S_ISREG(os.lstat(d).st_mode):
                raise ValueError(f"{'/'.join(dst)} is not a regular file")
            os.replace(s, d)
        elif not os.path.lexists(d):
            _own_folders(folder, dst[:-1], create=True)
            os.rename(s, d)


def _own_folders(folder, parts, create):
    """Check (and with ``create`` make) ``folder/parts[0]/parts[1]/...``: each a real folder of
    this user."""
    path = folder
    for p in parts:
        path = path / p
        if create and not os.path.lexists(path):
            path.mkdir()
        why = not_own_folder(path)
        if why:
            raise ValueError(f"{path.relative_to(folder).as_posix()}: {why}")


def not_own_folder(path):
    """Why ``path`` is not a real folder of this user (a phrase), or None."""
    try:
        st = os.lstat(path)
    except OSError as exc:
        return f"cannot be read ({exc.strerror or exc})"
    if stat.S_ISLNK(st.st_mode):
        return "is a symbolic link"
    if not stat.S_ISDIR(st.st_mode):
        return "is not a folder"
    if st.st_uid != os.getuid():
        return f"belongs to another user (uid {st.st_uid})"
    return None
