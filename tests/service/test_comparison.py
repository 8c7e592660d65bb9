"""The comparison table of a sweep (JSON and CSV) and the job records behind cancel, in process."""
from __future__ import annotations

import csv
import io
import json
import math
import sqlite3

import pytest

from service.comparison import SCALAR_ORDER, comparison_table, table_csv
from service.job_records import JobStore
from solver.spec import CaseSpec


def specs(*youngs: float) -> list[tuple[str, str]]:
    cases = [CaseSpec.model_validate({"ground": {"young": e}, "geometry": {"thickness": 0.3}}) for e in youngs]
    return [(c.case_id, c.canonical_json()) for c in cases]


def test_table_has_case_status_varied_parameters_then_scalars_and_csv_reads_back(tmp_path):
    store = JobStore(tmp_path / "jobs.sqlite")
    cases = specs(2e7, 5e7, 8e7)
    record, _ = store.add_sweep("0123456789abcdef", "t", "{}", cases)
    store.finish(cases[0][0], status="done", summary={"max_contact_pressure": 2.5e5, "max_utilization": math.inf,
                                                      "extra_scalar": 1.0})
    store.finish(cases[1][0], status="failed", error="boom")

    table = comparison_table(store, record)
    names = [c.name for c in table.columns]
    assert names[:3] == ["case_id", "status", "ground_young"]  # thickness is the same in all: not shown
    assert names[-2:] == ["error", "warnings"]
    scalars = names[3:-2]
    assert scalars[-1] == "extra_scalar"
    assert [s for s in scalars if s in SCALAR_ORDER] == [s for s in SCALAR_ORDER if s in scalars]
    # non-finite values survive JSON, as the text float() reads back
    assert json.loads(table.model_dump_json())["rows"][0]["max_utilization"] == "inf"

    units, *rows = csv.DictReader(io.StringIO(table_csv(table)))  # a units row under the header
    assert [r["case_id"] for r in rows] == [c for c, _ in cases]
    assert [r["status"] for r in rows] == ["done", "failed", "queued"]
    assert units["ground_young"] == "MPa" and units["max_contact_pressure"] == "kPa"
    assert [float(r["ground_young"]) for r in rows] == [20.0, 50.0, 80.0]
    assert float(rows[0]["max_contact_pressure"]) == 250.0
    assert float(rows[0]["max_utilization"]) == math.inf
    assert rows[1]["max_contact_pressure"] == rows[2]["max_contact_pressure"] == ""
    assert [r["error"] for r in rows] == ["", "boom", ""]


def test_cancel_takes_only_queued_cases_and_requeue_brings_them_back(tmp_path):
    store = JobStore(tmp_path / "jobs.sqlite")
    cases = specs(2e7, 5e7, 8e7)
    record, _ = store.add_sweep("0123456789abcdef", "t", "{}", cases)
    ids = [c for c, _ in cases]
    store.mark_running([ids[0]])
    store.finish(ids[1], status="done", summary={})
    assert store.mark_cancelled(ids) == [ids[2]]
    assert store.status_counts(ids) == {"queued": 0, "running": 1, "done": 1, "failed": 0, "cancelled": 1}
    assert store.open_case_ids() == [ids[0]]  # reconciliation leaves a cancelled case alone
    assert store.requeue(ids) == [ids[2]]
    assert store.get_case(ids[2]).status == "queued"


def test_a_database_from_before_cancel_is_migrated(tmp_path):
    path = tmp_path / "jobs.sqlite"
    db = sqlite3.connect(path)
    db.executescript("""
        CREATE TABLE cases (id TEXT PRIMARY KEY, spec TEXT NOT NULL,
            status TEXT NOT NULL CHECK (status IN ('queued', 'running', 'done', 'failed')),
            summary TEXT, error TEXT, submitted_at REAL NOT NULL, started_at REAL, finished_at REAL,
            submissions INTEGER NOT NULL DEFAULT 0);
        CREATE TABLE sweeps (id TEXT PRIMARY KEY, name TEXT NOT NULL, spec TEXT NOT NULL, submitted_at REAL NOT NULL);
        CREATE TABLE sweep_cases (sweep_id TEXT NOT NULL REFERENCES sweeps (id), position INTEGER NOT NULL,
            case_id TEXT NOT NULL REFERENCES cases (id), PRIMARY KEY (sweep_id, position));
        INSERT INTO cases (id, spec, status, submitted_at) VALUES ('aaaaaaaaaaaaaaaa', '{}', 'queued', 1.0);
        INSERT INTO sweeps VALUES ('bbbbbbbbbbbbbbbb', 'old', '{}', 1.0);
        INSERT INTO sweep_cases VALUES ('bbbbbbbbbbbbbbbb', 0, 'aaaaaaaaaaaaaaaa');""")
    db.commit()
    db.close()
    store = JobStore(path)
    assert store.get_sweep("bbbbbbbbbbbbbbbb").case_ids == ("aaaaaaaaaaaaaaaa",)
    assert store.mark_cancelled(["aaaaaaaaaaaaaaaa"]) == ["aaaaaaaaaaaaaaaa"]
    assert store._db.execute("PRAGMA foreign_key_check").fetchall() == []
    store.close()
    assert JobStore(path).get_case("aaaaaaaaaaaaaaaa").status == "cancelled"


