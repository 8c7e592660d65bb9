"""The sweep page's table and analyses, in process over planted job records (no cluster, no
solve): varied parameters, then η, then the status and the case link; the solver's warnings as a
mark whose text is read on hover, not a column that makes its row tall; the workbook linked; a
grid sweep without a reliability figure or β, a sampled one with them."""
from __future__ import annotations

import html
import json
import re
from types import SimpleNamespace

import pytest
from fastapi.testclient import TestClient

from service.app import create_app
from service.settings import Settings
from service.studies import _reliability_body
from solver.spec import CaseSpec

THICKNESS = (0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5, 0.55)
YOUNG = (2e7, 5e7, 1e8, 2e8)  # 8 x 4 = 32 cases: enough for the analyses (MIN_SAMPLES)
WARNING = "largest displacement 1.2 m exceeds 2% of the excavation radius: outside the small-displacement model"


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    # no cluster: the scheduler's address answers nothing and the app starts degraded
    app = create_app(Settings(results=tmp_path_factory.mktemp("results"), scheduler="tcp://127.0.0.1:9",
                              reconcile_interval=3600))
    with TestClient(app) as c:
        yield c


def plant(client, sweep_id: str, mode: str) -> list[str]:
    """A sweep of 32 done cases (thickness x ground stiffness), the second with a warning."""
    store = client.app.state.jobs.store
    specs = [CaseSpec.model_validate({"geometry": {"thickness": t}, "ground": {"young": e},
                                      "loads": {"surface_load": 1e4 if mode == "grid" else 2e4}})
             for t in THICKNESS for e in YOUNG]
    vary = {"lining.thickness": list(THICKNESS), "ground.young": list(YOUNG)}
    cases = [(s.case_id, s.canonical_json()) for s in specs]
    record, _ = store.add_sweep(sweep_id, mode, json.dumps({"name": mode, "mode": mode, "vary": vary}), cases)
    for i, spec in enumerate(specs):
        store.finish(spec.case_id, status="done", warnings=[WARNING] if i == 1 else [],
                     summary={"max_utilization": 0.5 + 0.02 * i, "max_thrust": 6e5 + i, "max_abs_moment": 4e4})
    return list(record.case_ids)


def headers(page: str) -> list[str]:
    return re.findall(r'<th data-col="(\w+)"', page)


def test_the_sweep_page_shows_parameters_then_eta_one_line_rows_linked_to_their_cases(client):
    ids = plant(client, "00000000000000a1", "grid")
    page = client.get("/ui/sweeps/00000000000000a1").text
    names = headers(page)
    assert names[:5] == ["lining_thickness", "ground_young", "max_utilization", "status", "case_id"]
    assert names[5] == "max_contact_pressure" and names[-1] == "error" and "warnings" not in names
    rows = dict(re.findall(r'<tr data-key="([0-9a-f]{16})"[^>]*>(.*?)</tr>', page, re.S))
    assert list(rows) == ids
    for case_id, row in rows.items():  # every row links to its case
        assert f'href="/ui/cases/{case_id}"' in row
    # the warning: a mark in the status cell, its text in the title (hover), no text in the row
    mark = re.compile(r'<span class="warn-icon"[^>]*title="([^"]*)"[^>]*>⚠</span>')
    marks = {k: mark.findall(row) for k, row in rows.items()}
    assert {k for k, m in marks.items() if m} == {ids[1]}
    assert html.unescape(marks[ids[1]][0]) == WARNING
    assert "small-displacement" not in re.sub(r'title="[^"]*"', "", rows[ids[1]])
    # the downloads: the workbook beside the CSV
    downloads = re.search(r'<section id="downloads".*?</section>', page, re.S).group(0)
    assert 'href="/sweeps/00000000000000a1/summary.xlsx"' in downloads
    assert 'href="/sweeps/00000000000000a1/summary.csv"' in downloads
    # a grid: sensitivity, but no reliability figure, form field or β
    analyses = re.search(r'<section id="analyses".*?</section>', page, re.S).group(0)
    assert 'id="analysis-form"' in analyses
    assert 'data-plot="reliability"' not in analyses and "reliability-output" not in analyses
    assert "no reliability figure and no β" in analyses


def test_a_sampled_sweep_keeps_its_reliability_figure(client):
    plant(client, "00000000000000b2", "lhs")
    analyses = re.search(r'<section id="analyses".*?</section>', client.get("/ui/sweeps/00000000000000b2").text,
                         re.S).group(0)
    assert 'data-plot="reliability"' in analyses and 'id="reliability-output"' in analyses
    assert 'id="no-reliability"' not in analyses


@pytest.mark.parametrize("mode, has_beta", [("grid", False), ("zip", False), ("lhs", True), ("sobol", True)])
def test_reliability_of_a_grid_has_no_beta(mode, has_beta):
    r = {"probability": 0.25, "beta": 0.674, "beta_ci": [0.3, 1.1], "note": None, "values": [1.0]}
    body = _reliability_body(SimpleNamespace(spec={"mode": mode}), r)
    assert "values" not in body and body["probability"] == 0.25
    assert (body["beta"], body["beta_ci"]) == ((0.674, [0.3, 1.1]) if has_beta else (None, [None, None]))
    assert (body["note"] is None) == has_beta
