"""The REST API in process (TestClient) on an embedded two-worker LocalCluster.

Every endpoint of SPEC §6, its status codes and error bodies.
"""
from __future__ import annotations

import json
import math

import numpy as np

import pytest
import xarray as xr

from service_helpers import COARSE, coarse_case, finished, wait_until
from service.app import create_app
from service.settings import Settings
from solver.spec import CaseSpec
from workflows.plots import PLOTS
from workflows.result_store import as_store

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
NETCDF_MAGIC = b"\x89HDF"


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    # reconciliation is left to the tests (they call it), so records planted in the
    # store stay as planted until then
    settings = Settings(results=tmp_path_factory.mktemp("results"), local_workers=2,
                        max_sweep_cases=50, poll_interval=0.1, reconcile_interval=3600)
    return create_app(settings)


@pytest.fixture(scope="module")
def done_case(client) -> dict:
    response = client.post("/cases", json=COARSE)
    assert response.status_code == 202
    return finished(client, response.json()["id"])


def plant(app, spec: dict) -> str:
    """Record a case as queued without submitting it (as a crash would leave it)."""
    case = CaseSpec.model_validate(spec)
    app.state.jobs.store.add_case(case.case_id, case.canonical_json())
    return case.case_id


# -- health ---------------------------------------------------------------------------------

def test_health_reports_scheduler_workers_and_store(client):
    response = client.get("/health")
    assert response.status_code == 200
    body = response.json()
    assert body["status"] == "ok"
    assert body["scheduler_reachable"] and body["results_writable"]
    assert body["workers"] == 2


def test_openapi_lists_every_endpoint_with_response_models(client):
    schema = client.get("/openapi.json").json()
    assert set(schema["paths"]) == {
        "/cases", "/cases/{case_id}", "/cases/{case_id}/result.nc", "/cases/{case_id}/plots/{name}.png",
        "/cases/{case_id}/report.pdf", "/cases/{case_id}/tables.xlsx", "/cases/{case_id}/forces.csv", "/sweeps",
        "/sweeps/{sweep_id}", "/sweeps/{sweep_id}/result.nc", "/health",
        "/sweeps/{sweep_id}/table", "/sweeps/{sweep_id}/table.parquet", "/sweeps/{sweep_id}/summary.csv",
        "/sweeps/{sweep_id}/summary.xlsx", "/sweeps/{sweep_id}/plots/{name}.png",
        "/sweeps/{sweep_id}/cancel", "/sweeps/{sweep_id}/sensitivity", "/sweeps/{sweep_id}/sensitivity.png",
        "/sweeps/{sweep_id}/reliability", "/sweeps/{sweep_id}/reliability.png", "/searches", "/searches/{search_id}",
        "/searches/{search_id}/trials.png", "/reliability", "/reliability/{study_id}",
        "/reliability/{study_id}/convergence.png"}
    post = schema["paths"]["/cases"]["post"]
    assert "202" in post["responses"] and "422" in post["responses"]
    assert {"Case", "CaseAccepted", "CasePage", "SweepStatus", "SweepAccepted", "Health"} <= set(
        schema["components"]["schemas"])
    assert client.get("/docs").status_code == 200


# -- cases ----------------------------------------------------------------------------------

def test_post_case_answers_202_with_location_then_solves(client, done_case):
    spec = CaseSpec.model_validate(COARSE)
    assert done_case["id"] == spec.case_id
    assert done_case["status"] == "done", done_case["error"]
    assert done_case["spec"] == json.loads(spec.canonical_json())
    assert done_case["summary"]["converged"] == 1.0
    assert done_case["summary"]["max_contact_pressure"] > 0
    assert done_case["error"] is None
    assert done_case["submitted_at"] <= done_case["started_at"] <= done_case["finished_at"]


