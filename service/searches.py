"""``/searches`` (SPEC §8): the smallest value of a design parameter that meets a requirement
over a set of grounds, found by bisection with each trial a sweep of the service's own.

A search's record is a JSON file in the results store (``searches/<id>.json``, written
atomically): its definition, status, trials and answer. The store is the truth: the job
records can be rebuilt without losing a search, and on start-up every search still running
is resumed. Resuming replays :func:`workflows.studies.next_trial` over the recorded trials;
the trial in flight when the service stopped is submitted again, and its cases, known to the
job records or stored, are not computed twice.

With several API replicas on one database (:mod:`service.shared_records`) a search is driven by
the replica holding its lease (``search:<id>``), renewed at every look at its trial; the others
look for running searches whose lease has expired every few seconds (:func:`service.replicas.adopt_orphans`)
and take over the driving of a replica that died.
"""
from __future__ import annotations

import asyncio
import hashlib
import json
import logging
import math
import time
from pathlib import Path
from typing import Any, Optional

from fastapi import APIRouter, Depends, Query, Request, Response
from pydantic import BaseModel

from workflows.files import write_atomically
from workflows.result_store import as_store, estimated_result_bytes
from workflows.studies import Search, StudyError, expand_trial, grid_cases, next_trial, trial_outcome
from workflows.sweep import expand_sweep, sweep_size

from .errors import invalid, responses
from .guards import check_capacity, require_token
from .params import Offset, SearchId, not_found, settings_of
from .replicas import adopt_orphans
from .schemas import FieldError
from .sweeps import enqueue_sweep, requeue_cancelled

logger = logging.getLogger(__name__)
router = APIRouter(prefix="/searches", tags=["studies"])

#: Seconds between looks at a trial's cases.
POLL = 0.25
#: Trials past :func:`max_trials` (its rounding) after which a search is failed rather than go on.
TRIAL_SLACK = 2


class SearchRecord(BaseModel):
    id: str
    name: str
    search: dict[str, Any]
    status: str  # running, done, failed
    value: Optional[float] = None
    satisfied: Optional[bool] = None
    trials: list[dict[str, Any]] = []
    max_trials: int
    grid_cases: Optional[dict[str, int]] = None
    error: Optional[str] = None
    submitted_at: float
    finished_at: Optional[float] = None


def search_id(search: Search) -> str:
    text = json.dumps(search.model_dump(mode="json"), sort_keys=True, separators=(",", ":"))
    return hashlib.blake2b(text.encode(), digest_size=8).hexdigest()


def max_trials(search: Search) -> int:
    return 2 + max(0, math.ceil(math.log2((search.high - search.low) / search.tolerance)))


class Searches:
    """The searches of one results store and the tasks that drive the running ones."""

    def __init__(self, jobs):
        self.jobs = jobs
        self.results = as_store(jobs.root)
        self.folder = self.results.root / "searches"
        self.tasks: dict[str, asyncio.Task] = {}
        self.adopting: Optional[asyncio.Task] = None

    def path(self, ident: str) -> Path:
        return self.folder / f"{ident}.json"

    def read(self, ident: str) -> Optional[SearchRecord]:
        try:
            if not self.results.fetched(self.path(ident)):  # on object storage: the current object
                return None
            return SearchRecord.model_validate_json(self.path(ident).read_text())
        except FileNotFoundError:
            return None

    def write(self, record: SearchRecord) -> None:
        write_atomically(self.path(record.id), lambda tmp: tmp.write_text(record.model_dump_json(indent=1)))
        self.results.publish(self.path(record.id))

    def all(self) -> list[SearchRecord]:
        out = []
        if self.results.url:
            self.results.remote.sync_folder(self.folder)
        for p in sorted(self.folder.glob("*.json")):
            try:
                out.append(SearchRecord.model_validate_json(p.read_text()))
            except (OSError, ValueError) as exc:
                logger.warning("search record %s unreadable: %s", p.name, exc)
        return sorted(out, key=lambda r: -r.submitted_at)

    def start(self, record: SearchRecord) -> None:
        """Drive ``record`` here if it is running, not driven here yet and its lease is free."""
        if record.status == "running" and record.id not in self.tasks and self.jobs.store.take_lease(_lease(record.id)):
            self.tasks[record.id] = asyncio.get_running_loop().create_task(self._drive(record.id))

    def resume(self) -> None:
        for record in self.all():
            self.start(record)
        if self.adopting is None:
            self.adopting = asyncio.get_running_loop().create_task(adopt_orphans(self.all, self.start, "searches"))

    async def stop(self) -> None:
        tasks = [*self.tasks.values(), *([self.adopting] if self.adopting else [])]
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        self.tasks.clear()
        self.adopting = None

    async def _drive(self, ident: str) -> None:
        jobs = self.jobs
        try:
            record = self.read(ident)
            search = Search.model_validate(record.search)
            while True:
                value, answer = next_trial(search, record.trials)
                if answer is not None:
                    record = record.model_copy(update={**answer, "status": "done", "finished_at": time.time(),
                                                       "grid_cases": grid_cases(search, record.trials)})
                    await asyncio.to_thread(self.write, record)
                    return
                if len(record.trials) >= record.max_trials + TRIAL_SLACK:  # never loop on
                    raise RuntimeError(f"no answer after {len(record.trials)} trials, more than this search "
                                       f"can need ({record.max_trials})")
                sweep = search.trial_sweep(value)
                sweep_record = jobs.store.get_sweep(sweep.sweep_id)
                if sweep_record is None:
                    specs = await asyncio.to_thread(expand_sweep, sweep)
                    sweep_record, _ = await enqueue_sweep(
                        jobs, sweep, [(s.case_id, s.canonical_json()) for s in specs],
                        {s.case_id: estimated_result_bytes(s) for s in specs})
                requeue_cancelled(jobs, sweep_record)
                ids = list(sweep_record.case_ids)
                while True:
                    counts = jobs.store.status_counts(ids)
                    if counts["queued"] == 0 and counts["running"] == 0:
                        break
                    await asyncio.sleep(POLL)
                    if not await asyncio.to_thread(jobs.store.take_lease, _lease(ident)):
                        logger.warning("search %s: its lease went to another replica; driven there", ident)
                        return
                trial = await asyncio.to_thread(trial_outcome, search, value, jobs.root, ids)
                record = record.model_copy(update={"trials": record.trials + [trial]})
                await asyncio.to_thread(self.write, record)
        except asyncio.CancelledError:
            raise
        except Exception as exc:  # a search that cannot go on says why; its trials stay
            logger.exception("search %s failed", ident)
            record = self.read(ident)
            if record is not None:
                self.write(record.model_copy(update={"status": "failed", "error": f"{type(exc).__name__}: {exc}",
                                                     "finished_at": time.time()}))
        finally:
            self.tasks.pop(ident, None)
            try:
                jobs.store.release_lease(_lease(ident))
            except Exception as exc:  # expires by itself
                logger.warning("could not release the lease of search %s (%s)", ident, exc)


