"""The comparison table of a sweep: one row per case, what varies first, then the results.

The same table feeds ``GET /sweeps/{id}/table`` (JSON), ``GET /sweeps/{id}/summary.csv``,
``GET /sweeps/{id}/table.parquet`` (with the sweep's ``name``: :func:`table_parquet`) and the
sweep page of the dashboard. It is built from the job records alone (the summary scalars
recorded when each case finished), so it costs no file reads. The JSON and Parquet tables hold
SI values (as the case JSON and the netCDF); what people read (the page, ``summary.csv`` and
``summary.xlsx``, each with a units row) is in engineering units (:func:`export_unit`).

Columns, in order
-----------------
``case_id``
    The case id (16 hex digits).
``status``
    ``queued``, ``running``, ``done``, ``failed`` or ``cancelled``.
the varied parameters
    Every case parameter whose value differs between the sweep's cases, by its flat
    name (``lining_thickness``, ``ground_young``: :mod:`workflows.parameters`), in
    case-model order, SI units as in the case JSON (SPEC §2); shown (page, CSV, workbook) in
    engineering units (:func:`workflows.units.parameter_unit`).
the scalars
    The result scalars of SPEC §3 (``max_contact_pressure``, ``contact_extent``, ...)
    in the contract's order, then any other recorded scalar by name; SI units as
    stored (Pa, N/m, N·m/m, m, degrees). Empty until the case is done; a non-finite
    value is written ``inf``, ``-inf`` or ``nan`` (what ``float()`` reads back).
``error``
    Why the case failed (the case record's error text); empty unless it failed.
``warnings``
    The solver's warnings about a done case's result (e.g. displacements outside the
    small-displacement model), joined by ``"; "``; empty when there are none.
"""
from __future__ import annotations

import csv
import io
import math
from typing import Literal, Optional, Union

from pydantic import BaseModel, Field

from solver.results.variables import SCALARS
from workflows.parameters import flat_parameters, parameter_attrs, shown_parameter_unit, varying_parameters
from workflows.units import display_unit

from .results import non_finite_text
from .job_records import JobStore, SweepRecord

#: Scalars of SPEC §3 in the contract's order; units and long names are the solver's
#: (:data:`solver.results.dataset.SCALARS`).
SCALAR_ORDER: tuple[str, ...] = (
    "max_contact_pressure", "contact_extent", "crown_settlement", "max_thrust", "max_abs_moment",
    "max_utilization", "max_shear_utilization", "max_crack_width", "ground_loss", "gaussian_max_settlement",
    "design_volume_loss", "design_max_settlement", "max_slope", "max_horizontal_strain", "axis_settlement",
    "max_surface_heave",
    "max_surface_settlement", "volume_loss", "ground_crown_settlement", "deconfinement", "ldp_ratio",
    "water_inflow", "phreatic_drawdown",
    "plastic_area", "max_plastic_extent", "stage1_plastic_area", "stage1_max_plastic_extent", "max_joint_opening",
    "max_joint_rotation", "max_joint_eccentricity", "max_joint_utilization",
    "lining_weight", "bolt_theta", "bolt_trials", "iterations", "converged", "kkt_residual",
    "solve_seconds",
)


class Column(BaseModel):
    """One column of the comparison table."""

    name: str
    kind: Literal["id", "status", "parameter", "scalar", "text"]
    units: str = Field("", description="CF units of the values (SI)")
    long_name: str = ""
    display_unit: str = Field("", description="unit the dashboard shows")
    display_factor: float = Field(1.0, description="shown value = value × display_factor")


Value = Union[float, str, None]


class ComparisonTable(BaseModel):
    """``GET /sweeps/{id}/table``: the sweep's cases, one row each (values keyed by column name)."""

    sweep_id: str
    columns: list[Column]
    rows: list[dict[str, Value]]


def scalar_column(name: str) -> Column:
    """The column of result scalar ``name`` (units from the contract, names from the solver)."""
    units, long_name = SCALARS.get(name, ("", name.replace("_", " ")))
    shown, factor = display_unit(units, name)
    return Column(name=name, kind="scalar", units=units, long_name=long_name, display_unit=shown,
                  display_factor=factor)


def parameter_column(name: str) -> Column:
    """The column of case parameter ``name`` (flat), shown in its engineering unit (MPa, kPa, mm, ...)."""
    shown, factor = shown_parameter_unit(name)
    return Column(name=name, kind="parameter", **parameter_attrs(name), display_unit=shown, display_factor=factor)


def ordered_scalars(names) -> list[str]:
    """``names`` in the contract's order, unknown ones last by name."""
    names = set(names)
    return [n for n in SCALAR_ORDER if n in names] + sorted(names - set(SCALAR_ORDER))


