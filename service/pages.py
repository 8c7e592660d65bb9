"""The dashboard: server-rendered pages over the same functions as the JSON routes.

``/`` lists sweeps and recent cases; ``/ui/sweeps/{id}`` is a sweep (progress, the
comparison table, plots, downloads); ``/ui/cases/{id}`` a case (summary, plots,
downloads, its JSON); ``/ui/submit`` a form for a case or a sweep. Templates and the
small script that keeps the status live (it polls the JSON routes) ship in the
package (:mod:`service.views` renders them): no build step, nothing fetched from outside.
"""
from __future__ import annotations

import asyncio
import json
import logging
import math
from typing import Optional
from urllib.parse import urlencode

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse

from solver.results.mesh_check import MESH_CHANGE_LIMIT
from solver.results.variables import ECCENTRICITY_LIMIT, SCALARS
from solver.spec import CaseSpec
from solver.spec.plausible import plausibility_warnings
from workflows.case_tables import stored_forces
from workflows.joint_check import statement
from workflows.section_check import check_of
from workflows.plots import PLOTS, SWEEP_PLOT_NAMES
from workflows.reliability_methods.records import design_point_of
from workflows.studies import MIN_SAMPLES, SENSITIVITY_MIN_SAMPLES
from workflows.units import DIAGNOSTICS

from . import cases, reliability, searches, studies
from .comparison import Column, comparison_table, ordered_scalars, scalar_column
from .form import case_form
from .params import CaseId, SearchId, SweepId, jobs_of, sweep_or_404
from .schemas import SweepStatus
from .studies import RANDOM_MODES
from .views import render

logger = logging.getLogger(__name__)

router = APIRouter(include_in_schema=False)

#: A small sweep for the submit form: coarse mesh, four cases. The ground block is the
#: default one (side boundary about 14 radii out): a narrower one stiffens the ground and
#: understates the settlements.
EXAMPLE_SWEEP = {
    "name": "thickness-and-stiffness",
    "base": {"mesh": {"interface_size": 0.15, "far_size": 8.0}},
    "vary": {"lining.thickness": [0.2, 0.3], "ground.young": [2.0e7, 5.0e7]},
    "mode": "grid",
}
EXAMPLE_CASE = {"geometry": {"thickness": 0.3, "gap": 0.01}, "mesh": {"interface_size": 0.1, "far_size": 6.0}}


@router.get("/", response_class=HTMLResponse)
async def index(request: Request) -> HTMLResponse:
    sweep_page = await studies.list_sweeps(request, limit=20, offset=0)
    search_list = (await searches.list_searches(request, limit=20, offset=0)).items
    studies_list = (await reliability.list_reliability(request, limit=20, offset=0)).items
    case_page = await cases.list_cases(request, status=None, limit=20, offset=0, newest_first=True)
    workers = (await jobs_of(request).cluster_state())[1]
    return await render(request, "index.html", sweeps=sweep_page, cases=case_page, workers=workers,
                         searches=search_list, reliability=studies_list)


@router.get("/ui/sweeps/{sweep_id}", response_class=HTMLResponse)
async def sweep_page(sweep_id: SweepId, request: Request, output: str = "max_abs_moment",
                     reliability_output: str = "max_utilization", limit: float = 1.0) -> HTMLResponse:
    store = jobs_of(request).store
    record = sweep_or_404(request, sweep_id)  # read once for the status, the table and the spec
    status = SweepStatus.of(record, store.status_counts(record.case_ids))
    outputs = sorted(SCALARS)
    output = output if output in SCALARS else "max_abs_moment"
    reliability_output = reliability_output if reliability_output in SCALARS else "max_utilization"
    limit = limit if math.isfinite(limit) else 1.0
    mode = record.spec.get("mode", "grid")
    analyses = {"min_samples": MIN_SAMPLES, "sensitivity_min": SENSITIVITY_MIN_SAMPLES, "outputs": outputs, "output": output, "limit": limit,
                "reliability_output": reliability_output, "mode": mode, "random": mode in RANDOM_MODES,
                "sensitivity_png": f"/sweeps/{sweep_id}/sensitivity.png?{urlencode({'output': output})}",
                "reliability_png": f"/sweeps/{sweep_id}/reliability.png?"
                                   f"{urlencode({'output': reliability_output, 'limit': limit})}"}
    table = comparison_table(store, record)
    return await render(request, "sweep.html", sweep=status, table=table, columns=page_columns(table.columns),
                         spec=record.spec, plots=SWEEP_PLOT_NAMES, analyses=analyses)


#: The result a sweep's reader looks at first: the section's utilization η (≤ 1 passes).
FIRST_RESULT = "max_utilization"


def page_columns(columns: list[Column]) -> list[Column]:
    """The sweep page's columns: what varies, η, the status and case (a link), the other results,
    then why a case failed. The solver's warnings are no column of their own: a mark in the status
    cell carries them (on hover), so that a row stays one line high."""
    kinds = {kind: [c for c in columns if c.kind == kind] for kind in ("parameter", "status", "id", "scalar", "text")}
    first = [c for c in kinds["scalar"] if c.name == FIRST_RESULT]
    others = [c for c in kinds["scalar"] if c.name != FIRST_RESULT]
    return kinds["parameter"] + first + kinds["status"] + kinds["id"] + others + [
        c for c in kinds["text"] if c.name != "warnings"]


