"""Review fixes, in process on an embedded LocalCluster: a sweep whose cases all failed has
no result (404, not 409 for ever); the comparison table says why a case failed; the
solver's warnings reach the REST record, the case page and the table (also when a record
is settled from a stored file); the first dask connection is not logged as a reconnection;
pages answer in HTML and link to the service by root-relative paths."""
from __future__ import annotations

import asyncio
import csv
import io
import json
import logging
import re
import sqlite3

import numpy as np
import pytest

from service_helpers import COARSE, coarse_case, finished, wait_until
from service.app import create_app
from service.jobs import Dispatcher
from service.settings import Settings
from service.job_records import JobStore
from solver.spec import CaseSpec
from workflows import Sweep, expand_sweep
from workflows.plots import SWEEP_PLOT_NAMES

#: A sweep whose two cases both fail (one Uzawa iteration cannot converge).
FAILING_SWEEP = {"name": "fails", "base": {**COARSE, "solver": {"inner": "uzawa", "max_iterations": 1}},
                 "vary": {"geometry.gap": [0.005, 0.015]}}
#: A surface load far beyond the small-displacement model: solved, with a warning.
HUGE_LOAD = coarse_case(loads={"surface_load": 1e9})


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    settings = Settings(results=tmp_path_factory.mktemp("results"), local_workers=2,
                        max_sweep_cases=50, poll_interval=0.1, reconcile_interval=3600)
    return create_app(settings)


def sweep_finished(client, sweep_id: str) -> dict:
    return wait_until(lambda: (s := client.get(f"/sweeps/{sweep_id}").json())["finished"] and s,
                      what=f"sweep {sweep_id}")


def csv_rows(client, sweep_id: str) -> list[dict]:
    response = client.get(f"/sweeps/{sweep_id}/summary.csv")
    assert response.status_code == 200
    units, *rows = csv.DictReader(io.StringIO(response.text))  # the units row under the header
    assert units["case_id"] == "" and units["max_thrust"] == "kN/m"
    # the workbook holds the same cases, with a units row
    from openpyxl import load_workbook

    book = client.get(f"/sweeps/{sweep_id}/summary.xlsx")
    assert book.status_code == 200 and book.headers["content-type"].startswith("application/vnd.openxml")
    sheet = list(load_workbook(io.BytesIO(book.content)).active.iter_rows(values_only=True))
    assert [r[0] for r in sheet[2:]] == [r["case_id"] for r in rows]
    return rows


# -- 1, 2: a sweep whose cases all failed -------------------------------------------------------

def test_a_sweep_whose_cases_all_failed_has_no_result_and_says_why(client):
    body = client.post("/sweeps", json=FAILING_SWEEP).json()
    sweep_id, case_ids = body["id"], body["case_ids"]
    status = sweep_finished(client, sweep_id)
    assert status["counts"]["failed"] == 2 and status["counts"]["done"] == 0

    for path in [f"/sweeps/{sweep_id}/result.nc", *(f"/sweeps/{sweep_id}/plots/{n}.png" for n in SWEEP_PLOT_NAMES)]:
        response = client.get(path)
        assert response.status_code == 404, path
        detail = response.json()["detail"]
        assert f"sweep {sweep_id} has no result" in detail and "all 2 cases failed" in detail, detail
        assert "retry=failed" in detail

    # the table, its CSV and the sweep page say why each case failed
    errors = {c: client.get(f"/cases/{c}").json()["error"] for c in case_ids}
    assert all("NotConvergedError" in e for e in errors.values())
    table = client.get(f"/sweeps/{sweep_id}/table").json()
    assert [c["name"] for c in table["columns"]][-2:] == ["error", "warnings"]
    assert {r["case_id"]: r["error"] for r in table["rows"]} == errors
    assert {r["case_id"]: r["error"] for r in csv_rows(client, sweep_id)} == errors
    page = client.get(f"/ui/sweeps/{sweep_id}").text
    cells = re.findall(r'<td class="text kind-text col-error" data-value="[^"]*" title="[^"]*">([^<]*)</td>', page)
    assert len(cells) == 2 and all("NotConvergedError" in c for c in cells)


