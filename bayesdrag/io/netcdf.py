"""Groups of named arrays written as a NetCDF-4 file, laid out as xarray writes an ArviZ
``InferenceData`` (``arviz.from_netcdf`` and ``xarray.open_dataset(..., group=...)`` read it).

:func:`write_groups` writes through h5netcdf (the engine ArviZ itself uses) what
``InferenceData.to_netcdf`` writes through xarray: one HDF5 group per group, each dimension a
dimension scale, floating-point variables with a NaN ``_FillValue``, strings variable-length
UTF-8, non-dimension coordinates named in their variables' ``coordinates`` attribute, numeric
variables compressed (byte shuffle and gzip). Without ArviZ's and xarray's imports and xarray's probe for dask, a
fit's folder is ~1 s quicker (docs/measurements.md, "posterior.nc without ArviZ").

:func:`read_inference_data` reads such a file from a folder someone else may have written: the
file's bytes are read once (a regular file, not a link, of bounded size), every member checked by
:func:`bayesdrag.io.hdf5_guard.check_hdf5` against the caller's bounds (no external storage, no
links, declared sizes and compressed chunks bounded), and only then are the groups decoded by
xarray from an in-memory image of those same bytes, as ``arviz.from_netcdf`` decodes them.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from .hdf5_guard import Hdf5Limits, check_hdf5, read_regular_file

__all__ = ["write_groups", "groups_bytes", "read_inference_data", "FILE_SLACK"]

#: bytes a NetCDF-4 file may hold beyond its values' declared bytes [bytes]: HDF5 headers, the
#: attributes, the chunk index, the strings' heap, gzip's few bytes per incompressible chunk
FILE_SLACK = 16 << 20


def write_groups(path, groups, attrs=None):
    """Write ``groups`` (name -> object with ``data_vars``, ``coords``: name -> ``(dims,
    array)``, and ``attrs``) to a new NetCDF-4 file ``path``, with file attributes ``attrs``.

    Parameters
    ----------
    path : str or Path
        The file (created; an existing one is replaced).
    groups : dict
        E.g. :func:`bayesdrag.estimate.bayes.posterior_groups.fit_groups`'s first value.
    attrs : dict, optional
        Attributes of the file's root group.
    """
    import h5netcdf
    import h5py

    with h5netcdf.File(str(path), "w") as f:
        for k, v in (attrs or {}).items():
            f.attrs[k] = v
        for name, g in groups.items():
            grp = f.create_group(name)
            sizes = {}
            for dims, arr in list(g.coords.values()) + list(g.data_vars.values()):
                for d, n in zip(dims, np.shape(arr)):
                    if sizes.setdefault(d, n) != n:
                        raise ValueError(f"group {name}: dimension {d} has lengths {sizes[d]} and {n}")
            grp.dimensions = sizes
            index = {c for c, (dims, _) in g.coords.items() if tuple(dims) == (c,)}
            # coordinate variables first (dimension scales), then the others, as xarray orders them
            for c in sorted(index, key=list(g.coords).index):
                _variable(grp, c, *g.coords[c], h5py)
            others = {c: v for c, v in g.coords.items() if c not in index}
            for c, (dims, arr) in others.items():
                _variable(grp, c, dims, arr, h5py)
            for v, (dims, arr) in g.data_vars.items():
                var = _variable(grp, v, dims, arr, h5py)
                attached = [c for c, (cd, _) in others.items() if set(cd) <= set(dims)]
                if attached:
                    var.attrs["coordinates"] = " ".join(attached)
            for k, val in g.attrs.items():
                grp.attrs[k] = val


def _variable(grp, name, dims, arr, h5py):
    """One variable of ``grp``: floats with a NaN fill value, strings variable-length, numbers
    compressed."""
    a = np.asarray(arr)
    dims = tuple(dims)
    if a.dtype.kind in "US" or a.dtype == object:
        return grp.create_variable(name, dims, dtype=h5py.string_dtype(), data=a.astype(object))
    # byte shuffle and the lightest gzip: smaller and faster than xarray's default (gzip 4, no
    # shuffle) on a posterior's floats (docs/measurements.md, "Where the constants come from")
    kw = {"compression": "gzip", "compression_opts": 1, "shuffle": True} if a.size else {}
    if a.dtype.kind == "f":
        kw["fillvalue"] = a.dtype.type(np.nan)
    return grp.create_variable(name, dims, data=a, **kw)


def groups_bytes(groups):
    """Bytes of the groups' arrays (what the file holds, before compression and overhead)."""
    return sum(int(np.asarray(arr).nbytes) for g in groups.values()
               for _, arr in list(g.data_vars.values()) + list(g.coords.values()))


def read_inference_data(path, limits: Hdf5Limits):
    """The ``arviz.InferenceData`` of the NetCDF-4 file ``path``, checked before it is decoded.

    Parameters
    ----------
    path : path
        A file in a folder someone else may have written (``posterior.nc``).
    limits : Hdf5Limits
        What its datasets may declare (:func:`bayesdrag.io.hdf5_guard.check_hdf5`); the file
        itself may be at most ``limits.max_bytes`` + :data:`FILE_SLACK` bytes.

    Returns
    -------
    arviz.InferenceData
        Every group of the file, loaded into memory, with the root group's attributes (what
        ``arviz.from_netcdf`` gives with ``data.load = "eager"``).

    Raises
    ------
    InputError
        One line naming the file and what is wrong: a link or not a regular file, too large, not
        an HDF5 file, a member refused by the checks, or groups xarray cannot decode.
    """
    import h5py

    name = str(path)
    raw = read_regular_file(path, max_bytes=limits.max_bytes + FILE_SLACK, what=limits.what, why=limits.why,
                            fix=limits.fix)
    try:
        # an in-memory image of the bytes read: what is checked is what is decoded
        f = h5py.File(h5py.h5f.open_file_image(raw))
    except (OSError, ValueError, RuntimeError) as exc:
        raise InputError(f"{name}: not an HDF5 (NetCDF-4) {limits.what} ({_detail(exc)}); {limits.fix}") from None
    with f:
        try:
            check_hdf5(f, name, limits)
            groups = [g for g in f if isinstance(f.get(g), h5py.Group)]
        except InputError:
            raise
        except (OSError, ValueError, TypeError, KeyError, RuntimeError, LookupError) as exc:
            raise InputError(f"{name}: not a readable {limits.what} ({_detail(exc)}); {limits.fix}") from None
        try:
            return _decode(f, groups)
        except (OSError, ValueError, TypeError, KeyError, RuntimeError, LookupError, AttributeError, ArithmeticError,
                MemoryError) as exc:
            raise InputError(f"{name}: the {limits.what} cannot be decoded as NetCDF groups ({_detail(exc)}); "
                             f"{limits.fix}") from None


def _decode(f, groups):
    """The groups of the checked open file ``f`` as xarray datasets in an InferenceData, decoded
    as ``arviz.from_netcdf`` decodes them (xarray's h5netcdf backend, vlen strings as str)."""
    import arviz as az
    import h5netcdf
    import xarray as xr

    def load(group):
        # closing xarray's store closes its h5netcdf wrapper, never the h5py file under it
        store = xr.backends.H5NetCDFStore(h5netcdf.File(f, "r", decode_vlen_strings=True), group=group)
        with xr.open_dataset(store) as data:
            return data.load()

    out = {g: load(g) for g in groups}
    return az.InferenceData(attrs=dict(load(None).attrs), **out)


def _detail(exc):
    """An exception's message on one short line."""
    return (" ".join(str(exc).split()) or type(exc).__name__)[:200]