@router.get("/ui/searches/{search_id}", response_class=HTMLResponse)
async def search_page(search_id: SearchId, request: Request) -> HTMLResponse:
    record = await searches.get_search(search_id, request)
    return await render(request, "search.html", search=record)


@router.get("/ui/cases/{case_id}", response_class=HTMLResponse)
async def case_page(case_id: CaseId, request: Request) -> HTMLResponse:
    case = cases.read_case(request, case_id)  # an unknown case: the error page (service.errors)
    values = {**(case.summary or {}), **{k: float(v) for k, v in case.non_finite.items()}}  # inf shown as inf
    names = ordered_scalars(values)
    checked = [n for n in names if n.startswith(MESH_CHANGE)]
    columns = [scalar_column(n) for n in names if n not in DIAGNOSTICS and n not in checked]
    diagnostics = [scalar_column(n) for n in names if n in DIAGNOSTICS]
    verdict = design_verdict(values, case.spec)
    forces = await forces_of(request, case_id) if case.status == "done" else None
    design_point = await asyncio.to_thread(design_point_of, jobs_of(request).root, case_id)
    return await render(request, "case.html", case=case, values=values, columns=columns, plots=list(PLOTS),
                        diagnostics=diagnostics, verdict=verdict, mesh_check=mesh_check_rows(values, checked),
                        forces=forces, warnings=case.warnings or input_warnings(case.spec), design_point=design_point)


async def forces_of(request: Request, case_id: str) -> Optional[dict]:
    """The lining forces table of a done case for its page (SPEC §9.3, as ``forces.csv``), values
    to 3 significant figures and the governing station (largest utilization) marked; None if its
    stored result cannot be read now (the downloads say why)."""
    try:
        table = await asyncio.to_thread(stored_forces, jobs_of(request).root, case_id)
    except Exception as exc:  # e.g. removed or damaged since: the page still answers
        logger.warning("forces table of case %s not shown: %s", case_id, exc)
        return None
    eta = table.names.index("utilization")
    values = [row[eta] for row in table.rows]
    # a station that fails at any load (inf) governs; a station without a value (NaN) never does
    governing = max(range(len(values)), key=lambda i: -math.inf if math.isnan(values[i]) else values[i]) \
        if values else None
    return {"names": table.names, "units": table.units, "governing": governing,
            "rows": [[f"{v:.3g}" if isinstance(v, float) else str(v) for v in row] for row in table.rows]}


#: The prefix of solver.mesh_check's scalars: the relative change of a key result on a mesh refined once.
MESH_CHANGE = "mesh_change_"


def mesh_check_rows(values: dict[str, float], names: list[str]) -> list[dict]:
    """The case page's mesh check (``solver.mesh_check``): per key result, its long name and its
    relative change (%) on a mesh refined once, and whether it is above the 1 % of a warning."""
    rows = []
    for name in names:
        result = name[len(MESH_CHANGE):]
        change = 100.0 * values[name]
        rows.append({"name": result, "long_name": scalar_column(result).long_name, "change": f"{change:+.2f} %",
                     "coarse": abs(values[name]) > MESH_CHANGE_LIMIT})
    return rows


def input_warnings(spec: dict) -> list[str]:
    """The implausible inputs of a recorded case (shown before its result has its own warnings)."""
    try:
        return plausibility_warnings(CaseSpec.model_validate(spec))
    except ValueError:  # a record of an older case model
        return []


def design_verdict(values: dict[str, float], spec: dict) -> Optional[dict]:
    """The case page's PASS/FAIL from a case's summary ``values``: the section's utilization
    (away from the joints of a segmental lining) and, for a segmental lining (``spec``), whether
    every joint carries its thrust within its contact strip (``max_joint_eccentricity`` ≤ 1) and the
    strip holds it (``max_joint_utilization`` ≤ 1, EN 1992-1-1 (12.10) on the strip).
    None before the case is done."""
    eta = values.get("max_utilization")
    if eta is None:
        return None
    segments = ((spec or {}).get("lining") or {}).get("joints", {}).get("count", 0)
    joints = None
    if segments and "max_joint_eccentricity" in values:
        worst = values["max_joint_eccentricity"]
        eta_j = values.get("max_joint_utilization")
        ok = bool(worst <= ECCENTRICITY_LIMIT and (eta_j is None or eta_j <= 1.0))
        joints = {"passes": ok, "text": statement(ok, worst, utilization=eta_j)}
    checks = check_of(values, spec)  # shear and crack width (SPEC §9.3)
    return {"passes": bool(eta <= 1.0) and (joints is None or joints["passes"]) and (checks is None or checks.passes),
            "section_passes": bool(eta <= 1.0), "eta": f"{eta:.3g}", "joints": joints,
            "checks": None if checks is None else {"passes": checks.passes, "text": checks.text()}}


@router.get("/ui/submit", response_class=HTMLResponse)
async def submit_page(request: Request) -> HTMLResponse:
    return await render(request, "submit.html", form=case_form(), example_sweep=json.dumps(EXAMPLE_SWEEP, indent=2),
                   example_case=json.dumps(EXAMPLE_CASE, indent=2))
