"""Run the service with uvicorn (what ``tunnel-contact serve`` calls; ``python -m service.server``
serves with the settings of the environment, as ``tunnel-contact serve`` does)."""
from __future__ import annotations

import logging
from pathlib import Path
from typing import Optional

import uvicorn

from .app import create_app
from .settings import Settings

logger = logging.getLogger(__name__)


#: Open files the API asks for at start: every idle client socket holds one, and the common
#: default soft limit (1 024) let about 1 200 idle connections stop /health (issue 24).
OPEN_FILES = 65536


def raise_open_files_limit(wanted: int = OPEN_FILES) -> int:
    """Raise this process's soft limit of open files towards ``wanted`` (at most the hard
    limit, which needs no privilege); return the limit in force."""
    import resource

    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    target = wanted if hard == resource.RLIM_INFINITY else min(wanted, hard)
    if soft != resource.RLIM_INFINITY and soft < target:
        try:
            resource.setrlimit(resource.RLIMIT_NOFILE, (target, hard))
            soft = target
        except (ValueError, OSError) as exc:
            logger.warning("could not raise the open-files limit from %d to %d: %s", soft, target, exc)
    logger.info("open-files limit %s", soft)
    return soft


def serve(*, host: Optional[str] = None, port: Optional[int] = None, scheduler: Optional[str] = None,
          results: str | Path | None = None, token: Optional[str] = None,
          access_log: Optional[bool] = None) -> None:
    """Serve the API until interrupted.

    Parameters
    ----------
    host, port : bind address; None: ``TUNNEL_CONTACT_HOST`` / ``TUNNEL_CONTACT_PORT`` or
        127.0.0.1:8000 (loopback unless asked otherwise).
    scheduler : dask scheduler address; None: ``DASK_SCHEDULER_ADDRESS`` or an embedded cluster.
    results : results directory; None: ``TUNNEL_CONTACT_RESULTS`` or ``./results``.
    token : bearer token required on POST; None: ``TUNNEL_CONTACT_TOKEN`` (or none).
    access_log : log every request; None: ``TUNNEL_CONTACT_ACCESS_LOG`` (or off).
    """
    settings = Settings.from_env(host=host, port=port, scheduler=scheduler, results=results, token=token,
                                 access_log=access_log)
    raise_open_files_limit()
    logger.info("serving on http://%s:%d", settings.host, settings.port)
    uvicorn.run(create_app(settings), host=settings.host, port=settings.port, log_level="info",
                access_log=settings.access_log)


if __name__ == "__main__":
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    serve()
