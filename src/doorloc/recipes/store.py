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

import builtins
import hashlib
import os
import random
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any, TypeVar

from sqlalchemy import Connection, Engine, create_engine, delete, event, func, insert, select, text
from sqlalchemy.engine import make_url
from sqlalchemy.exc import IntegrityError, OperationalError, SQLAlchemyError
from sqlalchemy.orm import Session, selectinload
from sqlalchemy.pool import StaticPool

from doorloc.recipes.models import MILLING, DoorRecipe, Hinge, PointCorrection
from doorloc.recipes.tables import DoorRow, HingeRow, RecipeVersionRow

_T = TypeVar("_T")

__all__ = [
    "ENV_DATABASE_URL",
    "DEFAULT_DB_FILENAME",
    "database_url",
    "redacted_url",
    "make_engine",
    "upgrade_schema",
    "schema_revision",
    "head_revision",
    "RecipeStore",
    "RecipeSummary",
    "RecipeStoreError",
    "StoredRecipeInvalid",
    "RecipeVersion",
    "RecipeChange",
    "recipe_changes",
    "recipe_sha256",
    "WRITE_ATTEMPTS",
    "SQLITE_BUSY_TIMEOUT_MS",
]

ENV_DATABASE_URL = "DOORLOC_DATABASE_URL"
DEFAULT_DB_FILENAME = "doorloc.db"
MIGRATIONS_DIR = Path(__file__).with_name("migrations")
#: Alembic keeps its migration context in module globals: one migration at a time per process
_MIGRATION_LOCK = threading.Lock()
#: rows per statement when deleting by door id (keeps below every backend's bound-parameter limit)
_CHUNK = 500
#: how long a SQLite writer waits for another one's lock before giving up (then it retries, see WRITE_ATTEMPTS)
SQLITE_BUSY_TIMEOUT_MS = 15_000
#: a write that still meets a lock, a serialisation failure or a concurrent insert is retried this many times
WRITE_ATTEMPTS = 6


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
    url: Any
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
        # Concurrent writers (several service workers, parallel PUTs): WAL lets readers go on while one
        # process writes, busy_timeout makes a writer wait for the lock instead of failing at once with
        # "database is locked", and writes begin IMMEDIATE (RecipeStore._write) so no transaction has to
        # upgrade a read lock into a write lock, which SQLite refuses without waiting.
        file_db = u.database not in (None, "", ":memory:")

        @event.listens_for(engine, "connect")
        def _sqlite_connect(dbapi_conn, _record) -> None:  # noqa: ANN001 - DB-API objects
            dbapi_conn.isolation_level = None
            cur = dbapi_conn.cursor()
            cur.execute("PRAGMA foreign_keys=ON")
            cur.execute(f"PRAGMA busy_timeout={SQLITE_BUSY_TIMEOUT_MS}")
            if file_db:
                cur.execute("PRAGMA journal_mode=WAL")
                cur.execute(
                    "PRAGMA synchronous=NORMAL"
                )  # WAL + NORMAL: durable at checkpoints, never corrupt
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


@dataclass(frozen=True)
class RecipeChange:
    """One field that differs between two versions of a recipe (``hinges[1].z_mm``, old and new value)."""

    field: str
    old: Any
    new: Any

    def __str__(self) -> str:
        return f"{self.field}: {self.old!r} -> {self.new!r}"


@dataclass(frozen=True)
class RecipeVersion:
    """One entry of a recipe's history: the version, what happened, who did it, when, and what changed."""

    door_id: str
    version: int
    action: str  # created, updated, deleted, migrated
    changed_by: str
    changed_at: datetime | None
    changes: list[RecipeChange] = field(default_factory=list)
    recipe: DoorRecipe | None = None


def recipe_sha256(r: DoorRecipe) -> str:
    """Hash of a recipe's content: equal recipes, equal hash (pydantic's JSON: fields in the model's order)."""
    return hashlib.sha256(r.model_dump_json().encode()).hexdigest()


