"""The deployment topology without containers: scheduler, two workers and the API as processes.

Submits a sweep over HTTP, kills the API (SIGKILL) and restarts it, and kills it
again right after queuing work: every record and result must survive and every
queued case must complete after the restart.
"""
from __future__ import annotations

import signal
from pathlib import Path

import httpx
import pytest
import xarray as xr

from service.process import api_command, free_port, running_cluster, start, stop, wait_healthy
from service_helpers import COARSE, coarse_case, wait_until
from workflows.result_store import as_store

SWEEP = {"name": "integration", "base": COARSE,
         "vary": {"lining.thickness": [0.2, 0.3], "ground.young": [2e7, 5e7]}, "mode": "grid"}


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """A dask scheduler and two single-threaded workers on loopback; yields the address."""
    with running_cluster(2, logs=tmp_path_factory.mktemp("logs")) as address:
        yield address


class Api:
    """The API process, restartable on the same port and results directory."""

    def __init__(self, scheduler: str, results: Path, log: Path):
        self.scheduler, self.results, self.log = scheduler, results, log
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.process = None

    def start(self) -> None:
        self.process = start(api_command(port=self.port, results=self.results, scheduler=self.scheduler),
                             log=self.log)
        wait_healthy(self.url, timeout=60, workers=2, process=self.process)

    def kill(self) -> None:
        """SIGKILL: no shutdown hook runs."""
        stop(self.process, sig=signal.SIGKILL)

    def get(self, path: str) -> httpx.Response:
        return httpx.get(self.url + path, timeout=30)

    def post(self, path: str, body: dict) -> httpx.Response:
        return httpx.post(self.url + path, json=body, timeout=30)


@pytest.fixture(scope="module")
def api(cluster, tmp_path_factory):
    results = tmp_path_factory.mktemp("results")
    api = Api(cluster, results, results.parent / "api.log")
    try:
        api.start()
        yield api
    finally:
        if api.process is not None:
            stop(api.process)


def sweep_finished(api: Api, sweep_id: str):
    body = api.get(f"/sweeps/{sweep_id}").json()
    return body if body["finished"] else None


def all_done(api: Api, case_ids: list[str]) -> bool:
    return all(api.get(f"/cases/{c}").json()["status"] == "done" for c in case_ids)


def test_sweep_over_http_then_records_survive_sigkill(api, tmp_path):
    health = api.get("/health").json()
    assert health["workers"] == 2 and health["scheduler"] == api.scheduler

    response = api.post("/sweeps", SWEEP)
    assert response.status_code == 202
    sweep = response.json()
    status = wait_until(lambda: sweep_finished(api, sweep["id"]), timeout=90, what="the sweep")
    assert status["counts"]["done"] == 4, status

    download = api.get(f"/sweeps/{sweep['id']}/result.nc")
    assert download.status_code == 200
    (tmp_path / "sweep.nc").write_bytes(download.content)
    with xr.open_dataset(tmp_path / "sweep.nc", engine="netcdf4") as ds:
        assert ds.sizes["case"] == 4
        assert sorted(set(ds["ground_young"].values)) == [2e7, 5e7]
    before = {c["id"]: c for c in api.get("/cases").json()["items"]}

    api.kill()
    api.start()

    after = {c["id"]: c for c in api.get("/cases").json()["items"]}
    assert after.keys() == before.keys()
    assert all(after[c]["status"] == "done" and after[c]["summary"] == before[c]["summary"] for c in after)
    assert api.get(f"/sweeps/{sweep['id']}").json()["counts"]["done"] == 4
    again = api.get(f"/sweeps/{sweep['id']}/result.nc")
    assert again.status_code == 200 and again.content == download.content
    assert api.post("/sweeps", SWEEP).json()["created"] is False


