"""The service under bad input, a full disk, broken result files and damaged job records
(issue 10): never a 500, never a broken file served, nothing stuck.

One in-process app (TestClient) on an embedded one-worker LocalCluster.
"""
from __future__ import annotations

import asyncio
import errno
import os
import sqlite3
import time

import pytest
import xarray as xr

from service.app import create_app
from service.jobs import Dispatcher
from service.settings import Settings
from service.job_records import JobStore
from service_helpers import COARSE, coarse_case, finished, wait_until
from solver.spec import CaseSpec
from workflows.result_store import as_store


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    settings = Settings(results=tmp_path_factory.mktemp("results"), local_workers=1,
                        poll_interval=0.1, reconcile_interval=3600, min_free_bytes=1 << 20)
    return create_app(settings)


@pytest.fixture(scope="module")
def done_case(client) -> dict:
    body = finished(client, client.post("/cases", json=COARSE).json()["id"])
    assert body["status"] == "done", body["error"]
    return body


# -- bad input: 422 naming the field, never 500 ---------------------------------------------

@pytest.mark.parametrize("raw, field", [
    (b'{"ground": {"young": Infinity}}', "ground.young"),
    (b'{"lining": {"young": -Infinity}}', "lining.young"),
    (b'{"lining": {"density": 1e400}}', "lining.density"),
    (b'{"loads": {"surface_load": NaN}}', "loads.surface_load"),
    (b'{"geometry": {"width": 1e308}}', "geometry.width"),
    (b'{"mesh": {"interface_size": 1e-300}}', "mesh.interface_size"),
    # a number is a number: lax validation solved `true` as a 1 m lining
    (b'{"geometry": {"thickness": true}}', "geometry.thickness"),
    (b'{"loads": {"lateral_ratio": "0.5"}}', "loads.lateral_ratio"),
    (b'{"solver": {"bolt": true}}', "solver.bolt"),
    (b'{"solver": {"max_iterations": 1000.5}}', "solver.max_iterations"),
    (b'{"interface": {"model": "bonded"}, "geometry": {"gap": 0.02}}', "geometry.gap"),
])
def test_non_finite_and_huge_numbers_are_422_naming_the_field(client, raw, field):
    response = client.post("/cases", content=raw, headers={"content-type": "application/json"})
    assert response.status_code == 422, response.text
    assert field in {e["field"] for e in response.json()["errors"]}


def test_non_finite_sweep_values_are_422_naming_the_varied_field(client):
    raw = b'{"name": "inf", "base": {}, "vary": {"ground.young": [5e7, Infinity], "lining.young": [1e400]}}'
    response = client.post("/sweeps", content=raw, headers={"content-type": "application/json"})
    assert response.status_code == 422, response.text
    fields = {e["field"] for e in response.json()["errors"]}
    assert any("ground.young" in f for f in fields) and any("lining.young" in f for f in fields), fields


@pytest.mark.parametrize("path", ["/cases", "/sweeps"])
@pytest.mark.parametrize("offset", ["1e23", str(10**30), "-1", "nan"])
def test_huge_or_bad_offset_is_422(client, path, offset):
    response = client.get(path, params={"offset": offset})
    assert response.status_code == 422
    assert response.json()["errors"][0]["field"] == "offset"


# -- a store that cannot take writes: 503 with the reason -------------------------------------

def test_post_is_503_with_the_reason_when_the_job_records_are_full(client, app, monkeypatch):
    def full(*args, **kwargs):
        raise sqlite3.OperationalError("database or disk is full")
    monkeypatch.setattr(app.state.jobs.store, "_write", full)
    response = client.post("/cases", json=coarse_case(loads={"surface_load": 4.321e4}))
    assert response.status_code == 503
    assert "cannot take writes" in response.json()["detail"] and "full" in response.json()["detail"]


def test_plot_write_on_a_full_disk_is_503_without_server_paths(client, app, done_case, monkeypatch):
    import service.cases

    def enospc(root, case_id, name, *args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(root / "plots" / case_id / f"{name}.png"))
    monkeypatch.setattr(service.cases, "render_plot", enospc)
    response = client.get(f"/cases/{done_case['id']}/plots/contact_pressure.png")
    assert response.status_code == 503
    assert "No space left" in response.json()["detail"] and str(app.state.jobs.root) not in response.text


def test_too_little_free_space_is_503_on_post_and_degraded_health(client, monkeypatch):
    import shutil as real_shutil

    import workflows.store_files

    usage = real_shutil.disk_usage("/")

    class Almost:
        @staticmethod
        def disk_usage(path):
            return usage._replace(free=344 * 1024)

    monkeypatch.setattr(workflows.store_files, "shutil", Almost)  # free_bytes' module
    health = client.get("/health")
    assert health.status_code == 503 and health.json()["results_free_bytes"] == 344 * 1024
    assert any("results store is full: 0.3 MiB free" in r for r in health.json()["reasons"])
    response = client.post("/cases", json=coarse_case(loads={"surface_load": 4.322e4}))
    assert response.status_code == 503 and "results store is full: 0.3 MiB free" in response.json()["detail"]


