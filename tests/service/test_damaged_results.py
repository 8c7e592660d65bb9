"""Stored files found damaged and results taken as they are, on a served store with a real
cluster (issue 38: 5, 6, 9, 11): a case file whose checksum no longer matches beside an index that
cannot vouch for it, cached figures and reports damaged on disk, a zero-byte job database, the
reliability of an output its cases do not define, a sampled sweep run from the command line
that the service takes as the same cases."""
from __future__ import annotations

import json

import pytest
from distributed import Client

from service.app import create_app
from service.job_records import UNREADABLE, JobStore, open_job_records
from service.settings import Settings
from service_helpers import coarse_case, wait_until
from workflows.files import checksum_path, verify
from workflows.result_store import as_store
from workflows.sweep import Sweep, expand_sweep, run_sweep

#: A random sample of bonded coarse cases: a bonded interface has no bolt point (bolt_theta NaN).
BONDED = {"name": "bonded sample", "base": coarse_case(interface={"model": "bonded"}), "mode": "lhs",
          "samples": 40, "seed": 11,
          "vary": {"loads.lateral_ratio": {"distribution": "uniform", "low": 0.5, "high": 1.0},
                   "design.load_factor": {"distribution": "uniform", "low": 1.2, "high": 1.5}}}


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    return create_app(Settings(results=tmp_path_factory.mktemp("results"), local_workers=2, poll_interval=0.1,
                               reconcile_interval=3600))


@pytest.fixture(scope="module")
def bonded(client):
    sweep = client.post("/sweeps", json=BONDED).json()
    wait_until(lambda: client.get(f"/sweeps/{sweep['id']}").json()["finished"], timeout=900,
               what="the bonded sample")  # a bound on waiting, not a speed requirement
    assert client.get(f"/sweeps/{sweep['id']}").json()["counts"]["done"] == 40
    return sweep


def test_reliability_of_an_output_the_cases_do_not_define_is_refused(client, bonded):
    """40 NaN values are no sample of the event: not P = 0."""
    sid = bonded["id"]
    refused = client.get(f"/sweeps/{sid}/reliability", params={"output": "bolt_theta"})
    assert refused.status_code == 422, refused.text
    assert refused.json()["errors"][0]["field"] == "output" and "defined (not NaN) in 0 of the 40" in refused.text
    assert client.get(f"/sweeps/{sid}/reliability.png", params={"output": "bolt_theta"}).status_code == 422
    defined = client.get(f"/sweeps/{sid}/reliability", params={"output": "max_abs_moment", "limit": 1e12}).json()
    assert defined["samples"] == 40 and defined["undefined"] == 0 and defined["probability"] == 0.0


