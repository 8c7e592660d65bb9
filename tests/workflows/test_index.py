"""The store object and the index of stored results behind open_results."""
from __future__ import annotations

import logging
import multiprocessing
import os
import pickle
import time

import numpy as np
import pytest
import xarray as xr

import solver
from solver import CaseSpec
from workflows import ResultStore, open_case, open_results, run_and_store
from workflows.combine import combine_files
from workflows.files import checksum_path
from workflows.result_store import as_store
from workflows.tasks import case_id_of_key, task_key

COARSE = {"mesh": {"interface_size": 0.2, "far_size": 8.0}}


@pytest.fixture(scope="module")
def solved() -> list[xr.Dataset]:
    return [solver.run_case(CaseSpec.model_validate({**COARSE, "geometry": {"thickness": t}}))
            for t in (0.25, 0.35)]


def clone(ds: xr.Dataset, surface_load: float) -> xr.Dataset:
    """A copy of ``ds`` posing as the case with another surface load (values scaled)."""
    data = CaseSpec.model_validate_json(ds.attrs["case_spec"]).model_dump(mode="json")
    data["loads"]["surface_load"] = surface_load
    spec = CaseSpec.model_validate(data)
    out = ds.copy(deep=True)
    out.attrs.update(case_id=spec.case_id, case_spec=spec.canonical_json())
    for name in ("contact_pressure", "thrust", "max_thrust", "max_contact_pressure"):
        out[name] = out[name] * (surface_load / 1e5)
    return out


@pytest.fixture
def store(tmp_path, solved) -> ResultStore:
    store = ResultStore(tmp_path / "results")
    for ds in solved:
        store.write_case(ds)
    for load in (5e4, 2e5):
        store.write_case(clone(solved[0], load))
    return store


def assert_same_as_files(store: ResultStore, case_ids=None) -> xr.Dataset:
    got = open_results(store, case_ids)
    xr.testing.assert_identical(got, combine_files(store, case_ids))
    return got


def value_of(combined: xr.Dataset, name: str, case_id: str) -> float:
    return float(combined[name].values[list(combined["case_id"].values).index(case_id)])


def test_store_round_trip_and_layout(tmp_path, solved):
    store = ResultStore(tmp_path)
    case_id = solved[0].attrs["case_id"]
    assert not store.is_stored(case_id) and store.case_ids() == []
    path = store.write_case(solved[0])
    assert path == store.case_path(case_id) == tmp_path / "cases" / f"{case_id}.nc"
    xr.testing.assert_identical(store.open_case(case_id), solved[0])
    xr.testing.assert_identical(open_case(str(tmp_path), case_id), solved[0])  # a path works as well
    assert store.is_stored(case_id) and store.case_ids() == [case_id]
    assert store.read_summary(case_id)["max_thrust"] == float(solved[0]["max_thrust"])
    # it is a value: picklable for dask tasks, equal when the folder is
    assert pickle.loads(pickle.dumps(store)) == store == as_store(str(tmp_path))
    assert as_store(store) is store
    spec = CaseSpec.model_validate({**COARSE, "geometry": {"thickness": 0.5}})
    store.write_error(spec, RuntimeError("boom"))
    assert store.read_error(spec.case_id)["error"] == "RuntimeError: boom"
    assert store.read_error(case_id) is None
    store.remove_case(case_id)
    assert store.case_ids() == [] and not store.index.pending_path(case_id).exists()
    with pytest.raises(ValueError):
        store.case_path("../x")


