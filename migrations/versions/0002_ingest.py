"""Ingest and alarm lifecycle: transport stream liveness, indexes for the alarm monitor.

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-22 00:40:00
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0002"
down_revision: str | None = "0001"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("transports") as batch_op:
        batch_op.add_column(sa.Column("last_frame_at", sa.DateTime(timezone=True), nullable=True))
        batch_op.create_index("ix_transports_active", ["ended_at"])
    with op.batch_alter_table("alarm_events") as batch_op:
        batch_op.create_index("ix_alarm_events_at", ["at"])


def downgrade() -> None:
    with op.batch_alter_table("alarm_events") as batch_op:
        batch_op.drop_index("ix_alarm_events_at")
    with op.batch_alter_table("transports") as batch_op:
        batch_op.drop_index("ix_transports_active")
        batch_op.drop_column("last_frame_at")
