"""Alarm distribution (IHE PCD ACM): the outbox of ORU^R40 messages (alarm_messages), the
dispositions the Alert Manager reports back (alarm_dispositions), alarms.acknowledged_via (an
acknowledgement accepted on a phone) and alarms about no robot (robot_id NULL: "alarm
distribution down" of a ward), whose one-unresolved index keys on coalesce(robot_id, '').

Revision ID: 0016_alarm_distribution
Revises: 0015_robot_behaviour
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0016_alarm_distribution"
down_revision: str | None = "0015_robot_behaviour"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

UNRESOLVED = sa.text("state != 'resolved'")


def upgrade() -> None:
    op.drop_index(
        "uq_alarms_one_unresolved",
        table_name="alarms",
        sqlite_where=UNRESOLVED,
        postgresql_where=UNRESOLVED,
    )
    with op.batch_alter_table("alarms") as batch_op:
        batch_op.alter_column("robot_id", existing_type=sa.String(64), nullable=True)
        batch_op.add_column(sa.Column("acknowledged_via", sa.String(200), nullable=True))
    op.create_index(
        "uq_alarms_one_unresolved",
        "alarms",
        [sa.text("coalesce(robot_id, '')"), "transport_key", "kind"],
        unique=True,
        sqlite_where=UNRESOLVED,
        postgresql_where=UNRESOLVED,
    )
    op.create_table(
        "alarm_messages",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("alarm_id", sa.Integer(), nullable=False),
        sa.Column("event_id", sa.Integer(), nullable=False),
        sa.Column("change", sa.String(16), nullable=False),
        sa.Column("ward", sa.String(64), nullable=False),
        sa.Column("destination", sa.String(255), nullable=False),
        sa.Column("control_id", sa.String(32), nullable=False),
        sa.Column("payload", sa.Text(), nullable=False),
        sa.Column("status", sa.String(16), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("attempts", sa.Integer(), nullable=False),
        sa.Column("last_attempt_at", sa.DateTime(timezone=True), nullable=True),
        sa.Column("acked_at", sa.DateTime(timezone=True), nullable=True),
        sa.Column("ack_code", sa.String(2), nullable=True),
        sa.Column("last_error", sa.Text(), nullable=True),
        sa.ForeignKeyConstraint(["alarm_id"], ["alarms.id"], ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["event_id"], ["alarm_events.id"], ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("id"),
        sa.UniqueConstraint("control_id"),
        sa.UniqueConstraint("event_id"),
    )
    op.create_index("ix_alarm_messages_alarm_id", "alarm_messages", ["alarm_id"])
    op.create_index("ix_alarm_messages_status_id", "alarm_messages", ["status", "id"])
    op.create_table(
        "alarm_dispositions",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("alarm_id", sa.Integer(), nullable=False),
        sa.Column("message_id", sa.Integer(), nullable=True),
        sa.Column("control_id", sa.String(64), nullable=False),
        sa.Column("disposition", sa.String(16), nullable=False),
        sa.Column("clinician_id", sa.String(64), nullable=False),
        sa.Column("clinician", sa.String(128), nullable=False),
        sa.Column("device", sa.String(128), nullable=False),
        sa.Column("at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("received_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(["alarm_id"], ["alarms.id"], ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["message_id"], ["alarm_messages.id"], ondelete="SET NULL"),
        sa.PrimaryKeyConstraint("id"),
        sa.UniqueConstraint("control_id"),
    )
    op.create_index("ix_alarm_dispositions_alarm_id", "alarm_dispositions", ["alarm_id"])


def downgrade() -> None:
    op.drop_index("ix_alarm_dispositions_alarm_id", table_name="alarm_dispositions")
    op.drop_table("alarm_dispositions")
    op.drop_index("ix_alarm_messages_status_id", table_name="alarm_messages")
    op.drop_index("ix_alarm_messages_alarm_id", table_name="alarm_messages")
    op.drop_table("alarm_messages")
    op.drop_index(
        "uq_alarms_one_unresolved",
        table_name="alarms",
        sqlite_where=UNRESOLVED,
        postgresql_where=UNRESOLVED,
    )
    # Alarms about no robot cannot outlive robot_id NOT NULL.
    op.execute("DELETE FROM alarms WHERE robot_id IS NULL")
    with op.batch_alter_table("alarms") as batch_op:
        batch_op.drop_column("acknowledged_via")
        batch_op.alter_column("robot_id", existing_type=sa.String(64), nullable=False)
    op.create_index(
        "uq_alarms_one_unresolved",
        "alarms",
        ["robot_id", "transport_key", "kind"],
        unique=True,
        sqlite_where=UNRESOLVED,
        postgresql_where=UNRESOLVED,
    )
