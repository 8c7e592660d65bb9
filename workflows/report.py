"""The printable record of one case: a PDF of A4 pages (matplotlib's PDF backend).

A calculation record. Page 1: the title block (project, job, author, checker, revision, date),
the design answer (PASS/FAIL with what governs, the utilization and where; for a segmental
lining also whether every joint carries its thrust within its contact strip), the results in
engineering units, the warnings. Page 2: the whole model (figure 1). Page 3: the stratigraphy
and every other input with its unit, and the solver's diagnostics. Page 4: the design basis
(code clauses, partial factors). Page 5: the lining forces every 5° (characteristic and design
values, the section checks: :mod:`workflows.report_tables`). A segmental lining then has a page of its joints (θ, N, M,
|M|/(N·a/2), opening, rotation, open). Then one page per figure of :data:`workflows.plots.PLOTS`,
numbered and captioned, as vector graphics on A4 landscape pages with the case id and the page
number in the margin.
"""
from __future__ import annotations

import io
import json
import textwrap
from datetime import datetime, timezone
from typing import Sequence

import numpy as np
import xarray as xr
from matplotlib.backends.backend_pdf import PdfPages
from matplotlib.figure import Figure
from matplotlib.patches import FancyBboxPatch

from solver.lining.design import ALPHA_CC, ALPHA_CC_PL, EPS_UD, ES, GAMMA_C, GAMMA_S
from solver.results.variables import SCALARS

from .joint_check import joint_check, joint_report, statement
from .joint_plots import OPEN_STYLE, has_joints
from .case_plots import load_factor
from .parameters import flat_parameters, parameter_attrs, parameter_path
from .report_tables import draw_forces_table
from .section_check import section_check, section_report
from .store_files import case_warnings
from .tables import utilization_report
from .units import DIAGNOSTICS, parameter_unit, shown_value

A4_PORTRAIT = (8.27, 11.69)
A4_LANDSCAPE = (11.69, 8.27)
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
        if not passes:  # say first what fails, so no line of a FAIL reads as the answer
            governs = "the joints' contact strips" if eta <= 1 else (
                "the section and the joints" if not check.passes else "the lining section")
            lines.insert(0, f"fails by {governs}; each check below:")
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


#: The title block's fields (optional, given with the request or on the command line).
TITLE_FIELDS = ("project", "job", "author", "checker", "revision", "date")
_TITLE_LABELS = {"project": "Project", "job": "Job no.", "author": "Author", "checker": "Checked",
                 "revision": "Rev.", "date": "Date"}


def title_block(title: dict | None) -> dict[str, str]:
    """The title block's fields, every one present (blank where not given; the date today's)."""
    title = {k: str(v) for k, v in (title or {}).items() if v not in (None, "")}
    unknown = sorted(set(title) - set(TITLE_FIELDS))
    if unknown:
        raise ValueError(f"{unknown[0]}: not a title block field (one of {', '.join(TITLE_FIELDS)})")
    today = datetime.now(timezone.utc).date().isoformat()
    return {k: title.get(k, today if k == "date" else "") for k in TITLE_FIELDS}


def _title_block(fig: Figure, ds: xr.Dataset, title: dict[str, str]) -> None:
    """A calculation record's title block across the top of page 1: project, job number, what
    is calculated, author, checker, revision and date, each in its own ruled cell."""
    name = ds.attrs.get("name") or f"case {ds.attrs.get('case_id', '?')}"
    cells = [("Project", title["project"], 0.06, 0.50), ("Job no.", title["job"], 0.50, 0.72),
             ("Rev.", title["revision"], 0.72, 0.82), ("Date", title["date"], 0.82, 0.94),
             ("Calculation", f"tunnel lining: {name}", 0.06, 0.50), ("Author", title["author"], 0.50, 0.72),
             ("Checked", title["checker"], 0.72, 0.94)]
    top, row = 0.965, 0.032
    for k, (label, value, x0, x1) in enumerate(cells):
        y1 = top - row * (k >= 4)
        fig.patches.append(FancyBboxPatch((x0, y1 - row), x1 - x0, row, boxstyle="square,pad=0",
                                          transform=fig.transFigure, facecolor="none", edgecolor="0.3", lw=0.6))
        fig.text(x0 + 0.005, y1 - 0.004, label, fontsize=6, color="0.45", va="top")
        fig.text(x0 + 0.005, y1 - row + 0.005, textwrap.shorten(value, int(95 * (x1 - x0)), placeholder="…"),
                 fontsize=8.5, va="bottom", gid=f"title-{label.lower().rstrip('.')}")


