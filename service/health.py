"""``/health``: is the service able to do its job right now?"""
from __future__ import annotations

import asyncio
import os
import tempfile

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse

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
    """200 when the scheduler answers, has workers, and the results store takes writes; else 503."""
    jobs = jobs_of(request)
    reachable, workers = await jobs.cluster_state()
    writable = await asyncio.to_thread(_results_writable, jobs.root) and jobs.store.writable()
    counts = jobs.store.status_counts()
    address = settings_of(request).scheduler or (jobs.client.scheduler.address if jobs.client else None)
    body = Health(status="ok" if reachable and workers > 0 and writable else "degraded",
                  scheduler=address, scheduler_reachable=reachable, workers=workers,
                  results_writable=writable, queued=counts["queued"], running=counts["running"])
    if body.status != "ok":
        return JSONResponse(status_code=503, content=body.model_dump())
    return body
