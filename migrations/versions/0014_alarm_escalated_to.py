"""alarms.escalated_to: a missed Emergency escalates on to the ward's further responders
(charge nurse, then the rapid-response team); the column names the last one reached.

Revision ID: 0014_alarm_escalated_to
Revises: 0013_transport_last_patient
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0014_alarm_escalated_to"
down_revision: str | None = "0013_transport_last_patient"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column("alarms", sa.Column("escalated_to", sa.String(64), nullable=True))


def downgrade() -> None:
    # ALTER TABLE ... DROP COLUMN (SQLite >= 3.35), as 0013.
    op.execute("ALTER TABLE alarms DROP COLUMN escalated_to")
