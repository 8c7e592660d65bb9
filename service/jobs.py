"""Submitting cases to dask and keeping their records true.

Life of a case record
---------------------
``queued``
    Recorded, then submitted to the scheduler (batched: every case that arrives within
    ``batch_delay`` = 10 ms goes in one graph update) with
    :func:`distributed.fire_and_forget` under the stable key
    ``solve_and_store-<case_id>``, so the task runs to the end
    even if this process goes away, and a resubmission after a restart attaches to
    the task still on the scheduler instead of starting a second one.
``running``
    A worker is executing the task: a poll every ``poll_interval`` seconds asks the
    workers (:meth:`distributed.Client.call_stack`, which lists only tasks in a
    worker thread right now) and moves ``queued`` records it finds to ``running``.
    A task too short to be seen by a poll goes from ``queued`` to ``done``; its
    ``started_at`` is then dated back by the run time the task reports.
``done`` / ``failed``
    Final. Set from the task's outcome (one asyncio watcher per submitted future):
    the dict :func:`workflows.tasks.solve_and_store` returns, or the exception the task
    raised (e.g. ``KilledWorker`` after repeated worker deaths).

Why nothing stays open forever
------------------------------
Every open record either has a watched future here or is picked up by
:meth:`Dispatcher.reconcile`, which runs at start-up and every ``reconcile_interval``
seconds: a stored result file makes the case ``done``; otherwise the case is
(re)submitted. A future cancelled because the scheduler connection was lost puts its
record back to ``queued`` for the next reconciliation. A worker dying mid-task is
handled by the scheduler (the task is rescheduled, the record stays ``running``).
"""
from __future__ import annotations

import asyncio
import json
import logging
import sqlite3
from pathlib import Path
from typing import Awaitable, Callable, Optional, Sequence

from distributed import Client, Future, fire_and_forget
from distributed.client import FutureCancelledError

from pydantic import ValidationError

from solver.errors import field_errors, format_errors
from solver.spec import CaseSpec
from workflows.result_store import STORE_FULL, ResultStore, case_warnings, estimated_result_bytes, free_bytes
from workflows.summary import summarize
from workflows.sweep import Sweep, expand_sweep
from workflows.tasks import case_id_of_key, map_cases  # one task key per case, CLI too

from .results import BrokenResult, public_error, result_state, stored_outcome, written
from .job_records import UNREADABLE, CaseRecord, JobStore, SweepRecord, integrity_problem, is_damage

logger = logging.getLogger(__name__)

#: Longest pause (s) between retries of a job-record write or a failed background round.
MAX_BACKOFF = 30.0
#: Done results whose files each reconciliation reads back (a rolling check of the store).
SCRUB_PER_ROUND = 20


def task_error(exc: BaseException, root: Path) -> str:
    """The case's error for a task that raised outside the solver, in words a user can act on
    (dask's ``KilledWorker: Attempted to run task 'solve_and_store-…'`` says nothing to one)."""
    from distributed.scheduler import KilledWorker

    if isinstance(exc, KilledWorker):
        return ("the worker process solving this case died each time it was tried (killed by the "
                "operating system, most likely for memory: a very fine mesh, mesh.interface_size, or a "
                "machine short of memory); coarsen the mesh or give the workers more memory, then submit "
                "again with ?retry=failed")
    return public_error(f"{type(exc).__name__}: {exc}", root)


