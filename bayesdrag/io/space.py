"""Room to write: a full disk, an exceeded quota or a file size limit (``ulimit -f``) named as
one line instead of a failure half-way through a write.

:func:`ensure_space` and :func:`ensure_file_size` let a writer check before it starts what it
could not finish (the chain file before each block: HDF5 crashed on ``ENOSPC`` and, with a
segfault, on ``EFBIG``); :func:`space_problem` recognises running out in an error raised anyway
(an ``OSError`` or a library's message quoting one), so the output folder can report it as
:class:`DiskFullError` (exit status 1) with nothing of the run kept.
"""
from __future__ import annotations

import errno
import os

from ..errors import OutputError

__all__ = ["DiskFullError", "DISK_FULL", "MIN_FREE_BYTES", "space_problem", "is_disk_full", "free_bytes",
           "file_size_limit", "ensure_space", "ensure_file_size"]

#: free space below which a run does not start [bytes]
MIN_FREE_BYTES = 1 << 20


class DiskFullError(OutputError):
    """No room for what a run writes: the disk is full, the quota exceeded, or a file would pass
    the largest size allowed (``ulimit -f``, the file system's). One line, exit status 1.

    Attributes
    ----------
    reason : str
        What ran out, as the one-line message of the run says it (``"the disk is full (No
        space left on device)"``, ...).
    """

    def __init__(self, message, reason=None):
        super().__init__(message)
        self.reason = reason or DISK_FULL


#: what a full disk is called in messages
DISK_FULL = "the disk is full (No space left on device)"
_REASONS = {errno.ENOSPC: DISK_FULL,
            errno.EDQUOT: "the disk quota is exceeded (Disk quota exceeded)",
            errno.EFBIG: "a file would pass the largest size allowed (File too large: the file size limit, "
                         "ulimit -f, or the file system's)"}
_REASON_TEXT = (("No space left on device", errno.ENOSPC), ("errno = 28", errno.ENOSPC),
                ("Disk quota exceeded", errno.EDQUOT), ("errno = 122", errno.EDQUOT),
                ("File too large", errno.EFBIG), ("errno = 27", errno.EFBIG))


def space_problem(exc, folder=None):
    """What ran out when ``exc`` was raised (one of the reasons of :class:`DiskFullError`), or
    None: an ``OSError`` with ``ENOSPC``, ``EDQUOT`` or ``EFBIG``, a library error quoting one
    (HDF5, netCDF), a :class:`DiskFullError`, or any error while ``folder``'s file system has
    less than :data:`MIN_FREE_BYTES` left."""
    seen = set()
    e = exc
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        if isinstance(e, DiskFullError):
            return e.reason
        if isinstance(e, OSError) and e.errno in _REASONS:
            return _REASONS[e.errno]
        text = str(e)
        for needle, code in _REASON_TEXT:
            if needle in text:
                return _REASONS[code]
        e = e.__cause__ or e.__context__
    if folder is not None:
        free = free_bytes(folder)
        if free is not None and free < MIN_FREE_BYTES:
            return DISK_FULL
    return None


def is_disk_full(exc, folder=None):
    """True when ``exc`` is (or wraps) running out of room (:func:`space_problem`)."""
    return space_problem(exc, folder) is not None


def free_bytes(folder):
    """Bytes available to this user on ``folder``'s file system (None when unknown)."""
    try:
        s = os.statvfs(folder)
    except OSError:
        return None
    return s.f_bavail * s.f_frsize


def file_size_limit():
    """The largest file this process may write [bytes] (``RLIMIT_FSIZE``), or None."""
    import resource

    soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    return None if soft == resource.RLIM_INFINITY else int(soft)


def ensure_space(folder, nbytes, what):
    """Raise :class:`DiskFullError` when ``folder``'s file system has less than ``nbytes`` plus
    :data:`MIN_FREE_BYTES` free, before a writer starts what it could not finish; and when one
    file of ``nbytes`` would pass the file size limit of the process (:func:`ensure_file_size`)."""
    free = free_bytes(folder)
    if free is not None and free < nbytes + MIN_FREE_BYTES:
        raise DiskFullError(f"{folder}: the disk is full ({free} bytes free, {int(nbytes)} needed) while "
                            f"writing {what}")
    ensure_file_size(os.path.join(folder, what), nbytes)


def ensure_file_size(path, nbytes):
    """Raise :class:`DiskFullError` when the file ``path`` (its size now, 0 when missing) would
    grow by ``nbytes`` past the file size limit of this process (``ulimit -f``): the write would
    fail with ``EFBIG``, which crashed HDF5 (a segfault) instead of failing."""
    limit = file_size_limit()
    if limit is None:
        return
    try:
        size = os.path.getsize(path)
    except OSError:
        size = 0
    if size + nbytes > limit:
        raise DiskFullError(f"{path}: the file would pass the file size limit of {limit} bytes (ulimit -f) with "
                            f"{int(size + nbytes)} bytes", reason=_REASONS[errno.EFBIG])
