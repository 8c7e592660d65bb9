"""The text a person reads: a case's scalars, where its lining is most utilized, the
comparison table of many cases (the command line prints them; the PDF report and the demo
use them too). Units as every table shows them (:mod:`workflows.units`).
"""
from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np
import xarray as xr

from solver.results.dataset import SCALARS

from .case_plots import load_factor, station_name
from .joint_plots import has_joints
from .parameters import flat_parameters, parameter_attrs, varying_parameters
from .result_store import StoreLike, as_store
from .summary import summarize
from .units import DIAGNOSTICS, display_unit, shown_number, shown_value

#: Columns of the comparison table: (summary scalar, header); values and units as every table
#: shows them (:mod:`workflows.units`).
TABLE_COLUMNS: tuple[tuple[str, str], ...] = (
    ("max_contact_pressure", "max λ"),
    ("contact_extent", "contact"),
    ("max_thrust", "max N"),
    ("max_abs_moment", "max |M|"),
    ("max_utilization", "max η"),
    ("crown_settlement", "lining crown"),
    ("ground_crown_settlement", "ground crown"),
    ("ground_loss", "ground loss"),
    ("gaussian_max_settlement", "trough max"),
    ("axis_settlement", "FE surface"),
)

#: Columns added to the comparison table when a case has a segmental lining (SPEC §1.6).
JOINT_TABLE_COLUMNS: tuple[tuple[str, str], ...] = (
    ("max_joint_opening", "joint gap"),
    ("max_joint_rotation", "joint rot."),
    ("max_joint_eccentricity", "joint |M|/(Na/2)"),
    ("max_joint_utilization", "joint η"),
)


def column_unit(name: str) -> str:
    """The unit row's label of result column ``name`` (the utilization and the joints'
    eccentricity: their limit, ``≤ 1``)."""
    if name in ("max_utilization", "max_joint_eccentricity", "max_joint_utilization"):
        return "≤ 1"
    return display_unit(SCALARS[name][0], name)[0]


def format_summary(summary: dict[str, float]) -> str:
    """The scalars of one case, one ``name = value unit`` per line, in the engineering units
    of every table and page (:mod:`workflows.units`: kPa, kN/m, kN·m/m, mm, %), the
    solver's diagnostics after a ``solver:`` line; non-finite values as ``inf``/``-``.
    """
    width = max((len(k) for k in summary), default=0)

    def line(k: str) -> str:
        return f"  {k:<{width}} = {shown_value(summary[k], SCALARS.get(k, (None,))[0], k, 6)}"

    return "\n".join([line(k) for k in summary if k not in DIAGNOSTICS] + ["  solver:"]
                     + [line(k) for k in summary if k in DIAGNOSTICS])


def _unit_label(units: str | None) -> str:
    """The unit as printed: nothing for a dimensionless (``1``) or unknown one."""
    return "" if units in (None, "", "1") else units


def with_unit(value: Any, units: str | None) -> str:
    """``value`` followed by its unit as printed (:func:`_unit_label`)."""
    label = _unit_label(units)
    return f"{value} {label}" if label else str(value)


def utilization_report(ds: xr.Dataset) -> str:
    """Where the lining is most utilized (EN 1992-1-1, SPEC §1.3): η, θ, side, N_Ed and M_Ed there
    (a segmental lining's section away from its joints: :func:`workflows.joint_check.joint_report`
    states the joints)."""
    eta = ds["utilization"].values
    if np.isnan(eta).all():
        return "max utilization: not computed"
    k = int(np.nanargmax(eta))
    gamma = load_factor(ds)
    theta = float(ds["theta"].values[k])
    n_ed, m_ed = gamma * float(ds["thrust"].values[k]), gamma * float(ds["moment"].values[k])
    worst = float(eta[k])
    verdict = "passes" if worst <= 1 else "fails" + (" at any load level" if math.isinf(worst) else "")
    fibre = "inner fibre compressed" if m_ed > 0 else "outer fibre compressed"
    failing = int(np.count_nonzero(eta > 1))
    checked = int(np.count_nonzero(~np.isnan(eta)))  # a segmental lining's joints are their strips'
    where = " away from the joints" if has_joints(ds) else ""
    return (f"max utilization η = {worst:.3g}{where} ({verdict}; EN 1992-1-1, γF = {gamma:g})\n"
            f"  at θ = {theta:.1f}° ({station_name(theta)} side): N_Ed = {n_ed / 1e3:.1f} kN/m, "
            f"M_Ed = {m_ed / 1e3:.1f} kN·m/m ({fibre})\n"
            f"  stations with η > 1: {failing} of {checked}")


