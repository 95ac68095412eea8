"""Doors and their hinges.

Revision ID: 0001
Revises:
Create Date: 2026-11-21
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0001"
down_revision: str | None = None
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "doors",
        sa.Column("id", sa.Integer(), primary_key=True, autoincrement=True),
        sa.Column("door_id", sa.String(64), nullable=False),
        sa.Column("width_mm", sa.Float(), nullable=False),
        sa.Column("height_mm", sa.Float(), nullable=False),
        sa.Column("thickness_mm", sa.Float(), nullable=False),
        sa.Column("arris_mm", sa.Float(), nullable=False),
        sa.Column("tool_diameter_mm", sa.Float(), nullable=False),
        sa.Column("spindle_rpm", sa.Float(), nullable=False),
        sa.Column("feed_mm_s", sa.Float(), nullable=False),
        sa.Column("updated_at", sa.DateTime(timezone=True), server_default=sa.func.now(), nullable=False),
        sa.UniqueConstraint("door_id", name="uq_doors_door_id"),
        sa.CheckConstraint("width_mm > 0", name="ck_doors_width_positive"),
        sa.CheckConstraint("height_mm > 0", name="ck_doors_height_positive"),
        sa.CheckConstraint("thickness_mm > 0", name="ck_doors_thickness_positive"),
        sa.CheckConstraint("arris_mm >= 0", name="ck_doors_arris_nonnegative"),
        sa.CheckConstraint("tool_diameter_mm > 0", name="ck_doors_tool_positive"),
        sa.CheckConstraint("spindle_rpm > 0", name="ck_doors_spindle_positive"),
        sa.CheckConstraint("feed_mm_s > 0", name="ck_doors_feed_positive"),
    )
    op.create_table(
        "hinges",
        sa.Column("id", sa.Integer(), primary_key=True, autoincrement=True),
        sa.Column("door_pk", sa.Integer(), nullable=False),
        sa.Column("position", sa.Integer(), nullable=False),
        sa.Column("z_mm", sa.Float(), nullable=False),
        sa.Column("length_mm", sa.Float(), nullable=False),
        sa.Column("width_mm", sa.Float(), nullable=False),
        sa.Column("x_mm", sa.Float(), nullable=False),
        sa.Column("depth_mm", sa.Float(), nullable=False),
        sa.Column("corner_radius_mm", sa.Float(), nullable=False),
        sa.Column("path_points", sa.Integer(), nullable=False),
        sa.Column("corrections", sa.JSON(), nullable=True),
        sa.ForeignKeyConstraint(["door_pk"], ["doors.id"], name="fk_hinges_door", ondelete="CASCADE"),
        sa.UniqueConstraint("door_pk", "position", name="uq_hinges_door_position"),
        sa.CheckConstraint("position >= 1", name="ck_hinges_position_positive"),
        sa.CheckConstraint("z_mm >= 0", name="ck_hinges_z_nonnegative"),
        sa.CheckConstraint("x_mm >= 0", name="ck_hinges_x_nonnegative"),
        sa.CheckConstraint("length_mm > 0", name="ck_hinges_length_positive"),
        sa.CheckConstraint("width_mm > 0", name="ck_hinges_width_positive"),
        sa.CheckConstraint("depth_mm > 0", name="ck_hinges_depth_positive"),
        sa.CheckConstraint("corner_radius_mm >= 0", name="ck_hinges_radius_nonnegative"),
        sa.CheckConstraint("path_points IN (6, 9)", name="ck_hinges_path_points"),
    )
    op.create_index("ix_hinges_door_pk", "hinges", ["door_pk"])


def downgrade() -> None:
    op.drop_index("ix_hinges_door_pk", table_name="hinges")
    op.drop_table("hinges")
    op.drop_table("doors")
