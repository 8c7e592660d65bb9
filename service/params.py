"""What the routers share: id path parameters, access to app state, common errors."""
from __future__ import annotations

from typing import Annotated

from fastapi import HTTPException, Path, Query, Request

from .jobs import Dispatcher
from .schemas import CASE_ID_PATTERN
from .settings import Settings
from .job_records import SweepRecord

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
