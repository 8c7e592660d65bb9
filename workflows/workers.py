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
"""
from __future__ import annotations

from contextlib import contextmanager
from typing import Iterator

import dask

#: Environment of every worker process, set by its nanny before the process starts.
WORKER_ENVIRON: dict[str, int] = {
    "MALLOC_MMAP_THRESHOLD_": 32 * 2**20,
    "MALLOC_TRIM_THRESHOLD_": 128 * 2**20,
}

_PRE_SPAWN = "distributed.nanny.pre-spawn-environ"


@contextmanager
def worker_config() -> Iterator[None]:
    """dask configuration in which nannies (of a LocalCluster made inside) start workers
    with :data:`WORKER_ENVIRON` (on top of dask's own, e.g. one BLAS thread)."""
    with dask.config.set({f"{_PRE_SPAWN}.{name}": value for name, value in WORKER_ENVIRON.items()}):
        yield


def worker_process_env() -> dict[str, str]:
    """Environment variables that give a ``dask worker`` command the same setting."""
    return {"DASK_DISTRIBUTED__NANNY__PRE_SPAWN_ENVIRON": repr(WORKER_ENVIRON)}
