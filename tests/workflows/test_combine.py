"""Combined results: one theta grid, varied parameters as coordinates, scalars stacked."""
from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from solver import CaseSpec
from workflows import open_case, open_results, run_and_store
from workflows.combine import THETA, for_netcdf, interface_quantities

# the interface quantities of SPEC §3 that are interpolated linearly
INTERPOLATED = ("contact_pressure", "normal_jump", "gap", "thrust", "moment", "shear")

# different lining thicknesses and, for the last case, a different mesh
CASES = [
    {"geometry": {"thickness": 0.25}, "mesh": {"interface_size": 0.25, "far_size": 8.0}},
    {"geometry": {"thickness": 0.35}, "mesh": {"interface_size": 0.25, "far_size": 8.0}},
    {"geometry": {"thickness": 0.35}, "mesh": {"interface_size": 0.3, "far_size": 8.0}},
]


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    root = tmp_path_factory.mktemp("combine")
    ids = [run_and_store(CaseSpec.model_validate(c), root) for c in CASES]
    return root, ids


def test_layout(store):
    root, ids = store
    combined = open_results(root, ids)
    assert combined.sizes["case"] == 3
    assert list(combined["case_id"].values) == ids
    np.testing.assert_array_equal(combined["theta"], np.arange(0.0, 181.0))
    # exactly the parameters that vary become coordinates, under their flat names
    params = {n for n in combined.coords if combined[n].dims == ("case",)} - {"case_id", "case"}
    assert params == {"lining_thickness", "mesh_interface_size"}
    # they identify the cases: a MultiIndex on case selects one case by both
    one = combined.sel(lining_thickness=0.35, mesh_interface_size=0.3)
    assert str(one["case_id"].values) == ids[2] and "case" not in one.dims
    assert combined.sel(lining_thickness=0.35).sizes["mesh_interface_size"] == 2  # pandas drops the level
    # both settlement profiles on one x grid
    assert combined["gaussian_settlement"].dims == ("case", "surface_x") == combined["surface_settlement"].dims
    assert float(combined["gaussian_settlement"].isel(case=0, surface_x=0)) == pytest.approx(
        float(combined["gaussian_max_settlement"].isel(case=0)))
    np.testing.assert_array_equal(combined["lining_thickness"], [0.25, 0.35, 0.35])
    np.testing.assert_array_equal(combined["mesh_interface_size"], [0.25, 0.25, 0.3])
    for name in INTERPOLATED + ("in_contact",):
        assert combined[name].dims == ("case", "theta")
    # every result quantity on the interface is combined; the mesh description is not
    linear, nearest = interface_quantities(open_case(root, ids[0]))
    assert set(INTERPOLATED) <= set(linear) and "in_contact" in nearest
    assert {"ground_node", "lining_node", "weight"}.isdisjoint(combined.data_vars)
    assert all(combined[n].dims == ("case", "theta") for n in linear + nearest)
    assert combined["in_contact"].dtype.kind == "i"
    assert combined["max_thrust"].dims == ("case",)
    assert combined.attrs["Conventions"].startswith("CF-")


def test_values_match_the_case_files(store):
    root, ids = store
    combined = open_results(root, ids)
    for i, case_id in enumerate(ids):
        ds = open_case(root, case_id)
        for name in ("max_contact_pressure", "contact_extent", "crown_settlement", "max_thrust",
                     "max_abs_moment", "lining_weight", "converged"):
            assert combined[name].values[i] == ds[name].values
        theta = ds["theta"].values
        on_grid = np.isclose(theta, np.round(theta), atol=1e-9)
        assert on_grid.sum() >= 2  # crown and invert at least
        linear, nearest = interface_quantities(ds)
        for name in linear + nearest:
            if not np.isfinite(ds[name].values).all():
                continue  # e.g. utilization of plain concrete in tension: inf spreads to neighbours
            scale = np.abs(ds[name].values).max()
            # stations sit on the grid up to rounding of theta (~1e-9 deg)
            at_stations = combined[name].isel(case=i).sel(theta=np.round(theta[on_grid])).values
            np.testing.assert_allclose(at_stations, ds[name].values[on_grid], rtol=0, atol=1e-7 * scale)
            # between stations linear interpolation stays within the neighbouring values
            k = np.searchsorted(theta, THETA, side="right").clip(1, theta.size - 1)
            lo = np.minimum(ds[name].values[k - 1], ds[name].values[k])
            hi = np.maximum(ds[name].values[k - 1], ds[name].values[k])
            values = combined[name].isel(case=i).values
            assert np.all(values >= lo - 1e-12 * scale) and np.all(values <= hi + 1e-12 * scale)
            if name in linear:  # linear between the two neighbouring stations
                v = ds[name].values
                w = (THETA - theta[k - 1]) / (theta[k] - theta[k - 1])
                np.testing.assert_allclose(values, v[k - 1] + w * (v[k] - v[k - 1]),
                                           rtol=0, atol=1e-9 * scale)


def test_meshes_differ_but_combine(store):
    root, ids = store
    sizes = {open_case(root, c).sizes["interface"] for c in ids}
    assert len(sizes) == 2


def test_all_cases_by_default_and_netcdf_round_trip(store, tmp_path):
    root, ids = store
    combined = open_results(root)
    assert sorted(combined["case_id"].values) == sorted(ids)
    for_netcdf(combined).to_netcdf(tmp_path / "combined.nc", engine="netcdf4")
    with xr.open_dataset(tmp_path / "combined.nc", engine="netcdf4") as back:
        xr.testing.assert_allclose(back.load(), for_netcdf(combined))


def test_subset_and_errors(store, tmp_path):
    root, ids = store
    one = open_results(root, [ids[1], ids[1]])
    assert list(one["case_id"].values) == [ids[1]]
    with pytest.raises(FileNotFoundError):
        open_results(root, [ids[0], "0123456789abcdef"])
    with pytest.raises(ValueError):
        open_results(root, ["../secret"])
    with pytest.raises(ValueError, match="no cases"):
        open_results(tmp_path)
