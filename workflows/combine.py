"""Combine stored cases into one Dataset along ``case`` (SPEC §3, combined results).

Cases may have different meshes: each case is reduced (:func:`reduce_case`) to its
0-d scalars and its interface quantities on one ``theta`` grid (0 to 180 by 1
degree); the meshes stay in the per-case files. The reduced cases are stacked
(:func:`stack_cases`) and labelled (:func:`label_cases`). :func:`workflows.open_results`
(:func:`workflows.result_store.open_results`) answers from the store's index
(:mod:`workflows.index`), which keeps the reduced cases; :func:`combine_files` reads every case file instead and is what the index
must reproduce exactly.

Segmental linings (SPEC §1.6): the per-joint variables (dim ``joint``: ``joint_theta``,
``joint_thrust``, ...) are not combined, as the meshes are not: cases with different numbers
of segments or offsets have joints at different angles, so a joint's index names nothing common
to the cases (padding them on one ``joint`` dim would line up unrelated joints). What compares
across cases are the joint scalars, ``max_joint_opening``, ``max_joint_rotation`` and
``max_joint_eccentricity`` (0 for a monolithic lining), which stack with the other scalars, and
the interface quantities on the θ grid, where a segmental lining's ``utilization`` is NaN near
its joints (:func:`on_theta_grid`); each case's joints stay in its file.
"""
from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np
import xarray as xr

from solver.spec import is_number

from .parameters import flat_parameters, parameter_attrs, varying_parameters
from .store_files import FilesLike, StoreFiles, check_case_id, data_variables, files_of

logger = logging.getLogger(__name__)

#: The common interface grid (deg).
THETA = np.arange(0.0, 181.0, 1.0)
#: The common ground-surface grid (m from the tunnel axis): both settlement profiles of every
#: case are combined on it (NaN beyond a case's model width).
SURFACE_X = np.arange(0.0, 200.25, 0.5)
#: Variables on ``surface`` combined on :data:`SURFACE_X`.
SURFACE_VARIABLES = ("surface_settlement", "gaussian_settlement", "design_settlement")
#: Variables on ``interface`` that describe a case's mesh, not its results: not combined.
MESH_VARIABLES = frozenset({"normal_x", "normal_y", "weight", "ground_node", "lining_node"})
#: Dataset attributes a reduced case keeps.
CASE_ATTRS = ("case_id", "case_spec", "software_version")


def interface_quantities(ds: xr.Dataset) -> tuple[list[str], list[str]]:
    """Names of the interface quantities of a result: ``(interpolated, nearest)``.

    Every data variable on dim ``interface`` alone, except :data:`MESH_VARIABLES`:
    floating-point ones are interpolated linearly in theta; integer ones (flags such
    as ``in_contact``) take the value of the nearest station, so they stay 0/1.
    """
    names = [n for n, v in data_variables(ds)
             if v.dims == ("interface",) and n not in MESH_VARIABLES]
    nearest = [n for n in names if ds.variables[n].dtype.kind in "biu"]
    return [n for n in names if n not in nearest], nearest


