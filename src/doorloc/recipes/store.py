"""The recipe database: door recipes by door id, through SQLAlchemy 2 (SQLite or PostgreSQL).

Where the database is (:func:`database_url`): an explicit URL (``--db``), else the environment
variable ``DOORLOC_DATABASE_URL`` (or a settings object's ``database_url``), else the SQLite file
``doorloc.db`` in the current working directory. PostgreSQL URLs use psycopg 3:
``postgresql+psycopg://user:password@host/dbname``.

Schema: the Alembic migrations in ``doorloc/recipes/migrations`` own it. :class:`RecipeStore`
upgrades the database to the newest revision when it opens it (``migrate=True``, the default;
cheap when it is already there, and serialised by an advisory lock on PostgreSQL), so a fresh file
or an empty PostgreSQL database just works. ``doorloc recipes init-db`` does the same explicitly,
for deployments that open the store with ``migrate=False``.

Examples
--------
>>> store = RecipeStore("sqlite://")        # in memory
>>> store.get("nope") is None
True
"""

from __future__ import annotations

import os
import threading
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

from sqlalchemy import Engine, create_engine, delete, event, func, insert, select
from sqlalchemy.engine import make_url
from sqlalchemy.exc import SQLAlchemyError
from sqlalchemy.orm import Session, selectinload
from sqlalchemy.pool import StaticPool

from doorloc.recipes.models import DoorRecipe, Hinge, PointCorrection
from doorloc.recipes.tables import DoorRow, HingeRow

__all__ = [
    "ENV_DATABASE_URL", "DEFAULT_DB_FILENAME", "database_url", "redacted_url", "make_engine", "upgrade_schema",
    "schema_revision", "head_revision", "RecipeStore", "RecipeSummary", "RecipeStoreError", "StoredRecipeInvalid",
]

ENV_DATABASE_URL = "DOORLOC_DATABASE_URL"
DEFAULT_DB_FILENAME = "doorloc.db"
MIGRATIONS_DIR = Path(__file__).with_name("migrations")
#: Alembic keeps its migration context in module globals: one migration at a time per process
_MIGRATION_LOCK = threading.Lock()
#: rows per statement when deleting by door id (keeps below every backend's bound-parameter limit)
_CHUNK = 500


class StoredRecipeInvalid(ValueError):
    """A stored recipe that today's rules refuse (written before a rule existed, or by another program)."""


class RecipeStoreError(RuntimeError):
    """The database cannot be opened, migrated or read; the message names the (redacted) URL."""


def database_url(source: Any = None) -> str:
    """The recipe database URL.

    Parameters
    ----------
    source : str, Mapping, object or None
        A URL string (used as given); a mapping of environment variables (``DOORLOC_DATABASE_URL``);
        an object with a ``database_url`` attribute (e.g. ``doorloc.app.settings.ServiceSettings``);
        or None for ``os.environ``. An empty or missing value falls back to the default.

    Returns
    -------
    str
        A SQLAlchemy URL; the default is ``sqlite:///<cwd>/doorloc.db``.
    """
    if source is None:
        source = os.environ
    if isinstance(source, str):
        url = source
    elif isinstance(source, Mapping):
        url = source.get(ENV_DATABASE_URL)
    else:
        url = getattr(source, "database_url", None)
    if url:
        return str(url)
    return f"sqlite:///{Path.cwd() / DEFAULT_DB_FILENAME}"


def redacted_url(url: str) -> str:
    """The URL with its password hidden, for messages and logs."""
    try:
        return make_url(url).render_as_string(hide_password=True)
    except Exception:  # an unparsable URL has no password we could find either
        return url


def make_engine(url: str) -> Engine:
    """An engine for ``url``; SQLite gets foreign keys switched on (for ``ON DELETE CASCADE``)."""
    u = make_url(url)
    kwargs: dict[str, Any] = {}
    if u.get_backend_name() == "sqlite" and u.database in (None, "", ":memory:"):
        kwargs["poolclass"] = StaticPool  # one in-memory database shared by every connection
        kwargs["connect_args"] = {"check_same_thread": False}
    engine = create_engine(url, **kwargs)
    if u.get_backend_name() == "sqlite":
        # SQLAlchemy's recipe for real SQLite transactions: the driver's own implicit BEGIN (before
        # DML only) is switched off and every transaction starts with our BEGIN, so DDL (migrations)
        # is transactional too, and a migration can take the write lock up front (BEGIN IMMEDIATE)
        @event.listens_for(engine, "connect")
        def _sqlite_connect(dbapi_conn, _record) -> None:  # noqa: ANN001 - DB-API objects
            dbapi_conn.isolation_level = None
            cur = dbapi_conn.cursor()
            cur.execute("PRAGMA foreign_keys=ON")
            cur.close()

        @event.listens_for(engine, "begin")
        def _sqlite_begin(conn) -> None:  # noqa: ANN001 - a Connection
            conn.exec_driver_sql("BEGIN " + conn.get_execution_options().get("sqlite_begin", "DEFERRED"))

    return engine


