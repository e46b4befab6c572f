"""Registry: deployment rollout state (robots, canary, previous assignments) and rollback record.

Revision ID: 0004
Revises: 0002
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0004"
down_revision: str | None = "0003"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("deployments") as batch_op:
        batch_op.add_column(sa.Column("rollout", sa.JSON(), nullable=True))
        batch_op.add_column(sa.Column("rolled_back_at", sa.DateTime(timezone=True), nullable=True))
        batch_op.add_column(sa.Column("rollback_reason", sa.Text(), nullable=True))
        batch_op.add_column(sa.Column("updated_at", sa.DateTime(timezone=True), nullable=True))
    with op.batch_alter_table("alarms") as batch_op:
        batch_op.create_index("ix_alarms_model_version", ["model_version"])


def downgrade() -> None:
    with op.batch_alter_table("alarms") as batch_op:
        batch_op.drop_index("ix_alarms_model_version")
    with op.batch_alter_table("deployments") as batch_op:
        batch_op.drop_column("updated_at")
        batch_op.drop_column("rollback_reason")
        batch_op.drop_column("rolled_back_at")
        batch_op.drop_column("rollout")
