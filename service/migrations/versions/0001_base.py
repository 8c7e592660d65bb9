"""The job records as they stood before Alembic: cases, sweeps and their members.

An existing SQLite file gets what its version lacked (``cancelled`` in the status check,
the ``warnings`` column) in place; a new database gets the tables.
"""
from alembic import op
import sqlalchemy as sa

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None

STATUS_CHECK = "status IN ('queued', 'running', 'done', 'failed', 'cancelled')"


def _cases_columns() -> list[sa.Column]:
    return [
        sa.Column("id", sa.Text, primary_key=True),
        sa.Column("spec", sa.Text, nullable=False),
        sa.Column("status", sa.Text, sa.CheckConstraint(STATUS_CHECK), nullable=False),
        sa.Column("summary", sa.Text),
        sa.Column("error", sa.Text),
        sa.Column("submitted_at", sa.Float, nullable=False),
        sa.Column("started_at", sa.Float),
        sa.Column("finished_at", sa.Float),
        sa.Column("submissions", sa.Integer, nullable=False, server_default=sa.text("0")),
        sa.Column("warnings", sa.Text),
    ]


def upgrade() -> None:
    bind = op.get_bind()
    tables = set(sa.inspect(bind).get_table_names())
    if "cases" in tables and bind.dialect.name == "sqlite":
        _upgrade_old_sqlite(bind)
    if "cases" not in tables:
        op.create_table("cases", *_cases_columns())
        op.create_index("cases_by_status", "cases", ["status", "submitted_at"])
    if "sweeps" not in tables:
        op.create_table("sweeps", sa.Column("id", sa.Text, primary_key=True),
                        sa.Column("name", sa.Text, nullable=False), sa.Column("spec", sa.Text, nullable=False),
                        sa.Column("submitted_at", sa.Float, nullable=False))
    if "sweep_cases" not in tables:
        op.create_table("sweep_cases", sa.Column("sweep_id", sa.Text, sa.ForeignKey("sweeps.id"), nullable=False),
                        sa.Column("position", sa.Integer, nullable=False),
                        sa.Column("case_id", sa.Text, sa.ForeignKey("cases.id"), nullable=False),
                        sa.PrimaryKeyConstraint("sweep_id", "position"))


def _upgrade_old_sqlite(bind) -> None:
    """A ``jobs.sqlite`` written before ``cancelled`` existed, or before warnings were kept.

    SQLite cannot alter a CHECK constraint: the table is rebuilt (copy, drop, rename;
    foreign keys are off on this connection)."""
    columns = {c["name"] for c in sa.inspect(bind).get_columns("cases")}
    sql = bind.exec_driver_sql("SELECT sql FROM sqlite_master WHERE type = 'table' AND name = 'cases'").scalar()
    if "'cancelled'" not in sql:
        op.create_table("cases_new", *_cases_columns())
        copied = ", ".join(c.name for c in _cases_columns() if c.name in columns)
        bind.exec_driver_sql(f"INSERT INTO cases_new ({copied}) SELECT {copied} FROM cases")
        op.drop_table("cases")
        op.rename_table("cases_new", "cases")
        op.create_index("cases_by_status", "cases", ["status", "submitted_at"])
    elif "warnings" not in columns:
        op.add_column("cases", sa.Column("warnings", sa.Text))
    bind.exec_driver_sql("CREATE INDEX IF NOT EXISTS cases_by_status ON cases (status, submitted_at)")
