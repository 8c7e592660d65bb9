"""Worker and scheduler deaths on the deployment's topology (real ``dask scheduler``,
``dask worker`` and API processes on loopback): a case whose workers keep dying fails
with a clean error and is recomputed on request; work queued while the scheduler is
gone runs once a scheduler and workers are back.
"""
from __future__ import annotations

import os
import signal

import httpx
import psutil
import pytest
from distributed import Client
from service_helpers import coarse_case, wait_until

from service.process import (
    dask_command,
    free_port,
    running_service,
    start,
    stop,
    worker_command,
)
from workflows.tasks import task_key

#: A fresh worker process spends a second or more importing the solver before this case runs:
#: time enough to kill it mid-task, again after its nanny has started a new one.
SLOW = coarse_case(loads={"surface_load": 6.1e4})


def listening(pid: int) -> list[tuple[str, int]]:
    """The (address, port) pairs process ``pid`` listens on."""
    return [c.laddr for c in psutil.Process(pid).net_connections(kind="inet") if c.status == psutil.CONN_LISTEN]


def status_of(url: str, case_id: str, *wanted: str):
    body = httpx.get(f"{url}/cases/{case_id}", timeout=30).json()
    return body if body["status"] in wanted else None


def kill_worker_running(dask: Client, key: str) -> None:
    """SIGKILL the worker process executing ``key`` (its nanny starts a new one)."""
    def holder():
        return next((w for w, keys in dask.processing().items() if key in keys), None)
    worker = wait_until(holder, interval=0.02, what=f"a worker to take {key}")
    pid = dask.run(os.getpid, workers=[worker])[worker]
    os.kill(pid, signal.SIGKILL)
    wait_until(lambda: worker not in dask.scheduler_info()["workers"], interval=0.05, what="the worker to go")


@pytest.mark.slow
def test_worker_and_scheduler_deaths(tmp_path):
    """One API on one cluster (starting them is most of the cost), two faults in turn."""
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"

    def cluster():
        # the second death of a worker running a task fails the task (default: the fourth)
        env = {"DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES": "1"}
        scheduler = start(dask_command("scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard",
                                       "--dashboard-address", "127.0.0.1:0"), log=tmp_path / "scheduler.log", env=env)
        return [scheduler, start(worker_command(address, "w"), log=tmp_path / "worker.log")]

    processes = cluster()
    try:
        wait_until(lambda: len(listening(processes[0].pid)) >= 2, what="the scheduler to listen (tcp, http)")
        assert {host for host, _ in listening(processes[0].pid)} == {"127.0.0.1"}  # its HTTP pages too
        # reconnection tried every second (5 s by default): the scheduler's return is seen sooner
        with running_service(tmp_path / "results", scheduler=address, log=tmp_path / "api.log",
                             env={"TUNNEL_CONTACT_RECONCILE_INTERVAL": "1"}) as url:
            repeated_worker_kill_fails_the_case_cleanly_and_retry_recomputes_it(url, address)
            for process in processes:  # the scheduler dies; a `dask worker` then exits (code 0)
                stop(process, sig=signal.SIGKILL)
            processes = work_queued_while_the_scheduler_is_gone_runs_when_it_returns(url, cluster)
    finally:
        for process in processes:
            stop(process)


def repeated_worker_kill_fails_the_case_cleanly_and_retry_recomputes_it(url: str, address: str) -> None:
    with Client(address, timeout=30) as dask:
        case_id = httpx.post(f"{url}/cases", json=SLOW, timeout=30).json()["id"]
        for _ in range(2):
            kill_worker_running(dask, task_key(case_id))
    failed = wait_until(lambda: status_of(url, case_id, "failed", "done"), what="the case to fail")
    assert failed["status"] == "failed", "the task finished before the second kill"
    # what happened and what to do, not dask's "KilledWorker: Attempted to run task ..."
    assert "worker process solving this case died" in failed["error"] and "retry=failed" in failed["error"]
    assert "tcp://" not in failed["error"] and "127.0.0.1" not in failed["error"]

    again = httpx.post(f"{url}/cases", json=SLOW, timeout=30).json()
    assert (again["status"], again["created"]) == ("failed", False)  # nothing recomputed unasked
    retried = httpx.post(f"{url}/cases", json=SLOW, params={"retry": "failed"}, timeout=30)
    assert retried.status_code == 202 and retried.json()["status"] == "queued"
    done = wait_until(lambda: status_of(url, case_id, "done", "failed"), what="the recomputed case")
    assert done["status"] == "done" and done["error"] is None
    assert httpx.get(f"{url}/cases/{case_id}/result.nc", timeout=30).status_code == 200


def work_queued_while_the_scheduler_is_gone_runs_when_it_returns(url: str, cluster) -> list:
    wait_until(lambda: httpx.get(f"{url}/health", timeout=30).status_code == 503, what="the API to notice")
    queued = httpx.post(f"{url}/cases", json=coarse_case(loads={"surface_load": 6.3e4}), timeout=30)
    assert queued.status_code == 202 and queued.json()["status"] == "queued"
    processes = cluster()  # what a supervisor with `restart: unless-stopped` does
    body = wait_until(lambda: status_of(url, queued.json()["id"], "done", "failed"), timeout=120,
                      what="the queued case after the scheduler came back")
    assert body["status"] == "done", body["error"]
    return processes
