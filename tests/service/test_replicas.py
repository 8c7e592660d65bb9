"""The multi-machine deployment on loopback (SPEC §9.7), every part a real server: PostgreSQL
from ``initdb``, an S3-compatible server (moto), a ``dask scheduler`` with two ``dask worker``
processes writing to the bucket directly, and two API replicas (``tunnel-contact serve``) on
the one database and the one bucket, each with a cache folder of its own (as on two machines).

A 60-case sweep and a FORM reliability study go to the first replica, which is SIGKILLed midway; the
second finishes the sweep and takes the study over (its lease expired) to the answer.
"""
from __future__ import annotations

import io
import signal
import uuid

import boto3
import httpx
import numpy as np
import pyarrow.parquet as pq
import pytest
import sqlalchemy as sa
import xarray as xr
from service_helpers import STUDY_MESH, coarse_case, wait_until

from bench.exact_limit_state import ExactLimitState

from service.database import engine_url
from service.process import api_command, free_port, running_cluster, start, stop, wait_healthy
from workflows.result_store import OPEN_OPTIONS, ResultStore
from workflows.sweep import Sweep, expand_sweep

CASES = 60
SWEEP = {"name": "replicas", "base": coarse_case(), "mode": "grid",
         "vary": {"ground.young": [1.5e7 + 1e6 * i for i in range(CASES)]}}
TTL = 3.0
#: A FORM study whose exact reliability index is 2 (bench.exact_limit_state), its cases coarse.
STUDY = {**ExactLimitState(mesh=STUDY_MESH).study(2.0, "form", 40, seed=4), "name": "replicas"}
#: What two solves of one case need not share: their time and the round-off left in the KKT conditions.
DIAGNOSTICS = {"solve_seconds", "kkt_residual"}


@pytest.mark.slow
def test_a_replica_killed_midway_leaves_its_sweep_to_the_other(database_url, s3, tmp_path):
    bucket = f"replicas-{uuid.uuid4().hex[:8]}"
    url = f"s3://{bucket}/results"
    s3_client = boto3.client("s3", endpoint_url=s3["AWS_ENDPOINT_URL"], aws_access_key_id="test",
                             aws_secret_access_key="test", region_name="us-east-1")
    s3_client.create_bucket(Bucket=bucket)
    # every version of every object kept: "written once" is then countable
    s3_client.put_bucket_versioning(Bucket=bucket, VersioningConfiguration={"Status": "Enabled"})
    common = {**s3, "TUNNEL_CONTACT_DATABASE": database_url, "TUNNEL_CONTACT_REPLICA_TTL": str(TTL),
              "TUNNEL_CONTACT_RECONCILE_INTERVAL": "1"}
    with running_cluster(2, logs=tmp_path, env={**common, "TUNNEL_CONTACT_CACHE": str(tmp_path / "workers")}) \
            as scheduler:
        first = replica("a", url, scheduler, common, tmp_path)
        second = replica("b", url, scheduler, common, tmp_path)
        try:
            a, b = (wait_for(p) for p in (first, second))
            posted = httpx.post(f"{a}/sweeps", json=SWEEP, timeout=60)
            assert posted.status_code == 202, posted.text
            sweep_id = posted.json()["id"]
            # a study whose cases queue behind the sweep's: still running when the first replica dies
            study = httpx.post(f"{a}/reliability", json=STUDY, timeout=60)
            assert study.status_code == 202, study.text
            study_id = study.json()["id"]
            seen = httpx.get(f"{b}/reliability/{study_id}", timeout=30)  # its record is the bucket's
            assert seen.status_code == 200 and seen.json()["status"] == "running", seen.text
            wait_until(lambda: counts(b, sweep_id)["done"] >= 8, timeout=180, interval=0.2,
                       what="some cases done")
            stop(first[0], sig=signal.SIGKILL)  # midway: the rest is the second replica's
            left = counts(b, sweep_id)
            assert left["queued"] + left["running"] > 0, f"the sweep finished before the kill: {left}"
            orphan = httpx.get(f"{b}/reliability/{study_id}", timeout=30).json()  # only the second can end it now
            assert orphan["status"] == "running", f"the study ended before the kill: {orphan}"
            wait_until(lambda: counts(b, sweep_id)["done"] == CASES, timeout=300, interval=0.5,
                       what="the second replica to finish the sweep")
            done = wait_until(lambda: (lambda r: r if r["status"] != "running" else None)(
                httpx.get(f"{b}/reliability/{study_id}", timeout=30).json()), timeout=300, interval=0.5,
                what="the second replica to take the study over and finish it")
            assert done["status"] == "done" and done["calls"] <= 40, done
            assert done["beta"] == pytest.approx(2.0, abs=0.02), done
            check_done_exactly_once(s3_client, bucket, database_url, sweep_id, done["case_ids"])
            check_combined_and_table(b, sweep_id, tmp_path)
            check_equal_to_a_local_run(b, tmp_path)
            check_a_damaged_object_is_not_served(b, s3_client, bucket)
        finally:
            for process, _ in (first, second):
                stop(process)


def replica(name: str, url: str, scheduler: str, env: dict, tmp_path):
    port = free_port()
    process = start(api_command(port=port, results=url, scheduler=scheduler), log=tmp_path / f"api-{name}.log",
                    env={**env, "TUNNEL_CONTACT_CACHE": str(tmp_path / f"cache-{name}")})
    return process, f"http://127.0.0.1:{port}"


