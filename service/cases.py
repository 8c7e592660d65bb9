"""``/cases``: submit one case, follow it, fetch its result and plots."""
from __future__ import annotations

import asyncio
from enum import Enum
from pathlib import Path
from typing import Literal, Optional

from fastapi import APIRouter, Depends, Query, Request, Response
from fastapi.responses import FileResponse

from solver.spec import CaseSpec, content_id
from solver.spec.plausible import plausibility_warnings
from workflows.files import DamagedFile
from workflows.plots import PLOTS, STAGED_PLOTS
from workflows.result_store import as_store, estimated_result_bytes

from workflows.artifacts import render_plot, render_report
from .errors import invalid, responses
from .guards import check_capacity, require_token
from .job_records import UNREADABLE
from .params import NETCDF, CaseId, Offset, jobs_of, not_found, not_ready
from .results import forget_read
from .schemas import Case, CaseAccepted, CasePage, FieldError, Status, json_response

router = APIRouter(prefix="/cases", tags=["cases"])

#: Plot names accepted in ``/cases/{id}/plots/{name}.png``.
PlotName = Enum("PlotName", {name: name for name in PLOTS}, type=str)


#: ``?retry=failed``: recompute what failed (SPEC §6).
Retry = Literal["failed"]
RETRY_QUERY = Query(None, description="'failed': recompute the case(s) that failed, and those whose "
                                      "stored result is missing or unreadable")


@router.post("", status_code=202, response_model=CaseAccepted,
             dependencies=[Depends(require_token)], responses=responses(401, 413, 422, 429, 503))
async def submit_case(spec: CaseSpec, request: Request, retry: Optional[Retry] = RETRY_QUERY) -> Response:
    """Record a case and queue it; a case seen before is returned as it is, not recomputed
    (unless ``retry=failed`` and it failed)."""
    jobs = jobs_of(request)
    spec_json = spec.canonical_json()
    case_id = content_id(spec_json)  # = spec.case_id, without building the JSON again
    known = jobs.store.get_case(case_id)
    room = estimated_result_bytes(spec)
    if known is None or known.status == "cancelled" or (retry and known.status == "failed"):
        check_capacity(request, need_bytes=room)
    if known is not None and UNREADABLE in known.spec:  # the posted case is what the record lost
        jobs.store.repair_spec(case_id, spec_json)
        known = jobs.store.get_case(case_id)
    if known is None:
        record, created = jobs.store.add_case(case_id, spec.named_json(), room=room)  # the name is recorded, not hashed
    elif known.status == "cancelled" and jobs.store.requeue([case_id]):  # submitted again
        record, created = jobs.store.get_case(case_id), True
    else:
        record, created = known, False
    if created:
        jobs.submit(record.id, spec.named_json())
    elif retry and await jobs.retry([record.id]):
        record = jobs.store.get_case(record.id)
    return json_response(CaseAccepted.of(record, created=created, input_warnings=plausibility_warnings(spec)),
                         status_code=202,
                         headers={"Location": f"/cases/{record.id}"})


@router.get("", response_model=CasePage, responses=responses(422))
async def list_cases(request: Request,
                     status: Optional[Status] = Query(None, description="only cases in this status"),
                     limit: int = Query(100, ge=1, le=1000),
                     offset: Offset = 0,
                     newest_first: bool = Query(False, description="newest submission first")) -> CasePage:
    """Cases, oldest submission first (or newest), a page at a time."""
    records, total = jobs_of(request).store.list_cases(status=status, limit=limit, offset=offset,
                                                       newest_first=newest_first)
    return CasePage(items=[Case.of(r) for r in records], total=total, limit=limit, offset=offset)


@router.get("/{case_id}", response_model=Case, responses=responses(404))
async def get_case(case_id: CaseId, request: Request) -> Response:
    """A case's status, spec, summary scalars and error."""
    return json_response(read_case(request, case_id))


def read_case(request: Request, case_id: str) -> Case:
    """The case ``case_id`` as the API shows it (404 if unknown)."""
    record = jobs_of(request).store.get_case(case_id)
    if record is None:
        raise not_found("case", case_id)
    return Case.of(record)


