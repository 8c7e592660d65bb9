"""Job records in a database several API replicas share (PostgreSQL; any SQLAlchemy URL works).

The same records and queries as :class:`service.job_records.JobStore` (the one-process SQLite
file), in SQLAlchemy Core over a connection pool, plus what replicas need to share them:

Replicas
    Each process is a :class:`service.replicas.Replica`: a heartbeat row, dead once silent
    for ``ttl`` seconds.
Claims
    An open case (``queued``, ``running``) is submitted and watched by one replica, its
    ``claimed_by``: the one that accepted it, else the one that claimed it in a reconciliation
    (:meth:`SharedJobStore.open_case_ids`: the unclaimed open cases and those of dead replicas,
    locked with ``FOR UPDATE SKIP LOCKED`` so two replicas reconciling at once never take the
    same row). A replica SIGKILLed midway thus leaves its cases to the next replica's round
    once its heartbeat is ``ttl`` old; the dask task keys are per case, so the new owner
    attaches to a task still on the scheduler instead of running the case twice.
Leases
    A driver (a search) runs in the replica that holds the lease row named after it
    (:meth:`service.replicas.Replica.take_lease`), renewed while it drives, taken over once expired.
"""
from __future__ import annotations

import json
import time
from typing import Iterable, Optional, Sequence

import sqlalchemy as sa

from .job_records import CaseRecord, SweepRecord, _case, _sweep
from .job_tables import STATUSES
from .replicas import Replica

metadata = sa.MetaData()
cases = sa.Table(
    "cases", metadata,
    sa.Column("id", sa.Text, primary_key=True), sa.Column("spec", sa.Text), sa.Column("status", sa.Text),
    sa.Column("summary", sa.Text), sa.Column("error", sa.Text), sa.Column("submitted_at", sa.Float),
    sa.Column("started_at", sa.Float), sa.Column("finished_at", sa.Float), sa.Column("submissions", sa.Integer),
    sa.Column("warnings", sa.Text), sa.Column("claimed_by", sa.Text), sa.Column("room", sa.Integer))
sweeps = sa.Table("sweeps", metadata, sa.Column("id", sa.Text, primary_key=True), sa.Column("name", sa.Text),
                  sa.Column("spec", sa.Text), sa.Column("submitted_at", sa.Float))
sweep_cases = sa.Table("sweep_cases", metadata, sa.Column("sweep_id", sa.Text), sa.Column("position", sa.Integer),
                       sa.Column("case_id", sa.Text))

OPEN = ("queued", "running")


