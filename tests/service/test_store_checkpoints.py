"""The service's job store checkpoints its WAL in a thread of its own, never in a commit.

SQLite's automatic checkpoint runs in the commit that takes the log past 1000 pages:
three ``fdatasync`` calls inside the call the event loop makes. These tests show that a
store with ``background_checkpoints`` leaves every commit append-only (the log grows past
the automatic limit while the checkpointer is held off), that its thread then copies the
log into the database file, and that closing it loses nothing.
"""
from __future__ import annotations

import sqlite3
import time

import pytest

from service import store as store_module
from service.store import JobStore

#: Pages SQLite's automatic checkpoint lets the WAL reach (its default ``wal_autocheckpoint``).
AUTO_PAGES = 1000


def _fill(store: JobStore, n: int, size: int = 4096) -> None:
    """``n`` one-page-plus records: each commit appends at least one page to the WAL."""
    pad = "x" * size
    for i in range(n):
        store.add_case(f"{i:016x}", '{"pad": "%s"}' % pad)


def _wal_pages(store: JobStore) -> float:
    page = sqlite3.connect(store.path).execute("PRAGMA page_size").fetchone()[0]
    wal = store.path.with_name(store.path.name + "-wal")
    return wal.stat().st_size / page if wal.exists() else 0.0


def test_default_store_checkpoints_in_its_commits(tmp_path):
    """The reference behaviour: the WAL is reused from its start once it has been
    checkpointed, so it never grows much past the automatic limit."""
    store = JobStore(tmp_path / "jobs.sqlite")
    _fill(store, 3 * AUTO_PAGES // 2)
    assert _wal_pages(store) < 1.2 * AUTO_PAGES
    store.close()


def test_background_store_commits_never_checkpoint(tmp_path, monkeypatch):
    """With the checkpointer held off, the log only grows: no commit copied it back."""
    monkeypatch.setattr(store_module, "CHECKPOINT_INTERVAL", 3600.0)
    path = tmp_path / "jobs.sqlite"
    store = JobStore(path, background_checkpoints=True)
    _fill(store, 3 * AUTO_PAGES // 2)
    assert _wal_pages(store) > 1.4 * AUTO_PAGES
    before = path.stat().st_size
    store.close()  # the checkpointer's last round copies the log back
    assert path.stat().st_size > before + AUTO_PAGES * 4096
    reopened = JobStore(path)
    assert reopened.count_open() == 3 * AUTO_PAGES // 2  # every record queued, none lost
    reopened.close()


def test_background_checkpointer_copies_the_log_while_the_store_is_open(tmp_path, monkeypatch):
    monkeypatch.setattr(store_module, "CHECKPOINT_INTERVAL", 0.05)
    path = tmp_path / "jobs.sqlite"
    store = JobStore(path, background_checkpoints=True)
    empty = path.stat().st_size
    _fill(store, 300)
    deadline = time.monotonic() + 60.0  # a bound on waiting, not a speed requirement
    while path.stat().st_size < empty + 300 * 4096 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert path.stat().st_size >= empty + 300 * 4096, "the checkpointer never copied the log back"
    assert store.get_case(f"{299:016x}").status == "queued"
    store.close()
    assert not store._checkpointer.is_alive()


def test_a_failing_checkpoint_is_logged_and_retried(tmp_path, caplog):
    class Broken:
        calls = 0

        def execute(self, sql):
            Broken.calls += 1
            raise sqlite3.OperationalError("database or disk is full")

    store_module._Checkpointer.checkpoint(Broken())
    assert Broken.calls == 1
    assert "checkpoint failed (database or disk is full)" in caplog.text


@pytest.fixture(autouse=True)
def _no_leaked_checkpointers():
    yield
    import threading

    assert not [t for t in threading.enumerate() if t.name.startswith("checkpoint ")]
