"""``/health``: is the service able to do its job right now?"""
from __future__ import annotations

import asyncio

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse

from solver.spec import CaseSpec
from workflows.files import can_write
from workflows.result_store import estimated_result_bytes, free_bytes

from .job_tables import DATABASE_ERRORS
from .params import jobs_of, settings_of
from .schemas import Health

router = APIRouter(tags=["health"])

#: Room the result of a case at the default mesh needs: less free space is a full store.
DEFAULT_CASE_BYTES = estimated_result_bytes(CaseSpec())


@router.get("/health", response_model=Health, responses={503: {"model": Health, "description": "degraded"}})
async def health(request: Request) -> Health | JSONResponse:
    """200 when the scheduler answers, has workers, and the results store takes writes and has
    room for a case; else 503 with the same body, ``reasons`` saying what is wrong."""
    jobs = jobs_of(request)
    reachable, workers = await jobs.cluster_state()
    settings = settings_of(request)
    free = await asyncio.to_thread(free_bytes, jobs.root)
    room = max(settings.min_free_bytes, DEFAULT_CASE_BYTES)
    writable = await asyncio.to_thread(can_write, jobs.root) and jobs.store.writable()
    try:
        counts = jobs.store.status_counts()
    except DATABASE_ERRORS:
        counts, writable = {"queued": 0, "running": 0}, False
    reasons = [text for ok, text in (
        (reachable, "scheduler unreachable"), (not reachable or workers > 0, "no workers"),
        (free >= room or not writable,
         f"results store is full: {free / 2**20:.1f} MiB free, a case at the default mesh needs about "
         f"{room / 2**20:.0f} MiB"),
        (writable, "results store is read-only: the results directory or the job records refuse writes "
                   "(stored results are still served)"))
        if not ok]
    address = settings.scheduler or (jobs.client.scheduler.address if jobs.client else None)
    body = Health(status="ok" if not reasons else "degraded", reasons=reasons,
                  scheduler=address, scheduler_reachable=reachable, workers=workers,
                  results_writable=writable, results_free_bytes=free,
                  queued=counts["queued"], running=counts["running"])
    if body.status != "ok":
        return JSONResponse(status_code=503, content=body.model_dump())
    return body
