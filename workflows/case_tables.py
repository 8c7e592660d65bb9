"""The tables an engineer copies into a calculation: lining forces per station, joints, summary and
inputs (SPEC §9.3), in one set of engineering units (m, mm, MPa, kPa, kN/m, kN·m/m, kN/m³, °, %)
with a units row, written as CSV (``forces.csv``) and as an Excel workbook (``tables.xlsx``).

Results stay SI in the netCDF (CF); here every number is converted once, by the column's factor.
Characteristic values are the computed forces; design values are those of the ULS checks: N_Ed of
the governing N–M combination (``design_thrust``: γF N, or 1.0 N where the lower thrust governs),
M_Ed = γF M, V_Ed = γF V.
"""
from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass, field
from datetime import datetime, timezone

import numpy as np
import xarray as xr

from solver.results.variables import SCALARS
from solver.spec import CaseSpec

from .case_plots import load_factor
from .parameters import flat_parameters, parameter_attrs, parameter_path
from .units import DIAGNOSTICS, display_unit, parameter_unit

#: Significant figures shown by the workbook's number formats (the cells keep every digit).
FIGURES = 3


@dataclass(frozen=True)
class Table:
    """A titled table: column names, their units (engineering), rows of values in those units."""

    title: str
    names: list[str]
    units: list[str]
    rows: list[list] = field(default_factory=list)


def _column(values, factor: float = 1.0) -> list:
    return [float(v) * factor for v in np.asarray(values, float)]


def arc_length(ds: xr.Dataset) -> np.ndarray:
    """Length (m) along the extrados from the crown to each station: the dataset's ``arc_length``
    where it has one, else the polyline through the interface nodes (P2 nodes: error O(h⁴))."""
    if "arc_length" in ds:
        return np.asarray(ds["arc_length"].values, float)
    x, y = ds["interface_x"].values, ds["interface_y"].values
    return np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])


def forces_table(ds: xr.Dataset) -> Table:
    """Per station: θ, arc length, characteristic N, M, V, contact and water pressure, design
    N_Ed, M_Ed, V_Ed, the utilizations and the crack width."""
    gamma = load_factor(ds)
    n_ed = ds["design_thrust"].values if "design_thrust" in ds else gamma * ds["thrust"].values
    spec = [  # name, unit, values, factor
        ("theta", "°", ds["theta"].values, 1.0),
        ("arc_length", "m", arc_length(ds), 1.0),
        ("N", "kN/m", ds["thrust"].values, 1e-3),
        ("M", "kN·m/m", ds["moment"].values, 1e-3),
        ("V", "kN/m", ds["shear"].values, 1e-3),
        ("contact_pressure", "kPa", ds["contact_pressure"].values, 1e-3),
        ("water_pressure", "kPa", ds["water_pressure"].values, 1e-3),
        ("N_Ed", "kN/m", n_ed, 1e-3),
        ("M_Ed", "kN·m/m", gamma * ds["moment"].values, 1e-3),
        ("V_Ed", "kN/m", gamma * ds["shear"].values, 1e-3),
        ("utilization", "1", ds["utilization"].values, 1.0),
    ]
    if "shear_utilization" in ds:
        spec += [("shear_utilization", "1", ds["shear_utilization"].values, 1.0),
                 ("crack_width", "mm", ds["crack_width"].values, 1e3)]
    columns = [_column(values, factor) for _, _, values, factor in spec]
    return Table("forces", [s[0] for s in spec], [s[1] for s in spec], [list(r) for r in zip(*columns)])


def joints_table(ds: xr.Dataset) -> Table | None:
    """Per joint: θ, N, M, opening, rotation, open, |M|/(N a/2), utilization (None when monolithic)."""
    if "joint_theta" not in ds:
        return None
    spec = [("theta", "°", ds["joint_theta"].values, 1.0), ("N", "kN/m", ds["joint_thrust"].values, 1e-3),
            ("M", "kN·m/m", ds["joint_moment"].values, 1e-3), ("opening", "mm", ds["joint_opening"].values, 1e3),
            ("rotation", "mrad", ds["joint_rotation"].values, 1e3), ("open", "1", ds["joint_open"].values, 1.0),
            ("eccentricity", "1", ds["joint_eccentricity"].values, 1.0),
            ("utilization", "1", ds["joint_utilization"].values, 1.0)]
    columns = [_column(values, factor) for _, _, values, factor in spec]
    return Table("joints", [s[0] for s in spec], [s[1] for s in spec], [list(r) for r in zip(*columns)])


def summary_table(ds: xr.Dataset) -> Table:
    """Every result scalar: name, value in its engineering unit, description."""
    rows = []
    for name, (units, long_name) in SCALARS.items():
        if name in ds and name not in DIAGNOSTICS:
            unit, factor = display_unit(units, name)
            rows.append([name, float(ds[name].values) * factor, unit or "1", long_name])
    return Table("summary", ["quantity", "value", "unit", "description"], ["", "", "", ""], rows)


def _case_data(ds: xr.Dataset) -> dict:
    """The case's every input (defaults filled), or its canonical JSON if this model cannot read it."""
    text = ds.attrs.get("case_spec", "{}")
    try:
        return CaseSpec.model_validate_json(text).model_dump(mode="json", exclude={"name"})
    except ValueError:  # a result of an older case model: what it recorded
        return json.loads(text)