class SharedJobStore(Replica):
    """The job records at the SQLAlchemy URL ``url`` as one replica among others
    (:class:`service.replicas.Replica`: heartbeat, leases)."""

    # -- cases ---------------------------------------------------------------------------

    def add_case(self, case_id: str, spec_json: str, room: Optional[int] = None) -> tuple[CaseRecord, bool]:
        row = {"id": case_id, "spec": spec_json, "status": "queued", "submitted_at": time.time(), "submissions": 0,
               "claimed_by": self.replica, "room": room}
        with self.engine.begin() as db:
            inserted = db.execute(self._insert(cases).values(**row).on_conflict_do_nothing()
                                  .returning(cases.c.id)).first()
        if inserted is None:
            return self.get_case(case_id), False
        return _case({c.name: row.get(c.name) for c in cases.columns}), True

    def repair_spec(self, case_id: str, spec_json: str) -> None:
        """As :meth:`service.job_records.JobStore.repair_spec`."""
        with self.engine.begin() as db:
            db.execute(cases.update().where(cases.c.id == case_id).values(spec=spec_json))

    def open_room(self) -> int:
        """Bytes held for the results of the open cases of every replica (their ``room``)."""
        with self.engine.connect() as db:
            return int(db.execute(sa.select(sa.func.coalesce(sa.func.sum(cases.c.room), 0))
                                  .where(cases.c.status.in_(OPEN))).scalar())

    def replace_damaged(self, problem: str) -> None:
        """A database server keeps its own files: nothing here is moved aside (the SQLite
        store's recovery, :meth:`service.job_tables.JobDatabase.replace_damaged`, does not apply)."""
        raise RuntimeError(f"the shared job records report damage ({problem}); repair the database server")

    def get_case(self, case_id: str) -> Optional[CaseRecord]:
        rows = self._read(sa.select(cases).where(cases.c.id == case_id))
        return _case(rows[0]) if rows else None

    def list_cases(self, *, status: str | None = None, limit: int = 100,
                   offset: int = 0, newest_first: bool = False) -> tuple[list[CaseRecord], int]:
        where = cases.c.status == status if status else sa.true()
        order = ((cases.c.submitted_at.desc(), cases.c.id.desc()) if newest_first
                 else (cases.c.submitted_at, cases.c.id))
        with self.engine.connect() as db:
            total = db.execute(sa.select(sa.func.count()).select_from(cases).where(where)).scalar()
            rows = db.execute(sa.select(cases).where(where).order_by(*order).limit(limit).offset(offset)
                              ).mappings().all()
        return [_case(r) for r in rows], total

    def open_case_ids(self) -> list[str]:
        """Claim, and return, the open cases this replica is to settle: its own, the unclaimed
        and those of replicas gone silent (rows locked ``FOR UPDATE SKIP LOCKED``: a case
        another replica is claiming at this moment is left to it)."""
        claimable = (cases.c.status.in_(OPEN)
                     & (cases.c.claimed_by.is_(None) | (cases.c.claimed_by == self.replica)
                        | cases.c.claimed_by.not_in(self.live())))
        with self.engine.begin() as db:
            ids = db.execute(sa.select(cases.c.id).where(claimable).order_by(cases.c.submitted_at, cases.c.id)
                             .with_for_update(skip_locked=True)).scalars().all()
            taken = [c for c in ids]
            if taken:
                db.execute(cases.update().where(cases.c.id.in_(taken) & (cases.c.claimed_by.is_distinct_from(
                    self.replica))).values(claimed_by=self.replica))
        return list(taken)

    def case_ids_with_status(self, status: str) -> list[str]:
        return list(self._scalars(sa.select(cases.c.id).where(cases.c.status == status)
                                  .order_by(cases.c.submitted_at, cases.c.id)))

    def failed_with(self, error_prefix: str) -> list[str]:
        return list(self._scalars(sa.select(cases.c.id).where(
            (cases.c.status == "failed") & cases.c.error.startswith(error_prefix, autoescape=True))
            .order_by(cases.c.submitted_at, cases.c.id)))

    def count_open(self) -> int:
        return self._scalars(sa.select(sa.func.count()).select_from(cases).where(cases.c.status.in_(OPEN)))[0]

    def count_submissions(self, case_ids: Sequence[str]) -> None:
        with self.engine.begin() as db:
            db.execute(cases.update().where(cases.c.id.in_(list(case_ids)))
                       .values(submissions=cases.c.submissions + 1))

    def mark_running(self, case_ids: Iterable[str]) -> int:
        now = time.time()
        with self.engine.begin() as db:
            return db.execute(cases.update().where(cases.c.id.in_(list(case_ids)) & (cases.c.status == "queued"))
                              .values(status="running", started_at=sa.func.coalesce(cases.c.started_at, now))).rowcount

    def mark_queued(self, case_id: str) -> None:
        with self.engine.begin() as db:
            db.execute(cases.update().where((cases.c.id == case_id) & cases.c.status.in_(OPEN))
                       .values(status="queued", started_at=None))

    def finish(self, case_id: str, *, status: str, summary: dict | None = None,
               error: str | None = None, seconds: float | None = None,
               warnings: Sequence[str] = ()) -> None:
        if status not in ("done", "failed"):
            raise ValueError(f"status: {status!r} is not final")
        now = time.time()
        started = now - seconds if seconds is not None else None
        with self.engine.begin() as db:
            db.execute(cases.update().where(cases.c.id == case_id).values(
                status=status, summary=json.dumps(summary) if summary is not None else None, error=error,
                finished_at=now, started_at=sa.func.coalesce(cases.c.started_at, started),
                warnings=json.dumps(list(warnings)) if warnings else None))

    def status_counts(self, case_ids: Sequence[str] | None = None) -> dict[str, int]:
        counts = dict.fromkeys(STATUSES, 0)
        query = sa.select(cases.c.status, sa.func.count()).group_by(cases.c.status)
        if case_ids is not None:
            query = query.where(cases.c.id.in_(list(case_ids)))
        with self.engine.connect() as db:
            counts.update({status: n for status, n in db.execute(query)})
        return counts

    def get_cases(self, case_ids: Sequence[str]) -> dict[str, CaseRecord]:
        return {r["id"]: _case(r) for r in self._read(sa.select(cases).where(cases.c.id.in_(list(case_ids))))}

    def mark_cancelled(self, case_ids: Sequence[str], *, statuses: Sequence[str] = ("queued",)) -> list[str]:
        with self.engine.begin() as db:
            return list(db.execute(cases.update().where(cases.c.status.in_(list(statuses))
                                                        & cases.c.id.in_(list(case_ids)))
                                   .values(status="cancelled", finished_at=time.time())
                                   .returning(cases.c.id)).scalars())

    def requeue(self, case_ids: Sequence[str], *, statuses: Sequence[str] = ("cancelled",)) -> list[str]:
        with self.engine.begin() as db:
            return list(db.execute(cases.update().where(cases.c.status.in_(list(statuses))
                                                        & cases.c.id.in_(list(case_ids)))
                                   .values(status="queued", summary=None, error=None, warnings=None, started_at=None,
                                           finished_at=None, claimed_by=self.replica)
                                   .returning(cases.c.id)).scalars())

    def statuses(self, case_ids: Sequence[str]) -> dict[str, str]:
        return {r["id"]: r["status"]
                for r in self._read(sa.select(cases.c.id, cases.c.status).where(cases.c.id.in_(list(case_ids))))}

    # -- sweeps --------------------------------------------------------------------------

    def add_sweep(self, sweep_id: str, name: str, spec_json: str, cases_: Sequence[tuple[str, str]],
                  rooms: Optional[dict[str, int]] = None) -> tuple[SweepRecord, list[str]]:
        """As :meth:`service.job_records.JobStore.add_sweep`, in one transaction; two replicas
        adding the same sweep at once: one records it, the other finds it recorded."""
        now = time.time()
        new: list[str] = []
        with self.engine.begin() as db:
            inserted = db.execute(self._insert(sweeps).values(id=sweep_id, name=name, spec=spec_json, submitted_at=now)
                                  .on_conflict_do_nothing().returning(sweeps.c.id)).first()
            if inserted is not None and cases_:
                ids = [c for c, _ in cases_]
                new = list(db.execute(self._insert(cases).values(
                    [{"id": c, "spec": s, "status": "queued", "submitted_at": now, "submissions": 0,
                      "claimed_by": self.replica, "room": (rooms or {}).get(c)} for c, s in cases_])
                    .on_conflict_do_nothing().returning(cases.c.id)).scalars())
                db.execute(sweep_cases.insert(), [{"sweep_id": sweep_id, "position": p, "case_id": c}
                                                  for p, c in enumerate(ids)])
        order = {c: i for i, (c, _) in enumerate(cases_)}
        return self.get_sweep(sweep_id), sorted(new, key=order.__getitem__)

    def sweep_ids(self) -> set[str]:
        return set(self._scalars(sa.select(sweeps.c.id)))

    def get_sweep(self, sweep_id: str) -> Optional[SweepRecord]:
        with self.engine.connect() as db:
            row = db.execute(sa.select(sweeps).where(sweeps.c.id == sweep_id)).mappings().first()
            if row is None:
                return None
            ids = db.execute(sa.select(sweep_cases.c.case_id).where(sweep_cases.c.sweep_id == sweep_id)
                             .order_by(sweep_cases.c.position)).scalars().all()
        return _sweep(row, ids)

    def list_sweeps(self, *, limit: int = 20, offset: int = 0) -> tuple[list[SweepRecord], int]:
        with self.engine.connect() as db:
            total = db.execute(sa.select(sa.func.count()).select_from(sweeps)).scalar()
            rows = db.execute(sa.select(sweeps).order_by(sweeps.c.submitted_at.desc(), sweeps.c.id.desc())
                              .limit(limit).offset(offset)).mappings().all()
            members: dict[str, list[str]] = {r["id"]: [] for r in rows}
            for sweep_id, case_id in db.execute(
                    sa.select(sweep_cases.c.sweep_id, sweep_cases.c.case_id)
                    .where(sweep_cases.c.sweep_id.in_(list(members)))
                    .order_by(sweep_cases.c.sweep_id, sweep_cases.c.position)):
                members[sweep_id].append(case_id)
        return [_sweep(r, members[r["id"]]) for r in rows], total

    def sweep_status_counts(self, sweep_ids: Sequence[str]) -> dict[str, dict[str, int]]:
        counts = {s: dict.fromkeys(STATUSES, 0) for s in sweep_ids}
        query = (sa.select(sweep_cases.c.sweep_id, cases.c.status, sa.func.count(sa.distinct(cases.c.id)))
                 .join(cases, cases.c.id == sweep_cases.c.case_id)
                 .where(sweep_cases.c.sweep_id.in_(list(sweep_ids)))
                 .group_by(sweep_cases.c.sweep_id, cases.c.status))
        with self.engine.connect() as db:
            for sweep_id, status, n in db.execute(query):
                counts[sweep_id][status] = n
        return counts

    # -- helpers -------------------------------------------------------------------------

    def _read(self, query) -> list:
        with self.engine.connect() as db:
            return db.execute(query).mappings().all()

    def _scalars(self, query) -> list:
        with self.engine.connect() as db:
            return db.execute(query).scalars().all()
