"""Alembic's environment: always run programmatically on the connection handed in by
:func:`service.database.migrate` (``config.attributes["connection"]``)."""
from alembic import context

connection = context.config.attributes["connection"]
context.configure(connection=connection, target_metadata=None, transactional_ddl=True)
with context.begin_transaction():
    context.run_migrations()
