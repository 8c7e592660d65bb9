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

from service import job_tables as store_module
from service.job_records import JobStore

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


def _filled_background_store(tmp_path, monkeypatch, n: int) -> tuple[JobStore, bool]:
    """A store checkpointing every 20 ms, given ``n`` records; and whether its database file
    then grew by their pages (the log copied back into it) within a minute."""
    monkeypatch.setattr(store_module, "CHECKPOINT_INTERVAL", 0.02)
    path = tmp_path / "jobs.sqlite"
    store = JobStore(path, background_checkpoints=True)
    size = path.stat().st_size + n * 4096
    _fill(store, n)
    deadline = time.monotonic() + 60.0  # a bound on waiting, not a speed requirement
    while path.stat().st_size < size and time.monotonic() < deadline:
        time.sleep(0.02)
    return store, path.stat().st_size >= size


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
    store, copied = _filled_background_store(tmp_path, monkeypatch, 300)
    assert copied, "the checkpointer never copied the log back"
    assert store.get_case(f"{299:016x}").status == "queued"
    checkpointer = store._checkpointer
    store.close()
    assert not checkpointer.is_alive()


def test_failing_rounds_are_logged_and_the_thread_tries_again(tmp_path, monkeypatch, caplog):
    """A round that fails (a full disk) must not end the thread: the next round tries again."""
    checkpoint = store_module._Checkpointer.checkpoint
    rounds = []

    class Full:
        def execute(self, sql):
            raise sqlite3.OperationalError("database or disk is full")

    def flaky(self, db):  # the first two rounds hit a full disk, the later ones the real database
        rounds.append(db)
        checkpoint(self, Full() if len(rounds) <= 2 else db)

    monkeypatch.setattr(store_module._Checkpointer, "checkpoint", flaky)
    store, copied = _filled_background_store(tmp_path, monkeypatch, 50)
    assert copied, "no round after the failing ones copied the log back"
    assert store._checkpointer.is_alive()
    store.close()
    assert len(rounds) > 2
    assert caplog.text.count("checkpoint failed (database or disk is full)") == 2


@pytest.fixture(autouse=True)
def _no_leaked_checkpointers():
    yield
    import threading

    assert not [t for t in threading.enumerate() if t.name.startswith("checkpoint ")]


def test_the_log_is_cut_back_after_a_burst(tmp_path, monkeypatch):
    """Issue 24: a burst of 10^4 cases left a 166 MB log beside an 8.8 MB database (PASSIVE
    checkpoints copy the log but never restart it under steady writes). Past
    WAL_SIZE_LIMIT the checkpointer truncates it: a few rounds after the burst it is empty."""
    monkeypatch.setattr(store_module, "CHECKPOINT_INTERVAL", 0.05)
    monkeypatch.setattr(store_module, "WAL_SIZE_LIMIT", 1 << 20)
    store = JobStore(tmp_path / "jobs.sqlite", background_checkpoints=True)
    _fill(store, 3000)
    wal = store.path.with_name(store.path.name + "-wal")
    deadline = time.monotonic() + 60.0  # a bound on waiting, not a speed requirement
    while wal.stat().st_size > store_module.WAL_SIZE_LIMIT and time.monotonic() < deadline:
        time.sleep(0.05)
    assert wal.stat().st_size <= store_module.WAL_SIZE_LIMIT
    assert store.count_open() == 3000
    store.close()
