"""The SQLite file of the job records: its schema and migrations, the one connection and its
lock, the checkpoints, and what to do with a damaged file. The records themselves (cases,
sweeps and the queries over them) are :class:`service.job_records.JobStore`, built on
:class:`JobDatabase`.

One connection, serialised by a lock, is shared by the event loop and worker threads;
every write is one short transaction, committed before a response goes out.

Checkpoints. SQLite copies the write-ahead log back into the database file in the
commit that takes the log past 1000 pages, in the committing thread: three
``fdatasync`` calls (5-20 ms each round on this machine's disk, seen with ``strace`` under
``python -m bench.service``), during which the service's event loop, which commits, answered
nothing. The service's store (``background_checkpoints=True``) turns that off and checkpoints
from a thread of its own, on its own connection, every :data:`CHECKPOINT_INTERVAL` seconds:
the event loop then never waits for the disk.
"""
from __future__ import annotations

import logging
import sqlite3
import threading
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator, Optional, Sequence

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


class JobDatabase:
    """The job records' SQLite file at ``path`` (created with its parent directory if missing):
    the connection, its lock and its transactions, the schema (migrated from older versions).

    ``background_checkpoints``: checkpoint the WAL from a thread of the store's own,
    never in a committing call (what the service's event loop wants; see the module
    notes). :meth:`close` stops it. ``read_only``: open an immutable file, take no writes.
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



def integrity_problem(store: JobDatabase) -> Optional[str]:
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