def test_post_existing_case_returns_it_without_recomputing(client, app, done_case):
    path = as_store(app.state.jobs.root).case_path(done_case["id"])
    stamp = path.stat().st_mtime_ns
    response = client.post("/cases", json=COARSE)
    assert response.status_code == 202
    assert response.headers["location"] == f"/cases/{done_case['id']}"
    body = response.json()
    assert (body["id"], body["status"], body["created"]) == (done_case["id"], "done", False)
    assert app.state.jobs.store.get_case(done_case["id"]).submissions == 1
    assert path.stat().st_mtime_ns == stamp


def test_a_new_case_is_queued_and_created(client):
    response = client.post("/cases", json=coarse_case(loads={"surface_load": 1.234e5}))
    assert response.status_code == 202
    body = response.json()
    assert body["created"] is True and body["status"] in ("queued", "running", "done")
    assert response.headers["location"] == f"/cases/{body['id']}"
    assert response.headers["content-type"] == "application/json"
    read = client.get(response.headers["location"]).json()
    assert set(read) == set(body) - {"created", "input_warnings"}  # one schema; what the POST adds aside
    assert {k: body[k] for k in ("id", "spec", "submitted_at")} == {k: read[k] for k in ("id", "spec", "submitted_at")}
    assert finished(client, body["id"])["status"] == "done"


def test_a_new_case_answer_is_the_record_as_stored(tmp_path):
    """``POST /cases`` answers a new case from the values it inserted (no read-back): the
    same record the store then reads, and the same body ``GET /cases/{id}`` serves."""
    from service.schemas import Case
    from service.job_records import JobStore

    store = JobStore(tmp_path / "jobs.sqlite")
    try:
        for i, spec_json in enumerate(('{"a": 1}', '{not json')):  # a damaged spec reads back alike
            record, created = store.add_case(f"{i:016x}", spec_json)
            assert created and record == store.get_case(record.id)
            assert Case.of(record).model_dump_json() == Case.of(store.get_case(record.id)).model_dump_json()
    finally:
        store.close()


def test_solver_failure_is_recorded_as_failed_with_its_error(client):
    bad = coarse_case(solver={"inner": "uzawa", "max_iterations": 1})
    body = finished(client, client.post("/cases", json=bad).json()["id"])
    assert body["status"] == "failed"
    assert "NotConvergedError" in body["error"]
    assert client.get(f"/cases/{body['id']}/result.nc").status_code == 409


def test_list_cases_filters_by_status_and_pages(client, done_case):
    everything = client.get("/cases", params={"limit": 1000}).json()
    assert everything["total"] == len(everything["items"]) >= 1
    done = client.get("/cases", params={"status": "done"}).json()
    assert done["items"] and all(c["status"] == "done" for c in done["items"])
    assert done_case["id"] in {c["id"] for c in done["items"]}
    first = client.get("/cases", params={"limit": 1, "offset": 0}).json()
    second = client.get("/cases", params={"limit": 1, "offset": 1}).json()
    assert len(first["items"]) == 1 and first["total"] == everything["total"]
    if everything["total"] > 1:
        assert first["items"][0]["id"] != second["items"][0]["id"]
    response = client.get("/cases", params={"status": "sleeping"})
    assert response.status_code == 422
    assert response.json()["errors"][0]["field"] == "status"
    assert client.get("/cases", params={"limit": 0}).status_code == 422


def downloaded(response, tmp_path) -> xr.Dataset:
    """The netCDF body of ``response``, loaded."""
    assert response.content.startswith(NETCDF_MAGIC)
    path = tmp_path / "download.nc"
    path.write_bytes(response.content)
    with xr.open_dataset(path, engine="netcdf4") as ds:
        return ds.load()


def test_result_file_of_a_done_case(client, done_case, tmp_path):
    response = client.get(f"/cases/{done_case['id']}/result.nc")
    assert response.status_code == 200
    assert response.headers["content-type"] == "application/x-netcdf"
    with downloaded(response, tmp_path) as ds:
        assert ds.attrs["case_id"] == done_case["id"]
        assert float(ds["max_contact_pressure"]) == pytest.approx(
            done_case["summary"]["max_contact_pressure"])