def test_pages_render_without_a_scheduler_and_unknown_ids_are_html_404(tmp_path):
    from fastapi.testclient import TestClient

    from service.app import create_app
    from service.settings import Settings

    # no cluster needed for a 404: the scheduler address points nowhere and the app starts degraded
    app = create_app(Settings(results=tmp_path, scheduler="tcp://127.0.0.1:9", reconcile_interval=3600))
    with TestClient(app) as client:
        for path in ("/ui/sweeps/0123456789abcdef", "/ui/cases/0123456789abcdef"):
            response = client.get(path)
            assert response.status_code == 404 and response.headers["content-type"].startswith("text/html")
            assert "unknown" in response.text and "0123456789abcdef" in response.text
        assert client.get("/").status_code == 200
        assert "Submit" in client.get("/ui/submit").text


def test_the_contract_order_names_every_scalar_the_solver_writes():
    from service.comparison import SCALAR_ORDER
    from solver.results.variables import SCALARS

    assert sorted(SCALAR_ORDER) == sorted(SCALARS)


def test_a_page_of_sweeps_and_their_counts_match_the_sweeps_one_by_one(tmp_path):
    """list_sweeps and sweep_status_counts (a few queries for a page) against get_sweep and
    status_counts per sweep, with sweeps sharing cases and a page boundary."""
    store = JobStore(tmp_path / "jobs.sqlite")
    a, b, c = specs(2e7, 5e7, 8e7), specs(5e7, 9e7), specs(1e8)
    for i, cases in enumerate((a, b, c)):
        store.add_sweep(f"{i:016x}", f"s{i}", "{}", cases)
    store.finish(a[1][0], status="done", summary={})  # also b's first case
    store.finish(a[2][0], status="failed", error="boom")
    for limit, offset in ((20, 0), (2, 0), (2, 2), (5, 3)):
        page, total = store.list_sweeps(limit=limit, offset=offset)
        assert total == 3
        counts = store.sweep_status_counts([r.id for r in page])
        for record in page:
            assert record == store.get_sweep(record.id)
            assert counts[record.id] == store.status_counts(record.case_ids)
    assert store.sweep_status_counts([f"{1:016x}"])[f"{1:016x}"] == {"queued": 1, "running": 0, "done": 1,
                                                                      "failed": 0, "cancelled": 0}


def test_summary_xlsx_opens_in_openpyxl_with_a_units_row(tmp_path):
    from openpyxl import load_workbook

    from service.comparison import table_xlsx

    store = JobStore(tmp_path / "jobs.sqlite")
    cases = specs(2e7, 5e7)
    record, _ = store.add_sweep("0123456789abcdef", "t", "{}", cases)
    store.finish(cases[0][0], status="done", summary={"max_contact_pressure": 2.5e5, "max_thrust": 6.24e5,
                                                      "max_utilization": math.inf})
    table = comparison_table(store, record)
    wb = load_workbook(io.BytesIO(table_xlsx(table)))
    ws = wb.active
    rows = list(ws.iter_rows(values_only=True))
    names, units = rows[0], rows[1]
    col = {n: i for i, n in enumerate(names)}
    assert names[:3] == ("case_id", "status", "ground_young")
    assert units[col["max_contact_pressure"]] == "kPa" and units[col["max_thrust"]] == "kN/m"
    assert units[col["ground_young"]] == "MPa"  # an input's engineering unit, as on the page and the form
    first = rows[2]
    assert first[col["case_id"]] == cases[0][0] and first[col["status"]] == "done"
    assert first[col["max_contact_pressure"]] == 250.0 and first[col["max_thrust"]] == 624.0
    assert first[col["ground_young"]] == 20.0  # MPa
    assert first[col["max_utilization"]] == "inf"  # no infinity in a spreadsheet cell: text
    assert rows[3][col["max_thrust"]] is None  # the second case is not done
    assert ws.freeze_panes == "A3"


