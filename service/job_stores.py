"""Which job records a service opens: the SQLite file of one process or a database replicas share."""
from __future__ import annotations

from typing import Optional

from .job_records import JobStore, open_job_records
from .shared_records import SharedJobStore


def open_records(settings, **options) -> tuple[JobStore | SharedJobStore, Optional[str]]:
    """The job records ``settings`` name (``TUNNEL_CONTACT_DATABASE``): the SQLite file
    (:func:`open_job_records`) or a shared database
    (:class:`service.shared_records.SharedJobStore`, never "damaged": the server keeps it).
    Returns the store and the damage found (None if none)."""
    if settings.shared_database:
        return SharedJobStore(settings.database_url, ttl=settings.replica_ttl), None
    return open_job_records(settings.database, **options)