def test_result_and_plots_of_an_unfinished_case_are_409(client, app):
    case_id = plant(app, coarse_case(loads={"surface_load": 7.77e4}))
    assert client.get(f"/cases/{case_id}").json()["status"] == "queued"
    for url in (f"/cases/{case_id}/result.nc", f"/cases/{case_id}/plots/contact_pressure.png",
                f"/cases/{case_id}/report.pdf", f"/cases/{case_id}/tables.xlsx", f"/cases/{case_id}/forces.csv"):
        response = client.get(url)
        assert response.status_code == 409
        assert "queued" in response.json()["detail"]


@pytest.mark.parametrize("name", sorted(PLOTS))
def test_plots_are_png_rendered_once_and_cached(client, app, done_case, name):
    url = f"/cases/{done_case['id']}/plots/{name}.png"
    response = client.get(url)
    assert response.status_code == 200
    assert response.headers["content-type"] == "image/png"
    assert response.content.startswith(PNG_MAGIC)
    cached = app.state.jobs.root / "plots" / done_case["id"] / f"{name}.png"
    stamp = cached.stat().st_mtime_ns
    assert client.get(url).content == response.content
    assert cached.stat().st_mtime_ns == stamp


def test_unknown_field_did_you_mean_and_implausible_input_warned(client, done_case):
    """Issue 39: a misspelt field is refused naming the closest; an implausible value is accepted with a
    warning (a density of 20 kg/m³ is a unit weight in kN/m³ typed in the wrong field)."""
    response = client.post("/cases", json={"ground": {"densty": 2000.0}})
    assert response.status_code == 422
    assert any(e["field"] == "ground.densty" and e["reason"] == "unknown field; did you mean 'density'?"
               for e in response.json()["errors"])
    again = client.post("/cases", json=COARSE)
    assert again.status_code == 202 and again.json()["input_warnings"] == []
    implausible = coarse_case(ground={"density": 20.0})
    response = client.post("/cases", json=implausible)
    assert response.status_code == 202
    (warning,) = response.json()["input_warnings"]
    assert warning.startswith("ground.density: 20 kg/m³")
    page = client.get(f"/ui/cases/{response.json()['id']}")
    assert "ground.density: 20 kg/m³" in page.text


def test_case_tables_read_back_in_engineering_units(client, app, done_case):
    """forces.csv and tables.xlsx of a finished case: a units row, the stored result's values converted."""
    import csv
    import io

    from openpyxl import load_workbook

    case_id = done_case["id"]
    response = client.get(f"/cases/{case_id}/forces.csv")
    assert response.status_code == 200 and response.headers["content-type"].startswith("text/csv")
    rows = list(csv.reader(io.StringIO(response.text)))
    with as_store(app.state.jobs.root).opened(case_id) as ds:
        thrust, moment = ds.thrust.values, ds.moment.values
    names, units = rows[0], rows[1]
    assert (units[names.index("N")], units[names.index("M")]) == ("kN/m", "kN·m/m")
    np.testing.assert_allclose([float(r[names.index("N")]) for r in rows[2:]], thrust / 1e3, rtol=1e-12)
    response = client.get(f"/cases/{case_id}/tables.xlsx")
    assert response.status_code == 200 and "spreadsheetml" in response.headers["content-type"]
    ws = load_workbook(io.BytesIO(response.content))["forces"]
    assert [c.value for c in ws[2]][:4] == ["°", "m", "kN/m", "kN·m/m"]
    np.testing.assert_allclose([ws.cell(row=r, column=4).value for r in range(3, 3 + thrust.size)],
                               moment / 1e3, rtol=1e-12)
    assert client.get("/cases/0123456789abcdef/forces.csv").status_code == 404


