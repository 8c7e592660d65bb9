"""Job records: cases and sweeps in one SQLite file (WAL mode) under the results directory.

The database holds what the service promised (which cases were asked for, in which
sweeps) and what it last learnt about each (status, timestamps, summary, error).
The result files themselves live next to it and are written by :mod:`workflows`.
The file itself (schema, connection, checkpoints, damage) is :mod:`service.job_tables`;
this module is the records and the queries over them.
"""
from __future__ import annotations

import json
import logging
import sqlite3
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Mapping, Optional, Sequence

from workflows.files import can_write

from .job_tables import STATUSES, JobDatabase, integrity_problem, move_aside

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class CaseRecord:
    """One row of ``cases``; times are Unix seconds."""

    id: str
    spec: dict
    status: str
    summary: Optional[dict]
    error: Optional[str]
    submitted_at: float
    started_at: Optional[float]
    finished_at: Optional[float]
    submissions: int
    warnings: tuple[str, ...] = ()


@dataclass(frozen=True)
class SweepRecord:
    """One row of ``sweeps`` with its case ids in sweep order."""

    id: str
    name: str
    spec: dict
    submitted_at: float
    case_ids: tuple[str, ...]


#: Key of the ``spec`` of a record whose JSON cannot be parsed (the record is then quarantined).
UNREADABLE = "unreadable_record"


def _json(text: Optional[str], default):
    """``text`` parsed, or ``default`` (a damaged record must not stop every listing)."""
    try:
        return json.loads(text) if text else None
    except (ValueError, TypeError) as exc:
        return default if default is not None else {UNREADABLE: f"not JSON ({exc})"}


def _case(row: Mapping) -> CaseRecord:
    spec = _json(row["spec"], None)
    summary = _json(row["summary"], {})
    return CaseRecord(
        id=row["id"], spec=spec if isinstance(spec, dict) else {UNREADABLE: "not a JSON object"},
        status=row["status"],
        summary=summary if isinstance(summary, dict) and summary else None, error=row["error"],
        submitted_at=row["submitted_at"], started_at=row["started_at"],
        finished_at=row["finished_at"], submissions=row["submissions"], warnings=_warnings(row["warnings"]))


def _warnings(text: Optional[str]) -> tuple[str, ...]:
    """The recorded warnings of a case (a JSON list); none if absent or damaged."""
    warnings = _json(text, [])
    return tuple(str(w) for w in warnings) if isinstance(warnings, list) else ()


def _sweep(row: sqlite3.Row, case_ids: Sequence[str]) -> SweepRecord:
    return SweepRecord(id=row["id"], name=row["name"], spec=json.loads(row["spec"]),
                       submitted_at=row["submitted_at"], case_ids=tuple(case_ids))