def test_index_is_identical_to_the_files(store, monkeypatch):
    ids = store.case_ids()
    got = assert_same_as_files(store)  # from pending entries
    assert list(got["case_id"].values) == ids
    assert set(got["loads_surface_load"].values) == {5e4, 1e5, 2e5}
    assert store.index.update() == 4
    assert not any(store.index.pending_dir.iterdir())  # merged into the index file
    assert_same_as_files(store)
    assert_same_as_files(store, [ids[3], ids[0], ids[3]])  # subset, order, duplicates
    with monkeypatch.context() as m:  # answered from the index alone: no case file is read
        m.setattr("workflows.index.read_reduced", None)
        open_results(store)
        store.write_case(clone(store.open_case(ids[0]), 6e4))
        assert open_results(store).sizes["case"] == 5  # the new case from its pending entry
    with pytest.raises(FileNotFoundError):
        open_results(store, [ids[0], "0123456789abcdef"])
    with pytest.raises(ValueError):
        open_results(store, ["../secret"])


def test_added_forced_and_removed_cases_are_reflected(store, solved, caplog):
    store.index.update()
    caplog.set_level(logging.WARNING)
    extra = clone(solved[1], 3e5)
    store.write_case(extra)  # added
    got = assert_same_as_files(store)
    assert extra.attrs["case_id"] in got["case_id"].values
    forced = extra.copy(deep=True)
    forced["max_thrust"] = forced["max_thrust"] * 2
    store.write_case(forced)  # forced again: a new file under the same id
    got = assert_same_as_files(store)
    assert value_of(got, "max_thrust", extra.attrs["case_id"]) == float(forced["max_thrust"])
    store.remove_case(extra.attrs["case_id"])  # removed through the store
    got = assert_same_as_files(store)
    assert extra.attrs["case_id"] not in got["case_id"].values
    store.index.update()
    victim = store.case_ids()[0]
    store.case_path(victim).unlink()  # removed behind the store's back
    got = assert_same_as_files(store)
    assert victim not in got["case_id"].values
    with pytest.raises(FileNotFoundError):
        open_results(store, [victim])
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]  # nothing was wrong


def test_case_rewritten_without_an_index_entry_is_read_from_its_file(store, solved, caplog):
    store.index.update()
    case_id = solved[0].attrs["case_id"]
    changed = solved[0].copy(deep=True)
    changed["max_thrust"] = changed["max_thrust"] + 1.0
    changed.to_netcdf(store.case_path(case_id), engine="netcdf4")  # no index entry written
    checksum_path(store.case_path(case_id)).unlink()  # nor a checksum: a writer of older versions
    with caplog.at_level(logging.WARNING):
        got = assert_same_as_files(store)
    assert value_of(got, "max_thrust", case_id) == float(changed["max_thrust"])
    assert "case files" in caplog.text


@pytest.mark.parametrize("damage", ["garbage", "truncated", "missing"])
def test_corrupt_or_missing_index_is_rebuilt_with_a_warning(store, caplog, damage):
    store.index.update()
    expected = combine_files(store)
    path = store.index.path
    if damage == "garbage":
        path.write_bytes(b"this is not netCDF")
    elif damage == "truncated":
        path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    else:
        path.unlink()
    with caplog.at_level(logging.WARNING):
        got = open_results(store)
    xr.testing.assert_identical(got, expected)
    assert "index" in caplog.text and caplog.records[-1].levelno == logging.WARNING
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        xr.testing.assert_identical(open_results(store), expected)  # rebuilt: quiet now
    assert not caplog.records


def test_cases_with_other_variables_combine_as_from_the_files(store, solved):
    newer = clone(solved[1], 7e4)
    newer["extra_scalar"] = ((), 3.5, {"units": "1", "long_name": "a quantity older cases lack"})
    newer["extra_flag"] = ("interface", np.ones(newer.sizes["interface"], dtype=np.int8),
                           {"units": "1", "long_name": "a flag older cases lack"})
    store.write_case(newer)
    got = assert_same_as_files(store)
    assert np.isnan(got["extra_scalar"].values).sum() == 4
    store.index.update()
    assert_same_as_files(store)


def _write_clones(root: str, base: xr.Dataset, loads: list[float]) -> None:
    store = ResultStore(root)
    for load in loads:
        store.write_case(clone(base, load))


