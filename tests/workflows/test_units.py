"""Units of the case parameters (one table, :data:`workflows.parameters.PARAMETER_ATTRS`) and
of the result scalars (the result's attributes) wherever they are shown: combined results
(files and index alike), the comparison tables and the ``run`` / ``show`` output."""
from __future__ import annotations

import io
import json
import typing

from pydantic import BaseModel

import pytest
import xarray as xr

import solver
from solver import CaseSpec
from solver.spec import Layer
from workflows import ResultStore, open_results
from workflows.combine import combine_files
from workflows.commands import comparison_table as cli_table
from workflows.commands import run_command, show_command
from workflows.parameters import LAYER_ATTRS, PARAMETER_ATTRS, flat_name, parameter_attrs, parameter_paths
from workflows.units import display_unit

COARSE = {"mesh": {"interface_size": 0.25, "far_size": 8.0}}


def _is_numeric(annotation) -> bool:
    return annotation in (int, float) or any(a in (int, float) for a in typing.get_args(annotation))


def _fields(model=CaseSpec, prefix=""):
    """Every leaf field of the case model (nested sections such as lining.joints walked into;
    a layer's fields are reached by index and described in LAYER_ATTRS)."""
    for name, info in model.model_fields.items():
        kind = info.annotation
        if isinstance(kind, type) and issubclass(kind, BaseModel):
            yield from _fields(kind, f"{prefix}{name}.")
        elif f"{prefix}{name}" not in ("ground.layers", "name"):  # a case's name is no input (SPEC §9.3)
            yield f"{prefix}{name}", kind


def test_every_layer_field_is_described():
    assert set(LAYER_ATTRS) == set(Layer.model_fields)
    assert parameter_attrs("ground.layers.1.young") == {"units": "Pa", "long_name": "layer Young's modulus (layer 1)"}
    assert parameter_attrs("ground_layers_0_thickness")["units"] == "m"


def test_every_case_parameter_is_described_and_every_numeric_one_has_a_unit():
    assert set(PARAMETER_ATTRS) == set(parameter_paths())
    numeric = [path for path, annotation in _fields() if _is_numeric(annotation)]
    assert "solver.bolt" in numeric and "geometry.gap" in numeric and "solver.max_iterations" in numeric
    for path in numeric:
        units, long_name = PARAMETER_ATTRS[path]
        assert units, f"{path} has no unit"
        assert long_name and not long_name.startswith("case parameter")
    for path, annotation in _fields():
        if not _is_numeric(annotation):
            assert PARAMETER_ATTRS[path][0] is None, f"{path} is a choice, it has no unit"


@pytest.mark.parametrize("name, units", [
    ("geometry_gap", "m"), ("lining_thickness", "m"), ("geometry.thickness", "m"), ("lining.thickness", "m"),
    ("ground_young", "Pa"), ("lining_density", "kg m-3"), ("ground_poisson", "1"), ("loads_gravity", "m s-2"),
    ("solver_bolt", "degree"), ("design_reinforcement_area", "m2 m-1"), ("loads_lateral_ratio", "1"),
])
def test_parameter_attrs_by_flat_name_or_path(name, units):
    attrs = parameter_attrs(name)
    assert attrs["units"] == units and attrs["long_name"]
    assert "units" not in parameter_attrs(name, numeric=False)  # values stored as text


def clone(ds: xr.Dataset, change: dict) -> xr.Dataset:
    """A copy of ``ds`` posing as the case with the spec fields ``change`` (values kept)."""
    data = CaseSpec.model_validate_json(ds.attrs["case_spec"]).model_dump(mode="json")
    for section, fields in change.items():
        data[section].update(fields)
    spec = CaseSpec.model_validate(data)
    out = ds.copy(deep=True)
    out.attrs.update(case_id=spec.case_id, case_spec=spec.canonical_json())
    return out


@pytest.fixture(scope="module")
def solved() -> xr.Dataset:
    return solver.run_case(CaseSpec.model_validate(COARSE))


@pytest.fixture
def store(tmp_path, solved) -> tuple[ResultStore, list[str]]:
    store = ResultStore(tmp_path / "results")
    changes = [{"geometry": {"gap": 0.0, "thickness": 0.25}},
               {"geometry": {"gap": 0.01, "thickness": 0.35}, "interface": {"model": "coulomb", "friction": 0.3}}]
    ids = []
    for change in changes:
        ds = clone(solved, change)
        store.write_case(ds)
        ids.append(ds.attrs["case_id"])
    return store, ids


