"""Worker processes get the malloc settings and dask configuration of
:mod:`workflows.workers`, however they are started, and those settings do what they are
for: a freed array's pages are reused, and the dask processes' housekeeping is lighter."""
from __future__ import annotations

import json
import os
import sys
import resource
from pathlib import Path

import cloudpickle
import dask.config
import pytest
import yaml
from dask.utils import parse_timedelta
from distributed import Client

from service.process import running_cluster
from workflows.sweep import local_client
from workflows.workers import CLUSTER_CONFIG, WORKER_ENVIRON, WORKER_PRELOAD, cluster_process_env, worker_process_env

ROOT = Path(__file__).resolve().parents[2]

# the probes below run on workers that cannot import this test module
cloudpickle.register_pickle_by_value(sys.modules[__name__])


def malloc_environ() -> dict[str, str]:
    return {k: os.environ.get(k) for k in WORKER_ENVIRON}


def cluster_config() -> dict[str, object]:
    """The :data:`CLUSTER_CONFIG` keys as this process's dask configuration has them."""
    return {k: dask.config.get(k) for k in CLUSTER_CONFIG}


def profiler_running(dask_worker) -> bool:
    """Whether the worker's statistical profiler samples its task thread (dask adds a
    periodic callback for it when profiling is on)."""
    return "profile" in dask_worker.periodic_callbacks


def system_monitor_interval_ms(dask_scheduler) -> float:
    return dask_scheduler.periodic_callbacks["monitor"].callback_time


def tick_interval_ms(dask_worker) -> float:
    return dask_worker.periodic_callbacks["tick"].callback_time


#: Bytes of each probe array: over glibc's default mmap threshold (128 KiB), under the 4 MiB
#: from which NumPy asks for transparent huge pages (2 faults instead of 1024 when the
#: kernel has them to give, which made the count depend on memory fragmentation).
PROBE = 2**20
PAGES = PROBE // 4096