def _summary_page(ds: xr.Dataset, spec: dict, page: int, pages: int, title: dict[str, str],
                  notes: Sequence[str] = ()) -> Figure:
    fig = _page()
    _margins(fig, ds, page, pages)
    _title_block(fig, ds, title)
    fig.text(0.06, 0.89, "Lining design check", fontsize=16, weight="bold", va="top")
    geometry, ground = spec.get("geometry", {}), spec.get("ground", {})
    layers = ground.get("layers") or []
    models = sorted({str(layer.get("model") or ground.get("model", "elastic")) for layer in layers}) or \
        [str(ground.get("model", "elastic"))]
    kind = (f"{len(layers)} layers ({', '.join(models)})" if layers else models[0])
    what = (f"lining {geometry.get('thickness', '?')} m thick, inner radius {geometry.get('inner_radius', '?')} m, "
            f"axis depth {geometry.get('depth', '?')} m; ground {kind}, "
            f"interface {spec.get('interface', {}).get('model', '?')}")
    segments = spec.get("lining", {}).get("joints", {}).get("count", 0)
    if segments:
        what += f"; segmental lining of {segments} segments"
    fig.text(0.06, 0.86, "\n".join(textwrap.wrap(what, 95) + list(notes)), fontsize=9, va="top", color="0.25")
    word, colour, lines = _verdict(ds)
    wrapped = [part for line in lines for part in textwrap.wrap(line, 78, subsequent_indent="    ")]
    bottom = min(0.72, 0.81 - 0.0112 * len(wrapped) - 0.008)  # room for the joints' lines
    fig.patches.append(FancyBboxPatch(
        (0.06, bottom), 0.88, 0.82 - bottom, boxstyle="round,pad=0.005", transform=fig.transFigure,
        facecolor=colour, alpha=0.1, edgecolor=colour, lw=1.5))
    fig.text(0.08, 0.805, word, fontsize=26, weight="bold", color=colour, va="top", gid="verdict")
    fig.text(0.27, 0.811, "\n".join(wrapped), fontsize=7.5, va="top", family="monospace")
    joints = has_joints(ds)
    rows = [(SCALARS.get(name, ("", name))[1], shown_value(ds[name].values, SCALARS[name][0], name), name)
            for name in SCALARS if name in ds and name not in DIAGNOSTICS
            and (joints or not name.startswith("max_joint_"))]  # a monolithic lining has none
    # solver.mesh_check: each key result's change on a mesh refined once
    rows += [(f"change of {name[len('mesh_change_'):]} on a mesh refined once", f"{100 * float(ds[name]):+.2f} %", name)
             for name in ds.data_vars if name.startswith("mesh_change_")]
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


#: The stratigraphy table's columns: (heading, value of a :class:`solver.ground.strata.Stratum`).
STRATA_COLUMNS = (
    ("layer", lambda s, g: str(s.index)),
    ("from–to (m)", lambda s, g: f"{s.top:g}–{s.bottom:g}"),
    ("γ (kN/m³)", lambda s, g: f"{s.density * g / 1e3:.3g}"),
    ("E (MPa)", lambda s, g: f"{s.young / 1e6:.4g}" + (f" +{s.young_gradient / 1e6:.3g}/m" if s.young_gradient else "")),
    ("ν", lambda s, g: f"{s.poisson:.3g}"),
    ("K0", lambda s, g: f"{s.k0:.3g}"),
    ("model", lambda s, g: s.model),
    ("c (kPa)", lambda s, g: f"{s.cohesion / 1e3:.3g}" if s.model == "mohr-coulomb" else "–"),
    ("φ (°)", lambda s, g: f"{s.friction_angle:.3g}" if s.model == "mohr-coulomb" else "–"),
    ("σci (MPa), GSI, mi, D", lambda s, g: f"{s.ucs / 1e6:.3g}, {s.gsi:.3g}, {s.mi:.3g}, {s.disturbance:.2g}"
     if s.model == "hoek-brown" else "–"),
    ("k (m/s)", lambda s, g: f"{s.permeability:.2g}"),
)


def stratigraphy(spec: dict) -> list[list[str]]:
    """The ground's layers as text cells (:data:`STRATA_COLUMNS`), every property resolved as the
    solver uses it (a one-layer ground is one row)."""
    from solver.ground.strata import strata
    from solver.spec import CaseSpec

    case = CaseSpec.model_validate(spec)
    return [[cell(s, case.loads.gravity) for _, cell in STRATA_COLUMNS] for s in strata(case)]