async def _result_of_done_case(request: Request, case_id: str) -> Path:
    """The readable result file of a case that is done: 404 unknown, 409 not done yet.

    A done case whose file is missing or unreadable is never served: it goes back to
    the queue and the answer is 409.
    """
    jobs = jobs_of(request)
    record = jobs.store.get_case(case_id)
    if record is None:
        raise not_found("case", case_id)
    if record.status != "done":
        raise not_ready(f"case {case_id}", record.status)
    store = as_store(jobs.root)
    broken = await jobs.recompute_broken(case_id)
    if not broken and store.url:  # on object storage: a verified copy of the object to serve
        try:
            await asyncio.to_thread(store.verified_copy, case_id)
        except (FileNotFoundError, DamagedFile):
            forget_read(case_id)
            broken = await jobs.recompute_broken(case_id)
    if broken:
        raise not_ready(f"case {case_id}", "its stored result was missing or unreadable; it is being recomputed")
    return store.case_path(case_id)


@router.get("/{case_id}/result.nc", response_class=FileResponse, responses={
    200: {"content": {NETCDF: {}}, "description": "the case's result (netCDF-4, SPEC §3)"},
    **responses(404, 409)})
async def get_case_result(case_id: CaseId, request: Request) -> FileResponse:
    """The result file of a finished case (409 until it is done)."""
    path = await _result_of_done_case(request, case_id)
    return FileResponse(path, media_type=NETCDF, filename=f"{case_id}.nc")


@router.get("/{case_id}/report.pdf", response_class=FileResponse, responses={
    200: {"content": {"application/pdf": {}}, "description": "the case's printable report, written once and cached"},
    **responses(404, 409, 422)})
async def get_case_report(case_id: CaseId, request: Request,
                          project: Optional[str] = Query(None, max_length=120, description="title block: project"),
                          job: Optional[str] = Query(None, max_length=40, description="title block: job number"),
                          author: Optional[str] = Query(None, max_length=60, description="title block: author"),
                          checker: Optional[str] = Query(None, max_length=60, description="title block: checker"),
                          revision: Optional[str] = Query(None, max_length=20, description="title block: revision"),
                          date: Optional[str] = Query(None, max_length=20, description="title block: date "
                                                                                          "(default today)"),
                          ) -> FileResponse:
    """The printable report of a finished case, a calculation record: the title block (optional
    fields), the design answer (PASS/FAIL), the results in engineering units, the warnings, the
    model, the stratigraphy and every input, the design basis and every figure, on A4 pages."""
    await _result_of_done_case(request, case_id)
    jobs = jobs_of(request)
    title = {"project": project, "job": job, "author": author, "checker": checker, "revision": revision,
             "date": date}
    try:
        path = await asyncio.to_thread(render_report, jobs.root, case_id, title=title)
    except Exception:
        if await jobs.recompute_broken(case_id):
            raise not_ready(f"case {case_id}", "its stored result was missing or unreadable; "
                                               "it is being recomputed") from None
        raise
    return FileResponse(path, media_type="application/pdf", filename=f"{case_id}.pdf")


@router.get("/{case_id}/plots/{name}.png", response_class=FileResponse, responses={
    200: {"content": {"image/png": {}}, "description": "the figure, rendered once and cached"},
    **responses(404, 409, 422)})
async def get_case_plot(case_id: CaseId, name: PlotName, request: Request,
                        stage: Optional[Literal["total", "1", "2"]] = Query(
                            None, description="deformed_mesh: the construction stage shown (every body in one "
                                              "reference): total since excavation, 1 before the lining, 2 since "
                                              "its placement")) -> Response:
    """A figure of a finished case (one of :data:`workflows.plots.PLOTS`)."""
    if stage is not None and name.value not in STAGED_PLOTS:
        return invalid([FieldError(field="stage", type="value_error",
                                   reason=f"the plot {name.value!r} has no stages (only {', '.join(STAGED_PLOTS)})")])
    await _result_of_done_case(request, case_id)
    jobs = jobs_of(request)
    try:
        path = await asyncio.to_thread(render_plot, jobs.root, case_id, name.value, stage=stage)
    except Exception:
        # the file may have broken since it was checked: then recompute, else a real fault
        if await jobs.recompute_broken(case_id):
            raise not_ready(f"case {case_id}", "its stored result was missing or unreadable; "
                                               "it is being recomputed") from None
        raise
    return FileResponse(path, media_type="image/png")