def _alembic_config():
    from alembic.config import Config

    cfg = Config()
    cfg.set_main_option("script_location", str(MIGRATIONS_DIR))
    return cfg


def upgrade_schema(engine: Engine, revision: str = "head") -> None:
    """Upgrade the database schema to ``revision`` (Alembic ``upgrade``), in one transaction.

    Processes opening a fresh database at the same time migrate one after the other: SQLite's
    ``BEGIN IMMEDIATE`` takes the write lock before the current revision is read, PostgreSQL uses an
    advisory lock (migrations/env.py); threads of one process take turns (Alembic is not thread-safe).
    """
    from alembic import command

    cfg = _alembic_config()
    with _MIGRATION_LOCK, engine.connect().execution_options(sqlite_begin="IMMEDIATE") as conn, conn.begin():
        cfg.attributes["connection"] = conn
        command.upgrade(cfg, revision)


def head_revision() -> str:
    """The newest migration's revision (what :func:`upgrade_schema` brings a database to)."""
    from alembic.script import ScriptDirectory

    head = ScriptDirectory.from_config(_alembic_config()).get_current_head()
    assert head is not None  # the package ships its migrations
    return head


def schema_revision(engine: Engine) -> str | None:
    """The Alembic revision the database is at (None for an empty database)."""
    from alembic.runtime.migration import MigrationContext

    with engine.connect() as conn:
        return MigrationContext.configure(conn).get_current_revision()


@dataclass(frozen=True)
class RecipeSummary:
    """One line of ``doorloc recipes list``."""

    door_id: str
    width_mm: float
    height_mm: float
    thickness_mm: float
    hinge_count: int
    updated_at: datetime | None


def _door_values(r: DoorRecipe) -> dict[str, Any]:
    return {
        "door_id": r.door_id, "width_mm": r.width_mm, "height_mm": r.height_mm, "thickness_mm": r.thickness_mm,
        "arris_mm": r.arris_mm, "tool_diameter_mm": r.tool_diameter_mm, "spindle_rpm": r.spindle_rpm,
        "feed_mm_s": r.feed_mm_s,
    }


def _hinge_values(h: Hinge, door_pk: int, position: int) -> dict[str, Any]:
    return {
        "door_pk": door_pk, "position": position, "z_mm": h.z_mm, "length_mm": h.length_mm, "width_mm": h.width_mm,
        "x_mm": h.x_mm, "depth_mm": h.depth_mm, "corner_radius_mm": h.corner_radius_mm,
        "path_points": h.path_points,
        "corrections": [[c.dx_mm, c.dy_mm, c.dz_mm] for c in h.corrections] or None,
    }


def _recipe_from_row(row: DoorRow) -> DoorRecipe:
    from pydantic import ValidationError

    try:
        return _build_recipe(row)
    except ValidationError as e:
        reasons = "; ".join(str(x["msg"]).removeprefix("Value error, ") for x in e.errors(include_url=False)[:3])
        raise StoredRecipeInvalid(
            f"the stored recipe of door '{row.door_id}' breaks today's rules ({reasons}); correct it "
            "(PUT /v1/doors/ID or doorloc recipes import --replace) before using it"
        ) from None


def _build_recipe(row: DoorRow) -> DoorRecipe:
    hinges = [
        Hinge(
            z_mm=h.z_mm, length_mm=h.length_mm, width_mm=h.width_mm, x_mm=h.x_mm, depth_mm=h.depth_mm,
            corner_radius_mm=h.corner_radius_mm, path_points=h.path_points,
            corrections=tuple(PointCorrection(dx_mm=c[0], dy_mm=c[1], dz_mm=c[2]) for c in (h.corrections or [])),
        )
        for h in row.hinges
    ]
    return DoorRecipe(
        door_id=row.door_id, width_mm=row.width_mm, height_mm=row.height_mm, thickness_mm=row.thickness_mm,
        arris_mm=row.arris_mm, hinges=hinges, tool_diameter_mm=row.tool_diameter_mm, spindle_rpm=row.spindle_rpm,
        feed_mm_s=row.feed_mm_s,
    )