def _layered_inputs(spec: dict) -> set[str]:
    """Flat input names the stratigraphy table states instead (a layer's own values apply)."""
    from solver.spec import LAYER_FIELDS

    if not (spec.get("ground") or {}).get("layers"):
        return set()
    return {f"ground_{field}" for field in LAYER_FIELDS} | {"loads_lateral_ratio"}


def _stratigraphy_table(fig: Figure, top: float, spec: dict) -> float:
    fig.text(0.06, top, "Stratigraphy (depths below the ground surface)", fontsize=11.5, weight="bold", va="top")
    x = (0.07, 0.13, 0.25, 0.35, 0.50, 0.56, 0.62, 0.73, 0.80, 0.87)
    y = top - 0.03
    for xi, (heading, _) in zip(x, STRATA_COLUMNS):
        fig.text(xi, y, heading, fontsize=7.5, weight="bold", va="top")
    for cells in stratigraphy(spec):
        y -= 0.018
        for xi, cell in zip(x, cells):
            fig.text(xi, y, cell, fontsize=7.5, va="top", family="monospace")
    return y - 0.03


def _inputs_page(ds: xr.Dataset, page: int, pages: int) -> Figure:
    fig = _page()
    _margins(fig, ds, page, pages)
    spec = json.loads(ds.attrs.get("case_spec", "{}"))
    y = _stratigraphy_table(fig, 0.955, spec)
    skip = _layered_inputs(spec)
    params = {name: value for name, value in flat_parameters(ds.attrs.get("case_spec", "{}")).items()
              if name not in skip and not name.startswith("ground_layers_")}
    rows = []
    for name, value in params.items():
        attrs = parameter_attrs(name, numeric=isinstance(value, (int, float)) and not isinstance(value, bool))
        unit, factor = (parameter_unit(parameter_path(name), attrs["units"], params.get("loads_gravity"))
                        if "units" in attrs else ("", 1.0))
        unit = "" if unit == "1" else unit
        text = f"{value * factor:.6g}" if isinstance(value, float) else str(value)
        rows.append((attrs.get("long_name", name), f"{text} {unit}".strip(), name))
    step = min(0.0185, (y - 0.2) / max(len(rows), 1))
    y = _table(fig, y, rows, title="Other inputs (every default filled in; JSON names on the right, in SI there)",
               size=min(8.5, 420 * step), step=step)
    diagnostics = [(SCALARS[name][1], shown_value(ds[name].values, SCALARS[name][0], name), name)
                   for name in DIAGNOSTICS if name in ds]
    _table(fig, max(y, 0.16), diagnostics, title="Solver diagnostics (how the answer was found)", size=8, step=0.017)
    return fig


def _basis_page(ds: xr.Dataset, spec: dict, page: int, pages: int) -> Figure:
    """The design basis: the code clauses and partial factors this check used, and what the
    model assumes (a calculation record states them)."""
    fig = _page()
    _margins(fig, ds, page, pages)
    design = spec.get("design", {})
    gamma = load_factor(ds)
    fck = float(design.get("concrete_strength", float("nan"))) / 1e6
    fyk = float(design.get("steel_strength", float("nan"))) / 1e6
    area = float(design.get("reinforcement_area", 0.0))
    lines = [
        ("Standard", "EN 1992-1-1:2004 (Eurocode 2), recommended values of the partial factors"),
        ("Actions", f"the FE section forces N, M, V times γF = {gamma:g} (design.load_factor) for the ULS; "
                    "SLS checks at characteristic values (γF = 1)"),
        ("Concrete", f"fck = {fck:g} MPa, γC = {GAMMA_C:g}, αcc = {ALPHA_CC:g} (reinforced) / αcc,pl = "
                     f"{ALPHA_CC_PL:g} (plain, §12.3.1): fcd = αcc fck / γC; parabola–rectangle diagram (3.17)"),
        ("Steel", f"fyk = {fyk:g} MPa, γS = {GAMMA_S:g}, Es = {ES / 1e9:g} GPa, class B, εud = {EPS_UD:g} (§3.2.7)"
                  + (f"; As = {area * 1e4:.3g} cm²/m per face" if area else "; plain section (no reinforcement)")),
        ("N–M", "§6.1: the section's design resistance envelope at the design thrust; where bending governs a "
                "lower thrust is unfavourable"),
        ("Plain sections", "§12.6.1 (12.10), the rectangular stress block, no tension; the joints' contact "
                           "strips checked by (12.10) as plain sections"),
        ("Model", "2D plane strain, P2 elements, staged excavation (λd released before the lining), contact "
                  "by the bolt-point method (Janovský & Procházka 1980); small displacements"),
    ]
    fig.text(0.06, 0.955, "Design basis: code clauses and partial factors", fontsize=14, weight="bold", va="top")
    y = 0.91
    for head, text in lines:
        wrapped = textwrap.wrap(text, 88)
        fig.text(0.07, y, head, fontsize=9, weight="bold", va="top")
        fig.text(0.25, y, "\n".join(wrapped), fontsize=9, va="top")
        y -= 0.022 * len(wrapped) + 0.012
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


