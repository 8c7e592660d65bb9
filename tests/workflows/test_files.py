"""Atomic writes tied to their writer, and whole-file checksums (workflows.files)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import solver
from solver import CaseSpec
from workflows.files import DamagedFile, checksum_path, remove_stale_temporaries, verify, write_atomically
from workflows.result_store import as_store

COARSE = {"mesh": {"interface_size": 0.25, "far_size": 8.0}}
TWO_HOURS = 7200.0


@pytest.fixture(scope="module")
def solved() -> xr.Dataset:
    return solver.run_case(CaseSpec.model_validate(COARSE))


def _dead_writer(folder: Path) -> None:
    """A process killed in the middle of write_atomically (its temporary and lock stay)."""
    code = textwrap.dedent(f"""
        import sys, time
        from pathlib import Path
        from workflows.files import write_atomically
        def write(tmp):
            tmp.write_bytes(b"partial")
            print("writing", flush=True)
            time.sleep(600)
        write_atomically(Path({str(folder / 'combined.nc')!r}), write)
    """)
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(Path(__file__).parents[2])})
    assert proc.stdout.readline().strip() == "writing"
    proc.send_signal(signal.SIGKILL)
    proc.wait()


def _temporaries(folder: Path) -> list[Path]:
    return sorted(folder.glob(".*.tmp"))


def test_a_live_write_survives_clean_up_under_a_skewed_clock_and_a_dead_one_goes(tmp_path):
    """The clean-up asks the writer's lock, not the clock: a temporary made to look two hours
    old while its writer is still writing stays; a killed writer's (made to look new) goes,
    in every folder of the store (a combined sweep file's too)."""
    cases, sweeps = tmp_path / "cases", tmp_path / "sweeps"
    sweeps.mkdir(parents=True)
    _dead_writer(sweeps)
    [dead] = _temporaries(sweeps)
    started, release = threading.Event(), threading.Event()

    def slow(tmp: Path) -> None:
        tmp.write_bytes(b"first half ")
        started.set()
        release.wait(30)
        with open(tmp, "ab") as fh:
            fh.write(b"second half")

    writer = threading.Thread(target=write_atomically, args=(cases / "a.nc", slow))
    writer.start()
    assert started.wait(30)
    [live] = _temporaries(cases)
    past = time.time() - TWO_HOURS
    os.utime(live, (past, past))
    for path in (live, live.with_suffix(".lock")):
        os.utime(path, (past, past))
    assert remove_stale_temporaries(tmp_path) == 1
    assert live.exists() and not dead.exists()
    assert not list(sweeps.glob(".*.lock"))  # the dead writer's lock went with its temporary
    release.set()
    writer.join(30)
    assert (cases / "a.nc").read_bytes() == b"first half second half"
    assert not _temporaries(cases) and not list(cases.glob(".*.lock"))


def test_a_failed_write_leaves_nothing(tmp_path):
    def fail(tmp: Path) -> None:
        tmp.write_bytes(b"x")
        raise RuntimeError("disk on fire")

    with pytest.raises(RuntimeError):
        write_atomically(tmp_path / "a.nc", fail, checksum=True)
    assert list(tmp_path.iterdir()) == []


def _overwrite_middle(path: Path, length: int = 64) -> None:
    """Damage ``path`` in place, as a disk fault would: same size, different bytes."""
    size = path.stat().st_size
    with open(path, "r+b") as fh:
        fh.seek(size // 2)
        old = fh.read(length)
        fh.seek(size // 2)
        fh.write(bytes(b ^ 0xFF for b in old))
    assert path.stat().st_size == size


def test_checksum_finds_an_overwrite_in_place(tmp_path):
    target = tmp_path / "x.bin"
    write_atomically(target, lambda tmp: tmp.write_bytes(os.urandom(100_000)), checksum=True)
    verify(target)
    _overwrite_middle(target)
    with pytest.raises(DamagedFile, match="x.bin"):
        verify(target)
    # a crash between the checksum and the rename: the old bytes meet the new checksum
    write_atomically(target, lambda tmp: tmp.write_bytes(b"old"), checksum=True)
    checksum_path(target).write_text("0" * 32 + "\n")
    with pytest.raises(DamagedFile):
        verify(target)


def test_a_file_without_checksum_is_adopted(tmp_path):
    target = tmp_path / "legacy.nc"
    target.write_bytes(b"written before checksums")
    verify(target)
    assert checksum_path(target).is_file()
    _overwrite_middle(target, 4)
    with pytest.raises(DamagedFile):
        verify(target)


def test_a_damaged_case_file_is_unreadable_and_recomputed(tmp_path, solved):
    """A stored result overwritten in the middle still opens as netCDF with wrong values; the
    store refuses it (the checksum) and computes the case again."""
    store = as_store(tmp_path)
    store.write_case(solved)
    case_id = solved.attrs["case_id"]
    path = store.case_path(case_id)
    _overwrite_middle(path, 512)
    with pytest.raises(DamagedFile):
        store.open_case(case_id)
    assert store.unreadable([case_id]) == [case_id]
    spec = CaseSpec.model_validate_json(solved.attrs["case_spec"])
    summary, _, computed = store.solve_or_read(spec)
    assert computed
    back = store.open_case(case_id)  # the recomputed file passes its checksum and holds the answer
    for name in ("displacement_x", "displacement_y", "stress_xx", "contact_pressure", "thrust"):
        # to round-off: a solve again need not repeat every last bit (a model shared with the process's
        # other cases, or OpenBLAS's threads, order the sums otherwise; seen once under the parallel suite)
        scale = float(np.abs(solved[name]).max())
        xr.testing.assert_allclose(back[name], solved[name], rtol=0, atol=1e-10 * scale)
    store.remove_case(case_id)
    assert not checksum_path(path).exists()


def test_free_space_of_a_store_not_made_yet_is_its_parents(tmp_path):
    """A first run into a new results folder has the room of the disk it will be made on (0
    here failed every first CLI run as a full store)."""
    import shutil

    from workflows.result_store import free_bytes

    assert free_bytes(tmp_path / "not" / "made") == pytest.approx(shutil.disk_usage(tmp_path).free, rel=0.01)
    assert free_bytes(tmp_path / "not" / "made") > 0


def test_the_memo_of_verified_files_is_bounded_and_an_evicted_file_is_verified_again(tmp_path, monkeypatch):
    """A long-running process meets every file of its store: the memo of verified versions keeps
    the most recently used ones only (least recently used evicted first), and a file that left it
    is hashed again at its next check, so a damage made meanwhile is still found."""
    import workflows.files as files
    from workflows.bounded import BoundedMemo

    memo = BoundedMemo(2)
    monkeypatch.setattr(files, "_VERIFIED", memo)
    hashed = []
    real_digest = files.digest
    monkeypatch.setattr(files, "digest", lambda p: hashed.append(Path(p).name) or real_digest(p))
    paths = []
    for name in "abc":
        path = tmp_path / f"{name}.bin"
        write_atomically(path, lambda tmp, n=name: tmp.write_bytes(n.encode() * 1000), checksum=True)
        paths.append(path)
    a, b, c = paths
    hashed.clear()  # (writing hashed the temporaries)
    verify(a), verify(b), verify(a)  # a again: remembered, and now the most recent
    assert hashed == ["a.bin", "b.bin"]
    verify(c)  # evicts b, the least recently used
    assert len(memo) == 2 and str(b) not in memo and str(a) in memo
    with open(b, "r+b") as fh:  # damaged in place while out of the memo
        fh.write(b"X")
    with pytest.raises(DamagedFile):
        verify(b)
    assert hashed[-1] == "b.bin"
    with pytest.raises(ValueError, match="size"):
        BoundedMemo(0)
