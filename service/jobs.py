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
import logging
from pathlib import Path
from typing import Awaitable, Callable, Optional

from distributed import Client, Future, fire_and_forget
from distributed.client import FutureCancelledError

from solver.spec import CaseSpec
from workflows.store import is_stored
from workflows.summary import read_summary
from workflows.tasks import solve_and_store

from .store import JobStore

logger = logging.getLogger(__name__)

KEY_PREFIX = "solve_and_store-"


def task_key(case_id: str) -> str:
    """Dask key of the task computing ``case_id`` (stable across service restarts)."""
    return f"{KEY_PREFIX}{case_id}"


def stored_summary(root: Path, case_id: str) -> Optional[dict[str, float]]:
    """Scalars of the stored result of ``case_id``, or None if it is not stored."""
    return read_summary(root, case_id) if is_stored(root, case_id) else None


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
        self._flush_timer: Optional[asyncio.TimerHandle] = None
        self._tasks: set[asyncio.Task] = set()

    # -- life cycle ----------------------------------------------------------------------

    async def start(self) -> None:
        """Connect, recover open records left by an earlier run, start the background loops.

        An unreachable scheduler does not stop the start: the service answers (``/health``
        says 503), records new cases as queued and connects when the scheduler appears.
        """
        await self.reconcile()
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
            futures = self.client.map(solve_and_store, [batch[c] for c in ids], [str(self.root)] * len(ids),
                                      key=[task_key(c) for c in ids], pure=False)
            fire_and_forget(futures)
        except Exception:
            logger.exception("could not submit %d cases; they stay queued", len(ids))
            return
        for case_id, future in zip(ids, futures):
            self._tracked[case_id] = future
            self._spawn(self._watch(case_id, future))
        self.store.count_submissions(ids)
        logger.debug("submitted %d cases", len(ids))

    async def _watch(self, case_id: str, future: Future) -> None:
        """Wait for one task and record its outcome."""
        try:
            try:
                outcome = await future
            except FutureCancelledError as exc:
                logger.warning("task of case %s cancelled (%s)", case_id, exc.reason)
                if not await self._resolve_from_store(case_id):
                    self.store.mark_queued(case_id)  # resubmitted by the next reconciliation
                return
            except Exception as exc:  # the task raised: KilledWorker, import errors, ...
                logger.warning("task of case %s raised %s: %s", case_id, type(exc).__name__, exc)
                if not await self._resolve_from_store(case_id):
                    self.store.finish(case_id, status="failed", error=f"{type(exc).__name__}: {exc}")
                return
            self._record(case_id, outcome)
        finally:
            if self._tracked.get(case_id) is future:
                del self._tracked[case_id]
            future.release()

    def _record(self, case_id: str, outcome: dict) -> None:
        seconds = outcome.get("seconds")
        if outcome.get("status") == "done":
            self.store.finish(case_id, status="done", summary=outcome.get("summary"), seconds=seconds)
        else:
            self.store.finish(case_id, status="failed", error=outcome.get("error") or "unknown error",
                              seconds=seconds)

    async def _resolve_from_store(self, case_id: str) -> bool:
        """Mark ``case_id`` done if its result file is stored; True if it was."""
        try:
            summary = await asyncio.to_thread(stored_summary, self.root, case_id)
        except Exception:
            logger.exception("stored result of case %s is unreadable", case_id)
            return False
        if summary is None:
            return False
        self.store.finish(case_id, status="done", summary=summary)
        return True

    # -- background loops ----------------------------------------------------------------

    async def reconcile(self) -> None:
        """Settle every open record that no watcher owns: done from the store, else resubmit."""
        if not self.connected:
            await self._reconnect()
        for case_id in self.store.open_case_ids():
            if case_id in self._tracked or case_id in self._pending:
                continue
            if await self._resolve_from_store(case_id):
                logger.info("case %s found in the store: done", case_id)
                continue
            record = self.store.get_case(case_id)
            if record is not None and record.status in ("queued", "running"):
                self.store.mark_queued(case_id)
                if self.submit(case_id, CaseSpec.model_validate(record.spec).canonical_json()):
                    logger.info("case %s resubmitted", case_id)

    async def _reconnect(self) -> None:
        if self.client is not None and self.client.status in ("connecting", "newly-created"):
            return  # distributed is still trying on its own
        logger.warning("dask client is %s; connecting again",
                       None if self.client is None else self.client.status)
        try:
            self.client = await self._connect()
        except Exception as exc:
            logger.warning("scheduler unreachable: %s", exc)

    async def _reconcile_forever(self) -> None:
        while True:
            await asyncio.sleep(self.reconcile_interval)
            try:
                await self.reconcile()
            except Exception:
                logger.exception("reconciliation failed; retrying in %s s", self.reconcile_interval)

    async def _poll_running(self) -> None:
        while True:
            await asyncio.sleep(self.poll_interval)
            if self._tracked and self.connected:
                await self._mark_executing()

    async def _mark_executing(self) -> None:
        """Move the queued records of tasks a worker is executing right now to ``running``."""
        try:
            executing = await self.client.call_stack()
        except Exception as exc:
            logger.debug("poll of executing tasks failed: %s", exc)
            return
        started = [key[len(KEY_PREFIX):] for keys in executing.values() for key in keys
                   if isinstance(key, str) and key.startswith(KEY_PREFIX)]
        if started:
            self.store.mark_running(started)

    # -- cancellation --------------------------------------------------------------------

    async def cancel(self, case_ids: list[str]) -> list[str]:
        """Cancel the cases among ``case_ids`` that no worker has started; return their ids.

        Their records become ``cancelled`` and their tasks are taken off the scheduler
        (``force``: the fire-and-forget hold goes too). Running cases finish: a worker
        thread cannot be interrupted, and its result is worth keeping. Their watchers
        see the cancellation and leave the ``cancelled`` record as it is.
        """
        if self.connected:
            await self._mark_executing()  # a task started since the last poll is running
        cancelled = self.store.cancel_queued(case_ids)
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
