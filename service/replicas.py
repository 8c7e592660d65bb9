"""One API replica among others on a shared database: its heartbeat and the leases it holds.

Each process is one row of ``replicas`` (a random id), its ``heartbeat_at`` renewed every
:data:`HEARTBEAT` seconds by a thread of its own; one silent for ``ttl`` (default :data:`TTL`)
counts as dead (:meth:`Replica.live` no longer lists it) and the others take over its open cases
(:class:`service.shared_records.SharedJobStore`) and its leases: a lease row names the one
replica that may run a driver (a search, a reliability study) until it expires; the others look for
drivers to take over every :data:`ADOPT_INTERVAL` seconds (:func:`adopt_orphans`).
"""
from __future__ import annotations

import asyncio
import logging
import threading
import time
import uuid
from typing import Optional

import sqlalchemy as sa
from sqlalchemy.dialects import postgresql, sqlite

from .database import engine_url, migrate

logger = logging.getLogger(__name__)

#: Seconds between a replica's heartbeats, and after which a silent replica counts as dead.
HEARTBEAT = 1.0
TTL = 10.0
#: Seconds after which the row of a replica long gone is deleted (by the next replica to start).
FORGET_AFTER = 86400.0
#: Seconds between looks for drivers (searches, reliability studies) whose replica has gone.
ADOPT_INTERVAL = 5.0


async def adopt_orphans(records, start, what: str, interval: float = ADOPT_INTERVAL) -> None:
    """Every ``interval`` seconds, ``start`` each of ``records()`` (read in a thread): ``start`` drives a
    running record here where its lease is free, so one whose driver's replica died (its lease expired)
    is taken over. Errors are logged and the loop goes on."""
    while True:
        await asyncio.sleep(interval)
        try:
            for record in await asyncio.to_thread(records):
                start(record)
        except Exception as exc:
            logger.warning("looking for %s to drive failed (%s: %s)", what, type(exc).__name__, exc)


metadata = sa.MetaData()
replicas = sa.Table("replicas", metadata, sa.Column("id", sa.Text, primary_key=True),
                    sa.Column("started_at", sa.Float), sa.Column("heartbeat_at", sa.Float))
leases = sa.Table("leases", metadata, sa.Column("name", sa.Text, primary_key=True), sa.Column("owner", sa.Text),
                  sa.Column("expires_at", sa.Float))


class Replica:
    """This process as a replica on the database at the SQLAlchemy URL ``url`` (its schema
    migrated by Alembic first): ``replica`` is its id (default: a new one)."""

    def __init__(self, url: str, *, replica: Optional[str] = None, ttl: float = TTL,
                 heartbeat: float = HEARTBEAT, **_options):
        self.url = url
        self.replica = replica or uuid.uuid4().hex[:12]
        self.ttl = ttl
        self.engine = sa.create_engine(engine_url(url), pool_pre_ping=True, pool_size=5, max_overflow=10)
        self._insert = postgresql.insert if self.engine.dialect.name == "postgresql" else sqlite.insert
        migrate(self.engine)
        with self.engine.begin() as db:
            now = time.time()
            db.execute(replicas.delete().where(replicas.c.heartbeat_at < now - FORGET_AFTER))
            db.execute(self._insert(replicas).values(id=self.replica, started_at=now, heartbeat_at=now)
                       .on_conflict_do_update(index_elements=["id"], set_={"heartbeat_at": now}))
        self._stopping = threading.Event()
        self._beating = threading.Thread(target=self._beat, args=(heartbeat,), daemon=True,
                                         name=f"heartbeat {self.replica}")
        self._beating.start()

    def __repr__(self) -> str:
        url = self.engine.url.render_as_string(hide_password=True)
        return f"{type(self).__name__}({url!r}, replica={self.replica!r})"

    def _beat(self, interval: float) -> None:
        while not self._stopping.wait(interval):
            try:
                self.heartbeat()
            except sa.exc.SQLAlchemyError as exc:  # the database away for a while: beat again later
                logger.warning("replica heartbeat failed (%s)", exc)

    def heartbeat(self) -> None:
        with self.engine.begin() as db:
            db.execute(replicas.update().where(replicas.c.id == self.replica).values(heartbeat_at=time.time()))

    def live(self) -> sa.Select:
        """Ids of the replicas heard from within ``ttl``."""
        return sa.select(replicas.c.id).where(replicas.c.heartbeat_at > time.time() - self.ttl)

    def close(self) -> None:
        self._stopping.set()
        self._beating.join()
        try:  # leave at once: the other replicas take this one's open cases in their next round
            with self.engine.begin() as db:
                db.execute(replicas.update().where(replicas.c.id == self.replica).values(heartbeat_at=0.0))
                db.execute(leases.delete().where(leases.c.owner == self.replica))
        except sa.exc.SQLAlchemyError as exc:
            logger.warning("could not sign replica %s off (%s)", self.replica, exc)
        self.engine.dispose()

    def writable(self) -> bool:
        try:
            with self.engine.begin() as db:
                db.execute(sa.select(1))
            return True
        except sa.exc.SQLAlchemyError:
            return False

    # -- leases --------------------------------------------------------------------------

    def take_lease(self, name: str, seconds: float | None = None) -> bool:
        """Hold (or renew) the lease ``name`` for ``seconds`` (default ``ttl``) if it is free,
        expired or already this replica's; True if this replica holds it now."""
        now = time.time()
        until = now + (seconds or self.ttl)
        statement = (self._insert(leases).values(name=name, owner=self.replica, expires_at=until)
                     .on_conflict_do_update(index_elements=["name"], set_={"owner": self.replica, "expires_at": until},
                                            where=(leases.c.owner == self.replica) | (leases.c.expires_at < now)))
        with self.engine.begin() as db:
            db.execute(statement)
            return db.execute(sa.select(leases.c.owner).where(leases.c.name == name)).scalar() == self.replica

    def release_lease(self, name: str) -> None:
        with self.engine.begin() as db:
            db.execute(leases.delete().where((leases.c.name == name) & (leases.c.owner == self.replica)))


