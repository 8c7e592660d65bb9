"""The job records kept true to the result store: outcomes written until the records take
them, a case settled from its stored file, damaged records rebuilt from the results, sweeps run
elsewhere imported. The base of :class:`service.jobs.Dispatcher` (see :mod:`service.jobs`).
"""
from __future__ import annotations

import asyncio
import json
import logging
import sqlite3
from pathlib import Path
from typing import Awaitable, Callable, Optional

from distributed import Client, Future
from pydantic import ValidationError

from workflows.result_store import ResultStore, case_warnings
from workflows.summary import summarize
from workflows.sweep import Sweep, expand_sweep

from .job_records import UNREADABLE, JobStore, SweepRecord
from .job_tables import integrity_problem, is_damage
from .results import BrokenResult, public_error, stored_outcome

#: The dispatcher's one logger, whichever of its modules logs.
logger = logging.getLogger("service.jobs")

#: Longest pause (s) between retries of a job-record write or a failed background round.
MAX_BACKOFF = 30.0


class RecordKeeper:
    """The state of a dispatcher (see :class:`service.jobs.Dispatcher` for the parameters) and
    the keeping of its job records: writes retried until taken, cases settled from the store,
    records rebuilt from the results."""

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

    def _spawn(self, coro) -> asyncio.Task:
        task = asyncio.get_running_loop().create_task(coro)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)
        return task

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

    # -- records from the result store ----------------------------------------------------

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
