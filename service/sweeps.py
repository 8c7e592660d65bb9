"""``/sweeps``: submit a parametric study, follow it, fetch its combined result."""
from __future__ import annotations

import asyncio
from typing import Optional

from fastapi import APIRouter, Depends, Request, Response
from fastapi.responses import FileResponse, JSONResponse

from solver.spec import CaseSpec
from workflows import Sweep, SweepError, expand_sweep
from workflows.result_store import estimated_result_bytes
from workflows.sweep import sweep_size

from workflows.artifacts import write_combined
from .errors import invalid, responses
from .cases import RETRY_QUERY, Retry
from .guards import check_capacity, require_token
from .params import NETCDF, SweepId, build_over_results, jobs_of, settings_of, sweep_or_404
from .schemas import FieldError, SweepAccepted, SweepStatus

router = APIRouter(prefix="/sweeps", tags=["sweeps"])


@router.post("", status_code=202, response_model=SweepAccepted,
             dependencies=[Depends(require_token)], responses=responses(401, 413, 422, 429, 503))
async def submit_sweep(sweep: Sweep, request: Request, response: Response,
                       retry: Optional[Retry] = RETRY_QUERY) -> SweepAccepted | JSONResponse:
    """Expand a sweep into cases, record them and queue the ones not known before
    (``retry=failed``: and recompute those of its cases that failed)."""
    jobs = jobs_of(request)
    record = jobs.store.get_sweep(sweep.sweep_id)
    created, new = False, []
    if record is None:
        cap = settings_of(request).max_sweep_cases
        size = sweep_size(sweep)
        if size > cap:
            return invalid([FieldError(field="vary", type="too_many_cases",
                                       reason=f"the sweep has {size:,} cases, over this service's cap of {cap:,}")])
        try:
            specs = await asyncio.to_thread(expand_sweep, sweep)
        except SweepError as exc:
            return invalid([FieldError(field=path, reason=message, type="value_error")
                            for path, message in exc.errors])
        cases = [(s.case_id, s.canonical_json()) for s in specs]
        known = jobs.store.statuses([c for c, _ in cases])
        rooms = {s.case_id: estimated_result_bytes(s) for s in specs if s.case_id not in known}
        check_capacity(request, len(cases) - len(known), sum(rooms.values()))
        record, new = await enqueue_sweep(jobs, sweep, cases, rooms)
        created = True
    new += requeue_cancelled(jobs, record)
    retried = []
    if retry:
        failed = await asyncio.to_thread(_failed_cases, jobs, record)  # each validated: off the loop
        if failed:  # the room of the failed cases that name a case (the others stay failed)
            check_capacity(request, len(failed), sum(map(estimated_result_bytes, failed)))
        retried = await jobs.retry(list(record.case_ids))
    response.headers["Location"] = f"/sweeps/{record.id}"
    counts = jobs.store.status_counts(record.case_ids)
    return SweepAccepted(**SweepStatus.of(record, counts).model_dump(), created=created, new_cases=len(new),
                         resubmitted=len(retried))


@router.get("/{sweep_id}", response_model=SweepStatus, responses=responses(404))
async def get_sweep(sweep_id: SweepId, request: Request) -> SweepStatus:
    """A sweep's cases and how many are in each status."""
    record = sweep_or_404(request, sweep_id)
    return SweepStatus.of(record, jobs_of(request).store.status_counts(record.case_ids))


@router.get("/{sweep_id}/result.nc", response_class=FileResponse, responses={
    200: {"content": {NETCDF: {}}, "description": "combined results of the sweep's finished cases "
                                                   "(header X-Cases-Included: done/total)"},
    **responses(404, 409)})
async def get_sweep_result(sweep_id: SweepId, request: Request) -> FileResponse:
    """The combined dataset (dim ``case``) of the sweep's finished cases; 409 while none is done
    but some is still queued or running, 404 (saying why) when none is done and none is open."""
    jobs, record = jobs_of(request), sweep_or_404(request, sweep_id)
    done, path = await build_over_results(jobs, record, lambda ids: write_combined(jobs.root, sweep_id, ids))
    return FileResponse(path, media_type=NETCDF, filename=f"sweep-{sweep_id}.nc",
                        headers={"X-Cases-Included": f"{len(done)}/{len(record.case_ids)}"})


async def enqueue_sweep(jobs, sweep: Sweep, cases: list[tuple[str, str]], rooms: dict[str, int]):
    """Record the sweep (job records and its record on disk) and submit its cases not known
    before; ``(record, new case ids)``. ``rooms``: the bytes each case's result will take (held
    for it while it is open). POST /sweeps and a search's trials come here."""
    record, new = jobs.store.add_sweep(sweep.sweep_id, sweep.name, sweep.definition_json(), cases, rooms)
    await jobs.record_sweep_on_disk(record)
    specs_by_id = dict(cases)
    for case_id in new:
        jobs.submit(case_id, specs_by_id[case_id])
    return record, new


def _failed_cases(jobs, record) -> list[CaseSpec]:
    """The cases of the sweep's ``failed`` records whose spec is a valid case."""
    cases = []
    for case in jobs.store.get_cases(list(record.case_ids)).values():
        if case.status == "failed":
            try:
                cases.append(CaseSpec.model_validate(case.spec))
            except ValueError:  # a record that names no case (pydantic's ValidationError too)
                pass
    return cases


def requeue_cancelled(jobs, record) -> list[str]:
    """Submit again the sweep's cases cancelled earlier (in this sweep or another)."""
    again = []
    for case_id in jobs.store.requeue(record.case_ids):
        again.append(case_id)
        jobs.submit(case_id, CaseSpec.model_validate(jobs.store.get_case(case_id).spec).canonical_json())
    return again