def test_the_study_table_as_parquet_reads_back_with_types_and_units(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    from service.comparison import table_parquet

    store = JobStore(tmp_path / "jobs.sqlite")
    cases = specs(2e7, 5e7, 8e7)
    record, _ = store.add_sweep("0123456789abcdef", "soft grounds", "{}", cases)
    store.finish(cases[0][0], status="done", summary={"max_contact_pressure": 2.5e5, "max_utilization": math.inf})
    store.finish(cases[1][0], status="failed", error="boom")
    read = pq.read_table(io.BytesIO(table_parquet(comparison_table(store, record), record.name)))
    assert read.column_names[:4] == ["case_id", "status", "name", "ground_young"]
    assert read.schema.field("max_contact_pressure").type == pa.float64()
    assert read.schema.field("max_contact_pressure").metadata[b"units"] == b"Pa"
    assert read.schema.metadata[b"sweep_id"] == b"0123456789abcdef"
    rows = read.to_pylist()
    assert [r["case_id"] for r in rows] == [c for c, _ in cases] and {r["name"] for r in rows} == {"soft grounds"}
    assert [r["ground_young"] for r in rows] == [2e7, 5e7, 8e7]
    assert rows[0]["max_contact_pressure"] == 2.5e5 and rows[0]["max_utilization"] == math.inf
    assert rows[1]["max_contact_pressure"] is None and rows[1]["error"] == "boom"


def test_summary_csv_has_the_workbooks_units_row_and_values_converted_at_full_precision(tmp_path):
    from openpyxl import load_workbook

    from service.comparison import table_xlsx

    store = JobStore(tmp_path / "jobs.sqlite")
    cases = [CaseSpec.model_validate({"geometry": {"gap": gap, "thickness": 0.3}, "loads": {"lateral_ratio": k}})
             for gap, k in ((0.007, 0.5), (0.013, 0.7))]
    record, _ = store.add_sweep("0123456789abcdef", "t", "{}", [(c.case_id, c.canonical_json()) for c in cases])
    summary = {"max_contact_pressure": 123456.789, "max_thrust": 6.2412345e5, "max_abs_moment": 4.5e4,
               "crown_settlement": -0.0123456789, "contact_extent": 171.5, "ground_loss": 0.00731,
               "max_utilization": 0.8123456789, "max_plastic_extent": 1.25, "max_surface_settlement": math.nan}
    store.finish(cases[0].case_id, status="done", summary=summary)
    table = comparison_table(store, record)
    header, units, *rows = csv.reader(io.StringIO(table_csv(table)))
    book = list(load_workbook(io.BytesIO(table_xlsx(table))).active.iter_rows(values_only=True))
    assert header == list(book[0]) and units == [u or "" for u in book[1]]  # the workbook's units
    unit = dict(zip(header, units))
    assert unit["case_id"] == unit["status"] == unit["error"] == unit["warnings"] == ""
    assert [unit[n] for n in ("geometry_gap", "loads_lateral_ratio", "max_contact_pressure", "max_thrust",
                              "max_abs_moment", "crown_settlement", "contact_extent", "ground_loss",
                              "max_plastic_extent")] == ["mm", "1", "kPa", "kN/m", "kN·m/m", "mm", "°", "%", "m"]
    done, queued = (dict(zip(header, r)) for r in rows)
    factors = {"max_contact_pressure": 1e-3, "max_thrust": 1e-3, "max_abs_moment": 1e-3, "crown_settlement": 1e3,
               "contact_extent": 1.0, "ground_loss": 100.0, "max_utilization": 1.0, "max_plastic_extent": 1.0}
    for name, factor in factors.items():
        assert float(done[name]) == pytest.approx(summary[name] * factor, rel=1e-14), name
    assert done["max_utilization"] == repr(summary["max_utilization"])  # unconverted: every digit
    assert done["max_contact_pressure"] == "123.456789" and done["crown_settlement"] == "-12.3456789"
    assert done["max_surface_settlement"] == "nan" and queued["max_thrust"] == ""
    assert [float(done["geometry_gap"]), float(queued["geometry_gap"])] == [7.0, 13.0]  # mm, not 7.000000000000001
    assert [float(r[header.index("loads_lateral_ratio")]) for r in rows] == [0.5, 0.7]