def comparison_table(store: JobStore, record: SweepRecord) -> ComparisonTable:
    """The comparison table of the sweep ``record`` from the job records."""
    cases = store.get_cases(record.case_ids)
    ordered = [cases[c] for c in record.case_ids if c in cases]
    flat = [flat_parameters(c.spec) for c in ordered]
    varied = varying_parameters(flat)
    # the solver's scalars always (columns do not come and go as cases finish), others once recorded
    scalars = ordered_scalars({*SCALARS, *(name for c in ordered for name in (c.summary or {}))})
    columns = [Column(name="case_id", kind="id", long_name="case id"),
               Column(name="status", kind="status", long_name="status")]
    columns += [parameter_column(p) for p in varied]
    columns += [scalar_column(s) for s in scalars]
    columns += [Column(name="error", kind="text", long_name="why the case failed"),
                Column(name="warnings", kind="text", long_name="solver warnings about the result")]
    rows = []
    for case, params in zip(ordered, flat):
        summary = case.summary or {}
        row: dict[str, Value] = {"case_id": case.id, "status": case.status}
        row.update({p: params.get(p) for p in varied})
        row.update({s: non_finite_text(summary.get(s)) for s in scalars})
        row.update(error=case.error or "", warnings="; ".join(case.warnings))
        rows.append(row)
    return ComparisonTable(sweep_id=record.id, columns=columns, rows=rows)


def export_unit(column: Column) -> tuple[str, float]:
    """``(unit, factor from the stored value)`` of ``column`` in the exports people read (CSV and
    workbook units rows): the dashboard's engineering unit; ``("", 1.0)`` for text columns."""
    if column.display_unit:
        return column.display_unit, column.display_factor
    return display_unit(column.units) if column.units else ("", 1.0)


def table_csv(table: ComparisonTable) -> str:
    """The table as CSV text: a header of column names, a row of units (engineering units, as the
    workbook's: mm, MPa, kPa, kN/m, ...), then one line per case with numbers in those units at
    full precision (empty = no value; ``inf``, ``-inf`` and ``nan`` as text)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    units = [export_unit(c) for c in table.columns]
    writer.writerow([c.name for c in table.columns])
    writer.writerow([unit for unit, _ in units])
    for row in table.rows:
        writer.writerow(["" if row.get(c.name) is None else _csv_value(row[c.name], factor)
                         for c, (_, factor) in zip(table.columns, units)])
    return out.getvalue()


def table_xlsx(table: ComparisonTable) -> bytes:
    """The table as an Excel workbook: a header row of column names, a row of units (the
    dashboard's engineering units), then one row per case with numbers in those units (blank
    where there is no value; inf and nan as text). The header and units rows are frozen."""
    from openpyxl import Workbook
    from openpyxl.styles import Font

    wb = Workbook()
    ws = wb.active
    ws.title = f"sweep {table.sweep_id}"[:31]
    names = [c.name for c in table.columns]
    shown = [export_unit(c) for c in table.columns]
    ws.append(names)
    ws.append([unit for unit, _ in shown])
    for cell in ws[1]:
        cell.font = Font(bold=True)
    for cell in ws[2]:
        cell.font = Font(italic=True)
    for row in table.rows:
        out = []
        for c, (_, factor) in zip(table.columns, shown):
            value = row.get(c.name)
            if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
                value = value * factor
            elif isinstance(value, float):
                value = str(value)
            out.append(value)
        ws.append(out)
    ws.freeze_panes = "A3"
    buffer = io.BytesIO()
    wb.save(buffer)
    return buffer.getvalue()


def table_parquet(table: ComparisonTable, name: str) -> bytes:
    """The table as Parquet (pyarrow): ``case_id``, ``status``, ``name`` (the sweep's), the varied
    parameters (float64, or text where a parameter is not a number), the scalars as float64 (null
    until the case is done; inf and nan as such), ``error`` and ``warnings``. Each field's
    metadata carries its ``units`` and ``long_name``; the schema's, the ``sweep_id``."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    fields, arrays = [pa.field("case_id", pa.string()), pa.field("status", pa.string()),
                      pa.field("name", pa.string())], []
    arrays += [[r["case_id"] for r in table.rows], [r["status"] for r in table.rows], [name] * len(table.rows)]
    for column in table.columns[2:]:
        values = [row.get(column.name) for row in table.rows]
        numeric = column.kind == "scalar" or all(
            v is None or (isinstance(v, (int, float)) and not isinstance(v, bool)) for v in values)
        kind = pa.float64() if numeric else pa.string()
        arrays.append([None if v is None or v == "" and numeric else float(v) if numeric else str(v) for v in values])
        fields.append(pa.field(column.name, kind, metadata={"units": column.units, "long_name": column.long_name}))
    schema = pa.schema(fields, metadata={"sweep_id": table.sweep_id})
    buffer = io.BytesIO()
    pq.write_table(pa.Table.from_arrays([pa.array(a, type=f.type) for a, f in zip(arrays, fields)], schema=schema),
                   buffer)
    return buffer.getvalue()


def _csv_value(value: Value, factor: float = 1.0) -> str:
    """A cell of the CSV: a number times ``factor`` (15 significant digits when converted, which
    drops the last bit's noise of the product: 70, not 70.00000000000001), text as it is."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return str(value)
    if factor == 1.0:
        return repr(value)
    return f"{value * factor:.15g}"


def shown(value: Optional[Value], column: Column) -> str:
    """A value as the dashboard shows it (4 significant digits, display units)."""
    if value is None:
        return ""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return f"{value * column.display_factor:.4g}"
    return str(value)
