"""Job records: cases and sweeps in one SQLite file (WAL mode) under the results directory.

The database holds what the service promised (which cases were asked for, in which
sweeps) and what it last learnt about each (status, timestamps, summary, error).
The result files themselves live next to it and are written by :mod:`workflows`.
One connection, serialised by a lock, is shared by the event loop and worker
threads; every write is one short transaction, committed before a response goes out.

Checkpoints. SQLite copies the write-ahead log back into the database file in the
commit that takes the log past 1000 pages, in the committing thread: three
``fdatasync`` calls (5-20 ms each round on this machine's disk, seen with ``strace`` under
``python -m bench.service``), during which the service's event loop, which commits, answered
nothing. The service's store (``background_checkpoints=True``) turns that off and checkpoints
from a thread of its own, on its own connection, every :data:`CHECKPOINT_INTERVAL` seconds:
the event loop then never waits for the disk.
"""
from __future__ import annotations

import json
import logging
import sqlite3
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Iterator, Mapping, Optional, Sequence

from workflows.files import can_write

logger = logging.getLogger(__name__)

#: Seconds between the checkpoints of a store with ``background_checkpoints``.
CHECKPOINT_INTERVAL = 1.0
#: Bytes the write-ahead log is truncated to after a checkpoint (SQLite's journal_size_limit).
WAL_SIZE_LIMIT = 4 << 20

#: Case states. ``queued`` and ``running`` are open; ``done`` and ``failed`` are final;
#: ``cancelled`` (a queued case whose sweep was cancelled) is final until submitted again.
STATUSES = ("queued", "running", "done", "failed", "cancelled")

_CASES_TABLE = """
CREATE TABLE IF NOT EXISTS {name} (
    id           TEXT PRIMARY KEY,
    spec         TEXT NOT NULL,
    status       TEXT NOT NULL CHECK (status IN ('queued', 'running', 'done', 'failed', 'cancelled')),
    summary      TEXT,
    error        TEXT,
    submitted_at REAL NOT NULL,
    started_at   REAL,
    finished_at  REAL,
    submissions  INTEGER NOT NULL DEFAULT 0,
    warnings     TEXT
);
"""

_SCHEMA = _CASES_TABLE.format(name="cases") + """
CREATE INDEX IF NOT EXISTS cases_by_status ON cases (status, submitted_at);
CREATE TABLE IF NOT EXISTS sweeps (
    id           TEXT PRIMARY KEY,
    name         TEXT NOT NULL,
    spec         TEXT NOT NULL,
    submitted_at REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS sweep_cases (
    sweep_id     TEXT NOT NULL REFERENCES sweeps (id),
    position     INTEGER NOT NULL,
    case_id      TEXT NOT NULL REFERENCES cases (id),
    PRIMARY KEY (sweep_id, position)
);
"""


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


class _Checkpointer(threading.Thread):
    """Checkpoints the WAL of ``path`` every ``interval`` seconds until stopped."""

    def __init__(self, path: Path, interval: float):
        super().__init__(name=f"checkpoint {path.name}", daemon=True)
        self.path, self.interval = path, interval
        self.stopping = threading.Event()

    def run(self) -> None:
        db = sqlite3.connect(self.path, isolation_level=None, timeout=30)
        try:
            while not self.stopping.wait(self.interval):
                self.checkpoint(db)
            self.checkpoint(db)
        finally:
            db.close()

    def checkpoint(self, db: sqlite3.Connection) -> None:
        wal = self.path.with_name(self.path.name + "-wal")
        try:
            # PASSIVE: copy what no reader still needs, never wait for a lock. Under steady
            # writes the log never restarts that way; past WAL_SIZE_LIMIT a TRUNCATE checkpoint
            # (a short wait for the writer) empties it.
            db.execute("PRAGMA wal_checkpoint(PASSIVE)").fetchall()
            if wal.stat().st_size > WAL_SIZE_LIMIT:
                db.execute("PRAGMA wal_checkpoint(TRUNCATE)").fetchall()
        except FileNotFoundError:
            pass
        except sqlite3.Error as exc:  # a full disk, say: the WAL keeps the data; try again later
            logger.warning("job store checkpoint failed (%s); retrying in the next round", exc)

    def stop(self) -> None:
        self.stopping.set()
        self.join()


