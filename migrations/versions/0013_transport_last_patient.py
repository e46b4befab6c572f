"""transports.last_patient_at: when a frame showing the patient was last committed, so the alarm
monitor can tell the nurse board that a robot has lost its patient (technical alarm
patient_not_seen) while its frames still flow.

Revision ID: 0013_transport_last_patient
Revises: 0012_video_frame_range
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0013_transport_last_patient"
down_revision: str | None = "0012_video_frame_range"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column(
        "transports", sa.Column("last_patient_at", sa.DateTime(timezone=True), nullable=True)
    )


def downgrade() -> None:
    # ALTER TABLE ... DROP COLUMN (SQLite >= 3.35), as 0012: no batch copy of a referenced table.
    op.execute("ALTER TABLE transports DROP COLUMN last_patient_at")
