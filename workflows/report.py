"""The printable record of one case: a PDF of A4 pages (matplotlib's PDF backend).

Page 1: the design answer (PASS/FAIL with the utilization and where; for a segmental lining
also whether every joint carries its thrust within its contact strip), the results in
engineering units, the warnings. Page 2: every input with its unit, and the solver's
diagnostics. A segmental lining then has a page of its joints (θ, N, M, |M|/(N·a/2), opening,
rotation, open). Then the lining forces every 5° (characteristic and design values, the section
checks: :mod:`workflows.report_tables`), then one page per figure of :data:`workflows.plots.PLOTS`, each fitted to an
A4 landscape page with the case id and the page number in the margin.
"""
from __future__ import annotations

import io
import json
import textwrap
from datetime import datetime, timezone

import numpy as np
import xarray as xr
from matplotlib.backends.backend_pdf import PdfPages
from matplotlib.figure import Figure
from matplotlib.patches import FancyBboxPatch

from solver.results.dataset import SCALARS

from .joint_check import joint_check, joint_report, statement
from .joint_plots import OPEN_STYLE, has_joints
from .parameters import flat_parameters, parameter_attrs, parameter_path
from .report_tables import draw_forces_table
from .result_store import case_warnings
from .section_check import section_check, section_report
from .units import DIAGNOSTICS, parameter_unit, shown_value

A4_PORTRAIT = (8.27, 11.69)
A4_LANDSCAPE = (11.69, 8.27)
#: Resolution of the figures placed on the pages (dots per inch).
FIGURE_DPI = 170
_PASS, _FAIL = "#1b7f3b", "#b3261e"


def _page(size=A4_PORTRAIT) -> Figure:
    return Figure(figsize=size)


def _margins(fig: Figure, ds: xr.Dataset, page: int, pages: int) -> None:
    name = f" · {ds.attrs['case_name']}" if ds.attrs.get("case_name") else ""
    fig.text(0.04, 0.985, f"tunnel-contact · case {ds.attrs.get('case_id', '?')}{name}"[:140], fontsize=8,
             color="0.4", va="top")
    fig.text(0.96, 0.985, f"page {page} of {pages}", fontsize=8, color="0.4", va="top", ha="right")
    fig.text(0.04, 0.012, str(ds.attrs.get("history", "")).split("\n")[0][:150], fontsize=6.5, color="0.5")


def _verdict(ds: xr.Dataset) -> tuple[str, str, list[str]]:
    """``(word, colour, lines)`` of the design answer."""
    from .commands import utilization_report

    if "utilization" not in ds or np.isnan(ds["utilization"].values).all():
        return "NO CHECK", "0.4", ["no EN 1992 check in this result"]
    eta = float(np.nanmax(ds["utilization"].values))
    check = joint_check(ds)
    section = section_check(ds)
    passes = eta <= 1 and (check is None or check.passes) and (section is None or section.passes)
    word, colour = ("PASS", _PASS) if passes else ("FAIL", _FAIL)
    lines = utilization_report(ds).splitlines() + section_report(ds).splitlines()
    if check is not None:  # the section away from the joints, then the joints' strips
        lines += joint_report(ds).splitlines()
    return word, colour, lines


def _table(fig: Figure, top: float, rows: list[tuple[str, str, str]], *, title: str, size: float = 8.5,
           step: float = 0.0205) -> float:
    """Rows of (quantity, value, name) from ``top`` (figure fraction); returns the next free y."""
    fig.text(0.06, top, title, fontsize=11.5, weight="bold", va="top")
    y = top - 0.032
    for quantity, value, name in rows:
        fig.text(0.07, y, textwrap.shorten(quantity, 72, placeholder="…"), fontsize=size, va="top")
        fig.text(0.74, y, value, fontsize=size, va="top", ha="right", family="monospace")
        fig.text(0.76, y, name, fontsize=size - 1.5, va="top", color="0.45", family="monospace")
        y -= step
    return y - 0.012