class Dispatcher:
    """Submits cases, watches their futures and keeps the job records in step.

    Parameters
    ----------
    connect : coroutine function returning a connected asynchronous ``Client``;
        called at start and again whenever the client has closed.
    store : the job records.
    root : results directory handed to the tasks (as seen by the workers).
    poll_interval, reconcile_interval : seconds between scheduler polls for running
        tasks and between reconciliations of open records.
    batch_delay : seconds a submission waits for others to go to the scheduler with it.
    """

    def __init__(self, connect: Callable[[], Awaitable[Client]], store: JobStore, root: Path, *,
                 poll_interval: float = 0.5, reconcile_interval: float = 5.0, batch_delay: float = 0.01):
        self._connect = connect
        self.store = store
        self.root = Path(root)
        self.poll_interval = poll_interval
        self.reconcile_interval = reconcile_interval
        self.batch_delay = batch_delay
        self.client: Optional[Client] = None
        self._tracked: dict[str, Future] = {}
        self._pending: dict[str, str] = {}
        self._scrubbed: set[str] = set()
        self._rounds = 0
        self._flush_timer: Optional[asyncio.TimerHandle] = None
        self._tasks: set[asyncio.Task] = set()
        self._recovering: Optional[asyncio.Task] = None

    # -- life cycle ----------------------------------------------------------------------

    async def start(self) -> None:
        """Connect, recover open records left by an earlier run, start the background loops.

        An unreachable scheduler does not stop the start: the service answers (``/health``
        says 503), records new cases as queued and connects when the scheduler appears.
        """
        try:
            await self.reconcile()
        except Exception as exc:  # e.g. a database that refuses writes: serve, retry later
            logger.error("start-up reconciliation failed (%s: %s); retrying in the background",
                         type(exc).__name__, exc)
        self._spawn(self._poll_running())
        self._spawn(self._reconcile_forever())

    async def stop(self) -> None:
        """Stop watching. Submitted tasks keep running on the scheduler (fire and forget);
        cases not sent yet stay ``queued`` in the records for the next start."""
        if self._flush_timer is not None:
            self._flush_timer.cancel()
        for task in list(self._tasks):
            task.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)
        self._tracked.clear()
        if self.client is not None:
            await self.client.close()

    def _spawn(self, coro) -> asyncio.Task:
        task = asyncio.get_running_loop().create_task(coro)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)
        return task

    @property
    def connected(self) -> bool:
        return self.client is not None and self.client.status == "running"

    # -- submission ----------------------------------------------------------------------

    def submit(self, case_id: str, spec_json: str) -> bool:
        """Queue ``case_id`` for the next batch to the scheduler; False if already on its way.

        The task reads a stored result back and computes the case again when there is none
        or it cannot be read (:meth:`workflows.result_store.ResultStore.solve_or_read`), so a
        broken file or a failed case needs nothing more than a submission.

        Batches go out ``batch_delay`` seconds after their first case, as one scheduler
        update (a sweep, or many clients posting at once, cost the scheduler one graph
        update instead of one each). Call from the event loop. Never raises for an
        unreachable scheduler: the record stays ``queued`` for the next reconciliation.
        """
        if case_id in self._tracked or case_id in self._pending:
            return False
        self._pending[case_id] = spec_json
        if self._flush_timer is None:
            self._flush_timer = asyncio.get_running_loop().call_later(self.batch_delay, self._flush)
        return True

    def _flush(self) -> None:
        """Send the pending cases to the scheduler, fire-and-forget, and watch them."""
        self._flush_timer = None
        batch, self._pending = self._pending, {}
        if not batch:
            return
        if not self.connected:
            logger.warning("scheduler not connected; %d cases stay queued", len(batch))
            return
        ids = list(batch)
        try:
            futures = map_cases(self.client, [batch[c] for c in ids], ids, str(self.root))
            fire_and_forget(futures)
        except Exception:
            logger.exception("could not submit %d cases; they stay queued", len(ids))
            return
        for case_id, future in zip(ids, futures):
            self._tracked[case_id] = future
            self._spawn(self._watch(case_id, future))
        try:
            self.store.count_submissions(ids)
        except Exception as exc:  # only a counter: the tasks are on their way
            logger.warning("could not count %d submissions: %s", len(ids), exc)
        logger.debug("submitted %d cases", len(ids))

    async def retry(self, case_ids: list[str]) -> list[str]:
        """Recompute the ``failed`` cases among ``case_ids``, and the ``done`` ones whose result
        file is missing or unreadable; return their ids (now ``queued``)."""
        records = self.store.get_cases(case_ids)
        _, broken = await self._recompute_unreadable([c for c, r in records.items() if r.status == "done"])
        failed = [c for c, r in records.items() if r.status == "failed"]
        again = self._requeue({c: records[c] for c in failed}, statuses=("failed",))
        if again:
            logger.info("recomputing %d failed cases", len(again))
        return again + broken

    async def readable_results(self, case_ids: Sequence[str]) -> list[str]:
        """The ``done`` cases among ``case_ids`` whose result file reads back, in order;
        done cases whose file is missing or unreadable go back to the queue."""
        statuses = self.store.statuses(case_ids)
        states, _ = await self._recompute_unreadable([c for c in case_ids if statuses.get(c) == "done"])
        return [c for c, state in states.items() if state == "readable"]

    async def recompute_broken(self, case_id: str) -> bool:
        """Requeue a ``done`` case whose result file is missing or unreadable; True if it was."""
        states, _ = await self._recompute_unreadable([case_id])
        return states[case_id] != "readable"

    async def _recompute_unreadable(self, done: Sequence[str]) -> tuple[dict[str, str], list[str]]:
        """The result state of each of the ``done`` cases (in order: ``readable``, ``missing``
        or ``broken``); those not readable go back to the queue. Returns the states and the
        cases requeued."""
        found = await asyncio.to_thread(lambda: [result_state(self.root, c) for c in done])
        states = dict(zip(done, found))
        unreadable = [c for c, state in states.items() if state != "readable"]
        if not unreadable:
            return states, []
        again = self._requeue(self.store.get_cases(unreadable), statuses=("done",))
        for case_id in again:
            logger.warning("result of case %s is %s: recomputing it", case_id, states[case_id])
        return states, again

    def _requeue(self, records: dict[str, CaseRecord], *, statuses: tuple[str, ...]) -> list[str]:
        """Move the ``records`` still in one of ``statuses`` back to ``queued`` and submit
        them; return their ids."""
        again = self.store.requeue(list(records), statuses=statuses)
        for case_id in again:
            self.submit(case_id, CaseSpec.model_validate(records[case_id].spec).canonical_json())
        return again

    async def _watch(self, case_id: str, future: Future) -> None:
        """Wait for one task and record its outcome."""
        try:
            try:
                outcome = await future
            except FutureCancelledError as exc:
                logger.warning("task of case %s cancelled (%s)", case_id, exc.reason)
                if await self._resolve_from_store(case_id) != "readable":
                    # resubmitted by the next reconciliation
                    await self._persist(self.store.mark_queued, case_id)
                return
            except Exception as exc:  # the task raised: KilledWorker, import errors, ...
                logger.warning("task of case %s raised %s: %s", case_id, type(exc).__name__, exc)
                if await self._resolve_from_store(case_id) != "readable":
                    await self._persist(self.store.finish, case_id, status="failed",
                                        error=task_error(exc, self.root))
                return
            await self._record(case_id, outcome)
        finally:
            if self._tracked.get(case_id) is future:
                del self._tracked[case_id]
            future.release()

    async def _record(self, case_id: str, outcome: dict) -> None:
        seconds = outcome.get("seconds")
        if outcome.get("status") == "cancelled":  # gave up on request: the record says cancelled already
            logger.info("case %s gave up after %.1f s (cancelled while running)", case_id, seconds or 0.0)
            return
        if outcome.get("status") == "done":
            if outcome.get("computed"):
                written(self.root, case_id)
            await self._persist(self.store.finish, case_id, status="done", summary=outcome.get("summary"),
                                seconds=seconds, warnings=outcome.get("warnings") or ())
        else:
            error = public_error(outcome.get("error") or "unknown error", self.root)
            await self._persist(self.store.finish, case_id, status="failed", error=error, seconds=seconds)

    async def _persist(self, write: Callable, *args, **kwargs) -> None:
        """Call the job-record write ``write(*args, **kwargs)`` until it succeeds.

        A full or read-only disk makes SQLite raise; the outcome is kept here and written
        once the database takes writes again (pauses double up to :data:`MAX_BACKOFF` s).
        """
        pause = 0.1
        while True:
            try:
                return write(*args, **kwargs)
            except sqlite3.Error as exc:
                logger.warning("job records refuse a write (%s); retrying in %.1f s", exc, pause)
                if is_damage(exc):
                    await self.recover_records(str(exc))
                await asyncio.sleep(pause)
                pause = min(2 * pause, MAX_BACKOFF)

    async def _resolve_from_store(self, case_id: str) -> str:
        """Mark ``case_id`` done if its result file is stored and readable; return the file's
        state (``readable``, ``missing`` or ``broken``), read once."""
        try:
            outcome = await asyncio.to_thread(stored_outcome, self.root, case_id)
        except BrokenResult as exc:
            logger.warning("stored result of case %s is unreadable: %s", case_id, public_error(str(exc), self.root))
            return "broken"
        if outcome is None:
            return "missing"
        summary, warnings = outcome
        await self._persist(self.store.finish, case_id, status="done", summary=summary, warnings=warnings)
        return "readable"

    # -- background loops ----------------------------------------------------------------

    async def record_sweep_on_disk(self, record: SweepRecord) -> None:
        """Write the sweep's record beside the results (what the job records can be rebuilt
        from); a store that refuses the write is logged, the sweep stands."""
        try:
            await asyncio.to_thread(ResultStore(self.root).write_sweep_record, record.id, record.name,
                                    json.dumps(record.spec), record.case_ids)
        except OSError as exc:
            logger.warning("could not write the record of sweep %s: %s", record.id, exc)

    def recover_soon(self, problem: str) -> None:
        """Start :meth:`recover_records` in the background (once at a time)."""
        if self._recovering is None or self._recovering.done():
            self._recovering = self._spawn(self.recover_records(problem))

    async def recover_records(self, problem: str) -> bool:
        """Damaged job records met while running (``database disk image is malformed``):
        confirm with SQLite's check, move the database aside, start an empty one and rebuild
        it from the results (:meth:`rebuild_records`), as at start-up. Returns whether it did.
        A case submitted alone and still running when the damage struck is known again once
        its result lands (the next import or rebuild) or when it is submitted again."""
        confirmed = await asyncio.to_thread(integrity_problem, self.store)
        if confirmed is None:
            logger.warning("job records raised %r but pass SQLite's check; not rebuilt", problem)
            return False
        await asyncio.to_thread(self.store.replace_damaged, confirmed)
        await self.rebuild_records()
        return True

    async def rebuild_records(self) -> int:
        """Fill empty job records from the result store (after damaged ones were moved aside):
        every stored case done with its scalars and warnings, every recorded failure failed
        with its reason; the sweeps then come from their records on disk
        (:meth:`import_sweep_records`). Returns the number of cases recorded."""
        results = ResultStore(self.root)

        def read_all() -> list[tuple[str, str, str, dict | None, list[str], str | None]]:
            found = []
            stored = set(results.case_ids())
            for case_id in sorted(stored):
                try:
                    with results.opened(case_id) as ds:
                        found.append((case_id, "done", ds.attrs["case_spec"], summarize(ds), case_warnings(ds), None))
                except Exception as exc:  # an unreadable file: left for the usual recompute
                    logger.warning("case %s not rebuilt: %s", case_id, exc)
            for path in results.cases_dir.glob("*.error.json") if results.cases_dir.is_dir() else ():
                case_id = path.name[:-len(".error.json")]
                error = results.read_error(case_id)
                if error and "spec" in error and case_id not in stored:
                    spec = error["spec"] if isinstance(error["spec"], str) else json.dumps(error["spec"])
                    found.append((case_id, "failed", spec, None, [], error.get("error")))
            return found

        found = await asyncio.to_thread(read_all)
        for case_id, status, spec, summary, warnings, error in found:
            self.store.add_case(case_id, spec)
            self.store.finish(case_id, status=status, summary=summary, warnings=warnings, error=error)
        sweeps = await self.import_sweep_records()
        logger.warning("job records rebuilt from the results: %d cases, %d sweeps", len(found), len(sweeps))
        return len(found)

    async def import_sweep_records(self) -> list[str]:
        """Add the sweeps recorded in the result store that the job records lack (a sweep run
        from the command line, or records lost): their cases done or failed as the store says,
        the rest queued (then solved like any queued case). Returns the ids imported."""
        known = self.store.sweep_ids()
        records = await asyncio.to_thread(lambda: list(ResultStore(self.root).sweep_records(skip=known)))
        imported = []
        for record in records:
            try:  # the cases from the sweep itself (the ids must be those recorded)
                specs = {s.case_id: s.canonical_json()
                         for s in await asyncio.to_thread(expand_sweep, Sweep.model_validate(record["spec"]))}
            except (ValidationError, ValueError) as exc:
                specs = {}
                logger.warning("sweep record %s no longer expands (%s)", record["id"], exc)
            cases = [(c, specs.get(c) or json.dumps({UNREADABLE: "the sweep record does not give this case"}))
                     for c in record["case_ids"]]
            _, new = self.store.add_sweep(record["id"], str(record.get("name", "")), json.dumps(record["spec"]), cases)
            for case_id in new:
                if await self._resolve_from_store(case_id) == "missing":
                    error = await asyncio.to_thread(ResultStore(self.root).read_error, case_id)
                    if error is not None:
                        await self._persist(self.store.finish, case_id, status="failed", error=error.get("error"))
            logger.info("sweep %s (%s) imported from the result store: %d cases, %d new",
                        record["id"], record.get("name", ""), len(cases), len(new))
            imported.append(record["id"])
        return imported

    async def reconcile(self) -> None:
        """Settle every open record that no watcher owns: done from the store, else resubmit.

        Also: a record whose case no longer validates (written by an older version, or
        damaged) is ``failed`` with the reason instead of stopping the service; a ``done``
        case whose file has gone is recomputed, and a few done files are read back each
        round (a broken one is recomputed too); stale temporary files are removed.
        """
        if not self.connected:
            await self._reconnect()
        if self._rounds % 5 == 0:  # sweeps run from the command line appear within a few rounds
            await self.import_sweep_records()
        for case_id in self.store.open_case_ids():
            if case_id in self._tracked or case_id in self._pending:
                continue
            state = await self._resolve_from_store(case_id)
            if state == "readable":
                logger.info("case %s found in the store: done", case_id)
                continue
            record = self.store.get_case(case_id)
            if record is None or record.status not in ("queued", "running"):
                continue
            spec = self._valid_spec(case_id, record.spec)
            if spec is None:
                continue
            self.store.mark_queued(case_id)
            if self.submit(case_id, spec.canonical_json()):
                logger.info("case %s resubmitted", case_id)
        await self._check_done_results()
        await self._retry_when_room()
        if self._rounds % 60 == 0:
            removed = await asyncio.to_thread(ResultStore(self.root).remove_stale_temporaries)
            if removed:
                logger.info("removed %d stale temporary files", removed)
        self._rounds += 1

    async def _retry_when_room(self) -> None:
        """Compute again the cases that failed on a full store, as many as there is room for now."""
        waiting = self.store.failed_with(f"{STORE_FULL}:")
        if not waiting:
            return
        room = await asyncio.to_thread(free_bytes, self.root)
        records, fits = self.store.get_cases(waiting), []
        for case_id, record in records.items():
            spec = self._valid_spec(case_id, record.spec)
            need = estimated_result_bytes(spec) if spec is not None else room + 1
            if need > room:
                break
            room -= need
            fits.append(case_id)
        again = self._requeue({c: records[c] for c in fits}, statuses=("failed",))
        if again:
            logger.info("room in the results store again: recomputing %d cases that failed on a full store",
                        len(again))

    def _valid_spec(self, case_id: str, spec: dict) -> Optional[CaseSpec]:
        """The case of a record, or None after marking the record failed (quarantine)."""
        try:
            if UNREADABLE in spec:
                raise ValueError(spec[UNREADABLE])
            return CaseSpec.model_validate(spec)
        except ValidationError as exc:
            reason = f"invalid job record: {format_errors(field_errors(exc))}"
        except Exception as exc:
            reason = f"invalid job record: {exc}"
        logger.error("case %s quarantined: %s", case_id, reason)
        self.store.finish(case_id, status="failed", error=reason)
        return None

    async def _check_done_results(self) -> None:
        """Recompute done cases whose file is missing; read back a few others (rolling)."""
        done = self.store.case_ids_with_status("done")
        if not done:
            return
        stored = set(await asyncio.to_thread(ResultStore(self.root).case_ids))
        for case_id in (c for c in done if c not in stored):
            await self.recompute_broken(case_id)
        unchecked = [c for c in done if c in stored and c not in self._scrubbed]
        if not unchecked:
            self._scrubbed.clear()
            return
        for case_id in unchecked[:SCRUB_PER_ROUND]:
            self._scrubbed.add(case_id)
            await self.recompute_broken(case_id)

    async def _reconnect(self) -> None:
        if self.client is not None and self.client.status in ("connecting", "newly-created"):
            return  # distributed is still trying on its own
        if self.client is None:  # never connected (or never succeeded): not a reconnection
            logger.info("connecting to the dask scheduler")
        else:
            logger.warning("dask client is %s; connecting again", self.client.status)
        try:
            self.client = await self._connect()
        except Exception as exc:
            logger.warning("scheduler unreachable: %s", exc)

    async def _reconcile_forever(self) -> None:
        pause = self.reconcile_interval
        while True:
            await asyncio.sleep(pause)
            try:
                await self.reconcile()
                pause = self.reconcile_interval
            except Exception as exc:  # a database or scheduler error: log, back off, go on
                if is_damage(exc):
                    await self.recover_records(str(exc))
                pause = min(2 * pause, max(MAX_BACKOFF, self.reconcile_interval))
                logger.warning("reconciliation failed (%s: %s); retrying in %.1f s",
                               type(exc).__name__, exc, pause)

    async def _poll_running(self) -> None:
        while True:
            await asyncio.sleep(self.poll_interval)
            if self._tracked and self.connected:
                try:
                    await self._mark_executing()
                except Exception as exc:  # e.g. the job records refuse writes: next poll retries
                    logger.warning("could not record running cases: %s", exc)

    async def _mark_executing(self) -> None:
        """Move the queued records of tasks a worker is executing right now to ``running``."""
        try:
            executing = await self.client.call_stack()
        except Exception as exc:
            logger.debug("poll of executing tasks failed: %s", exc)
            return
        started = [c for keys in executing.values() for key in keys if (c := case_id_of_key(key))]
        if started:
            self.store.mark_running(started)

    # -- cancellation --------------------------------------------------------------------

    async def cancel(self, case_ids: list[str]) -> list[str]:
        """Cancel the cases among ``case_ids`` that are queued or running; return their ids.

        Their records become ``cancelled``. Queued tasks are taken off the scheduler
        (``force``: the fire-and-forget hold goes too). A running case is asked to give up
        (a marker file in the result store that the solver's loops look at twice a second,
        :mod:`solver.limits`): its worker stops within about a second and is free for the
        next case; a case that finishes before it sees the marker is recorded done (its
        result is valid). Their watchers leave the ``cancelled`` record as it is.
        """
        if self.connected:
            await self._mark_executing()  # a task started since the last poll is running
        running = self.store.mark_cancelled(case_ids, statuses=("running",))
        results = ResultStore(self.root)
        for case_id in running:
            await asyncio.to_thread(results.request_cancel, case_id)
        cancelled = self.store.mark_cancelled(case_ids) + running
        futures = []
        for case_id in cancelled:
            self._pending.pop(case_id, None)
            if case_id in self._tracked:
                futures.append(self._tracked[case_id])
        if futures and self.connected:
            try:
                await self.client.cancel(futures, force=True)
            except Exception:
                logger.exception("could not cancel %d tasks on the scheduler", len(futures))
        logger.info("cancelled %d cases", len(cancelled))
        return cancelled

    # -- queries -------------------------------------------------------------------------

    async def cluster_state(self, timeout: float = 3.0) -> tuple[bool, int]:
        """Whether the scheduler answers within ``timeout`` s, and how many workers it has."""
        if not self.connected:
            return False, 0
        try:
            info = await asyncio.wait_for(self.client.scheduler.identity(), timeout)
        except Exception:
            return False, 0
        return True, len(info.get("workers", {}))
