"""What the service takes in, on an app whose scheduler is not there (every accepted case stays
queued, so what is held for it stays held): a search expanded off the event loop and bounded
first, searches that could not end or whose range is not valid refused by name, the Host header
checked against the allow-list, room held for queued cases, a failed record that names no case
retried without a server error (issue 38: 1, 2, 3, 7, 8, 11, 12)."""
from __future__ import annotations

import json
import math
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

import service.searches
import workflows.studies
import workflows.sweep
from service.app import create_app
from service.guards import host_allowed
from service.job_records import UNREADABLE
from service.process import free_port
from service.settings import LOOPBACK_NAMES, Settings
from service_helpers import COARSE, THINNEST_SEARCH, coarse_case
from solver.spec import CaseSpec
from workflows.result_store import estimated_result_bytes
from workflows.sweep import Sweep, expand_sweep, sweep_size

EXAMPLES = Path(__file__).parents[2] / "examples"


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    settings = Settings(results=tmp_path_factory.mktemp("results"), scheduler=f"tcp://127.0.0.1:{free_port()}",
                        reconcile_interval=3600, min_free_bytes=0)
    return create_app(settings)


# -- searches (1, 2, 3, 12) ------------------------------------------------------------------------

def test_a_search_is_expanded_off_the_event_loop(client, monkeypatch):
    """While the first trial's grounds are expanded the service answers other requests: the
    expansion waits for an answer to /health, which an event loop busy expanding never gives."""
    real = workflows.sweep.expand_sweep
    started, answered, waits = threading.Event(), threading.Event(), []

    def expand_when_health_answers(sweep):
        started.set()
        waits.append(answered.wait(timeout=60))
        return real(sweep)

    for module in (workflows.sweep, workflows.studies, service.searches):
        if hasattr(module, "expand_sweep"):
            monkeypatch.setattr(module, "expand_sweep", expand_when_health_answers)
    search = {**THINNEST_SEARCH, "name": "off the loop"}
    with ThreadPoolExecutor(1) as pool:
        posted = pool.submit(client.post, "/searches", json=search)
        assert started.wait(timeout=60)
        assert client.get("/health").status_code in (200, 503)  # 503: no scheduler, but an answer
        answered.set()
        response = posted.result(timeout=120)
    assert response.status_code == 202, response.text
    assert waits and all(waits), waits


def test_a_search_over_the_sweep_cap_is_refused_before_expanding(client, monkeypatch):
    def never(sweep):
        raise AssertionError("a search over the cap was expanded")

    for module in (workflows.sweep, workflows.studies, service.searches):
        for name in ("expand_sweep", "expand_trial"):
            if hasattr(module, name):
                monkeypatch.setattr(module, name, never)
    over = {"loads.lateral_ratio": [0.3 + 0.01 * k for k in range(70)],
            "ground.young": [1e7 + 1e5 * k for k in range(70)]}
    response = client.post("/searches", json={**THINNEST_SEARCH, "name": "large", "over": over})
    assert response.status_code == 422 and response.json()["errors"][0]["field"] == "over", response.text
    assert "4,900 cases" in response.json()["detail"]


def test_a_tolerance_finer_than_the_floats_between_the_bounds_is_refused(client):
    """Bisection below one unit in the last place of the bounds tried the same value forever."""
    low = 0.3
    high = math.nextafter(math.nextafter(low, 1.0), 1.0)
    search = {**THINNEST_SEARCH, "name": "below one ulp", "low": low, "high": high, "tolerance": 1e-18}
    response = client.post("/searches", json=search)
    assert response.status_code == 422, response.text
    assert "tolerance" in response.json()["detail"] and "units in the last place" in response.json()["detail"]


def test_a_range_end_that_is_no_valid_case_is_refused_naming_it(client):
    search = {"name": "n", "parameter": "geometry.thickness", "low": 0.2, "high": 30, "tolerance": 0.01}
    response = client.post("/searches", json=search)
    assert response.status_code == 422, response.text
    assert "high: 30 is not a valid geometry.thickness" in response.json()["detail"]


def test_a_long_search_name_is_no_error_of_its_grounds(client):
    search = {**THINNEST_SEARCH, "name": "n" * 200, "low": 0.2}
    response = client.post("/searches", json=search)
    assert response.status_code == 202, response.text
    trial = workflows.studies.Search.model_validate(search).trial_sweep(0.5)
    assert len(trial.name) == 200 and trial.name.endswith(": geometry.thickness = 0.5")


def test_a_sampled_sweep_with_nothing_varied_is_refused(client):
    sweep = {"name": "nothing", "base": COARSE, "vary": {}, "mode": "sobol", "samples": 8}
    response = client.post("/sweeps", json=sweep)
    assert response.status_code == 422 and response.json()["errors"][0]["field"] == "vary", response.text


def test_the_readmes_sobol_study_fits_the_default_cap():
    sweep = Sweep.model_validate(json.loads((EXAMPLES / "sobol-study.json").read_text()))
    assert sweep_size(sweep) == 1024 <= Settings().max_sweep_cases


# -- the Host header (7) ----------------------------------------------------------------------------

def test_a_foreign_host_is_refused_whatever_it_asks(client):
    """What a DNS-rebinding page sends: its own name as Host and Origin, no token configured."""
    evil = {"host": "evil.example:8250", "origin": "http://evil.example:8250"}
    cancelled = client.post("/sweeps/0123456789abcdef/cancel", headers=evil)
    assert cancelled.status_code == 400 and "evil.example:8250" in cancelled.json()["detail"]
    assert client.get("/cases", headers=evil).status_code == 400
    assert client.get("/", headers={"host": "evil.example"}).status_code == 400
    for own in ("localhost:8000", "127.0.0.1:8250", "[::1]:8000", "LOCALHOST"):
        assert client.get("/cases", headers={"host": own}).status_code == 200, own