def test_report_is_a_printable_pdf_of_every_figure_rendered_once(client, app, done_case):
    """The report read as a person would: its pages rendered to images, none blank, the first
    stating the verdict the summary gives (pdfium renders, pdfium extracts the text)."""
    import pypdfium2 as pdfium

    url = f"/cases/{done_case['id']}/report.pdf"
    response = client.get(url)
    assert response.status_code == 200 and response.headers["content-type"] == "application/pdf"
    assert response.content.startswith(b"%PDF")
    cached = app.state.jobs.root / "plots" / done_case["id"] / "report.pdf"
    stamp = cached.stat().st_mtime_ns
    assert client.get(url).content == response.content and cached.stat().st_mtime_ns == stamp
    pdf = pdfium.PdfDocument(response.content)
    assert len(pdf) == 4 + len(PLOTS)  # summary, inputs, design basis, lining forces, one page per figure
    for i in range(len(pdf)):
        pixels = np.asarray(pdf[i].render(scale=0.5).to_pil().convert("L"), dtype=float)
        inked = (pixels < 200).mean()
        assert 0.01 < inked < 0.6, f"page {i + 1} looks blank or black ({inked:.1%} inked)"
    first = pdf[0].get_textpage().get_text_range()
    eta = done_case["summary"]["max_utilization"]
    assert ("PASS" if eta <= 1 else "FAIL") in first and f"{eta:.3g}" in first
    assert "max_thrust" in first and "kN/m" in first
    assert "Figure 1. The model" in pdf[1].get_textpage().get_text_range()  # page 2: the whole model
    assert "ground_young" in pdf[2].get_textpage().get_text_range()
    assert "γC = 1.5" in pdf[3].get_textpage().get_text_range()  # the design basis: partial factors
    for i, name in enumerate([n for n in PLOTS if n != "model"], start=5):  # a page per figure, numbered
        assert f"Figure {i - 3}." in pdf[i].get_textpage().get_text_range()
    pdf.close()


@pytest.mark.parametrize("stage", ["1", "2", "total"])
def test_the_deformed_mesh_shows_each_construction_stage_each_cached_apart(client, app, done_case, stage):
    url = f"/cases/{done_case['id']}/plots/deformed_mesh.png?stage={stage}"
    response = client.get(url)
    assert response.status_code == 200 and response.content.startswith(PNG_MAGIC)
    name = "deformed_mesh" if stage == "total" else f"deformed_mesh-stage{stage}"
    assert (app.state.jobs.root / "plots" / done_case["id"] / f"{name}.png").read_bytes() == response.content


def test_a_stage_is_refused_naming_it_where_a_plot_has_none_or_it_is_unknown(client, done_case):
    for url in (f"/cases/{done_case['id']}/plots/contact_pressure.png?stage=1",
                f"/cases/{done_case['id']}/plots/deformed_mesh.png?stage=3"):
        response = client.get(url)
        assert response.status_code == 422
        assert any(e["field"].endswith("stage") for e in response.json()["errors"]), response.json()


def test_unknown_plot_name_is_404(client, done_case):
    assert client.get(f"/cases/{done_case['id']}/plots/stress_field.png").status_code == 404


@pytest.mark.parametrize("url", [
    "/cases/0123456789abcdef", "/cases/0123456789abcdef/result.nc",
    "/cases/0123456789abcdef/plots/contact_pressure.png",
    "/cases/NOTANID", "/cases/0123456789ABCDEF", "/cases/..%2F..%2Fjobs.sqlite/result.nc",
    "/sweeps/0123456789abcdef", "/sweeps/0123456789abcdef/result.nc", "/sweeps/xyz"])
def test_unknown_or_malformed_ids_are_404(client, url):
    response = client.get(url)
    assert response.status_code == 404
    assert response.json()["detail"]


# -- invalid input --------------------------------------------------------------------------

