"""The report's page of lining forces (SPEC §9.3): the forces table of :mod:`workflows.case_tables` at
every 5° from crown to invert, characteristic and design values, with the section checks."""
from __future__ import annotations

import math
import textwrap

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from .case_tables import forces_table

#: Stations shown (deg): the table's station nearest each.
STEP_DEG = 5.0
#: Headings of the page's columns by the table's column name.
HEADINGS = {"theta": "θ", "arc_length": "s", "N": "N", "M": "M", "V": "V", "contact_pressure": "λ",
            "water_pressure": "u_w", "N_Ed": "N_Ed", "M_Ed": "M_Ed", "V_Ed": "V_Ed", "utilization": "η",
            "shear_utilization": "η_V", "crack_width": "w_k"}


def _cell(value: float, unit: str) -> str:
    if math.isnan(value):
        return "–"
    if math.isinf(value):
        return "inf"
    if unit in ("1", "mm"):
        return f"{value:.3f}" if unit == "1" else f"{value:.3g}"
    return f"{value:.1f}" if unit != "m" else f"{value:.2f}"


def draw_forces_table(fig: Figure, ds: xr.Dataset) -> None:
    """The lining forces of ``ds`` on the page ``fig`` (A4 portrait, margins drawn by the caller)."""
    table = forces_table(ds)
    theta = np.asarray([row[0] for row in table.rows])
    picks = sorted({int(np.argmin(np.abs(theta - t))) for t in np.arange(0.0, 180.0 + 1e-9, STEP_DEG)})
    fig.text(0.06, 0.955, "Lining forces", fontsize=16, weight="bold", va="top")
    intro = ("Per metre of tunnel, from the crown (θ = 0°) to the invert; s along the extrados. Characteristic "
             "N (compression +), M (+ inner fibre compressed), V, contact pressure λ and water pressure u_w; "
             "design N_Ed (the governing of γF N and 1.0 N), M_Ed = γF M, V_Ed = γF V; η the EN 1992-1-1 N–M "
             "utilization, η_V the shear utilization (6.2.2, plain 12.6.3), w_k the characteristic crack width "
             "(7.3.4). Every station: GET /cases/{id}/forces.csv or tables.xlsx.")
    fig.text(0.06, 0.92, "\n".join(textwrap.wrap(intro, 118)), fontsize=7.5, va="top", color="0.25")
    n = len(table.names)
    x = np.linspace(0.06, 0.94, n + 1)[:-1]
    y = 0.845
    for xi, name, unit in zip(x, table.names, table.units):
        fig.text(xi, y, HEADINGS.get(name, name), fontsize=7.5, weight="bold", va="top")
        fig.text(xi, y - 0.014, "" if unit == "1" else unit, fontsize=6.5, va="top", color="0.4")
    y -= 0.034
    step = min(0.0195, 0.76 / max(len(picks), 1))
    for k in picks:
        for xi, value, unit, name in zip(x, table.rows[k], table.units, table.names):
            over = name in ("utilization", "shear_utilization") and value > 1.0
            fig.text(xi, y, _cell(value, unit), fontsize=7, va="top", family="monospace",
                     color="#b3261e" if over else "k")
        y -= step