def test_the_allowed_hosts_come_from_the_environment():
    settings = Settings.from_env({"TUNNEL_CONTACT_ALLOWED_HOSTS": " api.example.org, *.corp.example ,"})
    assert settings.allowed_hosts == ("api.example.org", "*.corp.example")
    assert Settings().allowed_hosts == LOOPBACK_NAMES
    assert host_allowed("api.example.org:443", settings.allowed_hosts)
    assert host_allowed("tunnels.corp.example", settings.allowed_hosts)
    assert not host_allowed("corp.example.evil.org", settings.allowed_hosts)
    assert not host_allowed("localhost", settings.allowed_hosts)
    assert host_allowed("anything", ("*",))


# -- room held for queued cases (8) -----------------------------------------------------------------

def test_room_is_held_for_the_cases_already_queued(client, app, monkeypatch):
    """Each case fits the free space alone; the third does not fit beside the two queued ones."""
    import shutil as real_shutil

    import workflows.store_files

    cases = [coarse_case(loads={"surface_load": 6.01e4 + 10 * k}) for k in range(3)]
    need = estimated_result_bytes(CaseSpec.model_validate(cases[0]))
    usage = real_shutil.disk_usage("/")
    free = app.state.jobs.store.open_room() + int(2.5 * need)

    class Free:
        @staticmethod
        def disk_usage(path):
            return usage._replace(free=free)

    monkeypatch.setattr(workflows.store_files, "shutil", Free)
    app.state.held_room = None  # counted again now
    assert [client.post("/cases", json=c).status_code for c in cases[:2]] == [202, 202]
    refused = client.post("/cases", json=cases[2])
    assert refused.status_code == 503, refused.text
    assert "held for the queued and running cases" in refused.json()["detail"]
    app.state.held_room = None  # from the job records alone, as after a restart
    assert client.post("/cases", json=cases[2]).status_code == 503


# -- a record that names no case (11) ---------------------------------------------------------------

def test_retrying_a_failed_record_that_names_no_case_is_no_server_error(client, app):
    """A sweep imported from a record that did not give every case (a command-line sweep's record
    of an older version): its unnamed case failed. Retrying the sweep leaves it failed (nothing to
    compute); posting the case itself gives the record its case back and computes it."""
    body = {"name": "half named", "base": COARSE, "mode": "grid", "vary": {"loads.surface_load": [5.1e4, 5.2e4]}}
    sweep = Sweep.model_validate(body)
    lost, kept = expand_sweep(sweep)
    store = app.state.jobs.store
    store.add_sweep(sweep.sweep_id, sweep.name, sweep.definition_json(),
                    [(lost.case_id, json.dumps({UNREADABLE: "the sweep record does not give this case"})),
                     (kept.case_id, kept.canonical_json())])
    store.finish(lost.case_id, status="failed", error="invalid job record: the sweep record does not give this case")
    store.finish(kept.case_id, status="failed", error="RuntimeError: planted")
    retried = client.post("/sweeps", params={"retry": "failed"}, json=body)
    assert retried.status_code == 202, retried.text
    assert retried.json()["resubmitted"] == 1
    assert client.get(f"/cases/{lost.case_id}").json()["status"] == "failed"
    again = client.post("/cases", params={"retry": "failed"}, json=json.loads(lost.canonical_json()))
    assert again.status_code == 202, again.text
    record = client.get(f"/cases/{lost.case_id}").json()
    assert record["status"] == "queued" and CaseSpec.model_validate(record["spec"]).case_id == lost.case_id


# -- python -m service.server (12) --------------------------------------------------------------------

def test_python_m_service_server_serves(tmp_path):
    """It exited 0 at once; it serves with the environment's settings (here: no scheduler, so
    /health answers 503, but it answers)."""
    import sys

    import httpx

    from service.process import start, stop
    from service_helpers import wait_until

    port = free_port()
    env = {"TUNNEL_CONTACT_PORT": str(port), "TUNNEL_CONTACT_RESULTS": str(tmp_path / "results"),
           "DASK_SCHEDULER_ADDRESS": f"tcp://127.0.0.1:{free_port()}", "PYTHONPATH": str(EXAMPLES.parent)}
    process = start([sys.executable, "-m", "service.server"], log=tmp_path / "server.log", env=env)

    def answered():
        assert process.poll() is None, (tmp_path / "server.log").read_text()[-2000:]
        try:
            return httpx.get(f"http://127.0.0.1:{port}/health", timeout=5).status_code
        except httpx.HTTPError:
            return None

    try:
        assert wait_until(answered, timeout=120, interval=0.2, what="python -m service.server to answer") == 503
    finally:
        stop(process)


def test_the_address_bound_to_is_answered_to():
    """``serve --host 10.1.2.3``: its clients call it by that address (a rebinding page sends a name)."""
    from fastapi.testclient import TestClient

    bare = create_app(Settings(host="10.1.2.3"))  # no lifespan: the host check answers first
    with_client = TestClient(bare)
    assert with_client.get("/health", headers={"host": "evil.example"}).status_code == 400
    assert with_client.get("/openapi.json", headers={"host": "10.1.2.3:8000"}).status_code == 200
