"""How the dask worker processes of this workload are set up: one place for every way
they are started (the embedded LocalClusters of the CLI and the service, the ``dask
worker`` processes of :mod:`service.process` and of ``docker-compose.yml``).

glibc malloc. A dask nanny starts its worker with ``MALLOC_TRIM_THRESHOLD_=65536`` (to
hand freed memory back to the system quickly). Setting any malloc threshold also fixes
the mmap threshold at 128 KiB, so every array over 128 KiB is a fresh ``mmap`` whose pages
fault in on first touch and are unmapped when freed. A case allocates thousands of such
arrays (stresses at quadrature points, stage loads, netCDF buffers): measured case by case
(``python -m bench.sweep --per-case``), a stored default case on a shared model took
95 ms in a worker against 67 ms in a plain process. Arrays up to 32 MiB
now come from the heap, and only more than 128 MiB free at its top is returned.

Memory kept. With those thresholds glibc keeps what a case frees for the next one, and
over a long run the free bytes it keeps inside its arenas grew (``python -m bench.soak``:
heap in use flat at 150-280 MiB over 1 200 mixed cases, free bytes kept 60 -> 220 MiB,
RSS 410 -> 556 MiB in steps, never back). That is retention, not a leak: the bytes are
free, in holes between live blocks that ``MALLOC_TRIM_THRESHOLD_`` (the top of the heap
only) never returns. :func:`release_memory`, called after each case, hands whole free
pages back (``malloc_trim(0)``) once more than :data:`KEEP_FREE` bytes are kept.

Housekeeping. Beside its tasks every dask process does periodic work: its event loop
ticks every 20 ms (to notice a blocked loop, reported from 3 s on), the worker samples its
task thread's stack every 10 ms for the dashboard's profile page, and every process reads
its CPU and memory with psutil every 0.5 s (system monitor) and every 0.1 s (memory
monitor of workers and nannies). Idle, that cost each worker 0.42-0.49 s of CPU per 10 s
and the process holding the scheduler and the nannies 0.55-0.75 s (``python -m bench.sweep
--idle``): up to 8 % of this machine's two cores, taken from the tasks when both workers
solve. :data:`CLUSTER_CONFIG` ticks every 0.2 s, turns the profiler off (no dashboard shows
it here) and reads the system every 2 s and the memory every 0.5 s (a case's memory is
bounded before it starts, by the element cap): 0.06 s per worker and 0.15-0.18 s.

Start. dask starts a worker process by ``spawn``: a fresh interpreter that imports the solver and
the workflows again, 2-3 s of CPU each. An embedded LocalCluster made inside :func:`worker_config`
forks its workers from one server process per parent that imported :data:`WORKER_PRELOAD` once
(``forkserver``), and a worker its nanny restarts too; the nanny hands on the parent's environment
as it is when the cluster starts. The ``dask worker`` commands keep dask's own start (one worker a
command: a server would import as much as the worker it saves).
"""
from __future__ import annotations

import multiprocessing
import os
from contextlib import contextmanager
from typing import Iterator

import dask

#: Environment of every worker process, set by its nanny before the process starts.
WORKER_ENVIRON: dict[str, int] = {
    "MALLOC_MMAP_THRESHOLD_": 32 * 2**20,
    "MALLOC_TRIM_THRESHOLD_": 128 * 2**20,
}

#: dask settings of every process of the cluster (scheduler, nannies, workers).
CLUSTER_CONFIG: dict[str, object] = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.worker.memory.monitor-interval": "500ms",
    "distributed.admin.tick.interval": "200ms",
}

_PRE_SPAWN = "distributed.nanny.pre-spawn-environ"

#: Modules a worker process of an embedded LocalCluster starts with: its nannies fork it from a
#: server process that imported them once (``forkserver``) instead of starting a fresh
#: interpreter that imports them again (``spawn``, dask's default: 2-3 s of CPU a worker).
WORKER_PRELOAD: tuple[str, ...] = ("distributed", "workflows.tasks", "solver.run", "gmsh", "pymetis")
#: How an embedded cluster's nannies start workers: ``forkserver`` where the platform has it (Linux,
#: macOS), dask's own ``spawn`` elsewhere (Windows).
START_METHOD = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"

