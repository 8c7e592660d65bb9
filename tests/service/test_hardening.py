"""Issue 24, input and origin: values no physics has, text no file can hold, answers of
bounded size, requests from other sites, BLAS threads, a dead worker's message. Each test
fails without its fix."""
from __future__ import annotations

import json

import pytest
from service_helpers import COARSE
from service.app import create_app
from service.settings import Settings


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    settings = Settings(results=tmp_path_factory.mktemp("results"), local_workers=1,
                        max_sweep_cases=50, poll_interval=0.1, reconcile_interval=3600)
    return create_app(settings)


def fields(response) -> list[str]:
    return [e["field"] for e in response.json()["errors"]]


@pytest.mark.parametrize("body, field", [
    ({"loads": {"gravity": 5e-324}}, "loads.gravity"),        # subnormal: accepted before, KKT 2.6e285
    ({"loads": {"gravity": 0.5}}, "loads.gravity"),           # below 1 m/s²: no physics
    ({"geometry": {"gap": 5e-324}}, "geometry.gap"),
    ({"solver": {"tolerance": 1e-16}}, "solver.tolerance"),   # finer than double precision resolves
    ({"solver": {"plastic_tolerance": 1e-7}}, "solver.plastic_tolerance"),  # finer than it is honoured
    ({"solver": {"plastic_tolerance": 0.5}}, "solver.plastic_tolerance"),   # no equilibrium at all
    ({"ground": {"layers": [{"thickness": 5e-324}]}}, "ground.layers.0.thickness"),
])
def test_values_no_physics_has_are_refused_naming_the_field(client, body, field):
    response = client.post("/cases", json=body)
    assert response.status_code == 422 and field in fields(response), response.json()


def test_minus_zero_is_zero_one_case_one_id(client):
    a = client.post("/cases", json={**COARSE, "geometry": {"gap": -0.0}})
    b = client.post("/cases", json={**COARSE, "geometry": {"gap": 0.0}})
    assert a.status_code == b.status_code == 202 and a.json()["id"] == b.json()["id"]


def test_a_zip_sweep_with_no_case_is_refused(client):
    response = client.post("/sweeps", json={"name": "empty", "mode": "zip", "vary": {}})
    assert response.status_code == 422 and fields(response) == ["vary"]


@pytest.mark.parametrize("sweep, field", [
    ('{"name": "x", "vary": {"\\ud800": [1]}}', "\\ud800"),  # the path, shown printable
    ('{"name": "\\ud800", "vary": {}}', "name"),
    ('{"name": "x", "vary": {"solver.bolt": ["\\ud800"]}}', "solver.bolt"),
])
def test_a_lone_surrogate_is_invalid_input_not_a_server_error(client, sweep, field):
    """A path or value that is no parameter is refused like any other (its text made printable
    in the answer); the name, stored as given, must be valid Unicode."""
    response = client.post("/sweeps", content=sweep.encode(), headers={"content-type": "application/json"})
    assert response.status_code == 422 and any(f.startswith(field) for f in fields(response))
    response.content.decode("utf-8")  # an answer any client can read
    if field == "name":
        assert "not valid Unicode" in response.text


def test_an_error_answer_stays_small_for_a_large_body_of_bad_values(client, monkeypatch):
    import workflows.sweep

    suggest, asked = workflows.sweep.did_you_mean, []
    monkeypatch.setattr(workflows.sweep, "did_you_mean", lambda *a: asked.append(a) or suggest(*a))
    body = json.dumps({"name": "big", "vary": {f"lining.no_such_{i}": [1] for i in range(36_000)}})
    assert len(body) > 900_000
    response = client.post("/sweeps", content=body.encode(), headers={"content-type": "application/json"})
    assert response.status_code == 422
    assert len(response.content) < 40_000, len(response.content)
    errors = response.json()["errors"]
    assert len(errors) <= 51 and errors[0]["field"] == "lining.no_such_0"
    assert errors[-1]["reason"] == "and 35,950 more errors not listed"
    assert "did you mean 'lining.young'" in errors[0]["reason"]
    assert len(asked) == workflows.sweep.SUGGESTED  # suggestions for the listed errors only (1 ms each)
    from service.errors import MAX_ERRORS

    assert workflows.sweep.SUGGESTED == MAX_ERRORS  # (workflows does not import the service)


# -- other origins ------------------------------------------------------------------------------

def test_a_post_from_another_site_is_refused_with_or_without_a_token(client):
    case = {**COARSE, "loads": {"surface_load": 9.1e4}}
    for headers in ({"origin": "https://evil.example"}, {"origin": "null"}, {"sec-fetch-site": "cross-site"}):
        response = client.post("/cases", json=case, headers=headers)
        assert response.status_code == 403 and "cross-site" in response.json()["detail"], headers
        assert client.post("/sweeps/0123456789abcdef/cancel", headers=headers).status_code == 403
    total = client.get("/cases").json()["total"]
    assert all(c["spec"]["loads"]["surface_load"] != 9.1e4 for c in client.get("/cases").json()["items"])
    # the service's own origin (the dashboard's fetch) and clients without one (curl, the CLI) pass
    own = client.post("/cases", json=case, headers={"origin": "http://localhost", "sec-fetch-site": "same-origin"})
    assert own.status_code == 202
    assert client.get("/cases").json()["total"] == total + 1


@pytest.mark.parametrize("path", ["/", "/ui/submit", "/health", "/cases", "/docs"])
def test_no_page_can_be_framed_by_another_site(client, path):
    headers = client.get(path).headers
    assert headers["x-frame-options"] == "DENY"
    assert "frame-ancestors 'none'" in headers["content-security-policy"]
    assert headers["x-content-type-options"] == "nosniff"


# -- the machine ----------------------------------------------------------------------------------

def test_the_solver_runs_on_one_blas_thread_in_any_process(monkeypatch):
    """Whatever the process set (here: as many threads as the machine has), factorization
    and contact run with one BLAS thread (threadpoolctl), so no case is many times slower."""
    from threadpoolctl import threadpool_info, threadpool_limits

    import solver.stages.recovery as model_module
    from solver.run import run_case
    from solver.spec import CaseSpec

    seen = []
    original = model_module.kkt_residual

    def spy(**kwargs):
        seen.append([pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"])
        return original(**kwargs)

    monkeypatch.setattr(model_module, "kkt_residual", spy)
    with threadpool_limits(limits=4, user_api="blas"):
        run_case(CaseSpec.model_validate(COARSE))
        outside = [pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"]
    assert seen and all(n == 1 for n in seen[0]), seen
    assert max(outside) > 1  # and the process's own setting is given back


def test_a_dead_workers_case_error_says_what_happened_and_how_to_retry(tmp_path):
    from distributed.scheduler import KilledWorker

    from service.jobs import task_error

    message = task_error(KilledWorker("solve_and_store-0123456789abcdef", "tcp://127.0.0.1:1", 4), tmp_path)
    assert "KilledWorker" not in message and "solve_and_store" not in message
    assert "died" in message and "memory" in message and "retry=failed" in message