def test_no_result_is_409_while_a_case_is_open_and_404_once_failed_or_cancelled(client, app):
    store = app.state.jobs.store
    cases = [CaseSpec.model_validate(coarse_case(loads={"surface_load": 1.0e4 + i})) for i in range(3)]
    ids = [c.case_id for c in cases]
    record, _ = store.add_sweep("00000000000000fe", "planted", "{}", [(c.case_id, c.canonical_json()) for c in cases])
    store.finish(ids[0], status="failed", error="boom")
    store.mark_cancelled([ids[1]])
    response = client.get(f"/sweeps/{record.id}/result.nc")  # ids[2] is still queued
    assert response.status_code == 409 and "no case is done yet" in response.json()["detail"]
    assert client.get(f"/sweeps/{record.id}/plots/scalars.png").status_code == 409
    store.mark_cancelled([ids[2]])
    for path in (f"/sweeps/{record.id}/result.nc", f"/sweeps/{record.id}/plots/scalars.png"):
        response = client.get(path)
        assert response.status_code == 404
        detail = response.json()["detail"]
        assert "none of its 3 cases is done (1 failed, 2 cancelled)" in detail
        assert "retry=failed recomputes failed cases" in detail and "posting the sweep again resumes" in detail
    assert {r["case_id"]: r["error"] for r in client.get(f"/sweeps/{record.id}/table").json()["rows"]} == \
        {ids[0]: "boom", ids[1]: "", ids[2]: ""}


# -- 3: warnings of a solved case ----------------------------------------------------------------

@pytest.fixture(scope="module")
def warned_case(client) -> dict:
    body = finished(client, client.post("/cases", json=HUGE_LOAD).json()["id"])
    assert body["status"] == "done"
    return body


def test_warnings_of_a_solved_case_reach_the_record_and_the_case_page(client, warned_case):
    assert warned_case["summary"]["crown_settlement"] > 1.0  # metres: far outside small displacements
    assert any("small-displacement" in w for w in warned_case["warnings"]), warned_case["warnings"]
    page = client.get(f"/ui/cases/{warned_case['id']}").text
    block = re.search(r'<div class="warnings" id="case-warnings" role="alert">(.*?)</div>', page, re.S)
    assert block and "small-displacement" in block.group(1)

    ordinary = finished(client, client.post("/cases", json=COARSE).json()["id"])
    assert ordinary["status"] == "done" and ordinary["warnings"] == []
    assert 'id="case-warnings"' not in client.get(f"/ui/cases/{ordinary['id']}").text


def test_the_case_page_shows_the_lining_forces_table(client):
    """SPEC §9.3 / issue 39: the forces table on the case page, as forces.csv (names, units row,
    one row per station), to 3 significant figures, the governing station marked."""
    body = finished(client, client.post("/cases", json=COARSE).json()["id"])
    page = client.get(f"/ui/cases/{body['id']}").text
    table = re.search(r'<table class="forces">.*?</table>', page, re.S).group(0)
    heads = re.findall(r"<th>([^<]*)</th>", table)
    csv_rows = list(csv.reader(io.StringIO(client.get(f"/cases/{body['id']}/forces.csv").text)))
    assert heads == csv_rows[0] + csv_rows[1]  # the names, then the units row
    rows = re.findall(r"<tr[^>]*>((?:<td[^>]*>[^<]*</td>)+)</tr>", table)
    assert len(rows) == len(csv_rows) - 2
    for shown, row in zip(rows[::17], csv_rows[2::17]):
        cells = re.findall(r">([^<]*)</td>", shown)
        assert cells == [f"{float(v):.3g}" for v in row]
    governing = re.search(r'<tr class="governing"[^>]*>(.*?)</tr>', table).group(1)
    eta = float(re.findall(r">([^<]*)</td>", governing)[csv_rows[0].index("utilization")])
    assert eta == pytest.approx(body["summary"]["max_utilization"], rel=5e-3)


def test_the_mesh_check_is_a_table_of_the_case_page(client):
    """solver.mesh_check: each key result's change on the refined mesh, in per cent, on the case
    page (the ones above 1 % marked), not mixed into the summary's results."""
    from solver.results.mesh_check import CHECKED

    coarse = {"mesh": {"interface_size": 0.7, "far_size": 20.0}, "solver": {"mesh_check": True}}
    body = finished(client, client.post("/cases", json=coarse).json()["id"])
    assert body["status"] == "done"
    page = client.get(f"/ui/cases/{body['id']}").text
    table = re.search(r'<table id="mesh-check".*?</table>', page, re.S).group(0)
    rows = dict(re.findall(r'<tr data-name="(\w+)"[^>]*><td[^>]*>[^<]*</td><td>([^<]*)</td></tr>', table))
    assert sorted(rows) == sorted(CHECKED)
    for name, shown in rows.items():
        change = 100.0 * body["summary"][f"mesh_change_{name}"]
        assert shown.startswith(f"{change:+.2f} %") and shown.endswith("⚠") == (abs(change) > 1.0), (name, shown)
    assert any(shown.endswith("⚠") for shown in rows.values())  # coarse enough to show
    summary = re.search(r'id="summary".*?</table>', page, re.S).group(0)
    assert "mesh_change_" not in summary


