"""The per-user private folder bayesdrag keeps state in: numba's compilation cache of the kernel
and the key that signs output-folder commit plans.

``$XDG_CACHE_HOME/bayesdrag`` (default ``~/.cache/bayesdrag``), or ``$TMPDIR/bayesdrag-<uid>``
when the home folder cannot be written. A folder is created 0700 and used only when it is a real
folder (not a symbolic link) owned by the user that no one else may write: numba's cache is
pickled by numba and loaded by it, so a cache folder someone else can write is a way to run code
as the user. Nothing here runs at import; callers ask when they need the folder.
"""
from __future__ import annotations

import os
import stat
import tempfile

__all__ = ["checked_folder", "user_cache_dir", "user_key"]


def checked_folder(path, create=True):
    """Why ``path`` may not hold pickled or secret state (a one-line reason), or None when it
    may: a real folder owned by this user, writable by no one else. Created 0700 (with its
    parents) when missing and ``create``; a folder that cannot be created gives a reason that
    starts with "cannot create"."""
    if create:
        try:
            os.makedirs(path, mode=0o700, exist_ok=True)
        except OSError as exc:
            return f"cannot create {path} ({exc.strerror or exc})"
    try:
        st = os.lstat(path)
    except OSError as exc:
        return f"cannot create {path} ({exc.strerror or exc})"
    if stat.S_ISLNK(st.st_mode):
        return f"{path} is a symbolic link"
    if not stat.S_ISDIR(st.st_mode):
        return f"{path} is not a folder"
    if st.st_uid != os.getuid():
        return f"{path} belongs to another user (uid {st.st_uid})"
    if st.st_mode & 0o022:
        return f"{path} can be written by others (mode {stat.S_IMODE(st.st_mode):o}; chmod go-w it)"
    return None


def user_cache_dir(sub=None):
    """(folder, None) for the private folder (``sub`` inside it, checked the same way), or
    (None, reason) when the first folder that exists or could be created is unsafe (a reason to
    tell the user: someone may have planted it) or none can be created.

    The home folder's is tried first; only when it cannot be created (a read-only or missing
    home) is the temporary folder's tried: an unsafe folder is reported, not silently replaced.
    """
    home = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    bases = (os.path.join(home, "bayesdrag"), os.path.join(tempfile.gettempdir(), f"bayesdrag-{os.getuid()}"))
    reason = None
    for base in bases:
        folder = base if sub is None else os.path.join(base, sub)
        why = checked_folder(base) or (checked_folder(folder) if sub is not None else None)
        if why is None:
            return folder, None
        if not why.startswith("cannot create"):
            return None, why
        reason = reason or why
    return None, reason


def user_key(name="commit.key", _retry=True):
    """A secret of this user (32 random bytes), kept in the private folder (file 0600, created on
    first use), or None when there is no private folder or the file is not a private file of
    this user. Signs what bayesdrag leaves in folders others may write (commit plans)."""
    import secrets

    folder, _ = user_cache_dir()
    if folder is None:
        return None
    path = os.path.join(folder, name)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    except FileNotFoundError:
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
        except FileExistsError:             # another process made it meanwhile
            return user_key(name, False) if _retry else None
        except OSError:
            return None
        with os.fdopen(fd, "wb") as fh:
            fh.write(secrets.token_bytes(32))
        return user_key(name, False)
    except OSError:
        return None
    with os.fdopen(fd, "rb") as fh:
        st = os.fstat(fh.fileno())
        if not stat.S_ISREG(st.st_mode) or st.st_uid != os.getuid() or st.st_mode & 0o077:
            return None
        key = fh.read(65)
    return key if len(key) == 32 else None