def _summary_page(ds: xr.Dataset, spec: dict, page: int, pages: int) -> Figure:
    fig = _page()
    _margins(fig, ds, page, pages)
    fig.text(0.06, 0.955, "Case report", fontsize=20, weight="bold", va="top")
    geometry, ground = spec.get("geometry", {}), spec.get("ground", {})
    what = (f"lining {geometry.get('thickness', '?')} m thick, inner radius {geometry.get('inner_radius', '?')} m, "
            f"cover {geometry.get('depth', '?')} m to the axis; ground {ground.get('model', 'linear-elastic')}, "
            f"interface {spec.get('interface', {}).get('model', '?')}")
    segments = spec.get("lining", {}).get("joints", {}).get("count", 0)
    if segments:
        what += f"; segmental lining of {segments} segments"
    fig.text(0.06, 0.915, "\n".join(textwrap.wrap(what, 95)), fontsize=9, va="top", color="0.25")
    word, colour, lines = _verdict(ds)
    wrapped = [part for line in lines for part in textwrap.wrap(line, 78, subsequent_indent="    ")]
    bottom = min(0.78, 0.866 - 0.0112 * len(wrapped) - 0.008)  # room for the joints' lines
    fig.patches.append(FancyBboxPatch(
        (0.06, bottom), 0.88, 0.875 - bottom, boxstyle="round,pad=0.005", transform=fig.transFigure,
        facecolor=colour, alpha=0.1, edgecolor=colour, lw=1.5))
    fig.text(0.08, 0.86, word, fontsize=26, weight="bold", color=colour, va="top", gid="verdict")
    fig.text(0.27, 0.866, "\n".join(wrapped), fontsize=7.5, va="top", family="monospace")
    joints = has_joints(ds)
    rows = [(SCALARS.get(name, ("", name))[1], shown_value(ds[name].values, SCALARS[name][0], name), name)
            for name in SCALARS if name in ds and name not in DIAGNOSTICS
            and (joints or not name.startswith("max_joint_"))]  # a monolithic lining has none
    y = _table(fig, bottom - 0.03, rows, title="Results (engineering units; settlements downward positive)")
    warnings = case_warnings(ds)
    fig.text(0.06, y, "Warnings", fontsize=11.5, weight="bold", va="top")
    y -= 0.03
    for warning in warnings or ["none"]:
        wrapped = textwrap.wrap(warning, 110) or [""]
        fig.text(0.07, y, "• " + "\n  ".join(wrapped), fontsize=8, va="top",
                 color="#8a5300" if warnings else "0.3")
        y -= 0.016 * len(wrapped) + 0.006
    return fig


def _inputs_page(ds: xr.Dataset, page: int, pages: int) -> Figure:
    fig = _page()
    _margins(fig, ds, page, pages)
    params = flat_parameters(ds.attrs.get("case_spec", "{}"))
    rows = []
    for name, value in params.items():
        attrs = parameter_attrs(name, numeric=isinstance(value, (int, float)) and not isinstance(value, bool))
        unit, factor = (parameter_unit(parameter_path(name), attrs["units"], params.get("loads_gravity"))
                        if "units" in attrs else ("", 1.0))
        unit = "" if unit == "1" else unit
        text = f"{value * factor:.6g}" if isinstance(value, float) else str(value)
        rows.append((attrs.get("long_name", name), f"{text} {unit}".strip(), name))
    step = min(0.0205, 0.70 / max(len(rows), 1))
    y = _table(fig, 0.955, rows, title="Inputs (every default filled in; JSON names on the right, in SI there)",
               size=min(8.5, 420 * step), step=step)
    diagnostics = [(SCALARS[name][1], shown_value(ds[name].values, SCALARS[name][0], name), name)
                   for name in DIAGNOSTICS if name in ds]
    _table(fig, max(y, 0.2), diagnostics, title="Solver diagnostics (how the answer was found)", size=8, step=0.019)
    return fig


#: Columns of the joints' table: (heading, variable, value format in display units).
JOINT_COLUMNS = (("joint", None, ""), ("θ (°)", "joint_theta", ".1f"), ("N (kN/m)", "joint_thrust", ".1f"),
                 ("M (kN·m/m)", "joint_moment", ".2f"), ("|M|/(N·a/2)", "joint_eccentricity", ".3f"),
                 ("η (12.10)", "joint_utilization", ".3f"), ("opening (mm)", "joint_opening", ".3g"),
                 ("rotation (mrad)", "joint_rotation", ".3g"), ("state", "joint_open", ""))
_JOINT_FACTORS = {"joint_thrust": 1e-3, "joint_moment": 1e-3, "joint_opening": 1e3, "joint_rotation": 1e3}


def joint_rows(ds: xr.Dataset) -> list[list[str]]:
    """The joints' table of a segmental lining as text cells (:data:`JOINT_COLUMNS`), crown to invert."""
    rows = []
    for j in range(ds.sizes["joint"]):
        cells = [str(j + 1)]
        for _, name, fmt in JOINT_COLUMNS[1:]:
            value = ds[name].values[j]
            if name == "joint_open":
                cells.append("open" if value else "closed")
            else:
                cells.append(format(float(value) * _JOINT_FACTORS.get(name, 1.0), fmt))
        rows.append(cells)
    return rows


