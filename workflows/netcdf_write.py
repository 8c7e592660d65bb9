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

#: the per-variable encoding keys this writer passes on to ``createVariable``
KNOWN_ENCODING = {"_FillValue", "zlib", "complevel", "shuffle", "dtype"}


def _encoded(ds: xr.Dataset, encoding: dict[str, dict[str, Any]]):
    """The variables and global attributes as ``to_netcdf`` would store them, or None where this
    writer does not apply."""
    variables, attrs = conventions.encode_dataset_coordinates(ds)
    out = {}
    for name, var in variables.items():
        var = var.copy(deep=False)
        var.encoding = {**var.encoding, **encoding.get(str(name), {})}
        enc = conventions.encode_cf_variable(var, name=name)
        if enc.dtype.kind not in "biuf" or not set(enc.encoding) <= KNOWN_ENCODING | {"source", "original_shape"}:
            return None
        out[str(name)] = enc
    return out, attrs


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
            var[...] = data


def _set_attribute(target, key: str, value) -> None:
    """An attribute as xarray's netCDF4 backend stores it (a list of strings as NC_STRING)."""
    arr = np.asarray(value)
    if arr.dtype.kind in "US" and arr.size > 1:
        target.setncattr_string(key, value)
    else:
        target.setncattr(key, value)
