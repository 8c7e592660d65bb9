"""The job records behind ``TUNNEL_CONTACT_DATABASE``: Alembic migrations (SQLite in place,
PostgreSQL from empty), one behaviour on either database, and the claims and leases by which
several replicas share one PostgreSQL (a real server from ``initdb``, see :mod:`real_servers`)."""
from __future__ import annotations

import json
import sqlite3
import threading
import time

import pytest
import sqlalchemy as sa

from service.database import HEAD, engine_url
from service.job_records import JobStore
from service.settings import Settings
from service.shared_records import SharedJobStore

A, B, C = "a" * 16, "b" * 16, "c" * 16
SPEC = json.dumps({"name": "x"})


@pytest.fixture(params=["sqlite", "postgresql"])
def store(request, tmp_path):
    if request.param == "sqlite":
        s = JobStore(tmp_path / "jobs.sqlite")
    else:
        s = SharedJobStore(request.getfixturevalue("database_url"))
    yield s
    s.close()


def test_the_records_behave_alike_on_sqlite_and_postgresql(store):
    record, new = store.add_case(A, SPEC)
    assert new and record.status == "queued" and record.submissions == 0 and record.spec == {"name": "x"}
    assert store.add_case(A, SPEC)[1] is False
    sweep, fresh = store.add_sweep(C, "study", json.dumps({"n": 2}), [(B, SPEC), (A, SPEC)])
    assert sweep.case_ids == (B, A) and fresh == [B]
    assert store.add_sweep(C, "study", "{}", [(B, SPEC)])[1] == []  # recorded once
    assert sorted(store.open_case_ids()) == [A, B] and store.count_open() == 2
    assert store.mark_running([A, B]) == 2 and store.mark_running([A]) == 0
    store.count_submissions([A])
    store.finish(A, status="done", summary={"max_abs_moment": 1.5}, warnings=["w"], seconds=1.0)
    store.finish(B, status="failed", error="StoreFull: no room")
    done = store.get_case(A)
    assert (done.status, done.summary, done.warnings, done.submissions) == ("done", {"max_abs_moment": 1.5}, ("w",), 1)
    assert store.failed_with("StoreFull:") == [B] and store.failed_with("Store_") == []
    assert store.status_counts([A, B]) == {"queued": 0, "running": 0, "done": 1, "failed": 1, "cancelled": 0}
    assert store.sweep_status_counts([C])[C]["done"] == 1
    assert store.requeue([A, B], statuses=("failed",)) == [B]
    assert store.mark_cancelled([A, B]) == [B] and store.statuses([A, B, C]) == {A: "done", B: "cancelled"}
    assert [r.id for r in store.list_cases(status="done")[0]] == [A]
    assert store.list_sweeps()[1] == 1 and store.sweep_ids() == {C}
    assert store.case_ids_with_status("cancelled") == [B] and set(store.get_cases([A, B, C])) == {A, B}
    assert store.take_lease("search:x") and store.writable()


def test_the_room_held_for_open_cases_is_counted_alike(store):
    """Admission's reserve (issue 38 item 8) on either database: the room of queued and running
    cases, none once they finish; an unreadable spec repaired in place."""
    assert store.open_room() == 0
    store.add_case(A, SPEC, room=1000)
    store.add_sweep(C, "study", "{}", [(B, SPEC)], {B: 250})
    assert store.open_room() == 1250
    store.mark_running([B])
    assert store.open_room() == 1250
    store.finish(A, status="done", summary={}, warnings=[])
    assert store.open_room() == 250
    store.repair_spec(B, json.dumps({"name": "y"}))
    assert store.get_case(B).spec == {"name": "y"}


def test_the_shared_store_answers_every_call_the_sqlite_one_does():
    """One interface: each public method of JobStore exists on SharedJobStore with the same
    parameters (a method missing there was a 500 on the replicas' POST /sweeps)."""
    import inspect

    for name, method in inspect.getmembers(JobStore, callable):
        if name.startswith("_"):
            continue
        assert hasattr(SharedJobStore, name), name
        params = list(inspect.signature(method).parameters)
        shared = list(inspect.signature(getattr(SharedJobStore, name)).parameters)
        assert [p for p in params if p != "self"] == [p for p in shared if p != "self"] or name == "add_sweep", name


def test_postgresql_is_migrated_by_alembic_from_empty_and_again_is_a_no_op(database_url):
    for _ in range(2):
        SharedJobStore(database_url).close()
    engine = sa.create_engine(engine_url(database_url))
    with engine.connect() as db:
        assert db.exec_driver_sql("SELECT version_num FROM alembic_version").scalars().all() == [HEAD]
        tables = set(sa.inspect(db).get_table_names())
    engine.dispose()
    assert {"cases", "sweeps", "sweep_cases", "replicas", "leases"} <= tables


