"""Service settings, read once from the environment.

Environment variables
---------------------
``DASK_SCHEDULER_ADDRESS``
    Address of an external dask scheduler (``tcp://host:8786``). Unset: the
    service starts an embedded ``LocalCluster`` (one process per worker, one
    thread each).
``TUNNEL_CONTACT_RESULTS``
    Results directory (default ``./results``): case files, plots, combined
    sweep files and the job database ``jobs.sqlite``. Or an fsspec URL of object storage
    (``s3://bucket/prefix``): the results are objects there (:mod:`workflows.object_store`;
    endpoint and keys from ``AWS_ENDPOINT_URL``, ``AWS_ACCESS_KEY_ID``, ``AWS_SECRET_ACCESS_KEY`` or
    ``TUNNEL_CONTACT_STORAGE_OPTIONS``, JSON), worked on in a local cache folder
    (``TUNNEL_CONTACT_CACHE``, default under ``~/.cache/tunnel-contact``), where ``jobs.sqlite``
    then lives unless ``TUNNEL_CONTACT_DATABASE`` says otherwise.
``TUNNEL_CONTACT_DATABASE``
    SQLAlchemy URL of the job records (default: the SQLite file ``jobs.sqlite`` in the results
    directory, one API process). ``postgresql://user:password@host/db``: PostgreSQL, shared by
    any number of API replicas (:mod:`service.shared_records`).
``TUNNEL_CONTACT_REPLICA_TTL``
    Seconds after which a replica that stopped beating counts as gone and its open cases and
    drivers are taken over by the others (default 10; PostgreSQL only).
``TUNNEL_CONTACT_RECONCILE_INTERVAL``
    Seconds between two reconciliations of the open records with the store (default 5).
``TUNNEL_CONTACT_HOST`` / ``TUNNEL_CONTACT_PORT``
    Bind address (default ``127.0.0.1:8000``; loopback unless asked otherwise).
``TUNNEL_CONTACT_ALLOWED_HOSTS``
    Comma-separated host names (or addresses) the service answers to, checked against every
    request's ``Host`` header (a page of another site that rebinds its own name to this
    machine's address sends its own name and is refused, 400). Default: the loopback names
    ``localhost``, ``127.0.0.1`` and ``::1`` (and the address bound to, unless a wildcard); add the name clients use behind a proxy or on a
    network (``api.example.org``), a leading ``*.`` for a whole domain, or ``*`` for any.
``TUNNEL_CONTACT_TOKEN``
    When set, every ``POST`` needs ``Authorization: Bearer <token>`` (or HTTP basic
    authentication with the token as the password, any user name).
``TUNNEL_CONTACT_TOKEN_READS``
    ``1`` (with a token): every request but ``/health`` needs the token too, results and
    pages included. A browser asks for it (HTTP basic authentication: any user name,
    the token as the password) and sends it with every later request of the dashboard.
``TUNNEL_CONTACT_MAX_BODY_BYTES`` / ``TUNNEL_CONTACT_MAX_SWEEP_CASES``
    Request body cap (default 1 MiB) and sweep size cap (default 4096 cases: the README's
    1 024-case Sobol' study fits, and a 4 096-point one).
``TUNNEL_CONTACT_LOCAL_WORKERS``
    Worker processes of the embedded cluster (default: one per CPU).
``TUNNEL_CONTACT_MAX_OPEN_CASES``
    Queued plus running cases above which a submission is refused with 429 and
    ``Retry-After`` (default 10000).
``TUNNEL_CONTACT_ACCESS_LOG``
    ``1``: log every request (uvicorn's access log, to standard output). Off by default:
    at load it cost a fifth of the API's CPU (``bench/service.py``: 800 against 970
    requests/s, p99 45–54 against 36–41 ms); the proxy in front usually keeps that log.
``TUNNEL_CONTACT_MIN_FREE_BYTES``
    Free space the results directory needs to take cases (default 32 MiB, the size of
    the largest result the element cap allows); below it submissions get 503 and
    ``/health`` is degraded.
"""
from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path
from typing import Mapping, Optional, Union

from pydantic import BaseModel, ConfigDict, Field, field_validator

#: Host names a service answers to unless told otherwise: this machine's loopback.
LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1")
from workflows.object_store import cache_folder, is_url

from .database import is_sqlite, sqlite_path

