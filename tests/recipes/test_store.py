"""The recipe database on SQLite and PostgreSQL: migrations, round trips, constraints, transactions."""

from __future__ import annotations

import pytest
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import insert, select, text
from sqlalchemy.exc import IntegrityError

from doorloc.recipes.store import (
    ENV_DATABASE_URL,
    RecipeStore,
    RecipeStoreError,
    database_url,
    head_revision,
    redacted_url,
    schema_revision,
)
from doorloc.recipes.tables import Base, DoorRow, HingeRow


def test_open_migrates_to_head_and_matches_the_orm(store):
    assert schema_revision(store.engine) == head_revision()
    with store.engine.connect() as conn:
        diffs = compare_metadata(MigrationContext.configure(conn), Base.metadata)
    assert diffs == []


def test_reopening_is_idempotent(db_url):
    with RecipeStore(db_url) as a:
        a.put(_recipe())
    with RecipeStore(db_url) as b:
        assert b.count() == 1


def test_put_get_round_trip(store, recipe_factory):
    r = recipe_factory()
    assert store.get(r.door_id) is None
    store.put(r)
    back = store.get(r.door_id)
    assert back == r
    assert back.hinges[1].corrections == r.hinges[1].corrections


def test_put_replaces_a_recipe_with_the_same_id(store, recipe_factory):
    store.put(recipe_factory())
    one_hinge = recipe_factory(hinges=[recipe_factory().hinges[0]], feed_mm_s=30)
    store.put(one_hinge)
    assert store.get("D-100") == one_hinge
    assert store.count() == 1
    with store.engine.connect() as conn:
        assert conn.scalar(text("SELECT count(*) FROM hinges")) == 1


def test_list_count_ids_and_iteration(store, recipe_factory):
    store.put_many([recipe_factory(f"D-{k:03d}") for k in (3, 1, 2)])
    rows = store.list()
    assert [r.door_id for r in rows] == ["D-001", "D-002", "D-003"]
    assert all(r.hinge_count == 2 and r.width_mm == 900 for r in rows)
    assert [r.door_id for r in store.list(limit=1, offset=1)] == ["D-002"]
    assert store.door_ids() == ["D-001", "D-002", "D-003"] and store.count() == 3
    assert [r.door_id for r in store.iter_recipes(batch=2)] == ["D-001", "D-002", "D-003"]


def test_delete_cascades_to_hinges(store, recipe_factory):
    store.put(recipe_factory())
    assert store.delete("D-100") is True
    assert store.delete("D-100") is False
    with store.engine.connect() as conn:
        assert conn.scalar(text("SELECT count(*) FROM hinges")) == 0


def test_put_many_refuses_duplicate_ids_and_writes_nothing(store, recipe_factory):
    with pytest.raises(ValueError, match="more than once: D-1"):
        store.put_many([recipe_factory("D-1"), recipe_factory("D-2"), recipe_factory("D-1")])
    assert store.count() == 0


def _door(**over):
    row = dict(
        door_id="RAW-1",
        width_mm=900,
        height_mm=2100,
        thickness_mm=50,
        arris_mm=0,
        tool_diameter_mm=16,
        spindle_rpm=18000,
        feed_mm_s=25,
    )
    row.update(over)
    return row


@pytest.mark.parametrize("bad", [{"width_mm": 0}, {"thickness_mm": -5}, {"feed_mm_s": 0}, {"arris_mm": -1}])
def test_database_checks_refuse_non_positive_sizes(store, bad):
    with pytest.raises(IntegrityError), store.engine.begin() as conn:
        conn.execute(insert(DoorRow), [_door(**bad)])


def test_database_refuses_duplicate_door_ids_and_orphan_hinges(store):
    with store.engine.begin() as conn:
        conn.execute(insert(DoorRow), [_door()])
    with pytest.raises(IntegrityError), store.engine.begin() as conn:
        conn.execute(insert(DoorRow), [_door()])
    hinge = dict(
        door_pk=999_999,
        position=1,
        z_mm=1,
        length_mm=1,
        width_mm=1,
        x_mm=0,
        depth_mm=1,
        corner_radius_mm=0.5,
        path_points=6,
    )
    with pytest.raises(IntegrityError), store.engine.begin() as conn:
        conn.execute(insert(HingeRow), [hinge])
    with store.engine.begin() as conn:
        pk = conn.scalar(select(DoorRow.id).where(DoorRow.door_id == "RAW-1"))
    with pytest.raises(IntegrityError), store.engine.begin() as conn:
        conn.execute(insert(HingeRow), [{**hinge, "door_pk": pk, "path_points": 7}])


def test_migrate_false_needs_an_existing_schema(tmp_path):
    url = f"sqlite:///{tmp_path / 'empty.db'}"
    with RecipeStore(url, migrate=False) as s:
        assert schema_revision(s.engine) is None


def test_unreachable_database_is_a_clear_error():
    with pytest.raises(
        RecipeStoreError, match=r"cannot open the recipe database postgresql\+psycopg://u:\*\*\*@"
    ):
        RecipeStore("postgresql+psycopg://u:secret@127.0.0.1:1/x?connect_timeout=2")


def test_database_url_precedence(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert database_url({}) == f"sqlite:///{tmp_path / 'doorloc.db'}"
    assert database_url({ENV_DATABASE_URL: "sqlite:///x.db"}) == "sqlite:///x.db"
    assert database_url("postgresql+psycopg://a/b") == "postgresql+psycopg://a/b"

    class Settings:
        database_url = None

    assert database_url(Settings()) == f"sqlite:///{tmp_path / 'doorloc.db'}"
    Settings.database_url = "sqlite:///y.db"
    assert database_url(Settings()) == "sqlite:///y.db"
    monkeypatch.setenv(ENV_DATABASE_URL, "sqlite:///env.db")
    assert database_url() == "sqlite:///env.db"
    assert redacted_url("postgresql+psycopg://u:pw@h/db") == "postgresql+psycopg://u:***@h/db"


def _recipe():
    from doorloc.recipes.models import DoorRecipe, Hinge

    return DoorRecipe(
        door_id="R-1",
        width_mm=900,
        height_mm=2100,
        thickness_mm=50,
        tool_diameter_mm=16,
        spindle_rpm=18000,
        feed_mm_s=25,
        hinges=[Hinge(z_mm=250, length_mm=100, width_mm=30, x_mm=10, depth_mm=3, corner_radius_mm=8)],
    )


def test_concurrent_first_opens_migrate_once(db_url):
    """Several workers opening a fresh database at once (e.g. service workers) must all succeed."""
    from concurrent.futures import ThreadPoolExecutor

    def open_and_count(_):
        with RecipeStore(db_url) as s:
            return s.count()

    with ThreadPoolExecutor(6) as ex:
        assert list(ex.map(open_and_count, range(6))) == [0] * 6
    with RecipeStore(db_url) as s:
        assert schema_revision(s.engine) == head_revision()


def test_migrations_downgrade_and_upgrade_again(store, recipe_factory):
    from alembic import command

    from doorloc.recipes.store import _alembic_config, upgrade_schema

    store.put(recipe_factory())
    cfg = _alembic_config()
    with store.engine.begin() as conn:
        cfg.attributes["connection"] = conn
        command.downgrade(cfg, "base")
    assert schema_revision(store.engine) is None
    upgrade_schema(store.engine)
    assert schema_revision(store.engine) == head_revision() and store.count() == 0