def test_combined_parameter_coordinates_have_units_from_files_and_index(store):
    store, ids = store
    from_files = combine_files(store, ids)
    for combined in (open_results(store, ids), open_results(store, ids)):  # index built, then read
        xr.testing.assert_identical(combined, from_files)
    assert from_files["geometry_gap"].attrs == {"units": "m", "long_name": PARAMETER_ATTRS["geometry.gap"][1]}
    assert from_files["lining_thickness"].attrs["units"] == PARAMETER_ATTRS["geometry.thickness"][0] == "m"
    assert from_files["interface_friction"].attrs["units"] == "1"
    assert "units" not in from_files["interface_model"].attrs  # text values
    for name in ("geometry_gap", "lining_thickness", "interface_friction", "interface_model"):
        assert from_files[name].dims == ("case",)
        assert from_files[name].attrs["long_name"] == parameter_attrs(name)["long_name"]


def test_service_table_gives_the_parameter_units(tmp_path):
    from service.comparison import comparison_table
    from service.job_records import JobStore

    jobs = JobStore(tmp_path / "jobs.sqlite")
    cases = [CaseSpec.model_validate({"ground": {"young": e}, "geometry": {"gap": g}})
             for e, g in ((2e7, 0.0), (5e7, 0.01))]
    record, _ = jobs.add_sweep("0123456789abcdef", "t", "{}", [(c.case_id, c.canonical_json()) for c in cases])
    columns = {c.name: c for c in comparison_table(jobs, record).columns}
    assert (columns["ground_young"].units, columns["geometry_gap"].units) == ("Pa", "m")
    assert columns["ground_young"].long_name == PARAMETER_ATTRS["ground.young"][1]
    assert columns["max_contact_pressure"].units == "Pa"


def test_cli_table_gives_the_parameter_units():
    rows = [{"case_id": f"{i:016x}", "status": "failed", "error": None, "summary": {},
             "params": {flat_name("geometry.thickness"): t, "ground_young": e}}
            for i, (t, e) in enumerate(((0.25, 2e7), (0.35, 5e7)))]
    header, units = cli_table(rows).splitlines()[:2]
    names, labels = header.split(), units.split()
    assert names[1:3] == ["lining_thickness", "ground_young"] and labels[:2] == ["m", "MPa"]
    assert "20" in cli_table(rows).splitlines()[3].split()  # 2e7 Pa shown as 20 MPa


def parse(text: str) -> dict[str, tuple[float, str]]:
    """``{name: (value, unit)}`` of the ``name = value [unit]`` lines of a report."""
    found = {}
    for line in text.splitlines():
        name, sep, rest = line.partition(" = ")
        name = name.strip()  # names are padded to align the values
        if sep and " " not in name:
            value, _, unit = rest.partition(" ")
            found[name] = (value, unit)
    return found


def test_run_and_show_print_each_scalar_with_its_unit(tmp_path):
    (tmp_path / "case.json").write_text(json.dumps({**COARSE, "geometry": {"gap": 0.005}}))
    results = str(tmp_path / "results")
    out = io.StringIO()
    assert run_command(str(tmp_path / "case.json"), results, out=out) == 0
    case_id = CaseSpec.model_validate({**COARSE, "geometry": {"gap": 0.005}}).case_id
    ds = ResultStore(results).open_case(case_id)
    ran = parse(out.getvalue())
    # results in the engineering units of the sweep table and the pages, the same in run and show
    assert ran["max_contact_pressure"][1] == "kPa" and ran["crown_settlement"][1] == "mm"
    assert ran["max_thrust"][1] == "kN/m" and ran["max_abs_moment"][1] == "kN·m/m"
    assert ran["ground_loss"][1] == "%" and ran["contact_extent"][1] == "°"
    assert ran["converged"][1] == ""  # dimensionless: no unit
    for name, (value, unit) in ran.items():
        expected, factor = display_unit(ds[name].attrs["units"], name)
        assert unit == expected
        assert float(value) == pytest.approx(float(ds[name]) * factor, rel=1e-5, nan_ok=True)
    assert out.getvalue().index("solver:") > out.getvalue().index("max_utilization")  # diagnostics apart

    out = io.StringIO()
    assert show_command(case_id, results, out=out) == 0
    shown = parse(out.getvalue())
    line = next(l for l in out.getvalue().splitlines() if l.strip().startswith("max_contact_pressure"))
    assert line.endswith(" kPa")
    assert {k: shown[k] for k in ran} == ran
    # inputs in the engineering units of the tables and the form (issue 39: no Pa beside kPa)
    assert shown["geometry_gap"] == ("5", "mm") and shown["ground_young"] == ("50", "MPa")
    assert shown["interface_model"] == ("frictionless", "")