@pytest.mark.parametrize("body, field, words", [
    (coarse_case(geometry={"depth": 1.0}), "geometry.depth", "cover"),
    (coarse_case(ground={"poisson": 0.5}), "ground.poisson", "less than or equal to 0.49"),
    (coarse_case(ground={"young": "soft"}), "ground.young", "number"),
    (coarse_case(lining={"colour": "grey"}), "lining.colour", "unknown field"),
    (coarse_case(solver={"bolt": 200}), "solver.bolt", "outside"),
    (coarse_case(solver={"inner": "magic"}), "solver.inner", "active-set"),
    ({"mesh": {"interface_size": 5.0, "far_size": 1.0}}, "mesh.far_size", "smaller"),
    ({"tunnel": {}}, "tunnel", "unknown field"),
    (coarse_case(lining={"joints": {"count": 6, "offset": 10.0}}), "lining.joints.offset", "unsymmetric"),
    (coarse_case(lining={"joints": {"count": 2}}), "lining.joints.count", "at least 3"),
    (coarse_case(lining={"joints": {"count": 6, "contact_height": 0.5}}), "lining.joints.contact_height",
     "exceeds the lining thickness"),
    (coarse_case(lining={"joints": {"count": 6, "contact_height": -0.1}}), "lining.joints.contact_height",
     "greater than 0"),
    (coarse_case(excavation={"face_distance": 1.5, "deconfinement": 0.3}), "excavation.deconfinement", "not both"),
    (coarse_case(geometry={"section": {"shape": "polycentric", "arcs": [{"radius": 1.0, "angle": 150.0},
                                                                         {"radius": 10.0, "angle": 20.0},
                                                                         {"angle": 10.0}]}}),
     "geometry.section.arcs.2.radius", "cannot close"),
])
def test_invalid_case_is_422_naming_the_field(client, body, field, words):
    response = client.post("/cases", json=body)
    assert response.status_code == 422
    errors = response.json()["errors"]
    assert field in {e["field"] for e in errors}, errors
    assert any(words in e["reason"] for e in errors if e["field"] == field), errors
    assert field in response.json()["detail"]


@pytest.mark.parametrize("content", [b"{not json", b"[1, 2]", b""])
def test_malformed_body_is_422(client, content):
    response = client.post("/cases", content=content, headers={"content-type": "application/json"})
    assert response.status_code == 422
    assert response.json()["errors"][0]["field"] == "body"


def test_oversized_body_is_413_before_parsing(client):
    big = b'{"pad": "' + b"x" * (1 << 20) + b'"}'
    response = client.post("/cases", content=big, headers={"content-type": "application/json"})
    assert response.status_code == 413

    def chunks():  # no Content-Length: the cap is enforced while reading
        for _ in range(20):
            yield b" " * 65536
    response = client.post("/sweeps", content=chunks(), headers={"content-type": "application/json"})
    assert response.status_code == 413


def test_body_just_under_the_cap_is_parsed(client):
    padded = json.dumps(COARSE).encode() + b" " * ((1 << 20) - 100)
    response = client.post("/cases", content=padded, headers={"content-type": "application/json"})
    assert response.status_code == 202


# -- sweeps ---------------------------------------------------------------------------------

SWEEP = {"name": "thickness", "base": COARSE,
         "vary": {"lining.thickness": [0.2, 0.3], "ground.young": [2e7, 5e7]}, "mode": "grid"}


def test_sweep_runs_and_combines(client, tmp_path):
    response = client.post("/sweeps", json=SWEEP)
    assert response.status_code == 202
    body = response.json()
    assert response.headers["location"] == f"/sweeps/{body['id']}"
    assert len(body["case_ids"]) == 4 and body["created"] is True
    assert sum(body["counts"].values()) == 4

    status = wait_until(lambda: (s := client.get(f"/sweeps/{body['id']}").json())["finished"] and s,
                        what="the sweep")
    assert status["counts"] == {"queued": 0, "running": 0, "done": 4, "failed": 0, "cancelled": 0}

    again = client.post("/sweeps", json=SWEEP).json()
    assert (again["id"], again["created"], again["new_cases"]) == (body["id"], False, 0)

    response = client.get(f"/sweeps/{body['id']}/result.nc")
    assert response.status_code == 200
    assert response.headers["x-cases-included"] == "4/4"
    with downloaded(response, tmp_path) as ds:
        assert ds.sizes["case"] == 4
        assert list(ds["case_id"].values) == body["case_ids"]
        assert sorted(set(ds["lining_thickness"].values)) == [0.2, 0.3]
        assert ds["contact_pressure"].dims == ("case", "theta")


