"""Schema migrations of the job records (Alembic, run at start by :func:`service.database.migrate`).

One chain of revisions for every database the records live in (SQLite or PostgreSQL):
``0001`` is the schema as it stood before Alembic (an existing ``jobs.sqlite`` is brought to it
in place: its older forms too), ``0002`` adds what several replicas sharing the records need
(case claims, replica heartbeats, driver leases).
"""
