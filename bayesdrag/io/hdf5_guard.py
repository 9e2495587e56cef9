"""Checks of an HDF5 file (a NetCDF-4 file included) read from a folder someone else may have
written, made before any of its values is read.

The chain file (:mod:`bayesdrag.io.chain`) showed what a planted HDF5 file does when it is read
as it comes: data stored in external files or virtual datasets copies another file's bytes into
the values, a symbolic link reads a file elsewhere, a dataset may declare far more values than
the file holds (never written, they read as fill values) and a compressed chunk may inflate to
a thousand times its size (HDF5's gzip filter grows its buffer until the stream ends: a 400 kB
chunk of a 1 kB dataset took 400 MB). :mod:`~bayesdrag.io.chain` refuses compression; a
``posterior.nc`` is compressed, so this module applies the same checks with gzip allowed:

* :func:`read_regular_file`: the path is a regular file, not a symbolic link (``lstat``, then
  opened with ``O_NOFOLLOW`` and the same inode required), of at most a given size, read into
  memory once, so that what is checked is what is read afterwards.
* :func:`check_hdf5`: every member is a hard link (no soft or external links), a group, a dataset
  or a committed type; at most :data:`MAX_OBJECTS` of them, :data:`MAX_DEPTH` groups deep. Every
  dataset is stored inside the file (not virtual, no external storage), contiguous, chunked or
  compact, numbers or strings, of at most :data:`MAX_RANK` dimensions each at most the caller's
  bound; its chunks (or contiguous block) are all allocated (a netCDF dimension without a
  variable excepted: its values are never read); only the gzip, shuffle and fletcher32 filters,
  and every gzip-compressed chunk inflates to no more than the chunk (checked with :mod:`zlib`
  and an output cap, never by HDF5); and the bytes the datasets declare, summed, are at most the
  caller's bound. Nothing is read from a dataset but its raw compressed chunks.

Each refusal is an :class:`~bayesdrag.errors.InputError` of one line naming the file, the
dataset and what was found.
"""
from __future__ import annotations

import math
import os
import stat
import zlib
from dataclasses import dataclass

import h5py

from ..errors import InputError

__all__ = ["Hdf5Limits", "read_regular_file", "check_hdf5", "MAX_RANK", "MAX_OBJECTS", "MAX_DEPTH", "MAX_CHUNKS",
           "VLEN_BYTES"]

#: most dimensions of one dataset (a posterior variable has chain, draw and at most two more)
MAX_RANK = 4
#: most groups, datasets and committed types in one file (a posterior.nc holds about 60)
MAX_OBJECTS = 4096
#: most levels of groups below the root (a NetCDF-4 posterior uses one)
MAX_DEPTH = 4
#: most compressed chunks inflated while checking one file: 4 GiB in h5py's smallest default
#: chunks (16 KiB); a posterior.nc of the demo holds about 700
MAX_CHUNKS = 262_144
#: memory a variable-length string element is counted for (a Python ``str`` read back) [bytes]
VLEN_BYTES = 64
#: bytes a variable-length element takes where it is stored (a global heap id) [bytes]
VLEN_STORED_BYTES = 16
#: the checksum the fletcher32 filter appends to a chunk [bytes]
FLETCHER32_BYTES = 4
#: the filters a NetCDF-4 writer applies and HDF5 decodes without plugins
FILTERS = {h5py.h5z.FILTER_DEFLATE: "gzip", h5py.h5z.FILTER_SHUFFLE: "shuffle",
           h5py.h5z.FILTER_FLETCHER32: "fletcher32"}
#: the NAME attribute h5netcdf and netCDF-C give a dimension that is no variable (never written, never read)
PHONY_DIMENSION = b"This is a netCDF dimension but not a netCDF variable"
_LAYOUTS = {h5py.h5d.CONTIGUOUS: "contiguous", h5py.h5d.CHUNKED: "chunked", h5py.h5d.COMPACT: "compact"}
#: dtype kinds read as numbers (strings are checked apart)
_NUMBER_KINDS = "biuf"


@dataclass(frozen=True)
class Hdf5Limits:
    """What a file may declare, derived by the caller from what it expects.

    Attributes
    ----------
    max_bytes : int
        Bytes of the values of all datasets together (as read into memory; a string
        :data:`VLEN_BYTES`; a chunked dataset at least one chunk) [bytes].
    max_length : int
        Length of any one dimension (and chunk dimension) of any dataset.
    why : str
        Where the bounds come from, for messages (``result.json records 16 walkers x ...``).
    fix : str
        What the user can do about a refused file, for messages.
    what : str
        The file's role, for messages (``posterior file``).
    """

    max_bytes: int
    max_length: int
    why: str
    fix: str
    what: str = "HDF5 file"


