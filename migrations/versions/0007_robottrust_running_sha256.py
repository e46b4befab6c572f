"""The sha256 of the model file each robot says it runs (robots.running_model_sha256), compared
by the fleet with the registry's sha256 of its target.

Revision ID: 0007_robottrust
Revises: 0006
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0007_robottrust"
down_revision: str | None = "0006"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("robots") as batch_op:
        batch_op.add_column(sa.Column("running_model_sha256", sa.String(64), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("robots") as batch_op:
        batch_op.drop_column("running_model_sha256")