class RecipeStore:
    """Door recipes by door id in a SQL database.

    Parameters
    ----------
    url : str, optional
        SQLAlchemy URL; None means :func:`database_url` (environment, then ``./doorloc.db``).
    migrate : bool
        Upgrade the schema to the newest migration on open (default). With False the schema must
        already be there (``doorloc recipes init-db``).

    Every method is one transaction; :meth:`put_many` writes all recipes or none.
    """

    def __init__(self, url: str | None = None, *, migrate: bool = True) -> None:
        self.url = url or database_url()
        try:
            self.engine = make_engine(self.url)
            if migrate:
                upgrade_schema(self.engine)
        except SQLAlchemyError as e:
            raise RecipeStoreError(f"cannot open the recipe database {redacted_url(self.url)}: {e.__class__.__name__}: "
                                   f"{str(e).splitlines()[0]}") from e

    # -- context manager -------------------------------------------------------------------------
    def close(self) -> None:
        """Release the database connections."""
        self.engine.dispose()

    def __enter__(self) -> RecipeStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"RecipeStore({redacted_url(self.url)!r})"

    # -- reading ---------------------------------------------------------------------------------
    def get(self, door_id: str) -> DoorRecipe | None:
        """The recipe of ``door_id``, or None when there is none."""
        with Session(self.engine) as s:
            row = s.scalars(
                select(DoorRow).where(DoorRow.door_id == door_id).options(selectinload(DoorRow.hinges))
            ).one_or_none()
            return None if row is None else _recipe_from_row(row)

    def list(self, *, limit: int | None = None, offset: int = 0) -> list[RecipeSummary]:
        """Summaries of the stored recipes, ordered by door id."""
        counts = select(HingeRow.door_pk, func.count().label("n")).group_by(HingeRow.door_pk).subquery()
        q = (
            select(DoorRow.door_id, DoorRow.width_mm, DoorRow.height_mm, DoorRow.thickness_mm,
                   func.coalesce(counts.c.n, 0), DoorRow.updated_at)
            .outerjoin(counts, counts.c.door_pk == DoorRow.id)
            .order_by(DoorRow.door_id)
            .offset(offset)
        )
        if limit is not None:
            q = q.limit(limit)
        with self.engine.connect() as conn:
            return [RecipeSummary(*row) for row in conn.execute(q)]

    def door_ids(self) -> list[str]:
        """Every stored door id, sorted."""
        with self.engine.connect() as conn:
            return list(conn.scalars(select(DoorRow.door_id).order_by(DoorRow.door_id)))

    def count(self) -> int:
        """How many recipes are stored."""
        with self.engine.connect() as conn:
            return int(conn.scalar(select(func.count()).select_from(DoorRow)) or 0)

    def iter_recipes(self, batch: int = 1000) -> Iterator[DoorRecipe]:
        """Every stored recipe, ordered by door id (loaded ``batch`` doors at a time)."""
        last = ""
        while True:
            with Session(self.engine) as s:
                rows = s.scalars(
                    select(DoorRow).where(DoorRow.door_id > last).order_by(DoorRow.door_id).limit(batch)
                    .options(selectinload(DoorRow.hinges))
                ).all()
                recipes = [_recipe_from_row(r) for r in rows]
            if not recipes:
                return
            yield from recipes
            last = recipes[-1].door_id

    # -- writing ---------------------------------------------------------------------------------
    def put(self, recipe: DoorRecipe) -> None:
        """Store ``recipe``, replacing any recipe with the same door id."""
        self.put_many([recipe])

    def put_many(self, recipes: Iterable[DoorRecipe]) -> int:
        """Store many recipes in one transaction (all or none), replacing same-id recipes.

        Bulk statements (one multi-row INSERT per table), not one ORM flush per door.

        Returns
        -------
        int
            The number of recipes written.
        """
        recipes = list(recipes)
        ids = [r.door_id for r in recipes]
        if len(set(ids)) != len(ids):
            seen: set[str] = set()
            dup = sorted({i for i in ids if i in seen or seen.add(i)})
            raise ValueError(f"door ids given more than once: {', '.join(dup[:10])}")
        if not recipes:
            return 0
        with self.engine.begin() as conn:
            for k in range(0, len(ids), _CHUNK):
                # the replaced doors' keys, then their hinges in one statement (SQLite's per-row
                # ON DELETE CASCADE is slow) and the doors; plain key lists keep every plan on the indexes
                pks = list(conn.scalars(select(DoorRow.id).where(DoorRow.door_id.in_(ids[k:k + _CHUNK]))))
                if pks:
                    conn.execute(delete(HingeRow).where(HingeRow.door_pk.in_(pks)))
                    conn.execute(delete(DoorRow).where(DoorRow.id.in_(pks)))
            result = conn.execute(
                insert(DoorRow).returning(DoorRow.id, DoorRow.door_id), [_door_values(r) for r in recipes]
            )
            pk = {door_id: door_pk for door_pk, door_id in result}
            hinge_rows = [
                _hinge_values(h, pk[r.door_id], i + 1) for r in recipes for i, h in enumerate(r.hinges)
            ]
            conn.execute(insert(HingeRow), hinge_rows)
        return len(recipes)

    def delete(self, door_id: str) -> bool:
        """Remove a recipe (and its hinges); True when there was one."""
        with self.engine.begin() as conn:
            return conn.execute(delete(DoorRow).where(DoorRow.door_id == door_id)).rowcount > 0