def _flatten(doc: Any, prefix: str = "") -> dict[str, Any]:
    if isinstance(doc, dict):
        out: dict[str, Any] = {}
        for k, v in doc.items():
            out.update(_flatten(v, f"{prefix}.{k}" if prefix else k))
        return out
    if isinstance(doc, list) and prefix == "hinges":
        out = {"hinges": len(doc)}
        for i, v in enumerate(doc):
            out.update(_flatten(v, f"hinges[{i}]"))
        return out
    return {prefix: doc}


def recipe_changes(old: DoorRecipe | dict | None, new: DoorRecipe | dict | None) -> list[RecipeChange]:
    """Field-by-field differences (hinges by position; ``hinges`` itself is their number)."""
    a = _flatten(old.model_dump(mode="json") if isinstance(old, DoorRecipe) else (old or {}))
    b = _flatten(new.model_dump(mode="json") if isinstance(new, DoorRecipe) else (new or {}))
    return [
        RecipeChange(k, a.get(k), b.get(k))
        for k in sorted(set(a) | set(b), key=_field_order)
        if a.get(k) != b.get(k)
    ]


def _field_order(name: str) -> tuple[int, str]:
    return (1 if name.startswith("hinges[") else 0, name)


def _door_values(r: DoorRecipe) -> dict[str, Any]:
    return {
        "door_id": r.door_id,
        "width_mm": r.width_mm,
        "height_mm": r.height_mm,
        "thickness_mm": r.thickness_mm,
        "arris_mm": r.arris_mm,
        "tool_diameter_mm": r.tool_diameter_mm,
        "spindle_rpm": r.spindle_rpm,
        "feed_mm_s": r.feed_mm_s,
    }


def _hinge_values(h: Hinge, door_pk: int, position: int) -> dict[str, Any]:
    return {
        "door_pk": door_pk,
        "position": position,
        "z_mm": h.z_mm,
        "length_mm": h.length_mm,
        "width_mm": h.width_mm,
        "x_mm": h.x_mm,
        "depth_mm": h.depth_mm,
        "corner_radius_mm": h.corner_radius_mm,
        "path_points": h.path_points,
        "corrections": [[c.dx_mm, c.dy_mm, c.dz_mm] for c in h.corrections] or None,
    }


def _recipe_from_row(row: DoorRow) -> DoorRecipe:
    from pydantic import ValidationError

    try:
        return _build_recipe(row)
    except ValidationError as e:
        reasons = "; ".join(
            str(x["msg"]).removeprefix("Value error, ") for x in e.errors(include_url=False)[:3]
        )
        raise StoredRecipeInvalid(
            f"the stored recipe of door '{row.door_id}' breaks today's rules ({reasons}); correct it "
            "(PUT /v1/doors/ID or doorloc recipes import --replace) before using it"
        ) from None


