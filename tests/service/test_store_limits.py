"""A full store and a read-only store, on real file systems (issue 24).

The API runs as a process in a mount namespace of its own (``unshare -m``, as root): a
small tmpfs for the full store, a read-only bind mount for the read-only one. The test
reaches the namespace's files through ``/proc/<pid>/root``.
"""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import httpx
import pytest

from service.process import api_command, free_port, start, stop, wait_healthy
from service_helpers import COARSE, wait_until
from solver.spec import CaseSpec
from workflows.result_store import estimated_result_bytes


def _namespaces_work() -> bool:
    if shutil.which("unshare") is None:
        return False
    probe = subprocess.run(["unshare", "-m", "sh", "-c", "mount -t tmpfs -o size=1m tmpfs /mnt"],
                           capture_output=True)
    return probe.returncode == 0


pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not _namespaces_work(), reason="needs unshare -m and mount (root)")]


def _serve_in_namespace(setup: str, results: Path, log: Path, env: dict | None = None):
    """The API on a free loopback port, started after ``setup`` (sh; $0 is the results folder)."""
    port = free_port()
    command = ["unshare", "-m", "sh", "-c", f'{setup} && exec "$@"', str(results),
               *api_command(port=port, results=results)]
    process = start(command, log=log, env=env)
    return process, f"http://127.0.0.1:{port}"


def _sweep(n: int) -> dict:
    return {"name": "fills the store", "base": COARSE, "mode": "grid",
            "vary": {"loads.surface_load": [1e4 * (k + 1) for k in range(n)]}}


def test_a_full_store_is_named_and_its_cases_retried_when_room_is_back(tmp_path):
    """On a 48 MiB tmpfs: a sweep accepted while there is room, then the store filled by a
    ballast file: the cases not yet written fail naming the full store (never "NetCDF: HDF
    error"), /health says so, a new case is refused with 503 (not 202) naming the room it
    needs; the ballast removed, the service computes the failed cases again by itself."""
    results = tmp_path / "results"
    results.mkdir()
    process, url = _serve_in_namespace('mount -t tmpfs -o size=48m tmpfs "$0"', results, tmp_path / "api.log",
                                       env={"TUNNEL_CONTACT_MIN_FREE_BYTES": str(1 << 20)})
    try:
        wait_healthy(url, timeout=90, process=process)
        inside = Path(f"/proc/{process.pid}/root") / results.relative_to("/")
        need = estimated_result_bytes(CaseSpec.model_validate(COARSE))
        sweep = httpx.post(f"{url}/sweeps", json=_sweep(6), timeout=30).json()
        ballast = inside / "ballast"
        with open(ballast, "wb") as fh:  # leave less room than one case needs
            free = shutil.disk_usage(inside).free
            fh.write(b"\0" * max(0, free - need // 2))

        def settled():
            body = httpx.get(f"{url}/sweeps/{sweep['id']}", timeout=30).json()
            return body if body["finished"] else None

        body = wait_until(settled, timeout=120, what="the sweep to settle")
        assert body["counts"]["failed"] >= 1, body
        errors = [httpx.get(f"{url}/cases/{c}", timeout=30).json()["error"] for c in sweep["case_ids"]]
        errors = [e for e in errors if e]
        assert errors and all("results store is full" in e and "HDF" not in e for e in errors), errors
        health = httpx.get(f"{url}/health", timeout=30)
        assert health.status_code == 503 and any("full" in r for r in health.json()["reasons"])
        refused = httpx.post(f"{url}/cases", json={**COARSE, "loads": {"surface_load": 9.9e4}}, timeout=30)
        assert refused.status_code == 503 and "results store is full" in refused.json()["detail"]
        assert f"{need / 2**20:.0f} MiB" in refused.json()["detail"]

        ballast.unlink()
        done = wait_until(lambda: (b := settled()) and b["counts"]["done"] == 6 and b, timeout=120,
                          what="the failed cases computed again")
        assert done["counts"]["failed"] == 0
    finally:
        stop(process)


def test_a_read_only_store_is_served_and_takes_no_work(tmp_path):
    """The API starts on a read-only mount of a store with a done case: lists and serves it,
    answers 503 (not 202) to new work, and /health says why."""
    results = tmp_path / "results"
    from service.process import running_service

    with running_service(results, log=tmp_path / "first.log") as first:
        case = httpx.post(f"{first}/cases", json=COARSE, timeout=30).json()
        wait_until(lambda: httpx.get(f"{first}/cases/{case['id']}", timeout=30).json()["status"] == "done",
                   timeout=120, what="the case")
    process, url = _serve_in_namespace('mount --bind "$0" "$0" && mount -o remount,bind,ro "$0"',
                                       results, tmp_path / "api.log")
    try:
        wait_until(lambda: _answers(url), timeout=90, what="the API on a read-only store")
        listed = httpx.get(f"{url}/cases", timeout=30).json()
        assert [c["status"] for c in listed["items"] if c["id"] == case["id"]] == ["done"]
        assert httpx.get(f"{url}/cases/{case['id']}/result.nc", timeout=30).status_code == 200
        refused = httpx.post(f"{url}/cases", json={**COARSE, "loads": {"surface_load": 8.8e4}}, timeout=30)
        assert refused.status_code == 503 and "read-only" in refused.json()["detail"]
        health = httpx.get(f"{url}/health", timeout=30)
        assert health.status_code == 503 and any("read-only" in r for r in health.json()["reasons"])
    finally:
        stop(process)


def _answers(url: str) -> bool:
    try:
        return httpx.get(f"{url}/health", timeout=2).status_code in (200, 503)
    except httpx.HTTPError:
        return False
