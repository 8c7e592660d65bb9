"""Combine stored cases into one Dataset along ``case`` (SPEC §3, combined results).

Cases may have different meshes: interface quantities are interpolated onto one
``theta`` grid (0 to 180 by 1 degree) and the meshes stay in the per-case files.
Files are read one after the other (netCDF4/HDF5 is not safe to read in parallel
threads here).
"""
from __future__ import annotations

import logging
import os
from collections.abc import Sequence

import numpy as np
import xarray as xr

from .parameters import flat_parameters, varying_parameters
from .store import OPEN_OPTIONS, case_path, check_case_id, stored_case_ids

logger = logging.getLogger(__name__)

#: The common interface grid (deg).
THETA = np.arange(0.0, 181.0, 1.0)
#: Interface quantities interpolated linearly in theta.
INTERPOLATED = ("contact_pressure", "normal_jump", "gap", "thrust", "moment", "shear")
#: Interface flags taken from the nearest station (they stay 0/1).
NEAREST = ("in_contact",)


def open_results(root: str | os.PathLike, case_ids: Sequence[str] | None = None) -> xr.Dataset:
    """Stack stored cases into one Dataset with dimension ``case``.

    Parameters
    ----------
    root : folder of the result store.
    case_ids : cases to combine, in this order (duplicates dropped); default: every
        stored case, sorted by id.

    Returns
    -------
    xr.Dataset
        Dimension ``case`` with coordinate ``case_id``; every case parameter whose
        value differs between the cases as a coordinate along ``case`` named
        ``<section>_<field>`` (``ground_young`` for ``ground.young``, ``geometry_gap``
        for ``geometry.gap``; the one exception is ``geometry.thickness``, named
        ``lining_thickness``, see :mod:`workflows.parameters`); the interface
        quantities ``contact_pressure``, ``normal_jump``, ``gap``, ``thrust``,
        ``moment``, ``shear`` (linear interpolation) and ``in_contact`` (nearest
        station) on ``(case, theta)`` with ``theta`` = 0, 1, ..., 180 deg; every 0-d
        scalar of the cases on ``case``; and ``case_spec`` (canonical JSON) on ``case``.

    Raises
    ------
    FileNotFoundError
        If a requested case is not stored.
    ValueError
        If a case id is malformed or no case is given.
    """
    ids = list(dict.fromkeys(check_case_id(c) for c in case_ids)) if case_ids is not None \
        else stored_case_ids(root)
    if not ids:
        raise ValueError(f"no cases to combine in {root}")
    parts = [_on_common_grid(root, c) for c in ids]
    combined = xr.concat(parts, dim="case", coords="minimal", compat="override",
                         combine_attrs="drop_conflicts", join="exact")
    flat = [flat_parameters(p.attrs["case_spec"]) for p in parts]
    for name in varying_parameters(flat):
        values = [f[name] for f in flat]
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            values = [str(v) for v in values]
        combined = combined.assign_coords({name: ("case", np.asarray(values))})
        combined[name].attrs["long_name"] = f"case parameter {name}"
    combined = combined.assign_coords(case_id=("case", np.asarray(ids)))
    combined["case_id"].attrs["long_name"] = "case id (hash of the canonical case JSON)"
    combined["case_spec"] = ("case", np.asarray([p.attrs["case_spec"] for p in parts]),
                             {"long_name": "canonical case JSON"})
    combined.attrs = {
        "Conventions": "CF-1.10",
        "title": "tunnel-contact combined results",
        "software_version": parts[0].attrs.get("software_version", ""),
        "history": f"combined from {len(ids)} cases by workflows.open_results",
    }
    logger.info("combined %d cases (%d varying parameters)", len(ids), len(combined.coords) - 2)
    return combined


def _on_common_grid(root: str | os.PathLike, case_id: str) -> xr.Dataset:
    """One case's interface quantities on :data:`THETA` and its scalars, in memory."""
    with xr.open_dataset(case_path(root, case_id), **OPEN_OPTIONS) as ds:
        theta = ds["theta"].values
        out = xr.Dataset(coords={"theta": ("theta", THETA, dict(ds["theta"].attrs))})
        for name in INTERPOLATED:
            out[name] = ("theta", np.interp(THETA, theta, ds[name].values), dict(ds[name].attrs))
        nearest = np.abs(THETA[:, None] - theta[None, :]).argmin(axis=1)
        for name in NEAREST:
            out[name] = ("theta", ds[name].values[nearest], dict(ds[name].attrs))
        for name, var in ds.data_vars.items():
            if var.ndim == 0 and name != "mesh":
                out[name] = ((), var.values, dict(var.attrs))
        out.attrs = dict(ds.attrs)
    return out