def test_concurrent_writers_lose_no_entries(store, solved):
    store.index.update()
    loads = [[1e5 + 1e3 * (10 * w + i) for i in range(1, 5)] for w in range(3)]
    ctx = multiprocessing.get_context("fork")
    writers = [ctx.Process(target=_write_clones, args=(str(store.root), solved[0], ls)) for ls in loads]
    for w in writers:
        w.start()
    while any(w.is_alive() for w in writers):  # readers merge entries while writers add them
        open_results(store)
        store.index.update()
        time.sleep(0.05)
    assert all(w.exitcode == 0 for w in writers)
    got = assert_same_as_files(store)
    assert got.sizes["case"] == 4 + 12
    store.index.update()
    assert_same_as_files(store)


def test_one_task_key_per_case():
    case_id = "0123456789abcdef"
    assert case_id_of_key(task_key(case_id)) == case_id
    assert case_id_of_key("something-else") is None


def test_run_and_store_accepts_a_store(tmp_path, monkeypatch, solved):
    monkeypatch.setattr(solver, "run_case", lambda spec, **options: solved[0])
    spec = CaseSpec.model_validate_json(solved[0].attrs["case_spec"])
    store = ResultStore(tmp_path)
    assert run_and_store(spec, store) == spec.case_id
    assert store.is_stored(spec.case_id) and os.path.isfile(store.index.pending_path(spec.case_id))


def test_damaged_pending_entry_is_not_used(store, caplog):
    case_id = store.case_ids()[0]
    entry = store.index.pending_path(case_id)
    data = bytearray(entry.read_bytes())
    data[-3] ^= 0xFF  # one flipped byte among the values
    entry.write_bytes(bytes(data))
    with caplog.at_level(logging.WARNING):
        assert_same_as_files(store)
    assert "checksum" in caplog.text and "case files" in caplog.text


def test_threads_reading_at_once_get_the_same_answer(store):
    from concurrent.futures import ThreadPoolExecutor

    store.index.update()
    store.write_case(clone(store.open_case(store.case_ids()[0]), 4e4))  # one pending entry too
    expected = combine_files(store)
    with ThreadPoolExecutor(4) as pool:
        answers = list(pool.map(lambda _: open_results(store), range(8)))
    for got in answers:
        xr.testing.assert_identical(got, expected)


def test_cli_table_rows_from_the_index_match_the_files(store, monkeypatch):
    from workflows.commands import case_row, case_rows

    ids = [*store.case_ids(), "0123456789abcdef"]  # the last one is not stored
    expected = [case_row(store, c) for c in ids]
    store.index.update()
    with monkeypatch.context() as m:  # stored rows come from the index: no case file is opened
        m.setattr(type(store), "opened", None)
        m.setattr("workflows.index.read_reduced", None)
        rows = case_rows(store, ids)
    assert rows == expected


def test_cases_of_a_study_share_one_block_of_the_index():
    """What a study varies (loads, ground, design, the design trough's inputs) changes values,
    never the variables' attributes: the index stacks the cases of one section in one block (a
    case's own number in an attribute once gave each case a block of its own, and a rewrite of
    a 1 000-case index took twenty minutes)."""
    from workflows.combine import reduce_case
    from workflows.index import _schema

    base = {"mesh": {"interface_size": 0.5, "far_size": 15.0}}
    changes = [{}, {"loads": {"surface_load": 3e4}}, {"ground": {"young": 2e7}, "loads": {"lateral_ratio": 0.7}},
               {"settlement": {"volume_loss": 0.01, "trough_width_factor": 0.35}},
               {"design": {"load_factor": 1.5, "concrete_strength": 3e7}},
               {"water": {"table": 5.0}}, {"interface": {"model": "coulomb", "friction": 0.4}}]
    schemas = {_schema(reduce_case(solver.run_case(CaseSpec.model_validate({**base, **c})))) for c in changes}
    assert len(schemas) == 1