#: Free heap bytes a process keeps between cases before :func:`release_memory` returns them.
KEEP_FREE = 64 * 2**20
_LIBC = None


def _libc():
    """glibc with ``mallinfo2`` typed, or False where there is none (musl, macOS, old glibc)."""
    global _LIBC
    if _LIBC is None:
        import ctypes

        class MallInfo2(ctypes.Structure):
            _fields_ = [(name, ctypes.c_size_t) for name in
                        ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks",
                         "fordblks", "keepcost")]
        try:
            _LIBC = ctypes.CDLL("libc.so.6")
            _LIBC.mallinfo2.restype = MallInfo2
        except (OSError, AttributeError):
            _LIBC = False
    return _LIBC


def heap_stats() -> dict[str, int]:
    """glibc's heap of this process: bytes ``in_use`` (mmapped blocks included) and ``free``
    bytes it keeps in its arenas; empty where there is no glibc."""
    libc = _libc()
    if not libc:
        return {}
    info = libc.mallinfo2()
    return {"in_use": info.uordblks + info.hblkhd, "free": info.fordblks}


def release_memory(keep_free: int = KEEP_FREE) -> int:
    """Return free heap pages to the system when glibc keeps more than ``keep_free`` bytes
    free (``malloc_trim(0)``); the bytes it kept free, 0 where there is no glibc. Cheap
    when there is little to do (one walk of the arenas' statistics)."""
    free = heap_stats().get("free", 0)
    if free > keep_free:
        _libc().malloc_trim(0)
    return free


def _env_name(key: str) -> str:
    return "DASK_" + "__".join(part.upper().replace("-", "_") for part in key.split("."))


@contextmanager
def worker_config() -> Iterator[None]:
    """dask configuration in which a LocalCluster made inside runs with
    :data:`CLUSTER_CONFIG` and its nannies start workers with :data:`WORKER_ENVIRON` (on
    top of dask's own, e.g. one BLAS thread). The nannies hand the configuration on to
    their workers, and fork them from a server that has imported :data:`WORKER_PRELOAD`."""
    # dask lets a variable already in this process's environment win over its pre-spawn setting,
    # and a nanny leaves its own there (a plain LocalCluster's MALLOC_TRIM_THRESHOLD_=65536); the
    # fork server, started once, would keep such a value for every later worker: ours go first
    os.environ.update({name: str(value) for name, value in WORKER_ENVIRON.items()})
    fork = {} if START_METHOD != "forkserver" else {
        "distributed.worker.multiprocessing-method": START_METHOD,
        # a forked worker starts with its fork server's environment: its nanny hands on this
        # process's as it is now (a variable removed since stays set there)
        "distributed.nanny.environ": dict(os.environ)}
    with dask.config.set({**CLUSTER_CONFIG, **fork,
                          **{f"{_PRE_SPAWN}.{name}": value for name, value in WORKER_ENVIRON.items()}}):
        if fork:
            _preload_forkserver()
        yield


def _preload_forkserver() -> None:
    """Have this process's fork server (started with its first worker, kept for its life)
    import :data:`WORKER_PRELOAD`. dask names its own list on its first use of the context;
    ours replaces it (a superset in effect: the solver imports numpy, pandas, dask and the rest)."""
    from distributed.utils import get_mp_context

    get_mp_context()
    multiprocessing.get_context("forkserver").set_forkserver_preload(list(WORKER_PRELOAD))


def cluster_process_env() -> dict[str, str]:
    """Environment variables that give a ``dask scheduler`` command :data:`CLUSTER_CONFIG`."""
    return {_env_name(key): str(value) for key, value in CLUSTER_CONFIG.items()}


def worker_process_env() -> dict[str, str]:
    """Environment variables that give a ``dask worker`` command the same settings as
    :func:`worker_config` gives a LocalCluster."""
    return {**cluster_process_env(), _env_name(_PRE_SPAWN): repr(WORKER_ENVIRON)}
