"""The room (bytes) each open case's result is expected to take, reserved at admission so that
queued work cannot overfill the store (issue 38 item 8); NULL for cases recorded before."""
from alembic import op
import sqlalchemy as sa

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None


def upgrade() -> None:
    columns = {c["name"] for c in sa.inspect(op.get_bind()).get_columns("cases")}
    if "room" not in columns:  # a SQLite file written by the pre-Alembic code may have it already
        op.add_column("cases", sa.Column("room", sa.Integer))
