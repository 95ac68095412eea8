"""SQLAlchemy 2 tables of the recipe database: ``doors`` and their ``hinges``.

The schema is created and upgraded by the Alembic migrations in ``doorloc/recipes/migrations``
(revision ``0001`` creates exactly these tables; a test compares the two). Constraints keep the
database honest even when it is written by something other than doorloc: unique ``door_id``,
positive sizes, ``path_points in (6, 9)``, and hinges deleted with their door (``ON DELETE CASCADE``).
"""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import (
    JSON,
    CheckConstraint,
    DateTime,
    Float,
    ForeignKey,
    Integer,
    String,
    UniqueConstraint,
    func,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship

__all__ = ["Base", "DoorRow", "HingeRow", "ApiKeyRow", "RecipeVersionRow"]


class Base(DeclarativeBase):
    pass


class DoorRow(Base):
    """One door recipe's door-level fields (mm, rpm, mm/s)."""

    __tablename__ = "doors"
    __table_args__ = (
        UniqueConstraint("door_id", name="uq_doors_door_id"),
        CheckConstraint("width_mm > 0", name="ck_doors_width_positive"),
        CheckConstraint("height_mm > 0", name="ck_doors_height_positive"),
        CheckConstraint("thickness_mm > 0", name="ck_doors_thickness_positive"),
        CheckConstraint("arris_mm >= 0", name="ck_doors_arris_nonnegative"),
        CheckConstraint("tool_diameter_mm > 0", name="ck_doors_tool_positive"),
        CheckConstraint("spindle_rpm > 0", name="ck_doors_spindle_positive"),
        CheckConstraint("feed_mm_s > 0", name="ck_doors_feed_positive"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    door_id: Mapped[str] = mapped_column(String(64), nullable=False)
    width_mm: Mapped[float] = mapped_column(Float, nullable=False)
    height_mm: Mapped[float] = mapped_column(Float, nullable=False)
    thickness_mm: Mapped[float] = mapped_column(Float, nullable=False)
    arris_mm: Mapped[float] = mapped_column(Float, nullable=False, default=0.0)
    tool_diameter_mm: Mapped[float] = mapped_column(Float, nullable=False)
    spindle_rpm: Mapped[float] = mapped_column(Float, nullable=False)
    feed_mm_s: Mapped[float] = mapped_column(Float, nullable=False)
    updated_at: Mapped[datetime] = mapped_column(
        DateTime(timezone=True), nullable=False, server_default=func.now()
    )
    #: revision 0003: the recipe's current version, a hash of its content (to skip unchanged re-imports), who wrote it
    version: Mapped[int] = mapped_column(Integer, nullable=False, server_default="1")
    content_sha256: Mapped[str | None] = mapped_column(String(64), nullable=True)
    updated_by: Mapped[str | None] = mapped_column(String(64), nullable=True)

    hinges: Mapped[list[HingeRow]] = relationship(
        back_populates="door",
        order_by="HingeRow.position",
        cascade="all, delete-orphan",
        passive_deletes=True,
    )


class HingeRow(Base):
    """One hinge pocket of a door, door frame, mm; ``position`` is its 1-based number in the recipe."""

    __tablename__ = "hinges"
    __table_args__ = (
        UniqueConstraint("door_pk", "position", name="uq_hinges_door_position"),
        CheckConstraint("position >= 1", name="ck_hinges_position_positive"),
        CheckConstraint("z_mm >= 0", name="ck_hinges_z_nonnegative"),
        CheckConstraint("x_mm >= 0", name="ck_hinges_x_nonnegative"),
        CheckConstraint("length_mm > 0", name="ck_hinges_length_positive"),
        CheckConstraint("width_mm > 0", name="ck_hinges_width_positive"),
        CheckConstraint("depth_mm > 0", name="ck_hinges_depth_positive"),
        CheckConstraint("corner_radius_mm >= 0", name="ck_hinges_radius_nonnegative"),
        CheckConstraint("path_points IN (6, 9)", name="ck_hinges_path_points"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    door_pk: Mapped[int] = mapped_column(
        ForeignKey("doors.id", ondelete="CASCADE", name="fk_hinges_door"), nullable=False, index=True
    )
    position: Mapped[int] = mapped_column(Integer, nullable=False)
    z_mm: Mapped[float] = mapped_column(Float, nullable=False)
    length_mm: Mapped[float] = mapped_column(Float, nullable=False)
    width_mm: Mapped[float] = mapped_column(Float, nullable=False)
    x_mm: Mapped[float] = mapped_column(Float, nullable=False)
    depth_mm: Mapped[float] = mapped_column(Float, nullable=False)
    corner_radius_mm: Mapped[float] = mapped_column(Float, nullable=False)
    path_points: Mapped[int] = mapped_column(Integer, nullable=False, default=6)
    #: force-displacement corrections: null, or a list of [dx_mm, dy_mm, dz_mm], one per pocket point
    corrections: Mapped[list | None] = mapped_column(JSON, nullable=True)

    door: Mapped[DoorRow] = relationship(back_populates="hinges")


class ApiKeyRow(Base):
    """One API key of the HTTP service (revision 0002): only a salted scrypt hash of its secret is kept.

    ``key_id`` is the public part of the key (``dlk_<key_id>_<secret>``) and finds the row; ``role`` is
    ``operator``, ``engineer`` or ``metrics``; a revoked key keeps its row (``revoked_at`` set) for the audit trail.
    """

    __tablename__ = "api_keys"
    __table_args__ = (
        UniqueConstraint("key_id", name="uq_api_keys_key_id"),
        CheckConstraint("role IN ('operator', 'engineer', 'metrics')", name="ck_api_keys_role"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    key_id: Mapped[str] = mapped_column(String(32), nullable=False)
    name: Mapped[str] = mapped_column(String(64), nullable=False, index=True)
    role: Mapped[str] = mapped_column(String(16), nullable=False)
    salt: Mapped[str] = mapped_column(String(64), nullable=False)
    key_hash: Mapped[str] = mapped_column(String(128), nullable=False)
    created_at: Mapped[datetime] = mapped_column(
        DateTime(timezone=True), nullable=False, server_default=func.now()
    )
    revoked_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)


class RecipeVersionRow(Base):
    """One change of a door recipe (revision 0003): who, when, what; ``recipe`` is the whole recipe as stored then
    (null for ``deleted`` and for ``migrated``, the rows of doors stored before history existed)."""

    __tablename__ = "recipe_versions"
    __table_args__ = (
        UniqueConstraint("door_id", "version", name="uq_recipe_versions_door_version"),
        CheckConstraint("version >= 1", name="ck_recipe_versions_version_positive"),
        CheckConstraint(
            "action IN ('created', 'updated', 'deleted', 'migrated')", name="ck_recipe_versions_action"
        ),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    door_id: Mapped[str] = mapped_column(String(64), nullable=False, index=True)
    version: Mapped[int] = mapped_column(Integer, nullable=False)
    action: Mapped[str] = mapped_column(String(16), nullable=False)
    changed_by: Mapped[str] = mapped_column(String(64), nullable=False)
    changed_at: Mapped[datetime] = mapped_column(
        DateTime(timezone=True), nullable=False, server_default=func.now()
    )
    recipe: Mapped[dict | None] = mapped_column(JSON, nullable=True)
    changes: Mapped[list | None] = mapped_column(JSON, nullable=True)