#: Two surface loads, the second far beyond small displacements (the case of ``warned_case``).
LOADS_SWEEP = {"name": "loads", "base": COARSE, "vary": {"loads.surface_load": [2.0e4, 1e9]}}


def test_the_sweep_table_marks_cases_with_warnings(client, warned_case):
    body = client.post("/sweeps", json=LOADS_SWEEP).json()
    assert warned_case["id"] in body["case_ids"]  # the same case: not recomputed
    sweep_finished(client, body["id"])
    rows = client.get(f"/sweeps/{body['id']}/table").json()["rows"]
    assert rows[0]["warnings"] == "" and "small-displacement" in rows[1]["warnings"]
    assert [r["error"] for r in rows] == ["", ""]
    assert [bool(r["warnings"]) for r in csv_rows(client, body["id"])] == [False, True]
    page = client.get(f"/ui/sweeps/{body['id']}").text
    marked = re.findall(r'<tr data-key="([0-9a-f]{16})" class="has-warnings">', page)
    assert marked == [warned_case["id"]]


def test_summary_csv_is_the_combined_netcdf_in_the_units_of_its_units_row(client, tmp_path):
    """summary.csv against the sweep's netCDF (SI, CF units): each number is the file's value
    converted to the unit the units row names (kPa, kN/m, mm, ...)."""
    import xarray as xr

    from workflows.units import display_unit

    body = client.post("/sweeps", json=LOADS_SWEEP).json()  # solved once in this module
    sweep_finished(client, body["id"])
    text = client.get(f"/sweeps/{body['id']}/summary.csv").text
    header, units, *rows = csv.reader(io.StringIO(text))
    unit = dict(zip(header, units))
    (tmp_path / "sweep.nc").write_bytes(client.get(f"/sweeps/{body['id']}/result.nc").content)
    with xr.open_dataset(tmp_path / "sweep.nc") as ds:
        assert [r[0] for r in rows] == [str(c) for c in ds["case_id"].values]
        assert unit["loads_surface_load"] == "kPa"
        np.testing.assert_allclose([float(r[header.index("loads_surface_load")]) for r in rows],
                                   ds["loads_surface_load"].values * 1e-3, rtol=1e-14)
        checked = 0
        for name in header:
            if name not in ds or ds[name].dims != ("case",) or ds[name].dtype.kind not in "biuf" \
                    or name == "loads_surface_load":
                continue
            shown, factor = display_unit(ds[name].attrs.get("units", ""), name)
            assert unit[name] == shown, name
            values = [float(r[header.index(name)]) for r in rows]
            np.testing.assert_allclose(values, ds[name].values.astype(float) * factor, rtol=1e-14, err_msg=name)
            checked += 1
    assert checked >= 20
    assert {unit[n] for n in ("max_contact_pressure", "max_thrust", "max_abs_moment", "crown_settlement",
                              "contact_extent", "ground_loss")} == {"kPa", "kN/m", "kN·m/m", "mm", "°", "%"}


def test_warnings_are_read_from_the_stored_file_at_reconciliation(client, app, warned_case):
    jobs = app.state.jobs
    # a record that lost its outcome (the process died before writing it) but whose file is stored
    jobs.store._write("UPDATE cases SET status = 'running', summary = NULL, warnings = NULL WHERE id = ?",
                      (warned_case["id"],))
    assert client.get(f"/cases/{warned_case['id']}").json()["warnings"] == []
    submissions = jobs.store.get_case(warned_case["id"]).submissions
    client.portal.call(jobs.reconcile)
    body = client.get(f"/cases/{warned_case['id']}").json()
    assert body["status"] == "done" and body["warnings"] == warned_case["warnings"]
    assert jobs.store.get_case(warned_case["id"]).submissions == submissions  # not solved again