class JobStore(JobDatabase):
    """Case and sweep records in ``path`` (created with its parent directory if missing); the
    file, its connection and checkpoints are :class:`~service.job_tables.JobDatabase`'s."""

    # -- cases ---------------------------------------------------------------------------

    def add_case(self, case_id: str, spec_json: str) -> tuple[CaseRecord, bool]:
        """Record a case as queued unless it exists; return the record and whether it is new."""
        row = {**self._new_case, "id": case_id, "spec": spec_json, "status": "queued", "submitted_at": time.time()}
        if self._write("INSERT OR IGNORE INTO cases (id, spec, status, submitted_at) VALUES (?, ?, ?, ?)",
                       (case_id, spec_json, row["status"], row["submitted_at"])) != 1:
            return self.get_case(case_id), False
        return _case(row), True  # the row inserted, without reading it back

    def get_case(self, case_id: str) -> Optional[CaseRecord]:
        rows = self._read("SELECT * FROM cases WHERE id = ?", (case_id,))
        return _case(rows[0]) if rows else None

    def list_cases(self, *, status: str | None = None, limit: int = 100,
                   offset: int = 0, newest_first: bool = False) -> tuple[list[CaseRecord], int]:
        """A page of cases, oldest (or newest) submission first, and the total matching ``status``."""
        where, params = ("WHERE status = ?", [status]) if status else ("", [])
        order = "submitted_at DESC, id DESC" if newest_first else "submitted_at, id"
        with self._lock:
            total = self._db.execute(f"SELECT count(*) FROM cases {where}", params).fetchone()[0]
            rows = self._db.execute(
                f"SELECT * FROM cases {where} ORDER BY {order} LIMIT ? OFFSET ?",
                [*params, limit, offset]).fetchall()
        return [_case(r) for r in rows], total

    def open_case_ids(self) -> list[str]:
        """Ids of cases still ``queued`` or ``running``, oldest first."""
        rows = self._read("SELECT id FROM cases WHERE status IN ('queued', 'running') "
                          "ORDER BY submitted_at, id")
        return [r["id"] for r in rows]

    def case_ids_with_status(self, status: str) -> list[str]:
        """Ids of the cases in ``status``, oldest first."""
        return [r["id"] for r in self._read("SELECT id FROM cases WHERE status = ? ORDER BY submitted_at, id",
                                            (status,))]

    def failed_with(self, error_prefix: str) -> list[str]:
        """Ids of the failed cases whose error starts with ``error_prefix``, oldest first."""
        return [r["id"] for r in self._read(
            "SELECT id FROM cases WHERE status = 'failed' AND substr(error, 1, ?) = ? ORDER BY submitted_at, id",
            (len(error_prefix), error_prefix))]

    def count_open(self) -> int:
        """How many cases are ``queued`` or ``running`` (the queue the 429 limit bounds)."""
        return self._read("SELECT count(*) AS n FROM cases WHERE status IN ('queued', 'running')")[0]["n"]

    def count_submissions(self, case_ids: Sequence[str]) -> None:
        """Note that the cases were (re)submitted to the scheduler."""
        with self._lock:
            self._db.execute("BEGIN")
            self._db.executemany("UPDATE cases SET submissions = submissions + 1 WHERE id = ?",
                                 [(c,) for c in case_ids])
            self._db.execute("COMMIT")

    def mark_running(self, case_ids: Iterable[str]) -> int:
        """Move queued cases to running (others untouched); return how many moved."""
        now = time.time()
        with self._lock:
            return sum(self._db.execute(
                "UPDATE cases SET status = 'running', started_at = coalesce(started_at, ?) "
                "WHERE id = ? AND status = 'queued'", (now, cid)).rowcount for cid in case_ids)

    def mark_queued(self, case_id: str) -> None:
        """Put an open case back in the queue (its task was lost and will be resubmitted)."""
        self._write("UPDATE cases SET status = 'queued', started_at = NULL "
                    "WHERE id = ? AND status IN ('queued', 'running')", (case_id,))

    def finish(self, case_id: str, *, status: str, summary: dict | None = None,
               error: str | None = None, seconds: float | None = None,
               warnings: Sequence[str] = ()) -> None:
        """Record a final outcome (``done`` or ``failed``).

        ``warnings``: the solver's warnings about the result (none for a failed case).

        ``seconds``, the task's run time, dates the start when no poll saw it running.
        """
        if status not in ("done", "failed"):
            raise ValueError(f"status: {status!r} is not final")
        now = time.time()
        started = now - seconds if seconds is not None else None
        self._write(
            "UPDATE cases SET status = ?, summary = ?, error = ?, finished_at = ?, "
            "started_at = coalesce(started_at, ?), warnings = ? WHERE id = ?",
            (status, json.dumps(summary) if summary is not None else None, error, now, started,
             json.dumps(list(warnings)) if warnings else None, case_id))

    def status_counts(self, case_ids: Sequence[str] | None = None) -> dict[str, int]:
        """Cases per status (every status present, zero if none), optionally among ``case_ids``."""
        counts = dict.fromkeys(STATUSES, 0)
        if case_ids is None:
            rows = self._read("SELECT status, count(*) AS n FROM cases GROUP BY status")
        else:
            rows = self._read(
                "SELECT status, count(*) AS n FROM cases WHERE id IN "
                "(SELECT value FROM json_each(?)) GROUP BY status", (json.dumps(list(case_ids)),))
        counts.update({r["status"]: r["n"] for r in rows})
        return counts

    def get_cases(self, case_ids: Sequence[str]) -> dict[str, CaseRecord]:
        """Records of ``case_ids`` (those that exist), by id, in one query."""
        rows = self._read("SELECT * FROM cases WHERE id IN (SELECT value FROM json_each(?))",
                          (json.dumps(list(case_ids)),))
        return {r["id"]: _case(r) for r in rows}

    def mark_cancelled(self, case_ids: Sequence[str], *, statuses: Sequence[str] = ("queued",)) -> list[str]:
        """Mark the cases among ``case_ids`` in ``statuses`` (default: queued) ``cancelled``;
        return their ids."""
        now = time.time()
        with self._lock, self._transaction() as db:
            return [r["id"] for r in db.execute(
                "UPDATE cases SET status = 'cancelled', finished_at = ? "
                "WHERE status IN (SELECT value FROM json_each(?)) "
                "AND id IN (SELECT value FROM json_each(?)) RETURNING id",
                (now, json.dumps(list(statuses)), json.dumps(list(case_ids)))).fetchall()]

    def requeue(self, case_ids: Sequence[str], *, statuses: Sequence[str] = ("cancelled",)) -> list[str]:
        """Put the cases among ``case_ids`` that are in ``statuses`` back to ``queued``; return their ids."""
        with self._lock, self._transaction() as db:
            return [r["id"] for r in db.execute(
                "UPDATE cases SET status = 'queued', summary = NULL, error = NULL, warnings = NULL, "
                "started_at = NULL, finished_at = NULL WHERE status IN (SELECT value FROM json_each(?)) "
                "AND id IN (SELECT value FROM json_each(?)) RETURNING id",
                (json.dumps(list(statuses)), json.dumps(list(case_ids)))).fetchall()]

    def statuses(self, case_ids: Sequence[str]) -> dict[str, str]:
        """Status of each of ``case_ids`` that has a record."""
        rows = self._read("SELECT id, status FROM cases WHERE id IN (SELECT value FROM json_each(?))",
                          (json.dumps(list(case_ids)),))
        return {r["id"]: r["status"] for r in rows}

    # -- sweeps --------------------------------------------------------------------------

    def add_sweep(self, sweep_id: str, name: str, spec_json: str,
                  cases: Sequence[tuple[str, str]]) -> tuple[SweepRecord, list[str]]:
        """Record a sweep and its cases (new cases queued) in one transaction.

        Returns the sweep record and the ids of cases that were not known before.
        An existing sweep is returned unchanged with no new cases.
        """
        now = time.time()
        new: list[str] = []
        with self._lock, self._transaction() as db:
            cursor = db.execute("INSERT OR IGNORE INTO sweeps (id, name, spec, submitted_at) VALUES (?, ?, ?, ?)",
                                (sweep_id, name, spec_json, now))
            if cursor.rowcount == 1:
                for position, (case_id, case_json) in enumerate(cases):
                    inserted = db.execute("INSERT OR IGNORE INTO cases (id, spec, status, submitted_at) "
                                          "VALUES (?, ?, 'queued', ?)", (case_id, case_json, now)).rowcount
                    if inserted == 1:
                        new.append(case_id)
                    db.execute("INSERT INTO sweep_cases (sweep_id, position, case_id) VALUES (?, ?, ?)",
                               (sweep_id, position, case_id))
        return self.get_sweep(sweep_id), new

    def sweep_ids(self) -> set[str]:
        """Ids of every recorded sweep."""
        return {r["id"] for r in self._read("SELECT id FROM sweeps")}

    def get_sweep(self, sweep_id: str) -> Optional[SweepRecord]:
        with self._lock:
            row = self._db.execute("SELECT * FROM sweeps WHERE id = ?", (sweep_id,)).fetchone()
            if row is None:
                return None
            ids = self._db.execute("SELECT case_id FROM sweep_cases WHERE sweep_id = ? ORDER BY position",
                                   (sweep_id,)).fetchall()
        return _sweep(row, [r["case_id"] for r in ids])

    def list_sweeps(self, *, limit: int = 20, offset: int = 0) -> tuple[list[SweepRecord], int]:
        """A page of sweeps, newest submission first, and how many there are (three queries)."""
        with self._lock:
            total = self._db.execute("SELECT count(*) FROM sweeps").fetchone()[0]
            rows = self._db.execute(
                "SELECT * FROM sweeps ORDER BY submitted_at DESC, id DESC LIMIT ? OFFSET ?",
                (limit, offset)).fetchall()
            members: dict[str, list[str]] = {r["id"]: [] for r in rows}
            for r in self._db.execute(
                    "SELECT sweep_id, case_id FROM sweep_cases WHERE sweep_id IN "
                    "(SELECT value FROM json_each(?)) ORDER BY sweep_id, position",
                    (json.dumps(list(members)),)).fetchall():
                members[r["sweep_id"]].append(r["case_id"])
        return [_sweep(r, members[r["id"]]) for r in rows], total

    def sweep_status_counts(self, sweep_ids: Sequence[str]) -> dict[str, dict[str, int]]:
        """:meth:`status_counts` of each sweep's cases, for many sweeps in one query."""
        counts = {s: dict.fromkeys(STATUSES, 0) for s in sweep_ids}
        rows = self._read(
            "SELECT m.sweep_id, c.status, count(DISTINCT c.id) AS n FROM sweep_cases m "
            "JOIN cases c ON c.id = m.case_id WHERE m.sweep_id IN (SELECT value FROM json_each(?)) "
            "GROUP BY m.sweep_id, c.status", (json.dumps(list(sweep_ids)),))
        for r in rows:
            counts[r["sweep_id"]][r["status"]] = r["n"]
        return counts



def open_job_records(path: Path | str, **options) -> tuple["JobStore", Optional[str]]:
    """The job records at ``path``, checked (:func:`integrity_problem`); a damaged database
    (a broken header: "file is not a database"; a broken page) is moved aside
    (:func:`move_aside`) and a new one is opened. Returns the store and the problem found
    (None if none): the caller rebuilds the records from the result store then
    (:meth:`service.jobs.Dispatcher.rebuild_records`)."""
    path = Path(path)
    if not can_write(path.parent):
        logger.error("job records %s are on a read-only store: serving what is recorded, taking no work",
                     path.name)
        return JobStore(path, read_only=True), None
    try:
        store = JobStore(path, **options)
        problem = integrity_problem(store)
        if problem is None:
            return store, None
        store.close()
    except sqlite3.DatabaseError as exc:
        problem = str(exc)
    move_aside(path, problem)
    return JobStore(path, **options), problem
