"""The result store on object storage (``s3://bucket/prefix``) against real S3-compatible servers
(moto's server mode and SeaweedFS on loopback: the ``s3`` and ``seaweedfs`` fixtures): one object
per file, written whole, read back only when it matches its checksum, the index answering
``open_results`` for a process that computed none of the cases, identical to a local store."""
from __future__ import annotations

import uuid

import pytest
import xarray as xr

from solver.spec import CaseSpec
from workflows.files import DamagedFile
from workflows.result_store import ResultStore, open_results

COARSE = {"mesh": {"interface_size": 0.25, "far_size": 8.0}}
#: What differs between two solves of one case: how long they took.
TIMES = ["solve_seconds"]
SPECS = [CaseSpec.model_validate({**COARSE, "ground": {"young": e}}) for e in (2e7, 4e7, 8e7)]


@pytest.fixture(params=["s3", "seaweedfs"])
def bucket(request, monkeypatch, tmp_path):
    """A new bucket on the server (moto's emulator, SeaweedFS); the environment set for it. Yields
    its URL."""
    for name, value in request.getfixturevalue(request.param).items():
        monkeypatch.setenv(name, value)
    monkeypatch.delenv("TUNNEL_CONTACT_STORAGE_OPTIONS", raising=False)
    url = f"s3://b{uuid.uuid4().hex[:12]}/studies/one"
    store_in(url, tmp_path / "setup", monkeypatch).remote.make_bucket()
    return url


def store_in(url: str, cache, monkeypatch) -> ResultStore:
    """The store at ``url`` as a process with the cache folder ``cache`` sees it (another machine)."""
    monkeypatch.setenv("TUNNEL_CONTACT_CACHE", str(cache))
    store = ResultStore(url)
    monkeypatch.delenv("TUNNEL_CONTACT_CACHE")
    return store


def test_cases_stored_by_one_process_are_read_by_another_as_from_a_local_folder(bucket, monkeypatch, tmp_path):
    writer = store_in(bucket, tmp_path / "worker", monkeypatch)
    local = ResultStore(tmp_path / "local")
    for spec in SPECS:
        writer.run_and_store(spec)
        local.run_and_store(spec)
    ids = sorted(s.case_id for s in SPECS)
    names = set(writer.remote.listing(writer.cases_dir))
    assert names == {f"{c}.nc" for c in ids} | {f"{c}.nc.b2" for c in ids}  # one object per file
    assert str(writer) == bucket and writer.root == tmp_path / "worker"

    reader = store_in(bucket, tmp_path / "api", monkeypatch)  # nothing cached here
    assert reader.case_ids() == ids and reader.is_stored(ids[0])
    xr.testing.assert_identical(reader.open_results().drop_vars(TIMES), open_results(local).drop_vars(TIMES))
    xr.testing.assert_identical(reader.open_case(ids[1]), writer.open_case(ids[1]))  # the object's bytes
    assert reader.index.update() == 3  # the index rewritten and published
    assert writer.remote.exists(writer.index_dir / "results.nc")
    fresh = store_in(bucket, tmp_path / "third", monkeypatch)
    xr.testing.assert_identical(fresh.open_results(ids[:2]).drop_vars(TIMES),
                                open_results(local, ids[:2]).drop_vars(TIMES))


def test_a_damaged_object_is_never_served_and_a_failure_is_recorded_there(bucket, monkeypatch, tmp_path):
    writer = store_in(bucket, tmp_path / "worker", monkeypatch)
    case_id = writer.run_and_store(SPECS[0])
    reader = store_in(bucket, tmp_path / "api", monkeypatch)
    reader.read_summary(case_id)  # a good copy cached
    key = writer.remote.key(writer.case_path(case_id))
    data = bytearray(writer.remote.fs.cat_file(key))
    data[len(data) // 2] ^= 0xFF  # one flipped bit in the middle of the object
    writer.remote.fs.pipe_file(key, bytes(data))
    with pytest.raises(DamagedFile):
        reader.read_summary(case_id)  # the new version is fetched and fails its checksum
    assert reader.unreadable([case_id]) == [case_id]
    writer.write_error(SPECS[1], RuntimeError("no convergence"))
    assert reader.read_error(SPECS[1].case_id)["error"] == "RuntimeError: no convergence"
    assert reader.error_ids() == [SPECS[1].case_id]
    reader.write_sweep_record("0123456789abcdef", "s", "{}", [case_id])
    assert [r["id"] for r in writer.sweep_records()] == ["0123456789abcdef"]
    reader.request_cancel(case_id)
    assert writer.cancel_requested(case_id)
    writer.clear_cancel(case_id)
    assert not reader.cancel_requested(case_id)


def test_an_upload_records_the_etag_a_head_reads(bucket, monkeypatch, tmp_path):
    """The object's ETag and size come from the upload's answer (no HEAD): the same a HEAD reads,
    checksum object first; a file above ``SINGLE_PUT`` by fsspec's upload and a HEAD alike."""
    import os

    from workflows import object_store

    remote = store_in(bucket, tmp_path / "worker", monkeypatch).remote
    for single_put in (object_store.SINGLE_PUT, 1000):
        monkeypatch.setattr(object_store, "SINGLE_PUT", single_put)
        path = remote.cache / "cases" / f"c{single_put}.nc"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(os.urandom(300_000))
        path.with_name(path.name + ".b2").write_bytes(b"checksum")
        info = remote.publish(path)
        head = remote.info(path)
        assert object_store.etag(info) == object_store.etag(head) and info["size"] == head["size"] == 300_000
        assert remote.read(path.with_name(path.name + ".b2")) == b"checksum"
        assert remote.fetch(path)  # the copy is current: nothing downloaded


def test_uploads_are_not_hashed_for_their_signature_unless_configured():
    from workflows.object_store import storage_options

    quiet = {"s3": {"payload_signing_enabled": False}}
    assert storage_options("s3", {"AWS_ENDPOINT_URL": "http://127.0.0.1:9000"}) == {
        "endpoint_url": "http://127.0.0.1:9000", "config_kwargs": quiet}
    assert storage_options("s3", {})["config_kwargs"] == quiet
    own = '{"config_kwargs": {"retries": {"max_attempts": 9}}}'
    assert storage_options("s3", {"TUNNEL_CONTACT_STORAGE_OPTIONS": own}) == {
        "config_kwargs": {"retries": {"max_attempts": 9}}}
    assert storage_options("gcs", {}) == {}


def test_a_damaged_cached_copy_is_fetched_again(bucket, monkeypatch, tmp_path):
    """The cached copy of a case a worker wrote into a bucket store is not fsynced (the object is the
    durable copy): where it is damaged (a crash before its bytes reached the disk), the reader fetches
    the object again instead of refusing a good case."""
    writer = store_in(bucket, tmp_path / "worker", monkeypatch)
    case_id = writer.run_and_store(SPECS[0])
    good = writer.open_case(case_id)
    path = writer.case_path(case_id)
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))
    xr.testing.assert_identical(writer.open_case(case_id), good)
    assert path.read_bytes() != bytes(data)  # the copy replaced by the object's bytes