def case_row(results: StoreLike, case_id: str) -> dict[str, Any]:
    """``{"case_id", "status", "params", "summary", "error"}`` of a case in the store."""
    store = as_store(results)
    if store.is_stored(case_id):
        with store.opened(case_id) as ds:
            return {"case_id": case_id, "status": "done", "error": None,
                    "params": flat_parameters(ds.attrs["case_spec"]), "summary": summarize(ds)}
    error = store.read_error(case_id) or {}
    return {"case_id": case_id, "status": "failed" if error else "missing",
            "params": flat_parameters(error["spec"]) if "spec" in error else {},
            "summary": {}, "error": error.get("error")}


def case_rows(results: StoreLike, case_ids: list[str]) -> list[dict[str, Any]]:
    """:func:`case_row` of each case; the stored ones come from the index in one read."""
    store = as_store(results)
    stored = store.file_keys()  # one directory scan, not a stat per case
    done = [c for c in case_ids if c in stored]
    rows: dict[str, dict[str, Any]] = {}
    try:
        combined = store.open_results(done) if done else None
    except FileNotFoundError:  # a case removed meanwhile: one by one
        combined = None
    if combined is not None:
        scalars = [str(n) for n, v in combined.data_vars.items() if v.dims == ("case",) and v.dtype.kind in "biuf"]
        for i, case_id in enumerate(done):
            rows[case_id] = {"case_id": case_id, "status": "done", "error": None,
                             "params": flat_parameters(str(combined["case_spec"].values[i])),
                             "summary": {n: float(combined[n].values[i]) for n in scalars}}
    return [rows[c] if c in rows else case_row(store, c) for c in case_ids]


def comparison_table(rows: Iterable[dict[str, Any]]) -> str:
    """Plain-text table: case id, the parameters that vary, the key results (two header lines:
    names, then units); the joints' maxima too when a case has a segmental lining.

    ``rows`` are :func:`case_row` dicts; failed cases show their status instead of numbers;
    a missing or NaN value shows ``-``, an infinite one ``inf``.
    """
    rows = list(rows)
    varied = varying_parameters([r["params"] for r in rows if r["params"]])
    columns = TABLE_COLUMNS
    if any(r["params"].get("lining_joints_count", 0) for r in rows):  # a segmental lining among them
        columns += JOINT_TABLE_COLUMNS
    header = ["case_id", *varied, *(h for _, h in columns)]
    units = ["", *(_unit_label(parameter_attrs(n).get("units")) for n in varied),
             *(column_unit(k) for k, _ in columns)]
    lines = []
    for r in rows:
        cells = [r["case_id"], *(_fmt(r["params"].get(n, "")) for n in varied)]
        if r["status"] == "done":
            cells += [shown_number(r["summary"].get(k), SCALARS[k][0], k) for k, _ in columns]
        else:
            cells += [r["status"]] + [""] * (len(columns) - 1)
        lines.append(cells)
    widths = [max(len(str(c)) for c in col) for col in zip(header, units, *lines)]
    fmt = "  ".join(f"{{:>{w}}}" for w in widths)
    text = [fmt.format(*header), fmt.format(*units).rstrip(), fmt.format(*("-" * w for w in widths))]
    text += [fmt.format(*cells) for cells in lines]
    errors = [f"  {r['case_id']}: {r['error']}" for r in rows if r["error"]]
    return "\n".join(text + (["failures:"] + errors if errors else []))


def _fmt(value: Any) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)
