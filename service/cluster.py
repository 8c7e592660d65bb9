"""Where the dask client comes from: an external scheduler or an embedded LocalCluster."""
from __future__ import annotations

import logging
from contextlib import asynccontextmanager
from typing import AsyncIterator, Awaitable, Callable

from distributed import Client, LocalCluster

from workflows.workers import worker_config

from .settings import Settings

logger = logging.getLogger(__name__)

#: Seconds to wait for an external scheduler before starting degraded (and retrying).
CONNECT_TIMEOUT = 5.0


@asynccontextmanager
async def cluster_connection(settings: Settings) -> AsyncIterator[Callable[[], Awaitable[Client]]]:
    """Yield a coroutine function that connects an asynchronous ``Client``.

    With ``settings.scheduler`` the client connects there; otherwise a LocalCluster
    (worker processes, one thread each, no dashboard) lives as long as this context.
    """
    if settings.scheduler:
        address = settings.scheduler

        async def connect() -> Client:
            return await Client(address, asynchronous=True, timeout=CONNECT_TIMEOUT)

        logger.info("using the dask scheduler at %s", address)
        yield connect
        return

    # the settings held for the cluster's life: a worker its nanny starts again (after a crash or a
    # kill) is forked from the same preloaded server as the first ones, not spawned and imported anew
    with worker_config():
        cluster = await LocalCluster(n_workers=settings.local_workers, processes=True,
                                     threads_per_worker=1, dashboard_address=None, asynchronous=True)
        logger.info("embedded dask cluster at %s with %d workers",
                    cluster.scheduler_address, len(cluster.workers))

        async def connect() -> Client:
            return await Client(cluster, asynchronous=True)

        try:
            yield connect
        finally:
            await cluster.close()
