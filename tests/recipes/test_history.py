"""Recipes with history: every change a version with who/when/what; identical writes add none; retire keeps the
history; concurrent writers on SQLite are serialised (WAL, busy timeout, BEGIN IMMEDIATE, retries)."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

from sqlalchemy import text
from typer.testing import CliRunner

from doorloc.app.cli import app as cli_app
from doorloc.recipes.importer import recipes_to_csv
from doorloc.recipes.store import RecipeStore, recipe_changes


def test_every_change_is_a_version_with_who_and_what(store, recipe_factory):
    r = recipe_factory()
    assert store.put(r, by="alice") == 1
    wider = recipe_factory(width_mm=1350)
    assert store.put(wider, by="bob") == 2
    assert store.put(wider, by="carol") == 2  # identical: no new version
    assert store.get_versioned("D-100") == (wider, 2)
    h = store.history("D-100")
    assert [(v.version, v.action, v.changed_by) for v in h] == [
        (1, "created", "alice"),
        (2, "updated", "bob"),
    ]
    assert [str(c) for c in h[1].changes] == ["width_mm: 900.0 -> 1350.0"]
    assert h[0].recipe == r and h[1].recipe == wider and h[1].changed_at is not None


def test_retire_keeps_the_history_and_versions_go_on(store, recipe_factory):
    store.put(recipe_factory(), by="alice")
    assert store.delete("D-100", by="bob") is True
    assert store.get("D-100") is None and store.delete("D-100") is False
    assert store.put(recipe_factory(feed_mm_s=30), by="carol") == 3
    assert [(v.version, v.action) for v in store.history("D-100")] == [
        (1, "created"),
        (2, "deleted"),
        (3, "created"),
    ]


def test_recipe_changes_name_hinge_fields(recipe_factory):
    a = recipe_factory()
    b = recipe_factory(hinges=[a.hinges[0]])
    names = [c.field for c in recipe_changes(a, b)]
    assert names[0] == "hinges" and any(n.startswith("hinges[1].") for n in names)


def test_50_parallel_writers_on_sqlite_all_succeed(tmp_path, recipe_factory):
    """Issue defect: 15-16 of 20 parallel writes failed with 'database is locked'."""
    url = f"sqlite:///{tmp_path / 'many.db'}"
    RecipeStore(url).close()

    def write(k: int) -> int:
        with RecipeStore(url) as s:  # each writer its own connection, as separate workers have
            return s.put(recipe_factory(feed_mm_s=10 + k), by=f"writer-{k}")

    with ThreadPoolExecutor(50) as ex:
        versions = list(ex.map(write, range(50)))
    assert sorted(versions) == list(range(1, 51))  # 50 writes, 50 distinct versions, none lost
    with RecipeStore(url) as s:
        assert len(s.history("D-100")) == 50
        with s.engine.connect() as conn:
            assert conn.execute(text("PRAGMA journal_mode")).scalar() == "wal"
            assert conn.execute(text("PRAGMA busy_timeout")).scalar() >= 1000


def test_reimport_shows_changes_and_needs_replace(tmp_path, recipe_factory):
    db = f"sqlite:///{tmp_path / 'cli.db'}"
    f = tmp_path / "r.csv"
    f.write_text(recipes_to_csv([recipe_factory()]))
    run = CliRunner().invoke
    assert run(cli_app, ["recipes", "import", str(f), "--db", db]).exit_code == 0
    f.write_text(recipes_to_csv([recipe_factory(width_mm=1000)]))
    r = run(cli_app, ["recipes", "import", str(f), "--db", db])
    assert r.exit_code == 1, r.output
    assert "D-100 would change: width_mm: 900.0 -> 1000.0" in r.output and "--replace" in r.output
    with RecipeStore(db) as s:
        assert s.get("D-100").width_mm == 900  # nothing written
    r = run(cli_app, ["recipes", "import", str(f), "--db", db, "--dry-run"])
    assert r.exit_code == 0 and "1 changed" in r.output
    r = run(cli_app, ["recipes", "import", str(f), "--db", db, "--replace"])
    assert r.exit_code == 0 and "1 changed" in r.output
    r = run(cli_app, ["recipes", "history", "D-100", "--db", db])
    assert "v2" in r.output and "width_mm: 900.0 -> 1000.0" in r.output and "cli:" in r.output
    assert (
        run(cli_app, ["recipes", "import", str(f), "--db", db]).exit_code == 0
    )  # unchanged: no --replace needed
    assert run(cli_app, ["recipes", "delete", "D-100", "--db", db]).exit_code == 0
    assert "deleted" in run(cli_app, ["recipes", "history", "D-100", "--db", db]).output
