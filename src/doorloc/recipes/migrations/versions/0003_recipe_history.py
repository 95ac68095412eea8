"""Recipe history: every change a new version with who, when and what; doors carry their current version.

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-23

Doors stored before this revision become version 1 with a history row of action ``migrated`` (their
earlier changes were never recorded, so the row holds no recipe and no change list).
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0003"
down_revision: str | None = "0002"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("doors") as batch:
        batch.add_column(sa.Column("version", sa.Integer(), nullable=False, server_default="1"))
        batch.add_column(sa.Column("content_sha256", sa.String(64), nullable=True))
        batch.add_column(sa.Column("updated_by", sa.String(64), nullable=True))
    op.create_table(
        "recipe_versions",
        sa.Column("id", sa.Integer(), primary_key=True, autoincrement=True),
        sa.Column("door_id", sa.String(64), nullable=False),
        sa.Column("version", sa.Integer(), nullable=False),
        sa.Column("action", sa.String(16), nullable=False),
        sa.Column("changed_by", sa.String(64), nullable=False),
        sa.Column("changed_at", sa.DateTime(timezone=True), server_default=sa.func.now(), nullable=False),
        sa.Column("recipe", sa.JSON(), nullable=True),
        sa.Column("changes", sa.JSON(), nullable=True),
        sa.UniqueConstraint("door_id", "version", name="uq_recipe_versions_door_version"),
        sa.CheckConstraint("version >= 1", name="ck_recipe_versions_version_positive"),
        sa.CheckConstraint(
            "action IN ('created', 'updated', 'deleted', 'migrated')", name="ck_recipe_versions_action"
        ),
    )
    op.create_index("ix_recipe_versions_door_id", "recipe_versions", ["door_id"])
    op.execute(
        "INSERT INTO recipe_versions (door_id, version, action, changed_by, changed_at) "
        "SELECT door_id, 1, 'migrated', 'migration 0003', updated_at FROM doors"
    )


def downgrade() -> None:
    op.drop_index("ix_recipe_versions_door_id", table_name="recipe_versions")
    op.drop_table("recipe_versions")
    with op.batch_alter_table("doors") as batch:
        batch.drop_column("updated_by")
        batch.drop_column("content_sha256")
        batch.drop_column("version")
