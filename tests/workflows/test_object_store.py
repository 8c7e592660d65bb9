"""The result store on object storage (``s3://bucket/prefix``) against real S3-compatible servers
(moto's server mode and SeaweedFS on loopback: the ``s3`` and ``seaweedfs`` fixtures): one object
per file, written whole, read back only when it matches its checksum, the index answering
``open_results`` for a process that computed none of the cases, identical to a local store."""
from __future__ import annotations

import logging
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


def test_cases_stored_by_one_process_are_read_by_another_as_from_a_local_folder(bucket, monkeypatch, tmp_path,
                                                                                 caplog):
    writer = store_in(bucket, tmp_path / "worker", monkeypatch)
    local = ResultStore(tmp_path / "local")
    for spec in SPECS:
        writer.run_and_store(spec)
        local.run_and_store(spec)
    ids = sorted(s.case_id for s in SPECS)
    names = set(writer.remote.listing(writer.cases_dir))
    assert names == {f"{c}.nc" for c in ids}  # one object per file, its checksum in its metadata
    assert writer.remote.info(writer.case_path(ids[0]))["Metadata"] == {
        "blake2b": writer.case_path(ids[0]).with_name(f"{ids[0]}.nc.b2").read_text().strip()}
    assert str(writer) == bucket and writer.root == tmp_path / "worker"

    reader = store_in(bucket, tmp_path / "api", monkeypatch)  # nothing cached here
    assert reader.case_ids() == ids and reader.is_stored(ids[0])
    xr.testing.assert_identical(reader.open_results().drop_vars(TIMES), open_results(local).drop_vars(TIMES))
    xr.testing.assert_identical(reader.open_case(ids[1]), writer.open_case(ids[1]))  # the object's bytes
    assert reader.index.update() == 3  # the index rewritten and published
    assert writer.remote.exists(writer.index_dir / "results.nc")
    fresh = store_in(bucket, tmp_path / "third", monkeypatch)
    with caplog.at_level(logging.WARNING, logger="workflows.index"):
        xr.testing.assert_identical(fresh.open_results(ids[:2]).drop_vars(TIMES),
                                    open_results(local, ids[:2]).drop_vars(TIMES))
    assert not [r for r in caplog.records if "rebuilding" in r.getMessage()]  # the index read, not rebuilt


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
    """The object's ETag and size come from the upload's answer (no HEAD): the same a HEAD reads.
    A case file's checksum travels in its object's metadata (one request), unless it is above
    ``SINGLE_PUT`` (fsspec's upload and a HEAD); other files' (the index's, which readers sync by a
    listing) as a checksum object first. A reader with no copy gets the file and its checksum."""
    import os

    from workflows import object_store

    remote = store_in(bucket, tmp_path / "worker", monkeypatch).remote
    reader = store_in(bucket, tmp_path / "reader", monkeypatch).remote
    for single_put, in_metadata in ((object_store.SINGLE_PUT, True), (1000, True), (object_store.SINGLE_PUT, False)):
        monkeypatch.setattr(object_store, "SINGLE_PUT", single_put)
        path = remote.cache / "cases" / f"c{single_put}-{in_metadata}.nc"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(os.urandom(300_000))
        path.with_name(path.name + ".b2").write_text(f"digest{single_put}\n")
        info = remote.publish(path, checksum_in_metadata=in_metadata)
        head = remote.info(path)
        assert object_store.etag(info) == object_store.etag(head) and info["size"] == head["size"] == 300_000
        checksum_object = remote.read(path.with_name(path.name + ".b2"))
        if in_metadata and single_put > 300_000:
            assert head["Metadata"] == {"blake2b": f"digest{single_put}"} and checksum_object is None
        else:
            assert checksum_object == f"digest{single_put}\n".encode() and head["Metadata"] == {}
        assert remote.fetch(path)  # the copy is current: nothing downloaded
        copy = reader.cache / "cases" / path.name
        assert reader.fetch(copy) and copy.read_bytes() == path.read_bytes()
        assert copy.with_name(copy.name + ".b2").read_text() == f"digest{single_put}\n"


