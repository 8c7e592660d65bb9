"""Reliability studies over REST (SPEC §9.6): a FORM study whose FE calls are cases of the
service, its answer, page and figure; bad input named (422, never 500); a study stopped with
the service resumes on the next start and ends with the answer its stored cases give."""
from __future__ import annotations

import time

import pytest
from fastapi.testclient import TestClient
from scipy import stats

from service.app import create_app
from service.settings import Settings

from bench.exact_limit_state import EXACT, GAMMA, ExactLimitState  # weightless ground, light lining
from service_helpers import STUDY_MESH


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    return _app(tmp_path_factory.mktemp("reliability-api"))


def _app(root):
    return create_app(Settings(results=root, local_workers=2, poll_interval=0.1, reconcile_interval=3600))


def _until(fn, timeout=600.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = fn()
        if value:
            return value
        time.sleep(0.3)
    raise AssertionError("timed out")


def study_at(beta: float, budget: int, name: str) -> dict:
    """A FORM study whose exact reliability index is ``beta`` (bench.exact_limit_state)."""
    return {**ExactLimitState(mesh=STUDY_MESH).study(beta, "form", budget, seed=4), "name": name}


@pytest.mark.parametrize("change, field", [
    ({"variables": {"ground.colour": {"distribution": "normal", "mean": 1, "std": 1}}}, "variables.ground.colour"),
    ({"variables": {"ground.young": {"distribution": "lognormal", "mean": -1, "std": 1}}}, "variables.ground.young"),
    ({"budget": 5}, "budget"),
    ({"method": "monte-carlo"}, "method"),
    ({"output": "moment"}, "output"),
    ({"limit": "inf"}, "limit"),
    ({"base": {"geometry": {"depth": -3}}}, "base.geometry.depth"),
    ({"variables": ["ground.young"]}, "variables"),
    ({"variables": {"ground.young": {"distribution": "truncated-normal", "mean": 1e7, "std": 1e6, "low": 2e7,
                                     "high": 1e7}}}, "variables.ground.young"),
    ({"seed": -1}, "seed"),
    ({"budget": 100, "method": "subset", "samples_per_level": 500}, "samples_per_level"),
    ({"colour": "red"}, "colour"),
    ({"name": ""}, "name"),
])
def test_bad_studies_are_422_naming_the_field(client, change, field):
    good = {"name": "x", "base": EXACT, "variables": {"design.load_factor": GAMMA}}
    r = client.post("/reliability", json={**good, **change})
    assert r.status_code == 422, r.text
    assert r.json()["errors"][0]["field"].startswith(field), r.json()


def test_unknown_studies_are_404(client):
    assert client.get("/reliability/0123456789abcdef").status_code == 404
    assert client.get("/reliability/nope").status_code == 404
    assert client.get("/ui/reliability/0123456789abcdef").status_code == 404
    assert client.get("/reliability").json()["total"] == 0


@pytest.mark.slow
def test_a_form_study_over_rest_and_across_a_restart(tmp_path):
    study = study_at(2.0, 40, "rest")
    with TestClient(_app(tmp_path)) as client:
        r = client.post("/reliability", json=study)
        assert r.status_code == 202 and r.headers["Location"] == f"/reliability/{r.json()['id']}"
        ident = r.json()["id"]
        assert client.post("/reliability", json=study).json()["id"] == ident  # the same study
        # stop the service midway: the study is left running
        _until(lambda: client.get(f"/reliability/{ident}").json()["calls"] >= 6)
    with TestClient(_app(tmp_path)) as client:  # a new start resumes it
        done = _until(lambda: (lambda j: j if j["status"] != "running" else None)(
            client.get(f"/reliability/{ident}").json()))
        assert done["status"] == "done", done
        assert done["calls"] <= 40 and done["beta"] == pytest.approx(2.0, abs=0.02)
        p = stats.norm.sf(2.0)
        assert done["ci_low"] <= p <= done["ci_high"]
        assert set(done["importance"]) == {"loads.surface_load", "design.load_factor"}
        case = client.get(f"/cases/{done['design_case']}").json()
        assert case["status"] == "done" and case["summary"]["max_utilization"] == pytest.approx(1.0, abs=2e-3)
        page = client.get(f"/ui/reliability/{ident}")
        assert page.status_code == 200 and "β = 2.0" in page.text and f"/ui/cases/{done['design_case']}" in page.text
        case_page = client.get(f"/ui/cases/{done['design_case']}").text  # and the case links back
        assert "The design point of reliability study" in case_page and f"/ui/reliability/{ident}" in case_page
        other = next(c for c in done["case_ids"] if c != done["design_case"])
        assert "The design point of reliability study" not in client.get(f"/ui/cases/{other}").text
        png = client.get(f"/reliability/{ident}/convergence.png")
        assert png.status_code == 200 and png.headers["content-type"] == "image/png"
        assert any(item["id"] == ident for item in client.get("/reliability").json()["items"])
        assert f"/ui/reliability/{ident}" in client.get("/").text  # listed on the dashboard
    # the answer is the one its stored cases give, replayed without solving anything
    from workflows.reliability_methods import ReliabilityStudy, StoreRunner, run_study

    replay = run_study(study, StoreRunner(tmp_path, None, "max_utilization"))
    for key in ("beta", "probability", "ci_low", "ci_high", "design_case", "case_ids"):
        assert replay[key] == done[key]
    assert ReliabilityStudy.model_validate(study).study_id == ident