#: Environment variable for each settings field.
ENVIRONMENT = {
    "scheduler": "DASK_SCHEDULER_ADDRESS",
    "results": "TUNNEL_CONTACT_RESULTS",
    "database_url": "TUNNEL_CONTACT_DATABASE",
    "replica_ttl": "TUNNEL_CONTACT_REPLICA_TTL",
    "reconcile_interval": "TUNNEL_CONTACT_RECONCILE_INTERVAL",
    "host": "TUNNEL_CONTACT_HOST",
    "port": "TUNNEL_CONTACT_PORT",
    "allowed_hosts": "TUNNEL_CONTACT_ALLOWED_HOSTS",
    "token": "TUNNEL_CONTACT_TOKEN",
    "token_reads": "TUNNEL_CONTACT_TOKEN_READS",
    "max_body_bytes": "TUNNEL_CONTACT_MAX_BODY_BYTES",
    "max_sweep_cases": "TUNNEL_CONTACT_MAX_SWEEP_CASES",
    "local_workers": "TUNNEL_CONTACT_LOCAL_WORKERS",
    "max_open_cases": "TUNNEL_CONTACT_MAX_OPEN_CASES",
    "min_free_bytes": "TUNNEL_CONTACT_MIN_FREE_BYTES",
    "access_log": "TUNNEL_CONTACT_ACCESS_LOG",
}


class Settings(BaseModel):
    """Everything the service needs to know about its surroundings."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    scheduler: Optional[str] = Field(None, description="external dask scheduler address; None: embedded cluster")
    results: Union[Path, str] = Field(Path("results"), description="results directory (case files and job "
                                                                    "database), or an fsspec URL (s3://bucket/prefix)")
    database_url: Optional[str] = Field(None, description="SQLAlchemy URL of the job records; None: jobs.sqlite "
                                                          "in the results directory")
    replica_ttl: float = Field(10.0, gt=0, description="seconds of silence after which a replica's cases and "
                                                        "drivers are taken over (shared database only)")
    host: str = Field("127.0.0.1", description="bind address")
    port: int = Field(8000, ge=0, le=65535, description="bind port")
    allowed_hosts: tuple[str, ...] = Field(LOOPBACK_NAMES, description="host names the service answers to "
                                           "(the Host header; '*.domain' for a domain, '*' for any)")
    token: Optional[str] = Field(None, description="bearer token required on POST; None: no authentication")
    token_reads: bool = Field(False, description="the token protects every request but /health (results, "
                                                 "pages), not only POSTs")
    max_body_bytes: int = Field(1 << 20, gt=0, description="largest accepted request body (bytes)")
    max_sweep_cases: int = Field(4096, gt=0, description="largest sweep (cases) accepted")
    local_workers: Optional[int] = Field(None, gt=0, description="embedded cluster worker processes")
    poll_interval: float = Field(0.5, gt=0, description="seconds between scheduler polls for running tasks")
    reconcile_interval: float = Field(5.0, gt=0, description="seconds between record/store reconciliations")
    max_open_cases: int = Field(10_000, gt=0, description="queued + running cases above which POST answers 429")
    retry_after: int = Field(30, gt=0, description="seconds a client is told to wait after a 429")
    min_free_bytes: int = Field(32 << 20, ge=0, description="free space (bytes) needed to accept cases: "
                                                            "about the largest result the element cap allows")

    access_log: bool = Field(False, description="log every request (uvicorn's access log)")

    @field_validator("allowed_hosts", mode="before")
    @classmethod
    def _host_list(cls, value):
        """A comma-separated list (the environment's form) as names, lower case, without blanks."""
        if isinstance(value, str):
            value = value.split(",")
        return tuple(str(v).strip().lower() for v in value if str(v).strip())
    @field_validator("results", mode="before")
    @classmethod
    def _path_unless_url(cls, value):
        return value if is_url(value) else Path(value)

    @property
    def results_folder(self) -> Path:
        """The folder the results are worked on in: the results directory, or the local cache of
        a store on object storage."""
        return cache_folder(self.results) if is_url(self.results) else self.results

    @property
    def database(self) -> Path:
        """The SQLite job database (default: inside the results directory)."""
        return sqlite_path(self.database_url if is_sqlite(self.database_url) else None, self.results_folder)

    @property
    def shared_database(self) -> bool:
        """Whether the job records are in a server database (PostgreSQL) replicas share."""
        return not is_sqlite(self.database_url)

    @classmethod
    def from_env(cls, environ: Mapping[str, str] | None = None, **overrides) -> "Settings":
        """Settings from environment variables, then keyword overrides (``None`` ignored).

        Empty variables count as unset.
        """
        environ = os.environ if environ is None else environ
        values = {field: environ[var] for field, var in ENVIRONMENT.items() if environ.get(var)}
        values.update({k: v for k, v in overrides.items() if v is not None})
        return cls(**values)


@lru_cache
def get_settings() -> Settings:
    """The process-wide settings (cached; tests override via ``create_app(settings)``)."""
    return Settings.from_env()
