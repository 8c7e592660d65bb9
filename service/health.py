"""``/health``: is the service able to do its job right now?"""
from __future__ import annotations

import asyncio
import os
import sqlite3
import tempfile

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse

from .guards import free_bytes
from .params import jobs_of, settings_of
from .schemas import Health

router = APIRouter(tags=["health"])


def _results_writable(root) -> bool:
    try:
        with tempfile.NamedTemporaryFile(dir=root, prefix=".health-", delete=True) as fh:
            fh.write(b"ok")
            fh.flush()
        return os.access(root, os.W_OK)
    except OSError:
        return False


@router.get("/health", response_model=Health, responses={503: {"model": Health, "description": "degraded"}})
async def health(request: Request) -> Health | JSONResponse:
    """200 when the scheduler answers, has workers, and the results store takes writes and has
    room for a case; else 503 with the same body, ``reasons`` saying what is wrong."""
    jobs = jobs_of(request)
    reachable, workers = await jobs.cluster_state()
    settings = settings_of(request)
    free = await asyncio.to_thread(free_bytes, jobs.root)
    writable = (free >= settings.min_free_bytes and await asyncio.to_thread(_results_writable, jobs.root)
                and jobs.store.writable())
    try:
        counts = jobs.store.status_counts()
    except sqlite3.Error:
        counts, writable = {"queued": 0, "running": 0}, False
    reasons = [text for ok, text in (
        (reachable, "scheduler unreachable"), (not reachable or workers > 0, "no workers"),
        (free >= settings.min_free_bytes,
         f"{free / 2**20:.1f} MiB free in the results directory, a case needs up to "
         f"{settings.min_free_bytes / 2**20:.0f} MiB"),
        (writable or free < settings.min_free_bytes, "results directory or job records refuse writes"))
        if not ok]
    address = settings.scheduler or (jobs.client.scheduler.address if jobs.client else None)
    body = Health(status="ok" if not reasons else "degraded", reasons=reasons,
                  scheduler=address, scheduler_reachable=reachable, workers=workers,
                  results_writable=writable, results_free_bytes=free,
                  queued=counts["queued"], running=counts["running"])
    if body.status != "ok":
        return JSONResponse(status_code=503, content=body.model_dump())
    return body
