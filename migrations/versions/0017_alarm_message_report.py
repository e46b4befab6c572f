"""Alarm distribution: the outbox keeps what each change reports (alarm_messages.report, the
AlertReport as JSON, and facility, MSH-4) and the sender builds the ORU^R40 (payload) before
its first send, outside the change's own transaction.

Revision ID: 0017_alarm_message_report
Revises: 0016_alarm_distribution
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0017_alarm_message_report"
down_revision: str | None = "0016_alarm_distribution"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("alarm_messages") as batch_op:
        batch_op.add_column(
            sa.Column("facility", sa.String(64), nullable=False, server_default="HOSPITAL")
        )
        batch_op.add_column(sa.Column("report", sa.Text(), nullable=True))
        batch_op.alter_column("payload", existing_type=sa.Text(), nullable=True)


def downgrade() -> None:
    unbuilt = op.get_bind().scalar(
        sa.text("SELECT count(*) FROM alarm_messages WHERE payload IS NULL")
    )
    if unbuilt:
        raise RuntimeError(
            f"{unbuilt} alarm messages are queued but not built yet; run the backend on this "
            "revision until the Alert Manager has them, then downgrade"
        )
    with op.batch_alter_table("alarm_messages") as batch_op:
        batch_op.alter_column("payload", existing_type=sa.Text(), nullable=False)
        batch_op.drop_column("report")
        batch_op.drop_column("facility")
