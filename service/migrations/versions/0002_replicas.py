"""What several API replicas sharing one database need.

``cases.claimed_by``: the replica that submits and watches an open case (the one that
accepted it, or one that took it over when its owner stopped beating); ``replicas``: each
process's heartbeat; ``leases``: a driver (a search) owned by one replica at a time.
"""
from alembic import op
import sqlalchemy as sa

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column("cases", sa.Column("claimed_by", sa.Text))
    op.create_table("replicas", sa.Column("id", sa.Text, primary_key=True),
                    sa.Column("started_at", sa.Float, nullable=False),
                    sa.Column("heartbeat_at", sa.Float, nullable=False))
    op.create_table("leases", sa.Column("name", sa.Text, primary_key=True),
                    sa.Column("owner", sa.Text, nullable=False),
                    sa.Column("expires_at", sa.Float, nullable=False))