def test_sweep_sharing_cases_reuses_them(client):
    first = client.post("/sweeps", json=SWEEP).json()
    other = dict(SWEEP, name="thickness again", vary={"lining.thickness": [0.2, 0.3], "ground.young": [5e7]})
    body = client.post("/sweeps", json=other).json()
    assert body["created"] is True and body["id"] != first["id"]
    assert set(body["case_ids"]) <= set(first["case_ids"]) and body["new_cases"] == 0


def test_sweep_result_is_409_until_a_case_is_done(client, app):
    spec = CaseSpec.model_validate(coarse_case(loads={"surface_load": 9.99e4}))
    app.state.jobs.store.add_sweep("00000000000000ff", "planted", "{}", [(spec.case_id, spec.canonical_json())])
    assert client.get("/sweeps/00000000000000ff").json()["counts"]["queued"] == 1
    assert client.get("/sweeps/00000000000000ff/result.nc").status_code == 409


@pytest.mark.parametrize("sweep, field, words", [
    (dict(SWEEP, vary={"lining.colour": [1, 2]}), "lining.colour", "unknown parameter"),
    (dict(SWEEP, vary={"ground.young": [2e7, -1.0]}), "ground.young", "greater than or equal"),
    (dict(SWEEP, vary={"ground.young": []}), "ground.young", "empty"),
    (dict(SWEEP, mode="zip", vary={"lining.thickness": [0.2, 0.3, 0.4], "ground.young": [2e7, 5e7]}),
     "lining.thickness", "equally long"),
    (dict(SWEEP, base={"geometry": {"depth": 1.0}}), "base.geometry.depth", "cover"),
    (dict(SWEEP, mode="diagonal"), "mode", "grid"),
    ({"base": COARSE, "vary": {}}, "name", "required"),
    (dict(SWEEP, vary={"ground.young": list(range(1, 11)), "loads.surface_load": list(range(1, 11))}),
     "vary", "cap"),
])
def test_invalid_sweep_is_422_naming_the_field(client, sweep, field, words):
    response = client.post("/sweeps", json=sweep)
    assert response.status_code == 422
    errors = response.json()["errors"]
    assert any(e["field"] == field and words in e["reason"] for e in errors), errors


# -- authentication -------------------------------------------------------------------------

def test_token_guards_every_post_but_not_gets(client, app):
    original = app.state.settings
    app.state.settings = original.model_copy(update={"token": "s3cret"})
    try:
        for url, body in (("/cases", COARSE), ("/sweeps", SWEEP)):
            assert client.post(url, json=body).status_code == 401
            wrong = client.post(url, json=body, headers={"Authorization": "Bearer nope"})
            assert wrong.status_code == 401 and wrong.headers["www-authenticate"].startswith("Bearer")
            right = client.post(url, json=body, headers={"Authorization": "Bearer s3cret"})
            assert right.status_code == 202
        assert client.get("/cases").status_code == 200
        assert client.get("/health").status_code == 200
    finally:
        app.state.settings = original


def test_token_reads_protects_every_read_and_page_but_health(tmp_path):
    """Issue 24: with a token set every GET (results, CSV, pages) needed nothing. With
    TUNNEL_CONTACT_TOKEN_READS the token guards them too, as a bearer token or as the
    password of basic authentication (what a browser asks for); /health stays open."""
    import base64

    from fastapi.testclient import TestClient

    from service.app import create_app
    from service.settings import Settings

    settings = Settings(results=tmp_path, local_workers=1, token="s3cret", token_reads=True)
    basic = "Basic " + base64.b64encode(b"anyone:s3cret").decode()
    wrong_basic = "Basic " + base64.b64encode(b"anyone:nope").decode()
    with TestClient(create_app(settings)) as client:
        case = client.post("/cases", json=COARSE, headers={"Authorization": "Bearer s3cret"})
        assert case.status_code == 202
        paths = ["/cases", f"/cases/{case.json()['id']}", "/sweeps", "/", "/ui/submit", "/openapi.json", "/docs"]
        for path in paths:
            refused = client.get(path)
            assert refused.status_code == 401, path
            assert 'Basic realm="tunnel-contact"' in refused.headers["www-authenticate"]
            assert client.get(path, headers={"Authorization": wrong_basic}).status_code == 401
            for authorization in ("Bearer s3cret", basic):
                assert client.get(path, headers={"Authorization": authorization}).status_code == 200, path
        assert client.get("/health").status_code in (200, 503)
        # the dashboard's form posts with the browser's basic credentials too
        assert client.post("/cases", json={**COARSE, "loads": {"surface_load": 3.3e4}},
                           headers={"Authorization": basic}).status_code == 202