def read_regular_file(path, *, max_bytes, what, why, fix):
    """The bytes of the regular file ``path``, read once (what is checked is what is used).

    Parameters
    ----------
    path : path
    max_bytes : int
        Largest size accepted [bytes].
    what, why, fix : str
        The file's role, where ``max_bytes`` comes from, and what to do, for messages.

    Raises
    ------
    InputError
        Missing, a symbolic link (even to a file inside the folder), not a regular file, larger
        than ``max_bytes``, replaced while it was opened, or unreadable.
    """
    path = os.fspath(path)
    try:
        st = os.lstat(path)
    except OSError as exc:
        raise InputError(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None
    if stat.S_ISLNK(st.st_mode):
        raise InputError(f"{path}: the {what} is a symbolic link, which is never followed (the folder's files are "
                         f"written in place); {fix}")
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{path}: the {what} is not a regular file; {fix}")
    if st.st_size > max_bytes:
        raise InputError(f"{path}: the {what} is {st.st_size} bytes, more than the {max_bytes} {why}; {fix}")
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise InputError(f"{path}: cannot read the {what} ({exc.strerror or exc}); {fix}") from None
    with os.fdopen(fd, "rb") as fh:
        now = os.fstat(fh.fileno())
        if (now.st_dev, now.st_ino) != (st.st_dev, st.st_ino) or not stat.S_ISREG(now.st_mode):
            raise InputError(f"{path}: the {what} was replaced while it was opened; {fix}")
        raw = fh.read(max_bytes + 1)
    if len(raw) > max_bytes:
        raise InputError(f"{path}: the {what} grew beyond {max_bytes} bytes while it was read; {fix}")
    return raw


def check_hdf5(f, path, limits):
    """Check every member of the open HDF5 file ``f`` (module docstring) before any value is read.

    Parameters
    ----------
    f : h5py.File
    path : path
        The file's name, for messages.
    limits : Hdf5Limits

    Returns
    -------
    int
        The bytes the datasets declare, summed (at most ``limits.max_bytes``).

    Raises
    ------
    InputError
        One line naming the file, the member and what is wrong.
    """
    c = _Checker(os.fspath(path), limits)
    c.walk(f)
    return c.total


class _Checker:
    """One walk over a file's members, counting objects, chunks and declared bytes."""

    def __init__(self, path, limits):
        self.path, self.limits = path, limits
        self.total = self.objects = self.chunks = 0

    def fail(self, what):
        raise InputError(f"{self.path}: {what}; {self.limits.fix}")

    def walk(self, root):
        stack = [(root, "", 0)]
        while stack:
            group, prefix, depth = stack.pop()
            for name in group:
                full = f"{prefix}/{name}" if prefix else name
                self.objects += 1
                if self.objects > MAX_OBJECTS:
                    self.fail(f"more than {MAX_OBJECTS} groups and datasets: not a {self.limits.what} bayesdrag "
                              f"writes (about 60)")
                link = group.get(name, getlink=True)
                if not isinstance(link, h5py.HardLink):
                    kind = "an external link" if isinstance(link, h5py.ExternalLink) else "a soft link"
                    self.fail(f"'{full}' is {kind} (to a value stored elsewhere): every member must be stored in "
                              f"this file")
                obj = group.get(name)
                if isinstance(obj, h5py.Group):
                    if depth + 1 > MAX_DEPTH:
                        self.fail(f"group '{full}' is nested {depth + 1} levels deep, at most {MAX_DEPTH} allowed")
                    stack.append((obj, full, depth + 1))
                elif isinstance(obj, h5py.Dataset):
                    self.total += self.dataset(obj, full)
                    if self.total > self.limits.max_bytes:
                        self.fail(f"its datasets declare {self.total} bytes of values (with '{full}'), more than the "
                                  f"{self.limits.max_bytes} {self.limits.why}")
                elif not isinstance(obj, h5py.Datatype):   # a committed type holds no values
                    self.fail(f"'{full}' is an HDF5 object of an unknown kind")

    def dataset(self, ds, name):
        """Check dataset ``name``; its declared bytes."""
        if ds.is_virtual:
            self.fail(f"dataset '{name}' is a virtual dataset (its values are in other files)")
        if ds.external:
            files = ", ".join(str(e[0]) for e in ds.external)[:200]
            self.fail(f"dataset '{name}' is stored in external files ({files}), not in this file")
        shape = ds.shape
        if shape is None:                       # a null dataspace holds nothing
            return 0
        lim = self.limits
        if len(shape) > MAX_RANK:
            self.fail(f"dataset '{name}' has {len(shape)} dimensions, at most {MAX_RANK} allowed")
        for i, n in enumerate(shape):
            if n > lim.max_length:
                self.fail(f"dimension {i} of dataset '{name}' has length {n}, more than the {lim.max_length} "
                          f"{lim.why}")
        dt = ds.dtype
        if dt.kind == "O":
            if h5py.check_string_dtype(dt) is None:
                self.fail(f"dataset '{name}' holds variable-length values that are not strings")
            memory, stored = VLEN_BYTES, VLEN_STORED_BYTES
        elif dt.kind in _NUMBER_KINDS or dt.kind == "S":
            memory = stored = dt.itemsize
        else:
            self.fail(f"dataset '{name}' has type {dt.str!r}, expected numbers or strings")
        n = math.prod(shape)
        declared = n * memory
        if declared > lim.max_bytes:            # before any chunk is looked at
            self.fail(f"dataset '{name}' declares {'x'.join(map(str, shape))} values ({declared} bytes), more than "
                      f"the {lim.max_bytes} {lim.why}")
        dcpl = ds.id.get_create_plist()
        layout = dcpl.get_layout()
        phony = self._phony(ds)
        if layout == h5py.h5d.CHUNKED:
            chunk = tuple(ds.chunks)
            if len(chunk) != len(shape) or any(c > max(lim.max_length, 1) for c in chunk):
                self.fail(f"dataset '{name}' has chunks {chunk}, longer than the {lim.max_length} {lim.why}")
            declared = max(declared, math.prod(chunk) * memory)   # HDF5 holds a whole chunk to read any of it
            self._chunks(ds, name, shape, chunk, math.prod(chunk) * stored, dcpl, phony)
        elif layout == h5py.h5d.CONTIGUOUS:
            if n and not phony and (ds.id.get_offset() is None or ds.id.get_storage_size() < n * stored):
                self.fail(f"dataset '{name}' is sparse: its values are not stored in the file")
        elif layout != h5py.h5d.COMPACT:
            self.fail(f"dataset '{name}' has {_LAYOUTS.get(layout, 'unknown')} storage, expected contiguous, chunked "
                      f"or compact")
        return declared

    @staticmethod
    def _phony(ds):
        v = ds.attrs.get("NAME") if "NAME" in ds.attrs else None
        if isinstance(v, str):
            v = v.encode("utf-8", "replace")
        return isinstance(v, bytes) and v.startswith(PHONY_DIMENSION)

    def _chunks(self, ds, name, shape, chunk, chunk_bytes, dcpl, phony):
        """Allocated chunks, allowed filters, and every compressed chunk no larger than a chunk
        once inflated."""
        pipeline = [dcpl.get_filter(i)[0] for i in range(dcpl.get_nfilters())]
        bad = [code for code in pipeline if code not in FILTERS]
        if bad:
            self.fail(f"dataset '{name}' uses HDF5 filter {bad[0]}; only {', '.join(FILTERS.values())} are read")
        deflate = h5py.h5z.FILTER_DEFLATE
        if h5py.h5z.FILTER_SHUFFLE in pipeline and deflate in pipeline:
            if pipeline.index(h5py.h5z.FILTER_SHUFFLE) > pipeline.index(deflate):
                self.fail(f"dataset '{name}' shuffles after compressing, which no NetCDF writer does")
        expected = math.prod(-(-s // c) for s, c in zip(shape, chunk))
        stored = ds.id.get_num_chunks()
        if stored < expected and not phony:
            self.fail(f"dataset '{name}' is sparse: {expected - stored} of its {expected} chunks are not stored in "
                      f"the file")
        if deflate not in pipeline:
            return
        self.chunks += stored
        if self.chunks > MAX_CHUNKS:
            self.fail(f"more than {MAX_CHUNKS} compressed chunks: not a {self.limits.what} bayesdrag writes")
        cap = chunk_bytes + FLETCHER32_BYTES * pipeline.count(h5py.h5z.FILTER_FLETCHER32)
        for i in range(stored):
            info = ds.id.get_chunk_info(i)
            mask, raw = ds.id.read_direct_chunk(info.chunk_offset)
            if self._inflated_size(raw, pipeline, mask, cap, name) > chunk_bytes:
                self.fail(f"a chunk of dataset '{name}' ({len(raw)} bytes stored) inflates to more than the "
                          f"{chunk_bytes} bytes of a chunk (a compression bomb)")

    def _inflated_size(self, raw, pipeline, mask, cap, name):
        """Bytes of a raw chunk once its filters are undone (last applied first), every gzip
        stage inflated to at most ``cap`` + 1 bytes."""
        data = raw
        for i in range(len(pipeline) - 1, -1, -1):
            if mask & (1 << i):                 # this filter was skipped for this chunk
                continue
            code = pipeline[i]
            if code == h5py.h5z.FILTER_FLETCHER32:
                if len(data) < FLETCHER32_BYTES:
                    self.fail(f"a chunk of dataset '{name}' is shorter than its checksum")
                data = data[:-FLETCHER32_BYTES]
            elif code == h5py.h5z.FILTER_DEFLATE:
                d = zlib.decompressobj()
                try:
                    data = d.decompress(data, cap + 1)
                except zlib.error as exc:
                    self.fail(f"a chunk of dataset '{name}' is not valid gzip data ({exc})")
                if len(data) > cap:
                    return len(data)
            # shuffle reorders bytes and keeps their number
        return len(data)