def test_a_database_without_the_warnings_column_is_migrated(tmp_path):
    path = tmp_path / "jobs.sqlite"
    db = sqlite3.connect(path)
    db.executescript("""
        CREATE TABLE cases (id TEXT PRIMARY KEY, spec TEXT NOT NULL,
            status TEXT NOT NULL CHECK (status IN ('queued', 'running', 'done', 'failed', 'cancelled')),
            summary TEXT, error TEXT, submitted_at REAL NOT NULL, started_at REAL, finished_at REAL,
            submissions INTEGER NOT NULL DEFAULT 0);
        INSERT INTO cases (id, spec, status, summary, submitted_at)
            VALUES ('aaaaaaaaaaaaaaaa', '{}', 'done', '{"converged": 1.0}', 1.0);
        INSERT INTO cases (id, spec, status, submitted_at) VALUES ('cccccccccccccccc', '{}', 'queued', 2.0);""")
    db.commit()
    db.close()
    store = JobStore(path)
    old = store.get_case("aaaaaaaaaaaaaaaa")
    assert (old.status, old.summary, old.warnings) == ("done", {"converged": 1.0}, ())
    store.finish("cccccccccccccccc", status="done", summary={}, warnings=["too far"])
    store.close()
    store = JobStore(path)  # opened again: nothing left to migrate
    assert store.get_case("cccccccccccccccc").warnings == ("too far",)
    assert store.requeue(["cccccccccccccccc"], statuses=("done",)) == ["cccccccccccccccc"]
    assert store.get_case("cccccccccccccccc").warnings == ()
    store.close()


# -- 4: the first connection is not a reconnection --------------------------------------------

class _FakeClient:
    def __init__(self, status: str = "running"):
        self.status = status

    async def close(self) -> None:
        self.status = "closed"


def test_first_connection_is_logged_at_info_and_a_reconnection_as_a_warning(tmp_path, caplog):
    async def connect():
        return _FakeClient()

    async def run():
        jobs = Dispatcher(connect, JobStore(tmp_path / "jobs.sqlite"), tmp_path, reconcile_interval=3600)
        await jobs.start()
        first = list(caplog.records)
        jobs.client.status = "closed"  # the scheduler went away
        caplog.clear()
        await jobs.reconcile()
        again = list(caplog.records)
        await jobs.stop()
        jobs.store.close()
        return first, again

    with caplog.at_level(logging.INFO, logger="service.jobs"):
        first, again = asyncio.run(run())
    assert not [r for r in first if r.levelno >= logging.WARNING], [r.getMessage() for r in first]
    assert any(r.levelno == logging.INFO and "connecting" in r.getMessage() for r in first)
    assert [r.getMessage() for r in again if r.levelno == logging.WARNING] == ["dask client is closed; connecting again"]


def test_a_clean_service_start_logs_no_reconnection(tmp_path, caplog):
    from fastapi.testclient import TestClient

    with caplog.at_level(logging.INFO, logger="service.jobs"):
        with TestClient(create_app(Settings(results=tmp_path, local_workers=1, reconcile_interval=3600))) as c:
            assert c.get("/health").status_code == 200
    assert not [r.getMessage() for r in caplog.records if r.name == "service.jobs" and r.levelno >= logging.WARNING]


# -- 5: pages -------------------------------------------------------------------------------

@pytest.mark.parametrize("path", ["/ui/sweeps/nope", "/ui/sweeps/0123456789ABCDEF", "/ui/cases/nope",
                                  "/ui/sweeps/0123456789abcdef", "/ui/no-such-page"])
def test_unknown_pages_are_html_404_pages(client, path):
    response = client.get(path, headers={"accept": "text/html"})
    assert response.status_code == 404
    assert response.headers["content-type"].startswith("text/html")
    assert 'id="error-detail"' in response.text


def test_no_page_links_to_the_service_by_an_absolute_url(client, warned_case):
    sweep_id = client.post("/sweeps", json=FAILING_SWEEP).json()["id"]
    own = str(client.base_url).rstrip("/")
    for path in ("/", "/ui/submit", f"/ui/sweeps/{sweep_id}", f"/ui/cases/{warned_case['id']}", "/ui/sweeps/nope"):
        page = client.get(path).text
        links = re.findall(r'(?:href|src)="([^"]*)"', page)
        assert '/static/dashboard.css' in links and '/static/dashboard.js' in links, path
        assert not [link for link in links if link.startswith(own) or link.startswith("//")], path
        assert own not in page, path
        for link in ("/static/dashboard.css", "/static/dashboard.js"):
            assert client.get(link).status_code == 200


def test_the_example_sweep_of_the_submit_page_has_a_domain_as_wide_as_the_default(client):
    page = client.get("/ui/submit").text
    examples = json.loads(re.search(r'<script type="application/json" id="examples">(.*?)</script>', page, re.S).group(1))
    default = CaseSpec().geometry
    specs = expand_sweep(Sweep.model_validate(json.loads(examples["sweep"])))
    assert len(specs) == 4
    for spec in specs:
        g = spec.geometry
        assert g.width >= default.width and g.height >= default.height
        assert g.width / g.outer_radius >= default.width / default.outer_radius