def _lease(ident: str) -> str:
    return f"search:{ident}"


def searches_of(request: Request) -> Searches:
    return request.app.state.searches


@router.post("", status_code=202, response_model=SearchRecord, dependencies=[Depends(require_token)],
             responses=responses(401, 422, 429, 503))
async def submit_search(search: Search, request: Request, response: Response):
    """Start a search (or find the same one already made): the smallest ``parameter`` in
    [low, high], to ``tolerance``, for which ``require`` holds in every case of ``over``. Its
    trials are sweeps of this service (each within the sweep cap; the first must fit the
    store and the queue); the search survives restarts of the API and workers."""
    searches = searches_of(request)
    ident = search_id(search)
    record = await asyncio.to_thread(searches.read, ident)
    if record is None:
        # off the event loop, and bounded before the expansion starts
        trial = await asyncio.to_thread(search.trial_sweep, search.high)
        size, cap = sweep_size(trial), settings_of(request).max_sweep_cases
        if size > cap:
            return invalid([FieldError(field="over", type="too_many_cases",
                                       reason=f"a trial has {size:,} cases, over this service's cap of {cap:,}")])
        try:
            first = await asyncio.to_thread(expand_trial, trial)
        except StudyError as exc:
            return invalid([FieldError(field=field, reason=reason, type="value_error") for field, reason in exc.errors])
        check_capacity(request, size, sum(estimated_result_bytes(s) for s in first))
        record = SearchRecord(id=ident, name=search.name, search=search.model_dump(mode="json"), status="running",
                              max_trials=max_trials(search), submitted_at=time.time())
        await asyncio.to_thread(searches.write, record)
    searches.start(record)
    response.headers["Location"] = f"/searches/{ident}"
    return record


class SearchPage(BaseModel):
    items: list[SearchRecord]
    total: int
    limit: int
    offset: int


@router.get("", response_model=SearchPage, responses=responses(422))
async def list_searches(request: Request, limit: int = Query(20, ge=1, le=200), offset: Offset = 0) -> SearchPage:
    """Searches, newest first, a page at a time."""
    every = await asyncio.to_thread(searches_of(request).all)
    return SearchPage(items=every[offset:offset + limit], total=len(every), limit=limit, offset=offset)


@router.get("/{search_id}", response_model=SearchRecord, responses=responses(404, 422))
async def get_search(search_id: SearchId, request: Request) -> SearchRecord:
    """A search's progress (``trials`` of at most ``max_trials``), its trials and its answer:
    ``value`` (None with ``satisfied`` false when no value in [low, high] meets the requirement)."""
    record = await asyncio.to_thread(searches_of(request).read, search_id)
    if record is None:
        raise not_found("search", search_id)
    return record


@router.get("/{search_id}/trials.png", response_class=Response,
            responses={200: {"content": {"image/png": {}}}, **responses(404, 422)})
async def get_search_plot(search_id: SearchId, request: Request) -> Response:
    """The search converging: the values tried, the bracket left and each trial's worst output."""
    from workflows.study_plots import plot_search, png

    record = await get_search(search_id, request)
    figure = await asyncio.to_thread(lambda: png(plot_search(record.search, record.trials, record.value)))
    return Response(figure, media_type="image/png")
