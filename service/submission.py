"""Submitting cases to dask and watching their tasks: the batches to the scheduler, one
watcher per future recording its outcome, the poll that sees cases start, cancellation.
The middle layer of :class:`service.jobs.Dispatcher` (see :mod:`service.jobs`).
"""
from __future__ import annotations

import asyncio
from pathlib import Path

from distributed import Future, fire_and_forget
from distributed.client import FutureCancelledError

from solver.spec import CaseSpec
from workflows.result_store import ResultStore
from workflows.tasks import case_id_of_key, map_cases  # one task key per case, CLI too

from .job_records import CaseRecord
from .record_keeping import RecordKeeper, logger
from .results import public_error, written


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


class Submitter(RecordKeeper):
    """Sends cases to the scheduler in batches and records what becomes of them."""

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

    # -- the scheduler ---------------------------------------------------------------------

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
