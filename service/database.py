"""Where the job records live and bringing their schema up to date.

``TUNNEL_CONTACT_DATABASE`` is a SQLAlchemy URL: unset, the records are the SQLite file
``jobs.sqlite`` in the results folder (:class:`service.job_records.JobStore`, one process);
``postgresql://…`` (or ``postgresql+psycopg://…``) puts them in PostgreSQL, which several API
replicas share (:class:`service.shared_records.SharedJobStore`). Either way the schema is
migrated by Alembic at start (:func:`migrate`; the revisions are :mod:`service.migrations`).
"""
from __future__ import annotations

import logging
import sqlite3
from contextlib import nullcontext
from pathlib import Path
from typing import Optional

import sqlalchemy as sa
from sqlalchemy.engine import make_url

logger = logging.getLogger(__name__)

#: The newest schema revision (:mod:`service.migrations.versions`).
HEAD = "0003"
_MIGRATIONS = Path(__file__).with_name("migrations")


def engine_url(url: str) -> sa.URL:
    """``url`` as SQLAlchemy takes it; a bare ``postgresql://`` goes through psycopg (3)."""
    parsed = make_url(url)
    if parsed.drivername == "postgresql":
        parsed = parsed.set(drivername="postgresql+psycopg")
    return parsed


def is_sqlite(url: Optional[str]) -> bool:
    return url is None or make_url(url).get_backend_name() == "sqlite"


def sqlite_path(url: Optional[str], results: Path) -> Path:
    """The SQLite file of ``url`` (None: ``jobs.sqlite`` in ``results``)."""
    if url is None:
        return Path(results) / "jobs.sqlite"
    database = make_url(url).database
    if not database or database == ":memory:":
        raise ValueError(f"TUNNEL_CONTACT_DATABASE={url!r}: a SQLite database must be a file")
    return Path(database)


def migrate(connectable: sa.Engine | sa.Connection) -> None:
    """Upgrade the schema of the job records to :data:`HEAD` (Alembic, programmatically).

    Every process starting on the records calls this; on PostgreSQL an advisory lock keeps two
    replicas starting at once from migrating together."""
    from alembic import command
    from alembic.config import Config

    config = Config()
    config.set_main_option("script_location", str(_MIGRATIONS))
    engine = connectable if isinstance(connectable, sa.Engine) else None
    with (engine.connect() if engine is not None else nullcontext(connectable)) as connection:
        if connection.dialect.name == "postgresql":
            connection.exec_driver_sql("SELECT pg_advisory_lock(424242)")
            connection.commit()
        try:
            config.attributes["connection"] = connection
            command.upgrade(config, "head")
            connection.commit()
        finally:
            if connection.dialect.name == "postgresql":
                connection.exec_driver_sql("SELECT pg_advisory_unlock(424242)")
                connection.commit()


def migrate_sqlite(path: Path) -> None:
    """:func:`migrate` the SQLite file ``path`` (made if missing), unless it is at :data:`HEAD`
    already (one read, no Alembic). SQLite's own errors come out as they are (``file is not a
    database``: the caller moves a damaged file aside)."""
    db = sqlite3.connect(path, timeout=30)
    try:
        if db.execute("SELECT version_num FROM alembic_version").fetchone() == (HEAD,):
            return
    except sqlite3.OperationalError as exc:
        if "no such table" not in str(exc):
            raise
    finally:
        db.close()
    engine = sa.create_engine(f"sqlite:///{Path(path).resolve()}", poolclass=sa.pool.NullPool,
                              connect_args={"timeout": 30, "isolation_level": None})

    # SQLite's own transactions (SQLAlchemy's recipe for pysqlite): every migration in one, so the
    # tables of a new file cost one sync of the disk, not one per statement
    @sa.event.listens_for(engine, "begin")
    def _begin(connection):
        connection.exec_driver_sql("BEGIN IMMEDIATE")

    try:
        migrate(engine)
    except sa.exc.DBAPIError as exc:
        raise exc.orig from exc
    finally:
        engine.dispose()
