"""What the routers share: id path parameters, access to app state, common errors."""
from __future__ import annotations

import asyncio
import logging
from typing import Annotated, Callable, TypeVar

from fastapi import HTTPException, Path, Query, Request

from workflows.files import DamagedFile

from .jobs import Dispatcher
from .schemas import CASE_ID_PATTERN
from .settings import Settings
from .job_records import SweepRecord
from .results import damaged_case, forget

logger = logging.getLogger(__name__)
T = TypeVar("T")

CaseId = Annotated[str, Path(pattern=CASE_ID_PATTERN, description="case id, 16 lowercase hex digits")]
SweepId = Annotated[str, Path(pattern=CASE_ID_PATTERN, description="sweep id, 16 lowercase hex digits")]
SearchId = Annotated[str, Path(pattern=CASE_ID_PATTERN, description="search id, 16 lowercase hex digits")]

#: Largest page offset (SQLite integers are 64-bit; no store holds a billion records).
MAX_OFFSET = 1_000_000_000
Offset = Annotated[int, Query(ge=0, le=MAX_OFFSET, description="records to skip")]

NETCDF = "application/x-netcdf"


def jobs_of(request: Request) -> Dispatcher:
    return request.app.state.jobs


def settings_of(request: Request) -> Settings:
    return request.app.state.settings


def not_found(kind: str, ident: str) -> HTTPException:
    return HTTPException(status_code=404, detail=f"unknown {kind} {ident}")


def sweep_or_404(request: Request, sweep_id: str) -> SweepRecord:
    """The stored sweep ``sweep_id``; 404 if there is none."""
    record = jobs_of(request).store.get_sweep(sweep_id)
    if record is None:
        raise not_found("sweep", sweep_id)
    return record


def not_ready(what: str, status: str) -> HTTPException:
    return HTTPException(status_code=409, detail=f"{what} not ready: {status}")


async def sweep_results(jobs: Dispatcher, record: SweepRecord) -> list[str]:
    """The sweep's done cases whose result files read back (a broken one goes back to the
    queue), for its combined file and its plots; none: :func:`no_sweep_result` is raised."""
    done = await jobs.readable_results(record.case_ids)
    if not done:
        raise no_sweep_result(record.id, jobs.store.status_counts(record.case_ids))
    return done


async def build_over_results(jobs: Dispatcher, record: SweepRecord, build: Callable[[list[str]], T]
                             ) -> tuple[list[str], T]:
    """``(done, build(done))`` over the sweep's readable done cases (:func:`sweep_results`),
    ``build`` run in a thread. A case file found damaged while building (it no longer matches
    its checksum though it read back earlier) goes back to the queue, and the rest are built
    again: a damaged result is recomputed, never served, nor a reason for a server error."""
    for _ in range(len(record.case_ids) + 1):
        done = await sweep_results(jobs, record)
        try:
            return done, await asyncio.to_thread(build, done)
        except DamagedFile as exc:
            case_id = damaged_case(exc, jobs.root)
            if case_id is None or case_id not in done:
                raise
            logger.warning("result of case %s found damaged (%s): recomputing it", case_id, exc)
            forget(case_id)
            await jobs.recompute_broken(case_id)
    raise RuntimeError(f"sweep {record.id}: its results kept changing while they were combined")


def no_sweep_result(sweep_id: str, counts: dict[str, int]) -> HTTPException:
    """Why a sweep with no readable done case has no result (combined file, plots): 409 while
    a case is still queued or running (it may yet finish), else 404 saying what became of the
    cases, so that a polling client stops."""
    if counts["queued"] + counts["running"]:
        return not_ready(f"sweep {sweep_id}", "no case is done yet")
    failed, cancelled = counts["failed"], counts["cancelled"]
    total = failed + cancelled
    if failed and not cancelled:
        what = f"all {failed} cases failed" if failed > 1 else "its only case failed"
    elif cancelled and not failed:
        what = f"all {cancelled} cases were cancelled" if cancelled > 1 else "its only case was cancelled"
    else:
        what = f"none of its {total} cases is done ({failed} failed, {cancelled} cancelled)"
    how = [hint for hint, needed in (("POST /sweeps?retry=failed recomputes failed cases", failed),
                                     ("posting the sweep again resumes cancelled ones", cancelled)) if needed]
    return HTTPException(status_code=404, detail=f"sweep {sweep_id} has no result: {what} ({'; '.join(how)})")
