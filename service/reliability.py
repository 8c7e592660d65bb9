"""``/reliability`` (SPEC §9.6): FORM, subset simulation and AK-MCS on the FE model, every
call a case of this service.

A study runs in a thread (:func:`workflows.reliability_methods.run_study`, the algorithm knows only its
limit state); its FE calls come back here as cases, recorded in the job records and queued to
the dispatcher like any posted case, and the thread waits for them. The study's record is its
JSON file in the results store (:mod:`workflows.reliability_methods.records`); on start-up every study
still running is started again, replays its (seeded) points, finds their cases done, and goes
on: a study killed midway ends with the answer it would have given.

With several API replicas on one database a study is driven by the replica holding its lease
(``reliability:<id>``), renewed at every look at its cases; the others take over the driving of a
replica that died (:func:`service.replicas.adopt_orphans`), replaying the study as a restart does.
"""
from __future__ import annotations

import asyncio
import concurrent.futures
import logging
import time
from typing import Annotated, Sequence

from fastapi import APIRouter, Depends, Query, Request, Response
from fastapi import Path as PathParam
from fastapi.responses import HTMLResponse
from pydantic import BaseModel

from workflows.reliability_methods import ReliabilityRecord, ReliabilityStudy, all_records, read_record, run_study
from workflows.reliability_methods.driver import finished, recorder
from workflows.reliability_methods.records import new_record, write_record
from workflows.result_store import as_store, estimated_result_bytes

from .errors import responses
from .guards import check_capacity, require_token
from .params import Offset, not_found
from .replicas import adopt_orphans
from .schemas import CASE_ID_PATTERN
from .views import render

logger = logging.getLogger(__name__)
router = APIRouter(tags=["studies"])

StudyId = Annotated[str, PathParam(pattern=CASE_ID_PATTERN, description="study id, 16 lowercase hex digits")]

#: Seconds between looks at the cases a study waits for.
POLL = 0.25


class StudyStopped(RuntimeError):
    """The service stops while a study waits for its cases."""


class LeaseLost(RuntimeError):
    """Another replica drives the study now (this one's lease expired: it was too slow to renew it)."""


def _lease(ident: str) -> str:
    return f"reliability:{ident}"


class JobRunner:
    """A study's runner (:data:`workflows.reliability_methods.limit_state.Runner`) over the service's
    job queue; called from the study's thread, it does its job-record work on the event loop."""

    def __init__(self, jobs, loop: asyncio.AbstractEventLoop, lease: str):
        self.jobs, self.loop, self.lease = jobs, loop, lease
        self.stopped = False

    def __call__(self, specs: Sequence) -> list[dict]:
        cases = [(s.case_id, s.canonical_json()) for s in specs]
        future = asyncio.run_coroutine_threadsafe(self._solve(cases), self.loop)
        while True:  # never blocks a stopping service: its loop would wait for this thread
            try:
                return future.result(timeout=0.5)
            except concurrent.futures.TimeoutError:
                if self.stopped or self.loop.is_closed():
                    future.cancel()
                    raise StudyStopped("the service stopped; the study resumes when it starts again") from None

    async def _solve(self, cases: list[tuple[str, str]]) -> list[dict]:
        jobs = self.jobs
        for case_id, spec_json in cases:
            known = jobs.store.get_case(case_id)
            if known is None:
                record, created = jobs.store.add_case(case_id, spec_json)
                if created:
                    jobs.submit(case_id, spec_json)
            elif known.status == "cancelled" and jobs.store.requeue([case_id]):
                jobs.submit(case_id, spec_json)
            elif known.status in ("queued", "running"):
                jobs.submit(case_id, spec_json)  # no-op when on its way; a lost task goes again
        ids = [c for c, _ in cases]
        while True:  # the lease renewed at every look, so also through a replay of cases all done
            if not await asyncio.to_thread(jobs.store.take_lease, self.lease):
                raise LeaseLost(f"the lease {self.lease} went to another replica")
            counts = jobs.store.status_counts(ids)
            if counts["queued"] == 0 and counts["running"] == 0:
                break
            await asyncio.sleep(POLL)
        records = jobs.store.get_cases(ids)
        return [{"case_id": c, "status": r.status, "summary": r.summary, "error": r.error}
                for c, r in records.items()]