# -- recovery -------------------------------------------------------------------------------

def test_reconcile_resubmits_orphans_and_adopts_stored_results(client, app, done_case):
    jobs = app.state.jobs
    orphan = plant(app, coarse_case(loads={"surface_load": 8.88e4}))
    jobs.store.mark_running([orphan])  # left running by a process that died
    assert client.get(f"/cases/{orphan}").json()["status"] == "running"
    client.portal.call(jobs.reconcile)
    assert finished(client, orphan)["status"] == "done"

    # a record that lost its outcome but whose result file exists is done without solving
    jobs.store._write("UPDATE cases SET status = 'running', summary = NULL WHERE id = ?", (done_case["id"],))
    submissions = jobs.store.get_case(done_case["id"]).submissions
    client.portal.call(jobs.reconcile)
    record = jobs.store.get_case(done_case["id"])
    assert record.status == "done" and record.summary["converged"] == 1.0
    assert record.submissions == submissions


@pytest.mark.parametrize("path, what", [("/ui/sweeps/0123456789abcdef", "unknown sweep 0123456789abcdef"),
                                        ("/ui/cases/0123456789abcdef", "unknown case 0123456789abcdef")])
def test_pages_of_unknown_ids_are_404_pages_that_say_so(client, path, what):
    response = client.get(path)
    assert response.status_code == 404
    assert response.headers["content-type"].startswith("text/html") and what in response.text


def test_a_section_that_fails_at_any_load_is_not_shown_as_blank(app, client):
    """max_utilization = inf (the section fails whatever the load level) and bolt_theta = nan
    (a bonded interface has none): null in the JSON summary, named in non_finite, and shown
    as inf / nan on the case page, never as an empty cell."""
    case_id = plant(app, {**COARSE, "loads": {"surface_load": 4.321e4}})
    app.state.jobs.store.finish(case_id, status="done", summary={
        "max_abs_moment": 1.5e5, "max_utilization": math.inf, "bolt_theta": math.nan})
    body = client.get(f"/cases/{case_id}").json()
    assert body["summary"] == {"max_abs_moment": 1.5e5, "max_utilization": None, "bolt_theta": None}
    assert body["non_finite"] == {"max_utilization": "inf", "bolt_theta": "nan"}
    page = client.get(f"/ui/cases/{case_id}").text
    row = page[page.index("<code>max_utilization</code>") - 300:page.index("<code>max_utilization</code>")]
    assert ">inf</td>" in row
    assert ">nan</td>" in page[page.index("<code>bolt_theta</code>") - 300:page.index("<code>bolt_theta</code>")]


def test_docs_and_redoc_load_nothing_from_outside(client):
    import re

    for path in ("/docs", "/redoc"):
        page = client.get(path)
        assert page.status_code == 200
        urls = re.findall(r"""(?:src|href)=["']([^"']+)["']|url: *['"]([^'"]+)['"]""", page.text)
        flat = [u for pair in urls for u in pair if u]
        assert flat and not [u for u in flat if u.startswith(("http:", "https:", "//"))], flat
        for url in flat:
            if url.startswith("/docs-assets/"):
                assert client.get(url).status_code == 200, url