def inputs_table(ds: xr.Dataset, *, exported: datetime | None = None) -> Table:
    """The case definition in engineering units, with the case's id, name, the software version,
    when it was solved and when this table was written."""
    data = _case_data(ds)
    gravity = float((data.get("loads") or {}).get("gravity", 9.81))
    exported = exported or datetime.now(timezone.utc)
    rows = [["case_id", ds.attrs.get("case_id", ""), "", "case id (hash of the inputs)"],
            ["name", ds.attrs.get("case_name", ""), "", "case name"],
            ["software_version", ds.attrs.get("software_version", ""), "", "tunnel-contact version that solved it"],
            ["solved", str(ds.attrs.get("history", "")).partition(": solved")[0], "", "when it was solved (UTC)"],
            ["exported", exported.strftime("%Y-%m-%dT%H:%M:%SZ"), "", "when this table was written (UTC)"]]
    for flat, value in flat_parameters(data).items():
        path = parameter_path(flat)
        long_name = parameter_attrs(path).get("long_name", "")
        if isinstance(value, list):  # an empty list of layers: one ground, given above
            continue
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            unit, factor = parameter_unit(path, parameter_attrs(path).get("units"), gravity)
            if unit == "kN/m³" and path.endswith("density"):
                long_name += " (as unit weight rho g)"
            rows.append([path, float(value) * factor, unit, long_name])
        else:
            rows.append([path, "" if value is None else str(value), "", long_name])
    return Table("inputs", ["parameter", "value", "unit", "description"], ["", "", "", ""], rows)


def case_tables(ds: xr.Dataset) -> list[Table]:
    """The workbook's sheets: forces, joints (segmental linings), summary, inputs."""
    joints = joints_table(ds)
    return [forces_table(ds), *([joints] if joints else []), summary_table(ds), inputs_table(ds)]


def _csv_cell(value) -> str:
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ("" if math.isnan(value) else str(value))
    return str(value)


def table_csv(table: Table) -> str:
    """CSV text: the names, a row of units, then the rows (every digit; empty where NaN)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(table.names)
    writer.writerow(table.units)
    for row in table.rows:
        writer.writerow([_csv_cell(v) for v in row])
    return out.getvalue()


def number_format(value: float, figures: int = FIGURES) -> str:
    """An Excel number format showing ``value`` with ``figures`` significant figures (fixed point
    from 0.001 to 10⁶, scientific beyond)."""
    if value == 0 or not math.isfinite(value):
        return "0"
    exponent = math.floor(math.log10(abs(value)))
    if -3 <= exponent < 6:
        decimals = max(figures - 1 - exponent, 0)
        return "0." + "0" * decimals if decimals else "0"
    return "0." + "0" * (figures - 1) + "E+00"


def _shown(value) -> str:
    """The text Excel shows for a cell (for the column widths)."""
    if isinstance(value, float) and math.isfinite(value):
        fmt = number_format(value)
        return f"{value:.{FIGURES - 1}E}" if "E" in fmt else f"{value:.{len(fmt.partition('.')[2])}f}"
    return str(value)


def _cell(value):
    """A cell's value: numbers as numbers, inf as text, NaN blank."""
    if isinstance(value, float) and not math.isfinite(value):
        return None if math.isnan(value) else ("inf" if value > 0 else "-inf")
    return value


def _sheet(wb, table: Table) -> None:
    from openpyxl.styles import Font
    from openpyxl.utils import get_column_letter

    ws = wb.create_sheet(table.title[:31])
    ws.append(table.names)
    units_row = any(table.units)
    if units_row:
        ws.append(table.units)
    for row in table.rows:
        ws.append([_cell(v) for v in row])
    first = 3 if units_row else 2
    for cell in ws[1]:
        cell.font = Font(bold=True)
    if units_row:
        for cell in ws[2]:
            cell.font = Font(italic=True)
    for col, name in enumerate(table.names, start=1):
        texts = [name, table.units[col - 1]]
        for r, row in enumerate(table.rows, start=first):
            value = row[col - 1]
            if isinstance(value, float) and math.isfinite(value):
                ws.cell(row=r, column=col).number_format = number_format(value)
            texts.append(_shown(value))
        ws.column_dimensions[get_column_letter(col)].width = min(max(len(t) for t in texts) + 2, 60)
    last = get_column_letter(len(table.names))
    # the filter's header is the last heading row (the units row when there is one)
    ws.auto_filter.ref = f"A{first - 1}:{last}{max(first - 1 + len(table.rows), first - 1)}"
    ws.freeze_panes = f"A{first}"


def case_workbook(ds: xr.Dataset) -> bytes:
    """The workbook of a case: one sheet per table of :func:`case_tables` (3 significant figures
    shown, every digit kept, column widths fitted, an autofilter, headings frozen)."""
    from openpyxl import Workbook

    wb = Workbook()
    wb.remove(wb.active)
    for table in case_tables(ds):
        _sheet(wb, table)
    buffer = io.BytesIO()
    wb.save(buffer)
    return buffer.getvalue()


def stored_forces(root, case_id: str) -> Table:
    """The forces table (:func:`forces_table`) of a stored case (the case page shows it).

    Raises FileNotFoundError if the case is not stored."""
    from .result_store import as_store

    with as_store(root).opened(case_id) as ds:
        return forces_table(ds)


def stored_tables(root, case_id: str, kind: str) -> bytes:
    """``kind`` ``"xlsx"`` (:func:`case_workbook`) or ``"csv"`` (the forces table) of a stored case.

    Raises FileNotFoundError if the case is not stored (:meth:`ResultStore.opened`)."""
    from .result_store import as_store

    with as_store(root).opened(case_id) as ds:
        return case_workbook(ds) if kind == "xlsx" else table_csv(forces_table(ds)).encode()