class Studies:
    """The reliability studies of one results store and the tasks that drive the running ones."""

    def __init__(self, jobs):
        self.jobs = jobs
        self.root = as_store(jobs.root)  # the store itself: a bucket's records are its objects
        self.tasks: dict[str, asyncio.Task] = {}
        self.runners: dict[str, JobRunner] = {}
        self.adopting: asyncio.Task | None = None

    def start(self, record: ReliabilityRecord) -> None:
        """Drive ``record`` here if it is running, not driven here yet and its lease is free."""
        if record.status == "running" and record.id not in self.tasks and self.jobs.store.take_lease(_lease(record.id)):
            logger.info("driving reliability study %s (%d of %d calls made)", record.id, record.calls, record.budget)
            self.tasks[record.id] = asyncio.get_running_loop().create_task(self._drive(record))

    def resume(self) -> None:
        for record in all_records(self.root):
            self.start(record)
        if self.adopting is None:
            self.adopting = asyncio.get_running_loop().create_task(
                adopt_orphans(lambda: all_records(self.root), self.start, "reliability studies"))

    async def stop(self) -> None:
        for runner in self.runners.values():
            runner.stopped = True
        tasks = [*self.tasks.values(), *([self.adopting] if self.adopting else [])]
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        self.tasks.clear()
        self.adopting = None

    async def _drive(self, record: ReliabilityRecord) -> None:
        lease = _lease(record.id)
        runner = self.runners[record.id] = JobRunner(self.jobs, asyncio.get_running_loop(), lease)
        record = record.model_copy(update={"history": []})
        try:
            study = ReliabilityStudy.model_validate(record.study)
            result = await asyncio.to_thread(run_study, study, runner, on_progress=recorder(self.root, record))
            await asyncio.to_thread(write_record, self.root, finished(record, result))
        except asyncio.CancelledError:  # the service stops; the thread ends with its next batch
            raise
        except LeaseLost as exc:  # driven by another replica now: its record is that one's to write
            logger.warning("reliability study %s: %s; driven there", record.id, exc)
        except Exception as exc:  # a study that cannot go on says why
            logger.exception("reliability study %s failed", record.id)
            await asyncio.to_thread(write_record, self.root, record.model_copy(update={
                "status": "failed", "error": f"{type(exc).__name__}: {exc}", "finished_at": time.time()}))
        finally:
            self.tasks.pop(record.id, None)
            self.runners.pop(record.id, None)
            try:
                self.jobs.store.release_lease(lease)
            except Exception as exc:  # expires by itself
                logger.warning("could not release the lease of reliability study %s (%s)", record.id, exc)


def studies_of(request: Request) -> Studies:
    state = request.app.state
    if getattr(state, "reliability", None) is None:
        state.reliability = Studies(state.jobs)
    return state.reliability


def resume(app) -> Studies:
    """Start again the studies left running by an earlier run of the service (lifespan hook;
    ``await app.state.reliability.stop()`` on shutdown: they resume on the next start)."""
    app.state.reliability = Studies(app.state.jobs)
    app.state.reliability.resume()
    return app.state.reliability


@router.post("/reliability", status_code=202, response_model=ReliabilityRecord, dependencies=[Depends(require_token)],
             responses=responses(401, 422, 429, 503))
async def submit_reliability(study: ReliabilityStudy, request: Request, response: Response):
    """Start a reliability study (or find the same one): the probability that ``output``
    exceeds ``limit`` with ``variables`` random, by ``form``, ``subset`` or ``ak-mcs``, in at
    most ``budget`` FE cases (each a case of this service)."""
    studies = studies_of(request)
    record = await asyncio.to_thread(read_record, studies.root, study.study_id)
    if record is None or record.status == "failed":
        base = study.case_at({p: float(d.ppf(0.5)) for p, d in study.variables.items()})
        check_capacity(request, 1, study.budget * estimated_result_bytes(base))
        record = new_record(study)
        await asyncio.to_thread(write_record, studies.root, record)
    studies.start(record)
    response.headers["Location"] = f"/reliability/{record.id}"
    return record


class ReliabilityPage(BaseModel):
    items: list[ReliabilityRecord]
    total: int
    limit: int
    offset: int


@router.get("/reliability", response_model=ReliabilityPage, responses=responses(422))
async def list_reliability(request: Request, limit: int = Query(20, ge=1, le=200),
                           offset: Offset = 0) -> ReliabilityPage:
    """Reliability studies, newest first, a page at a time (without their histories)."""
    every = await asyncio.to_thread(all_records, studies_of(request).root)
    items = [r.model_copy(update={"history": [], "case_ids": []}) for r in every[offset:offset + limit]]
    return ReliabilityPage(items=items, total=len(every), limit=limit, offset=offset)


@router.get("/reliability/{study_id}", response_model=ReliabilityRecord, responses=responses(404, 422))
async def get_reliability(study_id: StudyId, request: Request) -> ReliabilityRecord:
    """A study's progress (``calls`` of ``budget``, ``stage``, ``history``) and, when done,
    ``beta``, ``probability`` with ``ci_low``/``ci_high`` (95 %), ``design_point`` and its
    case ``design_case``, ``importance`` (α²) and ``calls``."""
    record = await asyncio.to_thread(read_record, studies_of(request).root, study_id)
    if record is None:
        raise not_found("reliability study", study_id)
    return record


@router.get("/reliability/{study_id}/convergence.png", response_class=Response,
            responses={200: {"content": {"image/png": {}}}, **responses(404, 422)})
async def get_convergence_plot(study_id: StudyId, request: Request) -> Response:
    """The estimate against FE calls, and the importance factors."""
    from workflows.reliability_methods.plots import plot_study
    from workflows.study_plots import png

    record = await get_reliability(study_id, request)
    return Response(await asyncio.to_thread(lambda: png(plot_study(record))), media_type="image/png")


@router.get("/ui/reliability/{study_id}", response_class=HTMLResponse, include_in_schema=False)
async def reliability_page(study_id: StudyId, request: Request) -> HTMLResponse:
    """The dashboard's page of a study: progress, β with its interval, importance, convergence."""
    record = await get_reliability(study_id, request)
    return await render(request, "reliability.html", study=record)
