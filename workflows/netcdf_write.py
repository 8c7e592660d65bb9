"""A case's result written to netCDF-4 in one pass: the file xarray's ``to_netcdf`` writes, faster.

xarray's netCDF4 backend writes one variable at a time: it defines the variable, writes its data
(the library leaves define mode and writes the metadata at each switch), and routes every write
through netCDF4-python's masking and scaling. For the ~90 small variables of a case that was
about 3.6 ms a variable and most of what a case costs a worker on a built model (issue 38,
item 13). Here xarray's own CF encoder (``xarray.conventions``) encodes the variables and
attributes exactly as ``to_netcdf`` would, then every dimension and variable is defined first
and the data written after, unmasked (the encoder has already applied every fill value), with
prefill off (every value is written). The file reads back identical to xarray's
(``tests/workflows/test_netcdf_write.py`` compares both writers on cases of every kind).

A data set this writer was not made for (strings, unlimited dimensions, groups, an encoding key
beyond :func:`workflows.store_files.netcdf_encoding`'s) goes through ``to_netcdf`` unchanged.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import netCDF4
import numpy as np
import xarray as xr
from xarray import conventions

#: encodings by which a variable names coordinates (CF's related data: xarray's rules for those)
CF_RELATED = frozenset(conventions.CF_RELATED_DATA)
#: the per-variable encoding keys this writer passes on to ``createVariable``
KNOWN_ENCODING = {"_FillValue", "zlib", "complevel", "shuffle", "dtype"}
#: attributes one of xarray's CF coders reads or writes: a variable with none of them, a numeric
#: dtype and no fill value is stored as it is (:func:`_plain`)
CODER_ATTRIBUTES = frozenset({"_FillValue", "missing_value", "scale_factor", "add_offset", "units", "calendar",
                              "dtype", "_Unsigned", "_Encoding", "coordinates"}) | CF_RELATED


def _coordinates(ds: xr.Dataset):
    """The ``coordinates`` attribute of each variable that gets one and the global attributes, as
    ``xarray.conventions.encode_dataset_coordinates`` gives them (a variable lists the non-dimension
    coordinates whose dimensions it has; the others go to the global attribute), without its
    search of every coordinate against every variable's encoding; None where a variable's own
    attributes or encoding speak of coordinates or CF's related data (xarray's rules then)."""
    coords = {name for name in ds.coords if name not in ds.dims}
    variables = ds.variables
    if "coordinates" in ds.attrs or any(not isinstance(c, str) or " " in c for c in coords) or any(
            "coordinates" in v.attrs or "coordinates" in v.encoding
            or not CF_RELATED.isdisjoint(v.encoding) for v in variables.values()):
        return None
    dims_of = {c: set(variables[c].dims) for c in coords}
    lists, written = {}, set()
    for name, var in variables.items():
        if name in coords or name in var.dims:
            continue
        names = sorted(c for c in coords if dims_of[c] <= set(var.dims))
        if names:
            lists[str(name)] = " ".join(names)
            written.update(names)
    attrs = dict(ds.attrs)
    if coords - written:
        attrs["coordinates"] = " ".join(sorted(coords - written))
    return lists, attrs


def _encoded(ds: xr.Dataset, encoding: dict[str, dict[str, Any]]):
    """The variables and global attributes as ``to_netcdf`` would store them, or None where this
    writer does not apply."""
    found = _coordinates(ds)
    if found is None:
        variables, attrs = conventions.encode_dataset_coordinates(ds)
        lists = {}
    else:
        (lists, attrs), variables = found, ds.variables
    out = {}
    for name, var in variables.items():
        var = var.copy(deep=False)
        if str(name) in lists:
            var.attrs["coordinates"] = lists[str(name)]
        if str(name) in encoding:  # as to_netcdf: the given encoding replaces the variable's own
            var.encoding = dict(encoding[str(name)])
        enc = var if _plain(var) else conventions.encode_cf_variable(var, name=name)
        if enc.dtype.kind not in "biuf" or not set(enc.encoding) <= KNOWN_ENCODING | {"source", "original_shape"}:
            return None
        out[str(name)] = enc
    return out, attrs


def _plain(var: xr.Variable) -> bool:
    """Whether xarray's CF encoder would leave ``var`` as it is: in-memory integers or floats
    (not booleans, times or strings) with no fill value (encoded ``_FillValue`` None), no
    attribute any coder reads (:data:`CODER_ATTRIBUTES`; ``units`` only as a time coder's) and
    only storage keys in its encoding. Most of a case's variables; the encoder's chain of nine
    coders costs about 0.1 ms a variable for nothing there."""
    e = var.encoding
    return (var.dtype.kind in "iuf" and isinstance(var.data, np.ndarray) and "_FillValue" in e
            and e["_FillValue"] is None and set(e) <= {"_FillValue", "zlib", "complevel", "shuffle"}
            and (CODER_ATTRIBUTES.isdisjoint(var.attrs) or _plain_units(var.attrs)))


def _plain_units(attrs) -> bool:
    """Attributes that meet :data:`CODER_ATTRIBUTES` only in ``units`` naming no time."""
    return set(attrs) & CODER_ATTRIBUTES == {"units"} and " since " not in str(attrs["units"])


def write_netcdf(ds: xr.Dataset, path: str | Path, encoding: dict[str, dict[str, Any]]) -> None:
    """Write ``ds`` (in memory) to a new netCDF-4 file ``path`` with the per-variable
    ``encoding`` (as for ``to_netcdf``); see the module's text."""
    encoded = _encoded(ds, encoding)
    if encoded is None:
        ds.to_netcdf(path, engine="netcdf4", format="NETCDF4", encoding=encoding)
        return
    variables, attrs = encoded
    with netCDF4.Dataset(path, "w", format="NETCDF4") as nc:
        nc.set_fill_off()
        for key, value in attrs.items():
            _set_attribute(nc, key, value)
        for dim, size in ds.sizes.items():
            nc.createDimension(str(dim), size)
        pending = []
        for name, enc in variables.items():  # every definition first: one switch to data mode
            e, var_attrs = enc.encoding, dict(enc.attrs)
            fill = e.get("_FillValue", var_attrs.pop("_FillValue", None))
            var = nc.createVariable(name, enc.dtype, enc.dims, fill_value=False if fill is None else fill,
                                    zlib=bool(e.get("zlib", False)), complevel=e.get("complevel", 4),
                                    shuffle=bool(e.get("shuffle", True)))
            for key, value in var_attrs.items():
                _set_attribute(var, key, value)
            var.set_auto_maskandscale(False)
            pending.append((var, enc.values))
        for var, data in pending:
            _put_whole(var, data)


def _put_whole(var: netCDF4.Variable, data: np.ndarray) -> None:
    """All of a variable's values in one ``nc_put_vara`` call: netCDF4-python's ``_put`` with the
    whole extent, without ``__setitem__``'s parsing of the index into start, count and stride (a
    fifth of the write of a coarse case's ~90 variables), a scalar's included."""
    data = np.ascontiguousarray(data, dtype=var.dtype)
    if data.ndim == 0:  # a scalar: one value at no index
        data = data.reshape(1)
    var._put(data, np.zeros(var.ndim, np.intp), np.asarray(var.shape, np.intp), np.ones(var.ndim, np.intp))


def _set_attribute(target, key: str, value) -> None:
    """An attribute as xarray's netCDF4 backend stores it (a list of strings as NC_STRING)."""
    arr = np.asarray(value)
    if arr.dtype.kind in "US" and arr.size > 1:
        target.setncattr_string(key, value)
    else:
        target.setncattr(key, value)