def _joints_page(ds: xr.Dataset, spec: dict, page: int, pages: int) -> Figure:
    """The joints of a segmental lining: the statement of their check and their table."""
    fig = _page()
    _margins(fig, ds, page, pages)
    check = joint_check(ds)
    joints = spec.get("lining", {}).get("joints", {})
    thickness = spec.get("geometry", {}).get("thickness", float("nan"))
    fig.text(0.06, 0.955, "Joints of the segmental lining", fontsize=16, weight="bold", va="top")
    what = (f"{joints.get('count', '?')} segments in the ring (offset {joints.get('offset', 0.0):g}°), "
            f"{check.count} joints in the half model from crown to invert; contact strip a = {check.height:g} m "
            f"of the {thickness:g} m lining, shear {joints.get('shear', 'bonded')}.")
    fig.text(0.06, 0.915, "\n".join(textwrap.wrap(what, 100)), fontsize=9, va="top", color="0.25")
    colour = _PASS if check.passes else _FAIL
    verdict = ("PASS: " if check.passes else "FAIL: ") + statement(check.passes, check.worst, check.count,
                                                                             check.utilization)
    fig.text(0.06, 0.875, "\n".join(textwrap.wrap(verdict, 85)), fontsize=9.5, weight="bold", color=colour,
             va="top", gid="joint-verdict")
    x = (0.06, 0.11, 0.18, 0.28, 0.40, 0.51, 0.62, 0.74, 0.895)
    y = 0.81
    for xi, (heading, _, _) in zip(x, JOINT_COLUMNS):
        fig.text(xi, y, heading, fontsize=8.5, weight="bold", va="top")
    for cells in joint_rows(ds):
        y -= 0.024
        for k, (xi, cell) in enumerate(zip(x, cells)):
            over = k == 4 and float(cell) > 1.0
            fig.text(xi, y, cell, fontsize=8.5, va="top", family="monospace",
                     color=_FAIL if over else OPEN_STYLE[0] if cell == "open" else "k")
    notes = ("N thrust (compression +) and M moment (+ inner fibre compressed) of the contact force across the "
             "joint's strip, about the lining's mid-surface; |M|/(N·a/2) ≤ 1: the thrust acts within the strip. "
             "A full-height joint opens where |M|/N exceeds a/6 (|M|/(N·a/2) > 1/3; a narrower strip later) "
             "and, at 1, turns as a hinge on the strip's edge. η (12.10): EN 1992-1-1 (12.10) on the strip as a "
             "plain section (no bar crosses a joint) at the joint's design thrust, |M_Ed| / (N_Ed (a − x)/2) "
             "with the stress block x = N_Ed / fcd,pl: a hinging joint passes only if its strip leaves room "
             "for the block. Opening: the largest normal gap over the strip; rotation: of the faces relative "
             "to each other, + opening at the extrados (1 mrad = 0.001 rad). The EN 1992 check of page 1 is "
             "the section's away from the joints: at a joint's station the section is the strip.")
    fig.text(0.06, y - 0.04, "\n".join(textwrap.wrap(notes, 110)), fontsize=8, va="top", color="0.3")
    return fig


def _figure_page(ds: xr.Dataset, figure: Figure, name: str, page: int, pages: int) -> Figure:
    """``figure`` rasterized and fitted to an A4 landscape page (vector pages of 20 000 mesh
    faces would print slowly and weigh megabytes)."""
    from matplotlib.image import imread

    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=FIGURE_DPI)
    buffer.seek(0)
    image = imread(buffer)
    fig = _page(A4_LANDSCAPE)
    _margins(fig, ds, page, pages)
    fig.text(0.04, 0.95, name.replace("_", " "), fontsize=13, weight="bold", va="top")
    h, w = image.shape[:2]
    box_w, box_h = 0.92, 0.86  # figure fractions below the heading
    aspect = (w / h) * (A4_LANDSCAPE[1] / A4_LANDSCAPE[0])  # width fraction per height fraction
    width, height = (box_w, box_w / aspect) if box_w / aspect <= box_h else (box_h * aspect, box_h)
    ax = fig.add_axes(((1 - width) / 2, 0.04 + (box_h - height) / 2, width, height))
    ax.imshow(image, interpolation="antialiased")
    ax.set_axis_off()
    return fig


def case_report(ds: xr.Dataset) -> bytes:
    """The PDF report of a case result (bytes)."""
    from .plots import PLOTS

    spec = json.loads(ds.attrs.get("case_spec", "{}"))
    joints = has_joints(ds)
    forces = "thrust" in ds and "interface_x" in ds
    pages = 2 + forces + joints + len(PLOTS)
    buffer = io.BytesIO()
    created = datetime.now(timezone.utc).replace(microsecond=0)
    with PdfPages(buffer, metadata={"Title": f"tunnel-contact case {ds.attrs.get('case_id', '')}",
                                     "Creator": f"tunnel-contact {ds.attrs.get('software_version', '')}",
                                     "CreationDate": created}) as pdf:
        pdf.savefig(_summary_page(ds, spec, 1, pages))
        pdf.savefig(_inputs_page(ds, 2, pages))
        if joints:
            pdf.savefig(_joints_page(ds, spec, 3, pages))
        if forces:  # the lining forces table (SPEC §9.3)
            fig = _page()
            _margins(fig, ds, 3 + joints, pages)
            draw_forces_table(fig, ds)
            pdf.savefig(fig)
        for k, (name, plot) in enumerate(PLOTS.items(), start=3 + forces + joints):
            pdf.savefig(_figure_page(ds, plot(ds), name, k, pages))
    return buffer.getvalue()

