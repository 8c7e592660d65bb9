"""The engineer's tables (SPEC §9.3, issue 39): read back from CSV and XLSX, every value the
dataset's, converted to the unit its units row names."""
from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest
from openpyxl import load_workbook

from solver import CaseSpec, run_case
from workflows.case_tables import case_workbook, forces_table, number_format, table_csv

COARSE = {"mesh": {"interface_size": 0.25, "far_size": 8.0}}
#: The forces table's columns: dataset expression and the factor from SI to the named unit.
UNITS = {"°": 1.0, "m": 1.0, "kN/m": 1e-3, "kN·m/m": 1e-3, "kPa": 1e-3, "mm": 1e3, "1": 1.0}


def expected_columns(ds) -> dict[str, np.ndarray]:
    """SI values of the forces table's columns, straight from the dataset (γF = 1.35)."""
    x, y = ds.interface_x.values, ds.interface_y.values
    return {"theta": ds.theta.values, "arc_length": np.r_[0, np.cumsum(np.hypot(np.diff(x), np.diff(y)))],
            "N": ds.thrust.values, "M": ds.moment.values, "V": ds.shear.values,
            "contact_pressure": ds.contact_pressure.values, "water_pressure": ds.water_pressure.values,
            "N_Ed": ds.design_thrust.values, "M_Ed": 1.35 * ds.moment.values, "V_Ed": 1.35 * ds.shear.values,
            "utilization": ds.utilization.values, "shear_utilization": ds.shear_utilization.values,
            "crack_width": ds.crack_width.values}


@pytest.fixture(scope="module")
def ds():
    return run_case(CaseSpec.model_validate({**COARSE, "name": "Shaft 3 adit", "water": {"table": 5.0}}))


def test_forces_csv_read_back(ds):
    rows = list(csv.reader(io.StringIO(table_csv(forces_table(ds)))))
    names, units, data = rows[0], rows[1], rows[2:]
    assert len(data) == ds.sizes["interface"]
    expected = expected_columns(ds)
    assert set(names) == set(expected)
    assert dict(zip(names, units)) == {
        "theta": "°", "arc_length": "m", "N": "kN/m", "M": "kN·m/m", "V": "kN/m", "contact_pressure": "kPa",
        "water_pressure": "kPa", "N_Ed": "kN/m", "M_Ed": "kN·m/m", "V_Ed": "kN/m", "utilization": "1",
        "shear_utilization": "1", "crack_width": "mm"}
    for k, (name, unit) in enumerate(zip(names, units)):
        got = np.array([float(r[k]) for r in data])
        # the dataset's arc length runs along the extrados's nodes (chords of the true curve), the
        # expected one along the circle: they differ by the chords' sag (1e-4), every other column is exact
        rtol = 3e-4 if name == "arc_length" else 1e-12
        np.testing.assert_allclose(got, expected[name] * UNITS[unit], rtol=rtol, atol=1e-12, err_msg=name)
    assert np.ptp([float(r[names.index("water_pressure")]) for r in data]) > 50  # the wet case: kPa
    # the arc length reaches half the extrados' circumference
    arc = float(data[-1][names.index("arc_length")])
    assert arc == pytest.approx(np.pi * 2.8, rel=1e-4)


def test_workbook_read_back(ds):
    wb = load_workbook(io.BytesIO(case_workbook(ds)))
    assert wb.sheetnames == ["forces", "summary", "inputs"]  # no joints: a monolithic lining
    ws = wb["forces"]
    names = [c.value for c in ws[1]]
    units = [c.value for c in ws[2]]
    expected = expected_columns(ds)
    for k, (name, unit) in enumerate(zip(names, units)):
        got = np.array([ws.cell(row=r, column=k + 1).value for r in range(3, 3 + ds.sizes["interface"])], float)
        # the dataset's arc length runs along the extrados's nodes (chords of the true curve), the
        # expected one along the circle: they differ by the chords' sag (1e-4), every other column is exact
        rtol = 3e-4 if name == "arc_length" else 1e-12
        np.testing.assert_allclose(got, expected[name] * UNITS[unit], rtol=rtol, atol=1e-12, err_msg=name)
    assert ws.auto_filter.ref == f"A2:M{2 + ds.sizes['interface']}" and ws.freeze_panes == "A3"
    assert ws["C3"].number_format == "0"                     # N ≈ 500 kN/m: 3 figures, no decimals
    assert ws.column_dimensions["A"].width >= len("theta")
    summary = {r[0]: r[1:3] for r in wb["summary"].iter_rows(min_row=2, values_only=True)}
    assert summary["max_thrust"] == (pytest.approx(float(ds.max_thrust) / 1e3, rel=1e-12), "kN/m")
    assert summary["max_crack_width"] == (pytest.approx(float(ds.max_crack_width) * 1e3, rel=1e-12), "mm")
    assert summary["volume_loss"][1] == "%"
    inputs = {r[0]: r[1:3] for r in wb["inputs"].iter_rows(min_row=2, values_only=True)}
    assert inputs["name"][0] == "Shaft 3 adit" and inputs["case_id"][0] == ds.attrs["case_id"]
    assert inputs["software_version"][0] == ds.attrs["software_version"] and inputs["exported"][0]
    assert inputs["ground.young"] == (50.0, "MPa") and inputs["loads.surface_load"] == (100.0, "kPa")
    assert inputs["ground.density"] == (pytest.approx(2000 * 9.81 / 1e3), "kN/m³")
    assert inputs["design.reinforcement_area"] == (pytest.approx(1500.0), "mm²/m")
    assert inputs["water.table"] == (5.0, "m") and inputs["design.crack_width_limit"] == (pytest.approx(0.3), "mm")
    spec = json.loads(ds.attrs["case_spec"])
    assert spec["geometry"]["thickness"] == inputs["geometry.thickness"][0]


@pytest.mark.parametrize("value, fmt", [(624.3, "0"), (12.34, "0.0"), (0.7712, "0.000"), (0.0021, "0.00000"),
                                        (-131.2, "0"), (2.5e-7, "0.00E+00"), (3.1e7, "0.00E+00"), (0.0, "0")])
def test_three_significant_figures(value, fmt):
    assert number_format(value) == fmt