def on_theta_grid(theta: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``values`` at the stations ``theta`` (deg) interpolated linearly onto :data:`THETA`.

    A NaN station is a value that does not apply there (a segmental lining's ``utilization`` at
    a joint, where the section is the joint's contact strip): the grid points nearest to it are
    NaN, and the others interpolate between the stations that have values, so a NaN spreads
    over no more than the station spacing whatever the mesh.
    """
    missing = np.isnan(values)
    if not missing.any():
        return np.interp(THETA, theta, values)
    out = np.interp(THETA, theta[~missing], values[~missing]) if not missing.all() else np.full(THETA.size, np.nan)
    out[missing[_nearest_station(theta)]] = np.nan
    return out


def _nearest_station(theta: np.ndarray) -> np.ndarray:
    """Index of the station of ``theta`` nearest each point of :data:`THETA`."""
    return np.abs(THETA[:, None] - theta[None, :]).argmin(axis=1)


def reduce_case(ds: xr.Dataset) -> xr.Dataset:
    """One case's interface quantities on :data:`THETA` and its 0-d scalars, in memory (a
    segmental lining's ``joint`` variables are left out: see the module docstring)."""
    var = ds.variables  # Variables, not DataArrays: building those costs more than the arithmetic
    theta = var["theta"].values
    interpolated, nearest = interface_quantities(ds)
    data = {name: ("theta", on_theta_grid(theta, var[name].values), dict(var[name].attrs))
            for name in interpolated}
    if nearest:
        station = _nearest_station(theta)
        data.update({name: ("theta", var[name].values[station], dict(var[name].attrs)) for name in nearest})
    data.update({name: ((), v.values, dict(v.attrs)) for name, v in data_variables(ds)
                 if v.ndim == 0 and name != "mesh"})
    coords = {"theta": ("theta", THETA, dict(var["theta"].attrs))}
    if "surface_x" in var:
        x = var["surface_x"].values
        for name in SURFACE_VARIABLES:
            if name in var:
                data[name] = ("surface_x", np.interp(SURFACE_X, x, var[name].values, right=np.nan),
                              dict(var[name].attrs))
        coords["surface_x"] = ("surface_x", SURFACE_X, dict(var["surface_x"].attrs))
    return xr.Dataset(data, coords=coords,
                      attrs={k: ds.attrs[k] for k in CASE_ATTRS if k in ds.attrs})


def stack_cases(parts: Sequence[xr.Dataset]) -> xr.Dataset:
    """Reduced cases (or blocks of them already along ``case``) stacked along ``case``.

    Variables missing from some parts are filled with NaN; attributes that differ
    between parts are dropped.
    """
    return xr.concat(list(parts), dim="case", coords="minimal", compat="override",
                     combine_attrs="drop_conflicts", join="exact")


def label_cases(stacked: xr.Dataset, case_ids: Sequence[str], specs: Sequence[str],
                software_version: str) -> xr.Dataset:
    """Stacked cases with their ids, varied parameters, specs and the global attributes.

    ``specs`` are the canonical case JSONs in the order of ``case_ids``.
    """
    flat = [flat_parameters(s) for s in specs]
    combined = stacked
    for name in varying_parameters(flat):
        values = [f[name] for f in flat]
        numeric = all(map(is_number, values))
        if not numeric:
            values = [str(v) for v in values]
        attrs = parameter_attrs(name, numeric=numeric)
        combined = combined.assign_coords({name: ("case", np.asarray(values), attrs)})
    combined = combined.assign_coords(case_id=("case", np.asarray(list(case_ids))))
    varied = varying_parameters(flat)
    if varied and len({tuple(f[name] for name in varied) for f in flat}) == len(flat):
        # the varied parameters identify the cases: select by them, ds.sel(a=..., b=...)
        combined = combined.set_xindex(varied)
    combined["case_id"].attrs["long_name"] = "case id (hash of the canonical case JSON)"
    combined["case_spec"] = ("case", np.asarray(list(specs)), {"long_name": "canonical case JSON"})
    combined.attrs = {
        "Conventions": "CF-1.10",
        "title": "tunnel-contact combined results",
        "software_version": software_version,
        "history": f"combined from {len(case_ids)} cases by workflows.open_results",
    }
    logger.info("combined %d cases (%d varying parameters)", len(case_ids), len(combined.coords) - 2)
    return combined


def requested_ids(store: StoreFiles, case_ids: Sequence[str] | None) -> list[str]:
    """The case ids to combine: checked and without duplicates, or every stored case, sorted."""
    ids = list(dict.fromkeys(check_case_id(c) for c in case_ids)) if case_ids is not None \
        else store.case_ids()
    if not ids:
        raise ValueError(f"no cases to combine in {store.root}")
    return ids


def read_reduced(store: StoreFiles, case_id: str) -> xr.Dataset:
    """:func:`reduce_case` of a stored case file."""
    with store.opened(case_id) as ds:
        return reduce_case(ds)


def combine_files(root: FilesLike, case_ids: Sequence[str] | None = None) -> xr.Dataset:
    """:func:`workflows.open_results` computed from the case files alone (no index); about 30 ms a case."""
    store = files_of(root)
    ids = requested_ids(store, case_ids)
    parts = [read_reduced(store, c) for c in ids]
    return label_cases(stack_cases(parts), ids, [p.attrs["case_spec"] for p in parts],
                       parts[0].attrs.get("software_version", ""))


def for_netcdf(combined: xr.Dataset) -> xr.Dataset:
    """Combined results as netCDF can hold them: the ``case`` MultiIndex (a pandas object)
    dropped, its levels kept as plain coordinates along ``case``."""
    return combined.reset_index("case") if "case" in combined.indexes else combined
