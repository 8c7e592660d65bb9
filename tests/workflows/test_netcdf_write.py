"""The one-pass netCDF writer (workflows.netcdf_write) writes the file xarray's ``to_netcdf`` writes.

Compared on cases of every kind of result (elastic, yielding with stage-1 zones, Hoek–Brown,
segmental joints, layered water-bearing drained ground, an elliptical section): the data sets read
back identical (values, dtypes, attributes, coordinates), with the same storage (compression,
chunking) per variable, and the stored case verifies from its content digest.
"""
from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

import solver
from solver import CaseSpec
from workflows.netcdf_write import write_netcdf
from workflows.result_store import ResultStore
from workflows.store_files import netcdf_encoding

MESH = {"mesh": {"interface_size": 0.5, "far_size": 16.0}}
CASES = {
    "elastic": {},
    "mohr-coulomb": {"ground": {"model": "mohr-coulomb", "cohesion": 3.0e4, "friction_angle": 28.0},
                     "solver": {"load_steps": 2}},
    "hoek-brown": {"ground": {"model": "hoek-brown", "young": 5.0e8, "ucs": 5.0e6, "gsi": 40.0, "mi": 10.0},
                   "solver": {"load_steps": 2}},
    "joints": {"lining": {"joints": {"count": 6}}},
    "drained-layers": {"ground": {"layers": [{"thickness": 6.0, "young": 2.0e7},
                                             {"thickness": 0.0, "young": 1.2e8}]},
                       "water": {"table": 3.0, "lining": "drained"}},
    "ellipse": {"geometry": {"section": {"shape": "ellipse", "width": 6.4, "height": 5.2}}},
}
STORAGE = ("dtype", "zlib", "shuffle", "complevel", "contiguous", "chunksizes")


@pytest.fixture(scope="module", params=list(CASES))
def result(request) -> xr.Dataset:
    return solver.run_case(CaseSpec.model_validate({**MESH, **CASES[request.param]}))


def test_the_file_reads_back_as_xarrays_own(result, tmp_path):
    enc = netcdf_encoding(result)
    result.to_netcdf(tmp_path / "xarray.nc", engine="netcdf4", format="NETCDF4", encoding=enc)
    write_netcdf(result, tmp_path / "one-pass.nc", enc)
    theirs, ours = xr.load_dataset(tmp_path / "xarray.nc"), xr.load_dataset(tmp_path / "one-pass.nc")
    xr.testing.assert_identical(ours, theirs)
    xr.testing.assert_identical(ours, result)
    assert list(ours.variables) == list(theirs.variables)
    for name in theirs.variables:
        assert ours[name].dtype == theirs[name].dtype, name
        assert {k: ours[name].encoding.get(k) for k in STORAGE} == {k: theirs[name].encoding.get(k)
                                                                  for k in STORAGE}, name


def test_a_stored_case_verifies_and_its_values_are_exact(result, tmp_path):
    store = ResultStore(tmp_path)
    path = store.write_case(result)
    back = store.open_case(result.attrs["case_id"])
    for name, var in result.data_vars.items():
        assert np.array_equal(back[name].values, var.values, equal_nan=var.dtype.kind == "f"), name
    assert path.exists()


def test_fields_of_zeros_are_deflated_and_the_others_are_not(result, tmp_path):
    """A float field that is zero throughout (a dry ground's pore pressure, an elastic ground's
    plastic strain) is stored deflated, the other float fields as they are (deflating them cost more
    than it saved); the values come back exact."""
    path = ResultStore(tmp_path).write_case(result)
    back = xr.open_dataset(path)
    try:
        checked = [name for name, var in result.variables.items() if var.dtype.kind == "f" and var.size > 1000]
        for name in checked:
            assert back[name].encoding.get("zlib", False) == (not np.any(result[name].values)), name
        assert {"pore_pressure", "stress_xx", "displacement_x"} <= set(checked)  # the fields are large enough
    finally:
        back.close()


def test_what_it_was_not_made_for_goes_through_xarray(tmp_path):
    ds = xr.Dataset({"label": ("n", np.array(["a", "bc"], dtype=object)), "x": ("n", [1.0, 2.0])},
                    attrs={"names": ["p", "q"]})
    write_netcdf(ds, tmp_path / "strings.nc", netcdf_encoding(ds))
    xr.testing.assert_identical(xr.load_dataset(tmp_path / "strings.nc"), ds)


def _small(kind: str) -> xr.Dataset:
    ds = xr.Dataset({"u": (("n", "m"), np.arange(6.0).reshape(2, 3)), "v": ("m", [1.0, 2.0, 3.0])},
                    coords={"x": ("n", [0.5, 1.5]), "y": ("m", [1, 2, 3]), "lone": ("k", [7.0, 8.0])})
    if kind == "own-attribute":
        ds["v"].attrs["coordinates"] = "y"
    if kind == "bounds":
        ds["x"].encoding["bounds"] = "y"
    return ds


@pytest.mark.parametrize("kind", ["plain", "own-attribute", "bounds"])
def test_coordinates_are_written_as_xarray_writes_them(kind, tmp_path):
    """A variable lists the non-dimension coordinates whose dimensions it has (u: x and y, v: y); a
    coordinate no variable spans (lone) goes to the global attribute; a variable's own attribute or
    CF's related data take xarray's rules."""
    ds = _small(kind)
    ds.to_netcdf(tmp_path / "xarray.nc", engine="netcdf4", format="NETCDF4", encoding=netcdf_encoding(ds))
    write_netcdf(_small(kind), tmp_path / "one-pass.nc", netcdf_encoding(ds))
    import netCDF4

    with netCDF4.Dataset(tmp_path / "xarray.nc") as a, netCDF4.Dataset(tmp_path / "one-pass.nc") as b:
        assert a.__dict__ == b.__dict__
        for name in a.variables:
            assert a[name].__dict__ == b[name].__dict__, name
    xr.testing.assert_identical(xr.load_dataset(tmp_path / "one-pass.nc"), xr.load_dataset(tmp_path / "xarray.nc"))