def test_watchers_keep_an_outcome_until_the_database_takes_it(client, app, monkeypatch):
    store = app.state.jobs.store
    real, refusals = store.finish, []

    def flaky(*args, **kwargs):
        if len(refusals) < 3:
            refusals.append(args)
            raise sqlite3.OperationalError("database or disk is full")
        return real(*args, **kwargs)
    monkeypatch.setattr(store, "finish", flaky)
    monkeypatch.setattr(store, "mark_running", lambda ids: (_ for _ in ()).throw(
        sqlite3.OperationalError("database or disk is full")))
    case_id = client.post("/cases", json=coarse_case(loads={"surface_load": 4.323e4})).json()["id"]
    assert finished(client, case_id)["status"] == "done"
    assert len(refusals) == 3
    pollers = [t for t in app.state.jobs._tasks if "_poll_running" in repr(t.get_coro())]
    assert pollers and not any(t.done() for t in pollers)


# -- broken result files are recomputed, never served ------------------------------------------

def test_truncated_result_is_recomputed_not_served(client, app, done_case):
    path = as_store(app.state.jobs.root).case_path(done_case["id"])
    good = path.read_bytes()
    path.write_bytes(good[: len(good) // 3])
    response = client.get(f"/cases/{done_case['id']}/result.nc")
    assert response.status_code == 409 and "recomputed" in response.json()["detail"]
    assert finished(client, done_case["id"])["status"] == "done"
    again = client.get(f"/cases/{done_case['id']}/result.nc")
    assert again.status_code == 200
    recomputed = path.with_name("served.nc")
    recomputed.write_bytes(again.content)
    with xr.open_dataset(recomputed) as ds:  # a whole result again, the same physics
        assert float(ds.max_contact_pressure) == done_case["summary"]["max_contact_pressure"]
    recomputed.unlink()


def test_result_overwritten_in_place_is_recomputed_never_served(client, app, done_case):
    """Issue 24: bytes overwritten inside stored files (same size) were served with 200 and
    opened with hundreds of wrong values; a plot answered 500. The checksum written with the
    file finds it: the plot and the file answer 409 while the case is computed again."""
    from workflows.files import digest, checksum_path

    path = as_store(app.state.jobs.root).case_path(done_case["id"])
    size = path.stat().st_size
    with open(path, "r+b") as fh:
        fh.seek(size // 2)
        fh.write(bytes(range(256)) * 2)
    assert path.stat().st_size == size
    plot = client.get(f"/cases/{done_case['id']}/plots/contact_pressure.png")
    assert plot.status_code == 409 and "recomputed" in plot.json()["detail"]
    assert client.get(f"/cases/{done_case['id']}/result.nc").status_code == 409
    assert finished(client, done_case["id"])["status"] == "done"
    again = client.get(f"/cases/{done_case['id']}/result.nc")
    assert again.status_code == 200
    assert digest(path) == checksum_path(path).read_text().strip()
    served = path.with_name("served.nc")
    served.write_bytes(again.content)
    with xr.open_dataset(served) as ds:
        assert float(ds.max_contact_pressure) == done_case["summary"]["max_contact_pressure"]
    served.unlink()
    assert client.get(f"/cases/{done_case['id']}/plots/contact_pressure.png").status_code == 200


def test_deleted_result_is_recomputed_at_reconciliation(client, app, done_case):
    as_store(app.state.jobs.root).case_path(done_case["id"]).unlink()
    client.portal.call(app.state.jobs.reconcile)
    # requeued by reconciliation (it cannot be done again yet: its file is gone)
    assert client.get(f"/cases/{done_case['id']}").json()["status"] in ("queued", "running")
    assert finished(client, done_case["id"])["status"] == "done"
    assert as_store(app.state.jobs.root).case_path(done_case["id"]).is_file()


def test_stale_temporaries_are_removed_by_the_service(client, app):
    jobs = app.state.jobs
    stale = as_store(jobs.root).cases_dir / ".0123456789abcdef.nc.x.tmp"
    stale.parent.mkdir(parents=True, exist_ok=True)
    stale.write_bytes(b"half")
    os.utime(stale, (time.time() - 7200, time.time() - 7200))
    jobs._rounds = 0
    client.portal.call(jobs.reconcile)
    assert not stale.exists()


# -- recompute on request; the bounded queue ---------------------------------------------------

def test_retry_failed_recomputes_a_failed_case_and_sweep(client, app):
    bad = coarse_case(solver={"inner": "uzawa", "max_iterations": 1})
    first = finished(client, client.post("/cases", json=bad).json()["id"])
    assert first["status"] == "failed"
    plain = client.post("/cases", json=bad).json()
    assert plain["status"] == "failed" and plain["created"] is False
    store = app.state.jobs.store
    before = store.get_case(first["id"]).submissions
    retried = client.post("/cases", json=bad, params={"retry": "failed"})
    assert retried.status_code == 202 and retried.json()["status"] == "queued"
    assert finished(client, first["id"])["status"] == "failed"  # the solver fails again, but it ran
    assert store.get_case(first["id"]).submissions == before + 1

    sweep = {"name": "retry", "base": bad, "vary": {"loads.surface_load": [1e5]}}
    sweep_id = client.post("/sweeps", json=sweep).json()["id"]
    wait_until(lambda: client.get(f"/sweeps/{sweep_id}").json()["finished"], what="the sweep")
    body = client.post("/sweeps", json=sweep, params={"retry": "failed"}).json()
    assert body["resubmitted"] == 1 and body["counts"]["failed"] == 0
    assert client.post("/cases", json=bad, params={"retry": "everything"}).status_code == 422


def test_429_with_retry_after_above_the_open_case_limit(client, app):
    original = app.state.settings
    # the earlier tests' cases settled first: one finishing between the count and the POST
    # would leave room (on a loaded machine it did)
    wait_until(lambda: app.state.jobs.store.count_open() == 0, what="the earlier cases to settle")
    app.state.settings = original.model_copy(update={"max_open_cases": 1, "retry_after": 7})
    try:
        planted = CaseSpec.model_validate(coarse_case(loads={"surface_load": 4.324e4}))
        app.state.jobs.store.add_case(planted.case_id, planted.canonical_json())  # fills the queue
        app.state.open_count = None  # counted again now, not up to 0.25 s later
        response = client.post("/cases", json=coarse_case(loads={"surface_load": 4.325e4}))
        assert response.status_code == 429 and response.headers["retry-after"] == "7"
        assert "limit" in response.json()["detail"]
        sweep = {"name": "full", "base": COARSE, "vary": {"loads.surface_load": [4.326e4, 4.327e4]}}
        assert client.post("/sweeps", json=sweep).status_code == 429
        known = client.post("/cases", json=coarse_case(loads={"surface_load": 4.324e4}))
        assert known.status_code == 202 and known.json()["created"] is False  # no new work
    finally:
        app.state.settings = original
        client.portal.call(app.state.jobs.reconcile)  # the planted case runs


# -- start-up, OpenAPI, serve ----------------------------------------------------------------

def test_startup_quarantines_unreadable_and_invalid_records(tmp_path):
    store = JobStore(tmp_path / "jobs.sqlite")
    store.add_case("00000000000000a1", '{"ground": {"poisson": 0.4999}}')  # valid before, not now
    store.add_case("00000000000000a2", "{not json")
    good = CaseSpec.model_validate(COARSE)
    store.add_case(good.case_id, good.canonical_json())

    async def unreachable():
        raise OSError("no scheduler")

    async def start_and_stop():
        jobs = Dispatcher(unreachable, store, tmp_path, reconcile_interval=3600)
        await jobs.start()
        await jobs.stop()

    asyncio.run(start_and_stop())
    invalid, garbled = store.get_case("00000000000000a1"), store.get_case("00000000000000a2")
    assert invalid.status == "failed" and "ground.poisson" in invalid.error and "invalid job record" in invalid.error
    assert garbled.status == "failed" and "not JSON" in garbled.error
    assert store.get_case(good.case_id).status == "queued"  # waits for the scheduler
    store.close()


def test_openapi_declares_a_bearer_token_only_when_configured(client, app):
    def security(schema):
        return "securitySchemes" in schema.get("components", {}) or any(
            "security" in op for ops in schema["paths"].values() for op in ops.values())
    assert not security(client.get("/openapi.json").json())
    original = app.state.settings
    app.state.settings = original.model_copy(update={"token": "s3cret"})
    try:
        assert security(client.get("/openapi.json").json())
    finally:
        app.state.settings = original


def test_serve_honours_host_and_port_from_the_environment(monkeypatch, tmp_path):
    import service.server
    from service.cli import main

    seen = {}
    monkeypatch.setattr(service.server.uvicorn, "run",
                        lambda app, host, port, **kw: seen.update(host=host, port=port, access_log=kw["access_log"]))
    monkeypatch.setenv("TUNNEL_CONTACT_HOST", "127.0.0.2")
    monkeypatch.setenv("TUNNEL_CONTACT_PORT", "8123")
    assert main(["serve", "--results", str(tmp_path)]) == 0
    assert seen == {"host": "127.0.0.2", "port": 8123, "access_log": False}
    assert main(["serve", "--results", str(tmp_path), "--port", "8124", "--access-log"]) == 0
    assert seen == {"host": "127.0.0.2", "port": 8124, "access_log": True}


@pytest.mark.parametrize("damage", ["header", "page"])
def test_damaged_job_records_are_moved_aside_and_rebuilt_from_the_results(tmp_path, damage):
    """Issue 24: with the SQLite header damaged the API exited at start; with a page damaged
    it answered 500 to everything while the results sat on disk. Now the database is checked
    at start, moved aside with the reason, and the records rebuilt: the done case, the
    failed case with its reason, the sweep (from its record beside the results)."""
    from fastapi.testclient import TestClient

    from service_helpers import COARSE, finished, wait_until

    settings = Settings(results=tmp_path / "results", local_workers=1, poll_interval=0.1, reconcile_interval=3600)
    sweep = {"name": "kept", "base": COARSE, "mode": "zip",
             "vary": {"solver.max_iterations": [100_000, 2], "solver.inner": ["active-set", "uzawa"]}}
    with TestClient(create_app(settings)) as client:
        body = client.post("/sweeps", json=sweep).json()
        wait_until(lambda: client.get(f"/sweeps/{body['id']}").json()["finished"], what="the sweep")
        before = {c: client.get(f"/cases/{c}").json() for c in body["case_ids"]}
    database = settings.database
    raw = bytearray(database.read_bytes())
    if damage == "header":
        raw[:100] = b"\x00" * 100
    else:  # a page in the middle (the cases table's)
        page = 4096
        raw[2 * page:3 * page] = bytes(range(256)) * (page // 256)
    database.write_bytes(bytes(raw))
    for suffix in ("-wal", "-shm"):
        database.with_name(database.name + suffix).unlink(missing_ok=True)

    with TestClient(create_app(settings)) as client:
        assert client.get("/health").status_code in (200, 503)
        status = client.get(f"/sweeps/{body['id']}").json()
        assert status["counts"]["done"] == 1 and status["counts"]["failed"] == 1
        for case_id, old in before.items():
            now = client.get(f"/cases/{case_id}").json()
            assert now["status"] == old["status"]
            if old["status"] == "done":
                assert now["summary"]["max_thrust"] == pytest.approx(old["summary"]["max_thrust"])
            else:
                assert "solver.inner='uzawa' did not converge" in now["error"]
        # and it takes new work
        assert finished(client, client.post("/cases", json={**COARSE, "loads": {"surface_load": 6.5e4}}).json()["id"])[
            "status"] == "done"
    assert list(database.parent.glob(database.name + ".damaged-*"))


def test_a_page_damaged_while_running_answers_503_and_the_records_are_rebuilt(tmp_path):
    """Issue 24: a page of the job records damaged under a running service answered 500 to
    every request. Now the request meeting it answers 503 with the reason, the database is
    moved aside and rebuilt from the results, and the service goes on: the done case listed
    as done, new cases taken."""
    from fastapi.testclient import TestClient

    settings = Settings(results=tmp_path / "results", local_workers=1, poll_interval=0.1, reconcile_interval=3600)
    with TestClient(create_app(settings)) as client:
        done = finished(client, client.post("/cases", json=COARSE).json()["id"])
        assert done["status"] == "done"
        database = settings.database
        other = sqlite3.connect(database, isolation_level=None)
        other.execute("PRAGMA wal_checkpoint(TRUNCATE)").fetchall()
        page = 4096
        with open(database, "r+b") as fh:  # every page but the header's, in place
            for k in range(1, database.stat().st_size // page):
                fh.seek(k * page)
                fh.write(bytes(range(256)) * (page // 256))
        other.execute("CREATE TABLE poke (x)")  # another writer: the service's page cache is stale
        other.close()
        answer = client.get("/cases")
        assert answer.status_code == 503, answer.text
        assert "damaged" in answer.json()["detail"] and "rebuilt" in answer.json()["detail"]
        wait_until(lambda: client.get(f"/cases/{done['id']}").status_code == 200, what="the rebuilt records")
        again = client.get(f"/cases/{done['id']}").json()
        assert again["status"] == "done"
        assert again["summary"]["max_thrust"] == pytest.approx(done["summary"]["max_thrust"])
        new = client.post("/cases", json={**COARSE, "loads": {"surface_load": 7.5e4}})
        assert new.status_code == 202 and finished(client, new.json()["id"])["status"] == "done"
        assert client.get("/health").json()["status"] != "error"
    assert list(database.parent.glob(database.name + ".damaged-*"))
