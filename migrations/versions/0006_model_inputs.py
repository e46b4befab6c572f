"""What robots can feed a model (robots.inputs), technical alarm details and the wider alarm
kind (detection_degraded), and the transport's real frame rate (transports.fps).

Revision ID: 0006
Revises: 0005
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0006"
down_revision: str | None = "0005"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("robots") as batch_op:
        batch_op.add_column(sa.Column("inputs", sa.JSON(), nullable=True))
    with op.batch_alter_table("transports") as batch_op:
        batch_op.add_column(sa.Column("fps", sa.Float(), nullable=True))
    with op.batch_alter_table("alarms") as batch_op:
        batch_op.add_column(sa.Column("details", sa.JSON(), nullable=True))
    if op.get_bind().dialect.name == "postgresql":  # SQLite does not enforce VARCHAR lengths
        op.alter_column("alarms", "kind", type_=sa.String(32), existing_type=sa.String(16))


def downgrade() -> None:
    if op.get_bind().dialect.name == "postgresql":
        op.execute(
            "DELETE FROM alarm_events WHERE alarm_id IN "
            "(SELECT id FROM alarms WHERE kind = 'detection_degraded')"
        )
        op.execute("DELETE FROM alarms WHERE kind = 'detection_degraded'")
        op.alter_column("alarms", "kind", type_=sa.String(16), existing_type=sa.String(32))
    with op.batch_alter_table("alarms") as batch_op:
        batch_op.drop_column("details")
    with op.batch_alter_table("transports") as batch_op:
        batch_op.drop_column("fps")
    with op.batch_alter_table("robots") as batch_op:
        batch_op.drop_column("inputs")