def test_a_stored_case_costs_three_requests(bucket, monkeypatch, tmp_path):
    """A case solved into a bucket is three requests to the store: its object (the checksum in its
    metadata), one bulk removal of an older failure's record and cancel request, its index entry; no
    checksum object, no delete before the solve, no HEAD after the upload (its answer carries the ETag).
    Unless forced, one HEAD before: whether the case is stored already."""
    import s3fs

    writer = store_in(bucket, tmp_path / "worker", monkeypatch)
    requests = []
    call, sync_call = s3fs.S3FileSystem._call_s3, s3fs.S3FileSystem.call_s3

    async def counted(self, method, *args, **kwargs):
        requests.append(method)
        return await call(self, method, *args, **kwargs)

    def sync_counted(self, method, *args, **kwargs):
        requests.append(method)
        return sync_call(self, method, *args, **kwargs)

    monkeypatch.setattr(s3fs.S3FileSystem, "_call_s3", counted)
    monkeypatch.setattr(s3fs.S3FileSystem, "call_s3", sync_counted)
    first, second = (CaseSpec.model_validate({**COARSE, "ground": {"young": 5e7 + 1e3 * (hash(bucket) % 1000 + k)}})
                     for k in (0, 1000))
    writer.run_and_store(first)  # the writer's first case also publishes the index's schema, once
    requests.clear()
    writer.run_and_store(second)
    assert sorted(requests) == ["delete_objects", "head_object", "put_object", "put_object"], requests
    requests.clear()
    writer.run_and_store(second, force=True)  # solved again: not even a look for a stored one
    assert sorted(requests) == ["delete_objects", "put_object", "put_object"], requests


def test_a_cancel_request_older_than_the_solve_is_void_by_the_stores_clock(bucket, monkeypatch, tmp_path):
    """A solve in a bucket store does not delete its case's cancel request before it starts (a request
    a case); a request the store dates before the solve began (an earlier run's, which ended first) is
    voided when the solve first asks, and one made since is honoured. The ages are the server's
    (its ``Date`` less the object's ``Last-Modified``), so no two machines' clocks are compared."""
    from workflows.store_files import STALE_CANCEL_SECONDS

    writer = store_in(bucket, tmp_path / "worker", monkeypatch)
    api = store_in(bucket, tmp_path / "api", monkeypatch)
    case_id = SPECS[0].case_id
    api.request_cancel(case_id)
    assert 0 <= writer.remote.age(writer.cancel_marker(case_id)) <= 1.5
    assert writer.cancel_requested(case_id, running_for=5.0)  # made while the solve ran
    assert writer.cancel_requested(case_id)  # no solve's age given: any request counts
    # a solve that began a few seconds after the request was made (a negative age of the solve
    # stands for waiting that long): the request is an earlier run's, removed
    assert not writer.cancel_requested(case_id, running_for=-(STALE_CANCEL_SECONDS + 2.0))
    assert writer.remote.age(writer.cancel_marker(case_id)) is None and not api.cancel_requested(case_id)

    # the same through a solve that asks at once, its case's request written before it began
    import time

    import solver.limits
    monkeypatch.setattr(solver.limits, "STOP_POLL", 0.0)
    asked, ask = [], ResultStore.cancel_requested
    monkeypatch.setattr(ResultStore, "cancel_requested",
                        lambda self, *a, **k: asked.append(ask(self, *a, **k)) or asked[-1])
    # cases of this bucket's own (a model keeps its last solutions: a case solved before asks nothing)
    old, new = (CaseSpec.model_validate({**COARSE, "ground": {"young": 3e7 + 1e3 * (hash(bucket) % 1000 + k)}})
                for k in (0, 1000))
    api.request_cancel(old.case_id)
    time.sleep(STALE_CANCEL_SECONDS + 1.5)
    assert writer.run_and_store(old) == old.case_id and writer.is_stored(old.case_id)
    assert asked and not any(asked) and not api.cancel_requested(old.case_id)
    api.request_cancel(new.case_id)  # made while the solve runs (here: just before it asks)
    with pytest.raises(solver.limits.CaseCancelled):
        writer.run_and_store(new)
    assert not writer.is_stored(new.case_id) and not api.cancel_requested(new.case_id)


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


def test_an_objects_age_on_a_file_system_without_s3s_clock(tmp_path):
    """Off S3 (here fsspec's memory file system) an object's age is this machine's clock against the
    object's time; none for a missing object."""
    from workflows.object_store import Remote

    remote = Remote(f"memory://age-{uuid.uuid4().hex[:8]}/store", tmp_path)
    assert remote.age(tmp_path / "cancel" / "x") is None
    remote.fs.pipe_file(remote.key(tmp_path / "cancel" / "x"), b"")
    assert 0.0 <= remote.age(tmp_path / "cancel" / "x") < 5.0
