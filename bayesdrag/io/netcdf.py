"""Groups of named arrays written as a NetCDF-4 file, laid out as xarray writes an ArviZ
``InferenceData`` (``arviz.from_netcdf`` and ``xarray.open_dataset(..., group=...)`` read it).

:func:`write_groups` writes through h5netcdf (the engine ArviZ itself uses) what
``InferenceData.to_netcdf`` writes through xarray: one HDF5 group per group, each dimension a
dimension scale, floating-point variables with a NaN ``_FillValue``, strings variable-length
UTF-8, non-dimension coordinates named in their variables' ``coordinates`` attribute, numeric
variables compressed (byte shuffle and gzip). Without ArviZ's and xarray's imports and xarray's probe for dask, a
fit's folder is ~1 s quicker (docs/measurements.md, "posterior.nc without ArviZ").
"""
from __future__ import annotations

import numpy as np

__all__ = ["write_groups", "groups_bytes"]


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
    # byte shuffle and the lightest gzip: on the demo's posterior 8.9 MB in 0.19 s, where
    # xarray's default (gzip 4, no shuffle) gave 10.3 MB in 0.30 s and none 12.5 MB in 0.08 s
    kw = {"compression": "gzip", "compression_opts": 1, "shuffle": True} if a.size else {}
    if a.dtype.kind == "f":
        kw["fillvalue"] = a.dtype.type(np.nan)
    return grp.create_variable(name, dims, data=a, **kw)


def groups_bytes(groups):
    """Bytes of the groups' arrays (what the file holds, before compression and overhead)."""
    return sum(int(np.asarray(arr).nbytes) for g in groups.values()
               for _, arr in list(g.data_vars.values()) + list(g.coords.values()))