def _damage(root, case_id: str, what: str) -> None:
    """Damage the case file's checksum (the file itself intact, never read by this process yet) or
    the file itself (its middle overwritten, the size kept), and leave an index that can vouch for
    no case."""
    path = as_store(root).case_path(case_id)
    if what == "checksum":
        checksum_path(path).write_text("0" * 32 + "\n")
    else:
        raw = bytearray(path.read_bytes())
        middle = slice(len(raw) // 2, len(raw) // 2 + 256)
        raw[middle] = bytes(b ^ 0xFF for b in raw[middle])  # every byte changed (the file has zero padding)
        path.write_bytes(bytes(raw))
    for template in (root / "index" / "schemas").glob("*.nc"):
        template.write_bytes(b"not netCDF")
    (root / "index" / "results.nc").unlink(missing_ok=True)


@pytest.mark.parametrize("path, victim, what", [("result.nc", 0, "checksum"), ("plots/scalars.png", 1, "file")])
def test_a_damaged_case_file_is_recomputed_and_the_rest_served(client, app, bonded, path, victim, what):
    """A checksum that no longer matches (a file the service has not read since it was written:
    found while the combined file is built) or a file damaged in place: the case is computed
    again, the rest served, no server error."""
    root = app.state.jobs.root
    case_id = bonded["case_ids"][victim]
    path_of = as_store(root).case_path(case_id)
    before = path_of.stat().st_ino
    _damage(root, case_id, what)
    response = client.get(f"/sweeps/{bonded['id']}/{path}")
    assert response.status_code == 200, response.text
    assert response.headers["x-cases-included"] in ("39/40", "40/40")
    wait_until(lambda: client.get(f"/cases/{case_id}").json()["status"] == "done", timeout=300,
               what="the damaged case recomputed")
    assert path_of.stat().st_ino != before  # computed again: a new file
    verify(path_of)  # with its own checksum


def test_cached_figures_and_reports_damaged_on_disk_are_built_again(client, app, bonded):
    store = as_store(app.state.jobs.root)
    case_id = bonded["case_ids"][2]
    figure = client.get(f"/cases/{case_id}/plots/contact_pressure.png").content
    store.plot_path(case_id, "contact_pressure").write_bytes(figure[: len(figure) // 2])
    assert client.get(f"/cases/{case_id}/plots/contact_pressure.png").content == figure
    report = client.get(f"/cases/{case_id}/report.pdf").content
    damaged = bytearray(report)
    damaged[len(report) // 2: len(report) // 2 + 64] = b"\0" * 64  # same size, other bytes
    (store.plot_dir(case_id) / "report.pdf").write_bytes(bytes(damaged))
    again = client.get(f"/cases/{case_id}/report.pdf").content
    assert again != bytes(damaged) and again.startswith(b"%PDF-") and b"%%EOF" in again[-64:]


def test_a_sampled_sweep_run_from_the_command_line_is_the_same_sweep_for_the_service(client, app):
    """Its record keeps ``vary`` in the order given (a sampled expansion takes the dimensions in
    that order): read back, it gives the cases that were solved, and the service imports them done."""
    sweep = {"name": "cli sample", "base": coarse_case(), "mode": "sobol", "samples": 4, "seed": 3,
             "vary": {"loads.lateral_ratio": {"distribution": "uniform", "low": 0.5, "high": 1.0},
                      "design.load_factor": {"distribution": "uniform", "low": 1.2, "high": 1.5}}}
    assert list(sweep["vary"]) != sorted(sweep["vary"])
    root = app.state.jobs.root
    with Client(app.state.jobs.client.scheduler.address, timeout=30) as dask:
        ids = run_sweep(sweep, root, dask)
    sweep_id = Sweep.model_validate(sweep).sweep_id
    record = json.loads((root / "sweeps" / "records" / f"{sweep_id}.json").read_text())
    assert [s.case_id for s in expand_sweep(Sweep.model_validate(record["spec"]))] == record["case_ids"] == ids
    client.portal.call(app.state.jobs.import_sweep_records)
    counts = client.get(f"/sweeps/{sweep_id}").json()["counts"]
    assert counts["done"] == len(ids) == 4 and counts["failed"] == 0


def test_a_failed_record_whose_result_is_stored_becomes_done(client, app, bonded):
    """A case the service quarantined (its record named no case) that was solved elsewhere."""
    case_id = bonded["case_ids"][3]
    store = app.state.jobs.store
    store.repair_spec(case_id, json.dumps({UNREADABLE: "the sweep record does not give this case"}))
    store.finish(case_id, status="failed", error="invalid job record: the sweep record does not give this case")
    client.portal.call(app.state.jobs.reconcile)
    record = client.get(f"/cases/{case_id}").json()
    assert record["status"] == "done" and record["error"] is None and record["summary"]


def test_a_zero_byte_job_database_is_rebuilt_not_taken_as_empty(tmp_path):
    path = tmp_path / "jobs.sqlite"
    store = JobStore(path)
    store.add_case("00000000000000a1", json.dumps(coarse_case()))
    store.close()
    for suffix in ("-wal", "-shm"):
        path.with_name(path.name + suffix).unlink(missing_ok=True)
    path.write_bytes(b"")
    store, problem = open_job_records(path)
    try:
        assert problem is not None and "empty" in problem
        assert list(tmp_path.glob("jobs.sqlite.damaged-*")), list(tmp_path.iterdir())
    finally:
        store.close()
