"""Labelling: coordinate space, camera intrinsics and RGB clip placement of a video; status
index for the review queue.

Revision ID: 0003
Revises: 0002
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0003"
down_revision: str | None = "0002"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("videos", schema=None) as batch_op:
        batch_op.add_column(sa.Column("image_width", sa.Float(), nullable=True))
        batch_op.add_column(sa.Column("image_height", sa.Float(), nullable=True))
        batch_op.add_column(sa.Column("rgb_crop", sa.JSON(), nullable=True))
        batch_op.add_column(sa.Column("intrinsics", sa.JSON(), nullable=True))
        batch_op.add_column(
            sa.Column("rgb_frame_offset", sa.Integer(), nullable=False, server_default="0")
        )
    with op.batch_alter_table("annotation_segments", schema=None) as batch_op:
        batch_op.create_index("ix_annotation_segments_status", ["status"], unique=False)


def downgrade() -> None:
    with op.batch_alter_table("annotation_segments", schema=None) as batch_op:
        batch_op.drop_index("ix_annotation_segments_status")
    with op.batch_alter_table("videos", schema=None) as batch_op:
        batch_op.drop_column("rgb_frame_offset")
        batch_op.drop_column("intrinsics")
        batch_op.drop_column("rgb_crop")
        batch_op.drop_column("image_height")
        batch_op.drop_column("image_width")
