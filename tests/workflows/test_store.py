"""Result store: exact round trip, atomic writes, error records, standard readers."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import solver
from solver import CaseSpec, SolverError
from workflows import open_case, run_and_store
from workflows.result_store import as_store, check_case_id

COARSE = {"mesh": {"interface_size": 0.25, "far_size": 8.0}}
CHECKER = Path(sys.executable).with_name("ugrid-checker")


@pytest.fixture(scope="module")
def solved() -> xr.Dataset:
    return solver.run_case(CaseSpec.model_validate(COARSE))


@pytest.fixture(scope="module")
def stored(tmp_path_factory, solved) -> Path:
    root = tmp_path_factory.mktemp("store")
    as_store(root).write_case(solved)
    return as_store(root).case_path(solved.attrs["case_id"])


def test_round_trip_is_identical(tmp_path, solved):
    as_store(tmp_path).write_case(solved)
    back = open_case(tmp_path, solved.attrs["case_id"])
    xr.testing.assert_identical(back, solved)
    assert back["face_nodes"].dtype == solved["face_nodes"].dtype
    # fully in memory: the file can be removed while the data stays usable
    as_store(tmp_path).case_path(solved.attrs["case_id"]).unlink()
    assert float(back["displacement_y"].sum()) == pytest.approx(float(solved["displacement_y"].sum()))


def test_stored_case_is_not_recomputed_unless_forced(tmp_path, monkeypatch, solved):
    calls = []

    def counting(spec, **options):
        calls.append(spec.case_id)
        return solved

    monkeypatch.setattr(solver, "run_case", counting)
    spec = CaseSpec.model_validate(COARSE)
    assert run_and_store(spec, tmp_path) == spec.case_id
    assert run_and_store(spec, tmp_path) == spec.case_id
    assert len(calls) == 1
    run_and_store(spec, tmp_path, force=True)
    assert len(calls) == 2
    assert as_store(tmp_path).case_ids() == [spec.case_id]


def test_crash_mid_write_leaves_no_file(tmp_path, monkeypatch, solved):
    def crash(ds, path, *args, **kwargs):
        Path(path).write_bytes(b"CDF partial")  # the temporary file exists, half written
        raise OSError("disk full")

    monkeypatch.setattr("workflows.result_store.write_netcdf", crash)
    with pytest.raises(OSError, match="disk full"):
        as_store(tmp_path).write_case(solved)
    folder = tmp_path / "cases"
    assert not as_store(tmp_path).case_path(solved.attrs["case_id"]).exists()
    assert list(folder.iterdir()) == []  # no stray temporary file either


def test_failure_is_recorded_and_cleared_by_a_later_success(tmp_path, monkeypatch, solved):
    spec = CaseSpec.model_validate(COARSE)

    def failing(spec, **options):
        raise SolverError("no admissible bolt")

    monkeypatch.setattr(solver, "run_case", failing)
    with pytest.raises(SolverError):
        run_and_store(spec, tmp_path)
    record = as_store(tmp_path).read_error(spec.case_id)
    assert record["case_id"] == spec.case_id
    assert record["error"] == "SolverError: no admissible bolt"
    assert CaseSpec.model_validate(record["spec"]) == spec
    assert json.loads(as_store(tmp_path).error_path(spec.case_id).read_text()) == record
    assert not as_store(tmp_path).case_path(spec.case_id).exists()

    monkeypatch.setattr(solver, "run_case", lambda spec, **options: solved)
    run_and_store(spec, tmp_path)
    assert as_store(tmp_path).read_error(spec.case_id) is None
    assert sorted(p.name for p in (tmp_path / "cases").iterdir()) == [f"{spec.case_id}.nc", f"{spec.case_id}.nc.b2"]


@pytest.mark.parametrize("bad", ["../../etc/passwd", "0123456789ABCDEF", "0123456789abcde",
                                 "0123456789abcdef0", "0123456789abcdeg", "", None])
def test_malformed_case_ids_never_reach_a_path(tmp_path, bad):
    with pytest.raises(ValueError, match="16 lowercase hex"):
        check_case_id(bad)
    with pytest.raises(ValueError):
        open_case(tmp_path, bad)


def test_unknown_case_raises_file_not_found(tmp_path):
    with pytest.raises(FileNotFoundError):
        open_case(tmp_path, "0123456789abcdef")


def test_ugrid_checker_finds_no_errors(stored, tmp_path):
    # no errors and no warnings or advisories either (the checker's exit code counts them)
    good = subprocess.run([str(CHECKER), str(stored)], capture_output=True, text=True)
    assert good.returncode == 0, good.stdout + good.stderr
    assert "No problems found" in good.stdout
    # the check can fail: the same file without the connectivity's cf_role is an error
    with xr.open_dataset(stored, mask_and_scale=False) as ds:
        broken = ds.load()
    del broken["face_nodes"].attrs["cf_role"]
    broken.to_netcdf(tmp_path / "broken.nc")
    bad = subprocess.run([str(CHECKER), "-e", str(tmp_path / "broken.nc")], capture_output=True, text=True)
    assert bad.returncode != 0 and "R301" in bad.stdout


def test_standard_readers_open_the_file(stored, solved):
    import xugrid

    with xr.open_dataset(stored) as plain:
        assert plain.attrs["case_id"] == solved.attrs["case_id"]
        assert "CF-1.10" in plain.attrs["Conventions"] and "UGRID-1.0" in plain.attrs["Conventions"]
        np.testing.assert_array_equal(plain["contact_pressure"], solved["contact_pressure"])
    uds = xugrid.open_dataset(stored)
    grid = uds.ugrid.grid
    assert grid.n_face == solved.sizes["face"] and grid.n_node == solved.sizes["node"]
    np.testing.assert_array_equal(grid.face_node_connectivity, solved["face_nodes"].values)
    np.testing.assert_array_equal(uds["displacement_x"].values, solved["displacement_x"].values)
    # the mesh is the one the solver produced: total triangle area is the model area
    x, y = grid.node_x[grid.face_node_connectivity], grid.node_y[grid.face_node_connectivity]
    area = 0.5 * np.abs((x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0]) - (x[:, 2] - x[:, 0]) * (y[:, 1] - y[:, 0]))
    g = CaseSpec.model_validate(COARSE).geometry
    expected = g.width * g.height - 0.5 * np.pi * g.hole_radius**2 + 0.5 * np.pi * (g.outer_radius**2 - g.inner_radius**2)
    assert area.sum() == pytest.approx(expected, rel=2e-3)


def test_rewriting_a_case_drops_its_cached_plots(tmp_path, solved):
    from workflows.artifacts import plot_path, render_plot

    case_id = solved.attrs["case_id"]
    as_store(tmp_path).write_case(solved)
    png = render_plot(tmp_path, case_id, "contact_pressure")
    assert png == plot_path(tmp_path, case_id, "contact_pressure") and png.stat().st_size > 1000
    assert render_plot(tmp_path, case_id, "contact_pressure") == png  # cached, not redrawn
    as_store(tmp_path).write_case(solved)  # a new result (e.g. forced recompute): old figures must go
    assert not png.exists()
    assert render_plot(tmp_path, case_id, "contact_pressure").is_file()


def test_threads_reading_and_writing_netcdf_at_once_do_not_crash(tmp_path, solved):
    """netCDF-C/HDF5 are not thread-safe: the API serves several plots of a case at once
    from threads, and before one process-wide lock guarded every access that crashed the
    process in HDF5 (a segfault would end this test run)."""
    from concurrent.futures import ThreadPoolExecutor

    from workflows.artifacts import render_plot
    from workflows.plots import PLOTS
    from workflows.result_store import ResultStore

    store = ResultStore(tmp_path)
    case_id = solved.attrs["case_id"]
    store.write_case(solved)
    other = solved.copy()
    other.attrs = {**solved.attrs, "case_id": "0123456789abcdef"}  # written while the first is read
    jobs = [lambda: store.open_case(case_id).sizes["node"], lambda: store.read_summary(case_id)["max_thrust"],
            lambda: store.write_case(other).name, *[lambda n=n: render_plot(store, case_id, n).stat().st_size
                                                    for n in PLOTS]] * 3
    with ThreadPoolExecutor(8) as pool:
        results = list(pool.map(lambda job: job(), jobs))
    assert len(results) == len(jobs) and all(results)
    xr.testing.assert_identical(store.open_case(case_id).drop_attrs(), solved.drop_attrs())


# -- a case file verifies without its checksum file (issue 38, 4) --------------------------------

def _without_checksum(tmp_path, solved) -> Path:
    from workflows.files import checksum_path

    as_store(tmp_path).write_case(solved)
    path = as_store(tmp_path).case_path(solved.attrs["case_id"])
    checksum_path(path).unlink()
    return path


def test_a_sound_case_file_without_its_checksum_file_verifies_by_its_digest(tmp_path, solved):
    from workflows.files import checksum_path

    path = _without_checksum(tmp_path, solved)
    xr.testing.assert_identical(open_case(tmp_path, solved.attrs["case_id"]), solved)  # its digest not shown
    assert checksum_path(path).is_file()  # adopted: checked by its content, then recorded


def test_a_case_file_damaged_mid_data_without_its_checksum_file_is_not_served(tmp_path, solved):
    """A lost ``.b2`` adopted the damaged bytes (hundreds of wrong values served); the digest of
    the values inside the file refuses them."""
    from workflows.files import DamagedFile

    path = _without_checksum(tmp_path, solved)
    values = solved["displacement_x"].values.astype("<f8")
    raw = bytearray(path.read_bytes())
    start = bytes(raw).find(values.tobytes()[:64])
    assert start > 0  # the values lie in the file as they are (floats are not compressed)
    middle = start + 8 * (values.size // 2)
    raw[middle: middle + 8] = np.float64(12345.678).tobytes()  # one value, HDF5 metadata untouched
    path.write_bytes(bytes(raw))
    store = as_store(tmp_path)
    with pytest.raises(DamagedFile):
        open_case(tmp_path, solved.attrs["case_id"])
    assert store.unreadable([solved.attrs["case_id"]]) == [solved.attrs["case_id"]]


def test_a_case_file_written_before_digests_is_adopted_without_its_checksum_file(tmp_path, solved):
    import netCDF4

    from workflows.store_files import CONTENT_DIGEST

    path = _without_checksum(tmp_path, solved)
    with netCDF4.Dataset(path, "a") as nc:
        nc.delncattr(CONTENT_DIGEST)
    xr.testing.assert_identical(open_case(tmp_path, solved.attrs["case_id"]), solved)


def test_a_sweep_figure_drawn_in_an_older_look_is_not_served(tmp_path, monkeypatch):
    import workflows.store_files as store_files

    store = as_store(tmp_path)
    ids = ["0123456789abcdef", "fedcba9876543210"]
    before = store.sweep_plot_path("00000000000000aa", ids, "scalars")
    monkeypatch.setattr(store_files, "SWEEP_FIGURE_STYLE", "a later look")
    assert store.sweep_plot_path("00000000000000aa", ids, "scalars") != before