def test_an_old_sqlite_file_upgrades_in_place(tmp_path):
    """A ``jobs.sqlite`` of before Alembic (and before ``cancelled``): kept, brought to head."""
    path = tmp_path / "jobs.sqlite"
    db = sqlite3.connect(path)
    db.executescript("""
        CREATE TABLE cases (id TEXT PRIMARY KEY, spec TEXT NOT NULL, status TEXT NOT NULL
            CHECK (status IN ('queued', 'running', 'done', 'failed')), summary TEXT, error TEXT,
            submitted_at REAL NOT NULL, started_at REAL, finished_at REAL, submissions INTEGER NOT NULL DEFAULT 0);
        CREATE TABLE sweeps (id TEXT PRIMARY KEY, name TEXT NOT NULL, spec TEXT NOT NULL, submitted_at REAL NOT NULL);
        CREATE TABLE sweep_cases (sweep_id TEXT NOT NULL REFERENCES sweeps (id), position INTEGER NOT NULL,
            case_id TEXT NOT NULL REFERENCES cases (id), PRIMARY KEY (sweep_id, position));""")
    db.execute("INSERT INTO cases (id, spec, status, submitted_at) VALUES (?, ?, 'queued', 1.0)", (A, SPEC))
    db.commit()
    db.close()
    store = JobStore(path)
    assert store.mark_cancelled([A]) == [A]
    assert [tuple(r) for r in store._db.execute("SELECT version_num FROM alembic_version")] == [(HEAD,)]
    assert "claimed_by" in {r[1] for r in store._db.execute("PRAGMA table_info(cases)")}
    store.close()


def test_settings_pick_the_database_from_the_url(tmp_path):
    assert Settings(results=tmp_path).database == tmp_path / "jobs.sqlite"
    assert not Settings(results=tmp_path).shared_database
    assert Settings(results=tmp_path, database_url=f"sqlite:///{tmp_path}/j.db").database == tmp_path / "j.db"
    assert Settings.from_env({"TUNNEL_CONTACT_DATABASE": "postgresql://u@h/db"}).shared_database


def test_two_replicas_never_claim_one_case_and_a_silent_one_is_taken_over(database_url):
    first = SharedJobStore(database_url, ttl=1.5, heartbeat=0.2)
    second = SharedJobStore(database_url, ttl=1.5, heartbeat=0.2)
    try:
        first.add_case(A, SPEC)  # accepted by the first: its own
        second.add_sweep(C, "s", "{}", [(f"{i:016x}", SPEC) for i in range(200)])
        assert first.open_case_ids() == [A]  # the second's cases are not the first's to settle
        # both reconciling at once over unclaimed cases: each row goes to exactly one
        with first.engine.begin() as db:
            db.execute(sa.text("UPDATE cases SET claimed_by = NULL"))
        claimed: dict[str, list[str]] = {}
        barrier = threading.Barrier(2)

        def claim(store):
            barrier.wait()
            claimed[store.replica] = store.open_case_ids()

        threads = [threading.Thread(target=claim, args=(s,)) for s in (first, second)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        mine, theirs = claimed[first.replica], claimed[second.replica]
        assert not set(mine) & set(theirs) and len(mine) + len(theirs) == 201
        assert set(first.open_case_ids()) == set(mine)  # again: only its own
        # the second stops beating (killed): after the TTL its cases are the first's
        second._stopping.set()
        second._beating.join()
        time.sleep(2.0)
        assert len(first.open_case_ids()) == 201
    finally:
        first.close()
        second.close()


def test_a_lease_is_held_by_one_replica_and_taken_over_when_it_expires(database_url):
    first, second = SharedJobStore(database_url), SharedJobStore(database_url)
    try:
        assert first.take_lease("search:1", seconds=1.0)
        assert not second.take_lease("search:1", seconds=1.0)
        assert first.take_lease("search:1", seconds=1.0)  # renewed by its holder
        time.sleep(1.2)
        assert second.take_lease("search:1", seconds=5.0) and not first.take_lease("search:1")
        second.release_lease("search:1")
        assert first.take_lease("search:1")
    finally:
        first.close()
        second.close()


def test_a_reliability_study_driven_elsewhere_stops_here(database_url):
    """A replica whose study's lease went to another (it was too slow to renew it) stops driving
    at its next look at the study's cases, and writes nothing (service.reliability.LeaseLost);
    the holder goes on."""
    import asyncio
    from types import SimpleNamespace

    from service.reliability import JobRunner, LeaseLost

    first, second = SharedJobStore(database_url), SharedJobStore(database_url)
    try:
        assert first.take_lease("reliability:1", seconds=30.0)

        async def look(store):
            runner = JobRunner(SimpleNamespace(store=store), asyncio.get_running_loop(), "reliability:1")
            return await runner._solve([])

        with pytest.raises(LeaseLost, match="reliability:1"):
            asyncio.run(look(second))
        assert asyncio.run(look(first)) == []  # the holder renews it and reads its cases
    finally:
        first.close()
        second.close()
