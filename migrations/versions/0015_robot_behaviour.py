"""The robot's behaviour as it reports it (protocol behaviour_changed): robots.behaviour_state,
behaviour_since, behaviour_reason for the fleet page; alarms.robot_state, robot_state_since for
the board ("robot stopped 12:03:05").

Revision ID: 0015_robot_behaviour
Revises: 0014_alarm_escalated_to
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0015_robot_behaviour"
down_revision: str | None = "0014_alarm_escalated_to"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column("robots", sa.Column("behaviour_state", sa.String(32), nullable=True))
    op.add_column("robots", sa.Column("behaviour_since", sa.DateTime(timezone=True), nullable=True))
    op.add_column("robots", sa.Column("behaviour_reason", sa.String(500), nullable=True))
    op.add_column("alarms", sa.Column("robot_state", sa.String(32), nullable=True))
    op.add_column(
        "alarms", sa.Column("robot_state_since", sa.DateTime(timezone=True), nullable=True)
    )


def downgrade() -> None:
    # ALTER TABLE ... DROP COLUMN (SQLite >= 3.35), as 0013.
    for table, column in (
        ("alarms", "robot_state_since"),
        ("alarms", "robot_state"),
        ("robots", "behaviour_reason"),
        ("robots", "behaviour_since"),
        ("robots", "behaviour_state"),
    ):
        op.execute(f"ALTER TABLE {table} DROP COLUMN {column}")