def page_faults_of_reused_arrays(n: int = 40, size: int = PROBE) -> int:
    """Minor page faults while allocating, touching and freeing a ``size``-byte array
    ``n`` times: about ``n * size / 4096`` if every array is a fresh mmap, few if the
    heap reuses the first one's pages."""
    import numpy as np

    np.ones(size // 8).sum()  # the first one may fault in
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(n):
        np.ones(size // 8).sum()
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before


@pytest.fixture(autouse=True)
def parent_without_malloc_settings(monkeypatch):
    """A nanny copies its pre-spawn environment into its own process (distributed's
    ``os.environ.update``), and a variable set there overrides the configuration for the
    next nanny: start each test from a process without them."""
    for name in WORKER_ENVIRON:
        monkeypatch.delenv(name, raising=False)


def expected() -> dict[str, str]:
    return {k: str(v) for k, v in WORKER_ENVIRON.items()}


def settings_seen(client) -> dict:
    """What one worker and the scheduler of ``client``'s cluster run with."""
    seen = {}
    for probe in (malloc_environ, cluster_config, profiler_running, tick_interval_ms):
        (seen[probe.__name__],) = client.run(probe).values()
    seen["system_monitor_interval_ms"] = client.run_on_scheduler(system_monitor_interval_ms)
    return seen


def ms(key: str) -> float:
    """A :data:`CLUSTER_CONFIG` interval in milliseconds."""
    return 1000 * parse_timedelta(CLUSTER_CONFIG[key])


OURS = {"malloc_environ": expected(), "cluster_config": CLUSTER_CONFIG, "profiler_running": False,
        "tick_interval_ms": ms("distributed.admin.tick.interval"),
        "system_monitor_interval_ms": ms("distributed.admin.system-monitor.interval")}


def test_local_cluster_workers():
    with local_client(1) as client:
        seen = settings_seen(client)
        (faults,) = client.run(page_faults_of_reused_arrays).values()
    assert seen == OURS
    assert faults < 40 * PAGES / 10, f"{faults} page faults: freed arrays are not reused"


def test_dask_worker_processes(tmp_path):
    """The ``dask scheduler`` and ``dask worker`` command lines of the deployment (service.process)."""
    with running_cluster(1, logs=tmp_path) as address, Client(address, timeout=30) as client:
        client.wait_for_workers(1, timeout=60)
        assert settings_seen(client) == OURS


def test_dask_defaults_profile_and_monitor_more_often():
    """Guards the tests above: without the settings a worker profiles, the scheduler
    reads the system every 0.5 s."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        seen = settings_seen(client)
    assert seen["profiler_running"]
    assert (seen["system_monitor_interval_ms"], seen["tick_interval_ms"]) == (500, 20)
    assert all(seen[k] != OURS[k] for k in ("profiler_running", "tick_interval_ms", "system_monitor_interval_ms"))


def test_without_the_settings_a_worker_faults_every_array():
    """What the settings fix: dask's own default (MALLOC_TRIM_THRESHOLD_ alone) maps a
    fresh array every time. (Guards the test above against passing for another reason.)"""
    with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": 65536}):
        from distributed import LocalCluster

        with LocalCluster(n_workers=1, threads_per_worker=1, dashboard_address=None) as cluster, \
                Client(cluster) as client:
            (environ,) = client.run(malloc_environ).values()
            (faults,) = client.run(page_faults_of_reused_arrays).values()
    assert environ == {"MALLOC_TRIM_THRESHOLD_": "65536", "MALLOC_MMAP_THRESHOLD_": None}
    assert faults > 40 * PAGES / 2, faults


def test_compose_workers_and_scheduler_get_the_same_environment():
    compose = yaml.safe_load((ROOT / "docker-compose.yml").read_text())
    every = compose["services"]["worker"]["environment"]
    environment = {k: v for k, v in every.items() if k.startswith("DASK_")}
    assert environment == worker_process_env()
    # the rest: where the results and the job records are, as the API replicas see them
    api = compose["services"]["api"]["environment"]
    assert {k: v for k, v in every.items() if not k.startswith("DASK_")} == {
        k: v for k, v in api.items() if k.startswith(("TUNNEL_CONTACT_RESULTS", "TUNNEL_CONTACT_DATABASE", "AWS_"))}
    assert compose["services"]["scheduler"]["environment"] == cluster_process_env()
    # and dask reads it as the same mapping
    parsed = dask.config.collect_env(environment)
    assert dask.config.get("distributed.nanny.pre-spawn-environ", config=parsed) == WORKER_ENVIRON
    assert {k: dask.config.get(k, config=parsed) for k in CLUSTER_CONFIG} == {
        k: v if isinstance(v, bool) else str(v) for k, v in CLUSTER_CONFIG.items()}


def test_free_heap_kept_by_the_workers_settings_goes_back_after_a_case(tmp_path):
    """Issue 24 (worker memory): with the workers' malloc thresholds, memory a case frees in
    the middle of the heap stays in the process (RSS grew 410 -> 556 MiB over 1 200 cases in
    ``bench.soak`` while the heap in use stayed flat). release_memory hands it back."""
    import subprocess
    import textwrap

    from workflows.workers import WORKER_ENVIRON

    code = textwrap.dedent("""
        import json, psutil
        import numpy as np
        from workflows.workers import release_memory
        rss = lambda: psutil.Process().memory_info().rss
        big, keep = [], []
        for k in range(300):  # 300 MiB of arrays freed later, with small live arrays between them
            big.append(np.ones(1 << 17))
            keep.append(np.ones(1 << 13))  # 64 KiB: too big for the holes imports left
        del big
        before = rss()
        kept = release_memory()
        print(json.dumps({"kept": kept, "before": before, "after": rss(), "again": release_memory()}))
    """)
    env = {**os.environ, **{k: str(v) for k, v in WORKER_ENVIRON.items()},
           "PYTHONPATH": str(Path(__file__).parents[2])}
    out = json.loads(subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                                    check=True).stdout)
    assert out["kept"] > 250 * 2**20  # freed, yet kept by the allocator
    assert out["before"] - out["after"] > 250 * 2**20  # and returned
    assert out["again"] < out["kept"]


def imported_at_start() -> dict[str, bool]:
    """Which of the preloaded modules the worker process has (no task has run on it)."""
    from workflows.workers import WORKER_PRELOAD

    return {name: name in sys.modules for name in WORKER_PRELOAD}


def environ_value() -> str | None:
    return os.environ.get("TUNNEL_CONTACT_TEST_PROBE")


def test_embedded_workers_start_with_the_solver_imported_and_this_process_environment(monkeypatch):
    """An embedded cluster's workers are forked from a server that imported the solver once
    (a spawned worker has none of it before its first task), and still see this process's
    environment as it is when the cluster starts, not as it was when the server started."""
    seen = []
    for value in ("first", "second"):
        monkeypatch.setenv("TUNNEL_CONTACT_TEST_PROBE", value)
        with local_client(2) as client:
            seen.append((list(client.run(imported_at_start).values()), set(client.run(environ_value).values())))
    everything = {name: True for name in WORKER_PRELOAD}
    assert seen == [([everything] * 2, {"first"}), ([everything] * 2, {"second"})]


def test_the_service_restarts_a_killed_embedded_worker_from_the_preloaded_server(tmp_path):
    """The service's embedded cluster holds :func:`worker_config` for its life: a worker killed
    (SIGKILL) is started again by its nanny as a fork of the preloaded server (a spawned one would
    have none of the solver's modules before its first task)."""
    import asyncio
    import signal

    from service.cluster import cluster_connection
    from service.settings import Settings

    async def kill_one_and_probe() -> tuple[int, int, dict]:
        async with cluster_connection(Settings(results=tmp_path, local_workers=1)) as connect:
            client = await connect()
            try:
                (before,) = (await client.run(os.getpid)).values()
                os.kill(before, signal.SIGKILL)
                after = before
                for _ in range(300):  # the nanny notices and starts another (up to 30 s)
                    await asyncio.sleep(0.1)
                    try:
                        pids = list((await client.run(os.getpid)).values())
                    except Exception:  # the dead worker is still listed for a moment
                        continue
                    if pids and pids[0] != before:
                        after = pids[0]
                        break
                (seen,) = (await client.run(imported_at_start)).values()
                return before, after, seen
            finally:
                await client.close()

    before, after, seen = asyncio.run(kill_one_and_probe())
    assert after != before
    assert seen == {name: True for name in WORKER_PRELOAD}


def test_without_a_fork_server_the_workers_are_spawned_as_dask_does(monkeypatch):
    """Where the platform has no ``forkserver`` (Windows), :func:`worker_config` leaves dask's own
    start method and environment hand-over alone; with one, it asks for the fork server."""
    from workflows import workers

    with workers.worker_config():
        assert dask.config.get("distributed.worker.multiprocessing-method") == "forkserver"
        assert dask.config.get("distributed.nanny.environ")["PATH"] == os.environ["PATH"]
    monkeypatch.setattr(workers, "START_METHOD", "spawn")
    with workers.worker_config():
        assert dask.config.get("distributed.worker.multiprocessing-method") == "spawn"
        assert dask.config.get("distributed.nanny.environ") == {}
        assert dask.config.get("distributed.admin.tick.interval") == CLUSTER_CONFIG["distributed.admin.tick.interval"]