def test_a_sweep_run_from_the_command_line_is_listed_by_the_service(client, app, tmp_path):
    """One world: the CLI writes the sweep's record beside the results; the service (same
    results folder) lists the sweep with its cases done or failed as the CLI left them,
    without solving anything again."""
    from service.cli import main

    root = app.state.jobs.root
    sweep = {"name": "from the command line", "base": COARSE, "mode": "zip",
             "vary": {"solver.max_iterations": [100_000, 2], "solver.inner": ["active-set", "uzawa"],
                      "geometry.thickness": [0.25, 0.35]}}  # cases no other test solved
    (tmp_path / "sweep.json").write_text(json.dumps(sweep))
    assert main(["sweep", str(tmp_path / "sweep.json"), "--results", str(root), "--no-progress"]) == 1  # one fails
    records = list((root / "sweeps" / "records").glob("*.json"))
    sweep_id = next(json.loads(p.read_text())["id"] for p in records
                    if json.loads(p.read_text())["name"] == "from the command line")
    assert client.get(f"/sweeps/{sweep_id}").status_code == 404  # not yet seen

    imported = client.portal.call(app.state.jobs.import_sweep_records)
    assert sweep_id in imported
    listed = client.get("/sweeps", params={"limit": 100}).json()
    assert sweep_id in [s["id"] for s in listed["items"]]
    status = client.get(f"/sweeps/{sweep_id}").json()
    assert status["total"] == 2 and status["counts"]["done"] == 1 and status["counts"]["failed"] == 1
    table = client.get(f"/sweeps/{sweep_id}/table").json()
    failed = next(r for r in table["rows"] if r["status"] == "failed")
    assert "solver.inner='uzawa' did not converge" in failed["error"]
    done = next(r for r in table["rows"] if r["status"] == "done")
    assert app.state.jobs.store.get_case(done["case_id"]).submissions == 0  # read, not solved again
    assert client.portal.call(app.state.jobs.import_sweep_records) == []  # once


def test_cancel_stops_a_running_case_and_frees_its_worker(client, app):
    """A running case is given up on cancel (issue 24: cancel stopped only queued cases, and
    two runaway posts stopped all work): cancelled within seconds, no result, no error
    record, and the worker takes the next case."""
    slow = {"name": "slow", "base": {"mesh": {"interface_size": 0.06, "far_size": 4.0}, "ground": {
        "model": "mohr-coulomb", "cohesion": 2.0e4, "friction_angle": 25.0, "tensile_strength": 1.0e4}},
        "vary": {"loads.surface_load": [1.234e5]}}
    sweep = client.post("/sweeps", json=slow).json()
    case_id = sweep["case_ids"][0]
    wait_until(lambda: client.get(f"/cases/{case_id}").json()["status"] == "running", timeout=60,
               what="the slow case to run")
    import time

    t0 = time.monotonic()
    answer = client.post(f"/sweeps/{sweep['id']}/cancel").json()
    assert answer["cancelled_now"] == [case_id]
    assert client.get(f"/cases/{case_id}").json()["status"] == "cancelled"
    root = app.state.jobs.root
    marker = root / "cancel" / case_id
    wait_until(lambda: not marker.exists(), timeout=30, what="the worker to give the case up")
    given_up = time.monotonic() - t0
    assert given_up < 10, given_up
    record = client.get(f"/cases/{case_id}").json()
    assert record["status"] == "cancelled" and record["summary"] is None
    assert not as_store(root).is_stored(case_id) and as_store(root).read_error(case_id) is None
    # the worker is free: a small case is solved
    assert finished(client, client.post("/cases", json=coarse_case(loads={"surface_load": 4.321e4})).json()["id"])[
        "status"] == "done"


def test_a_search_whose_trials_exceed_the_sweep_cap_is_refused_naming_over(client):
    search = {"name": "big", "parameter": "geometry.thickness", "low": 0.2, "high": 0.5, "tolerance": 0.01,
              "over": {"loads.lateral_ratio": [0.4 + 0.01 * i for i in range(60)]}}
    response = client.post("/searches", json=search)
    assert response.status_code == 422 and response.json()["errors"][0]["field"] == "over"
    assert "60 cases, over this service's cap of 50" in response.json()["detail"]
    assert client.get("/searches").json()["total"] == 0