class JobStore:
    """Case and sweep records in ``path`` (created with its parent directory if missing).

    ``background_checkpoints``: checkpoint the WAL from a thread of the store's own,
    never in a committing call (what the service's event loop wants; see the module
    notes). :meth:`close` stops it.
    """

    def __init__(self, path: Path | str, *, background_checkpoints: bool = False, read_only: bool = False):
        self.path = Path(path)
        self._lock = threading.Lock()
        self._background_checkpoints = background_checkpoints and not read_only
        self._checkpointer: Optional[_Checkpointer] = None
        self.read_only = read_only
        with self._lock:
            if read_only:
                # immutable: no -shm or -wal file is made (a read-only mount allows none)
                self._db = sqlite3.connect(f"{self.path.resolve().as_uri()}?mode=ro&immutable=1", uri=True,
                                           check_same_thread=False, isolation_level=None)
                self._db.row_factory = sqlite3.Row
                self._db.execute("SELECT count(*) FROM cases").fetchone()
            else:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                self._open()

    def _open(self) -> None:
        """Connect (the lock held), create or migrate the schema, start the checkpoints."""
        self._db = sqlite3.connect(self.path, check_same_thread=False, isolation_level=None, timeout=30)
        self._db.row_factory = sqlite3.Row
        try:
            self._db.execute("PRAGMA journal_mode=WAL")
            # NORMAL in WAL mode: a commit survives the process being killed (not power loss).
            self._db.execute("PRAGMA synchronous=NORMAL")
            # the log file is cut back to this size after each checkpoint (a burst of 10^4
            # cases left a 166 MB log beside an 8.8 MB database when it was not)
            self._db.execute(f"PRAGMA journal_size_limit={WAL_SIZE_LIMIT}")
            self._migrate_status_check()
            self._migrate_warnings_column()
            self._db.execute("PRAGMA foreign_keys=ON")
            self._db.executescript(_SCHEMA)
            # a new case's row as the table makes it: every column's default, evaluated by SQLite
            columns = self._db.execute("PRAGMA table_info(cases)").fetchall()
            defaults = self._db.execute("SELECT " + ", ".join(c["dflt_value"] or "NULL" for c in columns)).fetchone()
            self._new_case = dict(zip((c["name"] for c in columns), defaults))
            if self._background_checkpoints:
                self._db.execute("PRAGMA wal_autocheckpoint=0")
        except BaseException:
            self._db.close()
            raise
        if self._background_checkpoints:
            self._checkpointer = _Checkpointer(self.path, CHECKPOINT_INTERVAL)
            self._checkpointer.start()

    def replace_damaged(self, problem: str) -> None:
        """Move the damaged database aside (:func:`move_aside`) and start an empty one in its
        place; the same object goes on serving (the caller rebuilds the records)."""
        if self._checkpointer is not None:
            self._checkpointer.stop()
            self._checkpointer = None
        with self._lock:
            try:
                self._db.close()
            except sqlite3.Error:
                pass
            move_aside(self.path, problem)
            self._open()

    def _migrate_status_check(self) -> None:
        """Let a database written before ``cancelled`` existed take that status.

        SQLite cannot alter a CHECK constraint: the table is rebuilt (the documented
        procedure: foreign keys off, copy, drop, rename) in one transaction.
        """
        row = self._db.execute("SELECT sql FROM sqlite_master WHERE type = 'table' AND name = 'cases'").fetchone()
        if row is None or "'cancelled'" in row[0]:
            return
        self._db.execute("PRAGMA foreign_keys=OFF")
        with self._transaction() as db:
            db.execute(_CASES_TABLE.format(name="cases_new"))
            columns = ("id, spec, status, summary, error, submitted_at, started_at, finished_at, submissions"
                       + (", warnings" if "warnings" in self._case_columns() else ""))
            db.execute(f"INSERT INTO cases_new ({columns}) SELECT {columns} FROM cases")
            db.execute("DROP TABLE cases")
            db.execute("ALTER TABLE cases_new RENAME TO cases")

    def _case_columns(self) -> set[str]:
        return {r[1] for r in self._db.execute("PRAGMA table_info(cases)").fetchall()}

    def _migrate_warnings_column(self) -> None:
        """Give a database written before case warnings were recorded their column."""
        columns = self._case_columns()
        if columns and "warnings" not in columns:
            self._db.execute("ALTER TABLE cases ADD COLUMN warnings TEXT")

    def close(self) -> None:
        if self._checkpointer is not None:
            self._checkpointer.stop()
            self._checkpointer = None
        with self._lock:
            self._db.close()

    @contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        """One write transaction: ``BEGIN IMMEDIATE`` ... ``COMMIT``, rolled back on any error
        (a failed commit too). The caller holds the lock."""
        self._db.execute("BEGIN IMMEDIATE")
        try:
            yield self._db
            self._db.execute("COMMIT")
        except BaseException:
            self._db.execute("ROLLBACK")
            raise

    def _write(self, sql: str, params: Sequence = ()) -> int:
        with self._lock:
            return self._db.execute(sql, params).rowcount

    def _read(self, sql: str, params: Sequence = ()) -> list[sqlite3.Row]:
        with self._lock:
            return self._db.execute(sql, params).fetchall()

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

    def writable(self) -> bool:
        """Whether the database accepts a write (checked inside a rolled-back transaction)."""
        if self.read_only:
            return False
        try:
            with self._lock:
                self._db.execute("BEGIN IMMEDIATE")
                self._db.execute("ROLLBACK")
            return True
        except sqlite3.Error:
            return False


def integrity_problem(store: "JobStore") -> Optional[str]:
    """SQLite's own quick check of the job records: None if sound, else what it found."""
    try:
        with store._lock:
            rows = store._db.execute("PRAGMA quick_check").fetchall()
    except sqlite3.DatabaseError as exc:
        return str(exc)
    found = [r[0] for r in rows]
    return None if found == ["ok"] else "; ".join(found[:5])


def is_damage(exc: BaseException) -> bool:
    """Whether ``exc`` says the database file itself is damaged ("database disk image is
    malformed", "file is not a database"), not merely busy, full or read-only."""
    return isinstance(exc, sqlite3.DatabaseError) and not isinstance(exc, sqlite3.OperationalError)


def move_aside(path: Path, problem: str) -> None:
    """Rename a damaged database and its log files to ``<name>.damaged-<unix time>``, logged."""
    stamp = int(time.time())
    for suffix in ("", "-wal", "-shm"):
        part = path.with_name(path.name + suffix)
        if part.exists():
            part.replace(path.with_name(f"{path.name}{suffix}.damaged-{stamp}"))
    logger.error("job records %s are damaged (%s): moved aside as %s.damaged-%d; rebuilding them from the "
                 "results", path.name, problem, path.name, stamp)


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