def wait_for(replica) -> str:
    process, base = replica
    wait_healthy(base, timeout=120, workers=2, process=process)
    return base


def counts(base: str, sweep_id: str) -> dict:
    return httpx.get(f"{base}/sweeps/{sweep_id}", timeout=30).json()["counts"]


def case_ids() -> list[str]:
    return [s.case_id for s in expand_sweep(Sweep.model_validate(SWEEP))]


def check_done_exactly_once(s3_client, bucket: str, database_url: str, sweep_id: str, study_cases) -> None:
    """One object per case of the sweep and of the study, written once (one version); one record
    per case, none twice."""
    versions: dict[str, int] = {}
    for page in s3_client.get_paginator("list_object_versions").paginate(Bucket=bucket, Prefix="results/cases/"):
        for v in page.get("Versions", []):
            versions[v["Key"]] = versions.get(v["Key"], 0) + 1
    results = {k.rsplit("/", 1)[1][:16]: n for k, n in versions.items() if k.endswith(".nc")}
    every = set(case_ids()) | set(study_cases)
    assert sorted(results) == sorted(every)
    assert set(results.values()) == {1}, {c: n for c, n in results.items() if n != 1}
    engine = sa.create_engine(engine_url(database_url))
    with engine.connect() as db:
        rows = db.execute(sa.text("SELECT id, status, submissions FROM cases")).all()
        members = db.execute(sa.text("SELECT count(*) FROM sweep_cases WHERE sweep_id = :s"), {"s": sweep_id}).scalar()
    engine.dispose()
    assert len(rows) == len(every) and {r.status for r in rows} == {"done"} and members == CASES


def opened(content: bytes, path):
    path.write_bytes(content)
    return xr.open_dataset(path, **OPEN_OPTIONS)


def check_combined_and_table(base: str, sweep_id: str, tmp_path) -> None:
    combined = httpx.get(f"{base}/sweeps/{sweep_id}/result.nc", timeout=120)
    assert combined.status_code == 200 and combined.headers["X-Cases-Included"] == f"{CASES}/{CASES}"
    with opened(combined.content, tmp_path / "combined.nc") as ds:
        assert sorted(ds["case_id"].values.tolist()) == sorted(case_ids())
    table = httpx.get(f"{base}/sweeps/{sweep_id}/table.parquet", timeout=60)
    assert table.status_code == 200
    rows = pq.read_table(io.BytesIO(table.content)).to_pylist()
    assert [r["case_id"] for r in rows] == case_ids()
    assert all(r["status"] == "done" and r["max_contact_pressure"] > 0 and r["name"] == "replicas" for r in rows)


def check_equal_to_a_local_run(base: str, tmp_path) -> None:
    spec = expand_sweep(Sweep.model_validate(SWEEP))[17]
    local = ResultStore(tmp_path / "local")
    local.run_and_store(spec)
    served = httpx.get(f"{base}/cases/{spec.case_id}/result.nc", timeout=60)
    assert served.status_code == 200
    with opened(served.content, tmp_path / "served.nc") as ds:
        served_ds, local_ds = ds.load(), local.open_case(spec.case_id)
    assert set(served_ds.variables) == set(local_ds.variables) and served_ds.attrs["case_spec"] == spec.canonical_json()
    # the same to round-off (another process; a closed gap is zero to 1e-17 either way)
    for name, expected in local_ds.variables.items():
        if name in DIAGNOSTICS:
            continue
        if expected.dtype.kind not in "fc":
            assert np.array_equal(served_ds[name].values, expected.values), name
            continue
        scale = float(np.nanmax(np.abs(expected.values))) if expected.size else 0.0
        np.testing.assert_allclose(served_ds[name].values, expected.values, rtol=1e-8, atol=max(1e-10 * scale, 1e-12),
                                   err_msg=name)


def check_a_damaged_object_is_not_served(base: str, s3_client, bucket: str) -> None:
    case_id = case_ids()[3]
    key = f"results/cases/{case_id}.nc"
    assert httpx.get(f"{base}/cases/{case_id}/result.nc", timeout=60).status_code == 200  # cached, verified
    data = bytearray(s3_client.get_object(Bucket=bucket, Key=key)["Body"].read())
    data[len(data) // 2] ^= 0xFF
    s3_client.put_object(Bucket=bucket, Key=key, Body=bytes(data))
    damaged = httpx.get(f"{base}/cases/{case_id}/result.nc", timeout=60)
    # never the damaged bytes: this request finds the damage ("being recomputed"), or the reconciler's
    # read-back (every second here) found it first and the case is already back in the queue
    assert damaged.status_code == 409, damaged.text
    assert "recomputed" in damaged.text or "not ready: queued" in damaged.text \
        or "not ready: running" in damaged.text, damaged.text
    wait_until(lambda: httpx.get(f"{base}/cases/{case_id}", timeout=30).json()["status"] == "done", timeout=120,
               what="the damaged case recomputed")
    again = httpx.get(f"{base}/cases/{case_id}/result.nc", timeout=60)
    assert again.status_code == 200 and bytes(again.content) != bytes(data)