#: Each figure's caption in the report (what it shows and how to read it).
CAPTIONS = {
    "model": "The model: the half section with its layers, the water table, the boundary conditions and the mesh.",
    "contact_pressure": "Contact pressure on the lining's extrados against the angle from the crown.",
    "lining_forces": "The lining's section forces: thrust N, bending moment M and shear V around the ring.",
    "interaction": "N–M interaction: the design section forces of every station against the EN 1992 envelope.",
    "surface_settlement": "Surface settlement: the FE trough and the Gaussian trough holding the ground loss.",
    "deformed_mesh": "The deformed mesh (magnified), every body in one reference since excavation.",
    "contours": "Fields near the tunnel: displacement, effective stresses, pore pressure and plastic strain.",
    "ground_reaction": "Convergence–confinement: the ground reaction curve, the lining's line and the FE end state.",
}


def _figure_page(ds: xr.Dataset, figure: Figure, name: str, page: int, pages: int, number: int) -> Figure:
    """``figure`` itself as an A4 landscape page, numbered and captioned, kept as vector graphics
    (the mesh plots rasterize their thousands of faces themselves, their lines and text stay vector)."""
    figure.set_size_inches(*A4_LANDSCAPE)
    engine = figure.get_layout_engine()
    if engine is not None and hasattr(engine, "set"):
        engine.set(rect=(0.02, 0.07, 0.96, 0.90))  # room for the margins and the caption
    _margins(figure, ds, page, pages)
    caption = CAPTIONS.get(name, name.replace("_", " "))
    figure.text(0.04, 0.045, f"Figure {number}. {caption}", fontsize=9, va="bottom", style="italic", gid="caption")
    return figure


def case_report(ds: xr.Dataset, title: dict | None = None, notes: Sequence[str] = ()) -> bytes:
    """The PDF report of a case result (bytes): a calculation record with the title block's
    fields (:data:`TITLE_FIELDS`, optional) on page 1; ``notes``: lines said under its
    description (that it is a reliability study's design point)."""
    from .plots import PLOTS

    title = title_block(title)
    spec = json.loads(ds.attrs.get("case_spec", "{}"))
    joints = has_joints(ds)
    forces = "thrust" in ds and "interface_x" in ds
    pages = 3 + forces + joints + len(PLOTS)
    buffer = io.BytesIO()
    created = datetime.now(timezone.utc).replace(microsecond=0)
    with PdfPages(buffer, metadata={"Title": f"tunnel-contact case {ds.attrs.get('case_id', '')}",
                                     "Creator": f"tunnel-contact {ds.attrs.get('software_version', '')}",
                                     "CreationDate": created}) as pdf:
        pdf.savefig(_summary_page(ds, spec, 1, pages, title, notes))
        # page 2: the whole model, as the engineer checks it before any result
        pdf.savefig(_figure_page(ds, PLOTS["model"](ds), "model", 2, pages, 1))
        pdf.savefig(_inputs_page(ds, 3, pages))
        pdf.savefig(_basis_page(ds, spec, 4, pages))
        if forces:  # the lining forces table (SPEC §9.3)
            fig = _page()
            _margins(fig, ds, 5, pages)
            draw_forces_table(fig, ds)
            pdf.savefig(fig)
        if joints:
            pdf.savefig(_joints_page(ds, spec, 5 + forces, pages))
        rest = [(name, plot) for name, plot in PLOTS.items() if name != "model"]
        for k, (name, plot) in enumerate(rest, start=5 + forces + joints):
            pdf.savefig(_figure_page(ds, plot(ds), name, k, pages, k - 3 - forces - joints))
    return buffer.getvalue()

