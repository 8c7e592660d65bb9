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
Every open record either has a watched future or is picked up by
:meth:`Dispatcher.reconcile`, which runs at start-up and every ``reconcile_interval``
seconds: a stored result file makes the case ``done``; otherwise the case is
(re)submitted. A future cancelled because the scheduler connection was lost puts its
record back to ``queued`` for the next reconciliation. A worker dying mid-task is
handled by the scheduler (the task is rescheduled, the record stays ``running``).

The dispatcher stands in three layers, each a module: :mod:`service.record_keeping` (its
state, the job records kept true to the result store, their rebuilding),
:mod:`service.submission` (batches to the scheduler, watchers, cancellation) and this
one (start-up, reconciliation, retries).
"""
from __future__ import annotations

import asyncio
from typing import Optional, Sequence

from pydantic import ValidationError

from solver.errors import field_errors, format_errors
from solver.spec import CaseSpec
from workflows.result_store import STORE_FULL, ResultStore, estimated_result_bytes, free_bytes

from .job_records import UNREADABLE
from .job_tables import is_damage
from .record_keeping import MAX_BACKOFF, logger
from .results import result_state
from .submission import Submitter, task_error

__all__ = ["Dispatcher", "MAX_BACKOFF", "SCRUB_PER_ROUND", "task_error"]

#: Done results whose files each reconciliation reads back (a rolling check of the store).
SCRUB_PER_ROUND = 20


class Dispatcher(Submitter):
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

    # -- retries ---------------------------------------------------------------------------

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

    # -- reconciliation --------------------------------------------------------------------

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
