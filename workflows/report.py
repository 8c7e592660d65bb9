"""The printable record of one case: a PDF of A4 pages (matplotlib's PDF backend).

Page 1: the design answer (PASS/FAIL with the utilization and where), the results in
engineering units, the warnings. Page 2: every input with its unit, and the solver's
diagnostics. Then one page per figure of :data:`workflows.plots.PLOTS`, each fitted to an A4
landscape page with the case id and the page number in the margin.
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

from solver.dataset import SCALARS

from .parameters import flat_parameters, parameter_attrs
from .result_store import case_warnings
from .units import DIAGNOSTICS, input_unit, shown_value

A4_PORTRAIT = (8.27, 11.69)
A4_LANDSCAPE = (11.69, 8.27)
#: Resolution of the figures placed on the pages (dots per inch).
FIGURE_DPI = 170
_PASS, _FAIL = "#1b7f3b", "#b3261e"


def _page(size=A4_PORTRAIT) -> Figure:
    return Figure(figsize=size)


def _margins(fig: Figure, ds: xr.Dataset, page: int, pages: int) -> None:
    fig.text(0.04, 0.985, f"tunnel-contact · case {ds.attrs.get('case_id', '?')}", fontsize=8, color="0.4",
             va="top")
    fig.text(0.96, 0.985, f"page {page} of {pages}", fontsize=8, color="0.4", va="top", ha="right")
    fig.text(0.04, 0.012, str(ds.attrs.get("history", "")).split("\n")[0][:150], fontsize=6.5, color="0.5")


def _verdict(ds: xr.Dataset) -> tuple[str, str, list[str]]:
    """``(word, colour, lines)`` of the design answer."""
    from .commands import utilization_report

    if "utilization" not in ds or np.isnan(ds["utilization"].values).all():
        return "NO CHECK", "0.4", ["no EN 1992 check in this result"]
    eta = float(np.nanmax(ds["utilization"].values))
    word, colour = ("PASS", _PASS) if eta <= 1 else ("FAIL", _FAIL)
    return word, colour, utilization_report(ds).splitlines()


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
    fig.text(0.06, 0.915, "\n".join(textwrap.wrap(what, 95)), fontsize=9, va="top", color="0.25")
    word, colour, lines = _verdict(ds)
    fig.patches.append(FancyBboxPatch(
        (0.06, 0.78), 0.88, 0.095, boxstyle="round,pad=0.005", transform=fig.transFigure, facecolor=colour,
        alpha=0.1, edgecolor=colour, lw=1.5))
    fig.text(0.08, 0.86, word, fontsize=26, weight="bold", color=colour, va="top", gid="verdict")
    wrapped = [part for line in lines for part in textwrap.wrap(line, 78, subsequent_indent="    ")]
    fig.text(0.27, 0.866, "\n".join(wrapped), fontsize=7.5, va="top", family="monospace")
    rows = [(SCALARS.get(name, ("", name))[1], shown_value(ds[name].values, SCALARS[name][0], name), name)
            for name in SCALARS if name in ds and name not in DIAGNOSTICS]
    y = _table(fig, 0.75, rows, title="Results (engineering units; settlements downward positive)")
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
        unit, factor = input_unit(name, attrs.get("units"))
        text = f"{value * factor:.6g}" if isinstance(value, float) else str(value)
        rows.append((attrs.get("long_name", name), f"{text} {unit}".strip(), name))
    step = min(0.0205, 0.70 / max(len(rows), 1))
    y = _table(fig, 0.955, rows, title="Inputs (every default filled in; JSON names on the right, in SI there)",
               size=min(8.5, 420 * step), step=step)
    diagnostics = [(SCALARS[name][1], shown_value(ds[name].values, SCALARS[name][0], name), name)
                   for name in DIAGNOSTICS if name in ds]
    _table(fig, max(y, 0.2), diagnostics, title="Solver diagnostics (how the answer was found)", size=8, step=0.019)
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
    pages = 2 + len(PLOTS)
    buffer = io.BytesIO()
    created = datetime.now(timezone.utc).replace(microsecond=0)
    with PdfPages(buffer, metadata={"Title": f"tunnel-contact case {ds.attrs.get('case_id', '')}",
                                     "Creator": f"tunnel-contact {ds.attrs.get('software_version', '')}",
                                     "CreationDate": created}) as pdf:
        pdf.savefig(_summary_page(ds, spec, 1, pages))
        pdf.savefig(_inputs_page(ds, 2, pages))
        for k, (name, plot) in enumerate(PLOTS.items(), start=3):
            pdf.savefig(_figure_page(ds, plot(ds), name, k, pages))
    return buffer.getvalue()