def test_cases_queued_when_the_api_is_killed_complete_after_restart(api):
    cases = [coarse_case(loads={"surface_load": 5e4 + 1e4 * i}, lining={"young": 2.5e10}) for i in range(6)]
    recorded = api.get("/cases").json()["total"]  # (the module's other tests may have run first, or not)
    ids = []
    for case in cases:
        response = api.post("/cases", case)
        assert response.status_code == 202 and response.json()["created"] is True
        ids.append(response.json()["id"])
    api.kill()  # most are still queued on the scheduler, some maybe not even sent
    assert not all(as_store(api.results).case_path(c).is_file() for c in ids[-2:]), "too late to test anything"

    api.start()
    wait_until(lambda: all_done(api, ids), timeout=90, what="the cases queued before the kill")
    recovered = api.log.read_text()
    assert "resubmitted" in recovered or "found in the store" in recovered
    for case_id in ids:
        assert as_store(api.results).case_path(case_id).is_file()
        record = api.get(f"/cases/{case_id}").json()
        assert record["summary"]["converged"] == 1.0
        assert record["finished_at"] >= record["submitted_at"]
    assert api.get("/cases").json()["total"] == recorded + len(ids)
    assert api.get("/health").json()["queued"] == 0
    assert '"GET /health HTTP/1.1" 200' not in api.log.read_text()  # no access log by default


def test_api_started_before_the_scheduler_catches_up(tmp_path):
    """Compose may start the API first: it serves degraded, then connects and runs what was queued."""
    import socket

    # the scheduler's port held (bound, not listening: a connection is refused) until the scheduler
    # starts, so that no other test's process takes it meanwhile (as a scheduler or a worker did once)
    holder = socket.socket()
    holder.bind(("127.0.0.1", 0))
    port = holder.getsockname()[1]
    address = f"tcp://127.0.0.1:{port}"
    api = Api(address, tmp_path / "results", tmp_path / "api.log")
    api.process = start(api_command(port=api.port, results=api.results, scheduler=address), log=api.log,
                        env={"TUNNEL_CONTACT_ACCESS_LOG": "1", "TUNNEL_CONTACT_RECONCILE_INTERVAL": "1"})
    try:
        health = wait_until(lambda: _answer(api, "/health"), timeout=60, what="the API to answer")
        assert health.status_code == 503 and health.json()["scheduler_reachable"] is False
        queued = api.post("/cases", coarse_case(loads={"surface_load": 6.5e4}))
        assert queued.status_code == 202 and queued.json()["status"] == "queued"

        holder.close()
        with running_cluster(1, logs=tmp_path, port=port):
            wait_healthy(api.url, timeout=60, workers=1, process=api.process)
            wait_until(lambda: all_done(api, [queued.json()["id"]]), timeout=60, what="the queued case")
    finally:
        holder.close()
        stop(api.process)
    assert '"POST /cases HTTP/1.1" 202' in api.log.read_text()  # asked for: every request logged


def _answer(api: Api, path: str):
    try:
        return api.get(path)
    except httpx.HTTPError:
        return None


def test_health_answers_under_an_idle_connection_flood(tmp_path):
    """1 300 idle sockets against an API started with the common 1 024 open-files limit:
    /health still answers (the API raises its own limit at start; see docs/deployment.md for
    the proxy in front, which bounds idle clients anyway)."""
    import socket
    import sys

    port = free_port()
    command = api_command(port=port, results=tmp_path / "results")
    # the process starts with a soft limit of 1 024 open files, as many systems give
    lowered = [sys.executable, "-c",
               "import os, resource, sys; h = resource.getrlimit(resource.RLIMIT_NOFILE)[1]; "
               "resource.setrlimit(resource.RLIMIT_NOFILE, (1024, h)); os.execvp(sys.argv[1], sys.argv[1:])",
               *command]
    process = start(lowered, log=tmp_path / "api.log")
    sockets = []
    try:
        url = f"http://127.0.0.1:{port}"
        wait_healthy(url, timeout=90, process=process)
        for _ in range(1300):
            sockets.append(socket.create_connection(("127.0.0.1", port), timeout=5))
        response = httpx.get(url + "/health", timeout=15)
        assert response.status_code in (200, 503) and "workers" in response.json()
    finally:
        for s in sockets:
            s.close()
        stop(process)