def _build_recipe(row: DoorRow) -> DoorRecipe:
    hinges = [
        Hinge(
            z_mm=h.z_mm,
            length_mm=h.length_mm,
            width_mm=h.width_mm,
            x_mm=h.x_mm,
            depth_mm=h.depth_mm,
            corner_radius_mm=h.corner_radius_mm,
            path_points=h.path_points,
            corrections=tuple(
                PointCorrection(dx_mm=c[0], dy_mm=c[1], dz_mm=c[2]) for c in (h.corrections or [])
            ),
        )
        for h in row.hinges
    ]
    # the cell's spindle and cutter bounds are checked where the recipe meets the cell (its milling: section)
    return DoorRecipe.model_validate(
        {
            "door_id": row.door_id,
            "width_mm": row.width_mm,
            "height_mm": row.height_mm,
            "thickness_mm": row.thickness_mm,
            "arris_mm": row.arris_mm,
            "hinges": hinges,
            "tool_diameter_mm": row.tool_diameter_mm,
            "spindle_rpm": row.spindle_rpm,
            "feed_mm_s": row.feed_mm_s,
        },
        context={MILLING: None},
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
        # writers of one process take turns here (an in-memory database is one shared connection);
        # writers of several processes are serialised by the database itself (see _write)
        self._write_lock = threading.Lock()
        try:
            self.engine = make_engine(self.url)
            if migrate:
                upgrade_schema(self.engine)
        except SQLAlchemyError as e:
            raise RecipeStoreError(
                f"cannot open the recipe database {redacted_url(self.url)}: {e.__class__.__name__}: "
                f"{str(e).splitlines()[0]}"
            ) from e

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

    def get_versioned(self, door_id: str) -> tuple[DoorRecipe, int] | None:
        """The recipe of ``door_id`` and its version, or None when there is none."""
        with Session(self.engine) as s:
            row = s.scalars(
                select(DoorRow).where(DoorRow.door_id == door_id).options(selectinload(DoorRow.hinges))
            ).one_or_none()
            return None if row is None else (_recipe_from_row(row), row.version)

    def history(self, door_id: str) -> builtins.list[RecipeVersion]:
        """Every recorded change of ``door_id``, oldest first (empty when the door never existed)."""
        with self.engine.connect() as conn:
            rows = conn.execute(
                select(RecipeVersionRow)
                .where(RecipeVersionRow.door_id == door_id)
                .order_by(RecipeVersionRow.version)
            ).all()
        out = []
        for r in rows:
            recipe = None
            if r.recipe is not None:
                try:
                    recipe = DoorRecipe.model_validate(r.recipe, context={MILLING: None})
                except ValueError:  # a version that today's rules refuse is still part of the history
                    recipe = None
            out.append(
                RecipeVersion(
                    r.door_id,
                    r.version,
                    r.action,
                    r.changed_by,
                    r.changed_at,
                    [RecipeChange(**c) for c in (r.changes or [])],
                    recipe,
                )
            )
        return out

    def preview(self, recipes: Iterable[DoorRecipe]) -> dict[str, builtins.list[RecipeChange] | None]:
        """What writing ``recipes`` would change: per door id, None (new door), [] (unchanged) or the changes."""
        recipes = list(recipes)
        ids = [r.door_id for r in recipes]
        stored: dict[str, str | None] = {}
        with self.engine.connect() as conn:
            for k in range(0, len(ids), _CHUNK):
                stored.update(
                    conn.execute(
                        select(DoorRow.door_id, DoorRow.content_sha256).where(
                            DoorRow.door_id.in_(ids[k : k + _CHUNK])
                        )
                    ).all()
                )
        out: dict[str, builtins.list[RecipeChange] | None] = {}
        for r in recipes:
            if r.door_id not in stored:
                out[r.door_id] = None
            elif stored[r.door_id] == recipe_sha256(r):
                out[r.door_id] = []
            else:
                out[r.door_id] = recipe_changes(self.get(r.door_id), r)
        return out

    def list(self, *, limit: int | None = None, offset: int = 0) -> builtins.list[RecipeSummary]:
        """Summaries of the stored recipes, ordered by door id."""
        counts = select(HingeRow.door_pk, func.count().label("n")).group_by(HingeRow.door_pk).subquery()
        q = (
            select(
                DoorRow.door_id,
                DoorRow.width_mm,
                DoorRow.height_mm,
                DoorRow.thickness_mm,
                func.coalesce(counts.c.n, 0),
                DoorRow.updated_at,
            )
            .outerjoin(counts, counts.c.door_pk == DoorRow.id)
            .order_by(DoorRow.door_id)
            .offset(offset)
        )
        if limit is not None:
            q = q.limit(limit)
        with self.engine.connect() as conn:
            return [RecipeSummary(*row) for row in conn.execute(q)]

    def door_ids(self) -> builtins.list[str]:
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
                    select(DoorRow)
                    .where(DoorRow.door_id > last)
                    .order_by(DoorRow.door_id)
                    .limit(batch)
                    .options(selectinload(DoorRow.hinges))
                ).all()
                recipes = [_recipe_from_row(r) for r in rows]
            if not recipes:
                return
            yield from recipes
            last = recipes[-1].door_id

    # -- writing ---------------------------------------------------------------------------------
    def _write(self, work: Callable[[Connection], _T]) -> _T:
        """Run ``work`` in one write transaction, retried when it meets another writer.

        SQLite: BEGIN IMMEDIATE takes the write lock first (waiting up to the busy timeout); PostgreSQL:
        per-door advisory locks inside ``work``. A lock timeout, a serialisation failure or a unique-key
        race (two writers creating the same door's next version) rolls back and runs again, up to
        :data:`WRITE_ATTEMPTS` times with a growing random pause.
        """
        for attempt in range(1, WRITE_ATTEMPTS + 1):
            try:
                with (
                    self._write_lock,
                    self.engine.connect().execution_options(sqlite_begin="IMMEDIATE") as conn,
                ):
                    with conn.begin():
                        return work(conn)
            except (OperationalError, IntegrityError) as e:
                retryable = (isinstance(e, IntegrityError) and "recipe_versions" in str(e)) or _is_lock_error(
                    e
                )
                if not retryable or attempt == WRITE_ATTEMPTS:
                    raise
                time.sleep(random.uniform(0.01, 0.05) * 2**attempt)
        raise AssertionError("unreachable")  # pragma: no cover

    def put(self, recipe: DoorRecipe, *, by: str = "unknown") -> int:
        """Store ``recipe``, replacing any recipe with the same door id; its version (unchanged: the old one)."""
        return self.put_versions([recipe], by=by)[recipe.door_id]

    def put_many(self, recipes: Iterable[DoorRecipe], *, by: str = "unknown") -> int:
        """Store many recipes in one transaction (all or none), replacing same-id recipes.

        Each changed recipe becomes a new version in the history; one identical to the stored one is left
        as it is. Bulk statements (one multi-row INSERT per table), not one ORM flush per door.

        Returns
        -------
        int
            The number of recipes given (written or already identical).
        """
        recipes = list(recipes)
        self.put_versions(recipes, by=by)
        return len(recipes)

    def put_versions(self, recipes: Iterable[DoorRecipe], *, by: str = "unknown") -> dict[str, int]:
        """Like :meth:`put_many`; returns each door's version after the write."""
        recipes = list(recipes)
        ids = [r.door_id for r in recipes]
        if len(set(ids)) != len(ids):
            from collections import Counter

            dup = sorted(i for i, n in Counter(ids).items() if n > 1)
            raise ValueError(f"door ids given more than once: {', '.join(dup[:10])}")
        if not recipes:
            return {}
        return self._write(lambda conn: self._put_rows(conn, recipes, by[:64]))

    def _put_rows(self, conn: Connection, recipes: builtins.list[DoorRecipe], by: str) -> dict[str, int]:
        ids = sorted(r.door_id for r in recipes)
        if conn.dialect.name == "postgresql":  # one writer per door at a time, in a fixed order (no deadlock)
            for door_id in ids:
                conn.execute(
                    text("SELECT pg_advisory_xact_lock(hashtext(:k))"), {"k": "doorloc-door:" + door_id}
                )
        current: dict[str, tuple[int, int, str | None]] = {}
        last: dict[str, int] = {}
        for k in range(0, len(ids), _CHUNK):
            chunk = ids[k : k + _CHUNK]
            for row_pk, door_id, version, sha in conn.execute(
                select(DoorRow.id, DoorRow.door_id, DoorRow.version, DoorRow.content_sha256).where(
                    DoorRow.door_id.in_(chunk)
                )
            ):
                current[door_id] = (row_pk, version, sha)
            for door_id, v in conn.execute(
                select(RecipeVersionRow.door_id, func.max(RecipeVersionRow.version))
                .where(RecipeVersionRow.door_id.in_(chunk))
                .group_by(RecipeVersionRow.door_id)
            ):
                last[door_id] = int(v)
        versions: dict[str, int] = {}
        changed: builtins.list[tuple[DoorRecipe, str, dict]] = []
        for r in recipes:
            sha = recipe_sha256(r)
            cur = current.get(r.door_id)
            if cur is not None and cur[2] == sha:
                versions[r.door_id] = cur[1]  # identical: no new version
            else:
                changed.append((r, sha, r.model_dump(mode="json")))
        if not changed:
            return versions
        previous = self._stored_documents(conn, [r.door_id for r, _, _ in changed if r.door_id in current])
        replaced = [current[r.door_id][0] for r, _, _ in changed if r.door_id in current]
        for k in range(0, len(replaced), _CHUNK):
            # the replaced doors' hinges in one statement (SQLite's per-row ON DELETE CASCADE is slow), then the doors
            conn.execute(delete(HingeRow).where(HingeRow.door_pk.in_(replaced[k : k + _CHUNK])))
            conn.execute(delete(DoorRow).where(DoorRow.id.in_(replaced[k : k + _CHUNK])))
        history = []
        door_rows = []
        for r, sha, doc in changed:
            v = max(last.get(r.door_id, 0), current.get(r.door_id, (0, 0, None))[1]) + 1
            versions[r.door_id] = v
            door_rows.append({**_door_values(r), "version": v, "content_sha256": sha, "updated_by": by})
            old = previous.get(r.door_id)
            history.append(
                {
                    "door_id": r.door_id,
                    "version": v,
                    "action": "updated" if r.door_id in current else "created",
                    "changed_by": by,
                    "recipe": doc,
                    "changes": [c.__dict__ for c in recipe_changes(old, doc)] if old is not None else None,
                }
            )
        result = conn.execute(insert(DoorRow).returning(DoorRow.id, DoorRow.door_id), door_rows)
        pk = {door_id: door_pk for door_pk, door_id in result}
        hinge_rows = [
            _hinge_values(h, pk[r.door_id], i + 1) for r, _, _ in changed for i, h in enumerate(r.hinges)
        ]
        conn.execute(insert(HingeRow), hinge_rows)
        conn.execute(insert(RecipeVersionRow), history)
        return versions

    @staticmethod
    def _stored_documents(conn: Connection, door_ids: builtins.list[str]) -> dict[str, dict]:
        """The recipe JSON of each door's newest history entry (for the change list of the next version)."""
        out: dict[str, dict] = {}
        for k in range(0, len(door_ids), _CHUNK):
            chunk = door_ids[k : k + _CHUNK]
            newest = (
                select(RecipeVersionRow.door_id, func.max(RecipeVersionRow.version).label("v"))
                .where(RecipeVersionRow.door_id.in_(chunk))
                .group_by(RecipeVersionRow.door_id)
                .subquery()
            )
            q = select(RecipeVersionRow.door_id, RecipeVersionRow.recipe).join(
                newest,
                (newest.c.door_id == RecipeVersionRow.door_id) & (newest.c.v == RecipeVersionRow.version),
            )
            out.update({d: doc for d, doc in conn.execute(q) if doc is not None})
        return out

    def delete(self, door_id: str, *, by: str = "unknown") -> bool:
        """Retire a recipe: it no longer serves locate or targets; its history stays, ending in a ``deleted``
        version. True when there was one."""

        def work(conn: Connection) -> bool:
            row = conn.execute(
                select(DoorRow.id, DoorRow.version).where(DoorRow.door_id == door_id)
            ).one_or_none()
            if row is None:
                return False
            last = conn.scalar(
                select(func.max(RecipeVersionRow.version)).where(RecipeVersionRow.door_id == door_id)
            )
            conn.execute(delete(HingeRow).where(HingeRow.door_pk == row.id))
            conn.execute(delete(DoorRow).where(DoorRow.id == row.id))
            conn.execute(
                insert(RecipeVersionRow).values(
                    door_id=door_id,
                    version=max(int(last or 0), row.version) + 1,
                    action="deleted",
                    changed_by=by[:64],
                )
            )
            return True

        return self._write(work)


def _is_lock_error(e: Exception) -> bool:
    msg = str(e).lower()
    return any(
        s in msg
        for s in (
            "database is locked",
            "database table is locked",
            "busy",
            "deadlock detected",
            "could not serialize",
        )
    )
