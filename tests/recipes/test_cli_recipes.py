"""`doorloc recipes ...` and `doorloc targets` end to end on a SQLite file."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from doorloc.app.cli import app
from doorloc.recipes.rapid import parse_rapid_text
from doorloc.recipes.store import head_revision

GOLDEN = Path(__file__).with_name("golden")
_spec = importlib.util.spec_from_file_location(
    "golden_compare", Path(__file__).with_name("golden_compare.py")
)
golden_compare = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(golden_compare)


@pytest.fixture
def db(tmp_path) -> str:
    return f"sqlite:///{tmp_path / 'cli.db'}"


def run(*args: str, env: dict | None = None):
    return CliRunner().invoke(app, [str(a) for a in args], env=env)


def test_import_list_show_export_targets(db, tmp_path):
    r = run("recipes", "import", GOLDEN / "golden_recipe.csv", "--db", db)
    assert r.exit_code == 0, r.output
    assert "imported 1 door(s), 2 hinge(s)" in r.output

    r = run("recipes", "list", "--db", db, "--format", "json")
    assert json.loads(r.stdout) == [
        {"door_id": "GOLDEN-1", "width_mm": 900.0, "height_mm": 2100.0, "thickness_mm": 50.0, "hinges": 2}
    ]
    r = run("recipes", "show", "GOLDEN-1", "--db", db)
    assert json.loads(r.stdout)["hinges"][1]["path_points"] == 9

    out = tmp_path / "all.csv"
    r = run("recipes", "export", "--db", db, "--out", out)
    assert r.exit_code == 0 and out.read_text().startswith("door_id,")

    r = run(
        "targets",
        "--door-id",
        "GOLDEN-1",
        "--pose",
        "1.25",
        "-3.5",
        "0.8",
        "--db",
        db,
        "--format",
        "rapid-module",
    )
    assert r.exit_code == 0, r.output
    golden_compare.assert_same_values((GOLDEN / "GOLDEN-1.mod").read_text(), r.stdout, "GOLDEN-1.mod")

    r = run(
        "targets", "--door-id", "GOLDEN-1", "--pose", "-1", "2", "-0.5", "--db", db, "--format", "rapid-text"
    )
    assert len(parse_rapid_text(r.stdout)) == 19

    r = run("targets", "--door-id", "GOLDEN-1", "--pose", "0", "0", "0", "--db", db)
    doc = json.loads(r.stdout)
    assert doc["face_y_mm"] == 0.0 and doc["targets"][1]["name"] == "H1_P1"
    assert doc["targets"][1]["quat"] == [1.0, 0.0, 0.0, 0.0]


def test_database_from_environment(tmp_path):
    url = f"sqlite:///{tmp_path / 'env.db'}"
    r = run("recipes", "import", GOLDEN / "golden_recipe.csv", env={"DOORLOC_DATABASE_URL": url})
    assert r.exit_code == 0, r.output
    assert (tmp_path / "env.db").is_file()
    assert "GOLDEN-1" in run("recipes", "list", env={"DOORLOC_DATABASE_URL": url}).stdout


def test_one_database_option_and_plain_help(db):
    """--db everywhere (serve and batch still take their older --database-url, unlisted); --pose reads X Z YAW or
    X,Z,YAW; flags show no type; `version` is kept for scripts but only --version is listed."""
    assert run("recipes", "import", GOLDEN / "golden_recipe.csv", "--db", db).exit_code == 0
    assert run("targets", "--door-id", "GOLDEN-1", "--pose", "0,0,0", "--db", db).exit_code == 0
    same = run("targets", "--door-id", "GOLDEN-1", "--pose", "0", "0", "0", "--db", db)
    assert run("targets", "--door-id", "GOLDEN-1", "--pose=0,0,0", "--db", db).stdout == same.stdout
    for command in ("serve", "batch", "locate", "reach", "targets", "recipes list", "keys list"):
        help_text = run(*command.split(), "--help").stdout
        assert "--db URL" in help_text and "--database-url" not in help_text, command
        assert "<bool>" not in help_text, command
    assert "X Z YAW" in run("reach", "--help").stdout
    top = run("--help").stdout
    commands = top.split("Commands:")[1]
    assert "--version" in top and "render" in commands and "\n  version " not in commands
    assert run("version").exit_code == 0 and run("--version").exit_code == 0


def test_targets_use_the_cell_fixture_and_robot_section(db, tmp_path):
    run("recipes", "import", GOLDEN / "golden_recipe.csv", "--db", db)
    cell_src = (Path(__file__).parents[2] / "fixtures" / "cell_thesis.yaml").read_text()
    cell = tmp_path / "cell.yaml"
    cell.write_text(cell_src + "\nrobot:\n  tool_name: tRouter\n")
    # move the fixture so the hinge face lies 7 mm deeper for this door
    cell.write_text(cell.read_text().replace("face_y_mm: 0.0", "face_y_mm: 7.0"))
    r = run("targets", "--door-id", "GOLDEN-1", "--pose", "0", "0", "0", "--db", db, "--cell", cell)
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["face_y_mm"] == 7.0 and doc["targets"][1]["y_mm"] == pytest.approx(3.5 + 7.0)
    r = run(
        "targets",
        "--door-id",
        "GOLDEN-1",
        "--pose",
        "0",
        "0",
        "0",
        "--db",
        db,
        "--cell",
        cell,
        "--format",
        "rapid-module",
    )
    assert "PERS tooldata tRouter:=" in r.stdout


def test_bad_input_gives_a_sentence_and_exit_2(db, tmp_path):
    bad = tmp_path / "bad.csv"
    lines = (GOLDEN / "golden_recipe.csv").read_text().splitlines()
    bad.write_text("\n".join([lines[0], lines[1].replace(",3.5,", ",0,")]) + "\n")
    r = run("recipes", "import", bad, "--db", db)
    assert r.exit_code == 2
    assert "line 2, hinge_depth_mm" in r.stderr and "Traceback" not in r.output
    assert run("recipes", "list", "--db", db, "--format", "json").stdout.strip() == "[]"

    r = run("recipes", "import", tmp_path / "missing.csv", "--db", db)
    assert r.exit_code == 2 and "no such recipe file" in r.stderr
    r = run("recipes", "show", "NOPE", "--db", db)
    assert r.exit_code == 2 and "no recipe for door 'NOPE'" in r.stderr
    r = run("targets", "--door-id", "NOPE", "--pose", "0", "0", "0", "--db", db)
    assert r.exit_code == 2
    r = run("recipes", "list", "--db", "postgresql+psycopg://u:pw@127.0.0.1:1/x?connect_timeout=2")
    assert r.exit_code == 3 and "cannot open the recipe database" in r.stderr and ":pw@" not in r.stderr


def test_dry_run_and_init_db(db):
    r = run("recipes", "import", GOLDEN / "golden_recipe.csv", "--db", db, "--dry-run")
    assert r.exit_code == 0 and "dry run" in r.stdout
    r = run("recipes", "init-db", "--db", db)
    assert r.exit_code == 0 and f"revision {head_revision()}" in r.stdout
    assert "0 recipe(s)" in run("recipes", "list", "--db", db).stderr


def test_spindle_on_tool_z(db, tmp_path):
    run("recipes", "import", GOLDEN / "golden_recipe.csv", "--db", db)
    cell = tmp_path / "cell.yaml"
    cell.write_text(
        (Path(__file__).parents[2] / "fixtures" / "cell_thesis.yaml").read_text()
        + "\nrobot:\n  spindle_axis: z\n"
    )
    r = run("targets", "--door-id", "GOLDEN-1", "--pose", "0", "0", "0", "--db", db, "--cell", cell)
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["targets"][0]["quat"] == pytest.approx([0.5**0.5, -(0.5**0.5), 0, 0])
    r = run(
        "targets",
        "--door-id",
        "GOLDEN-1",
        "--pose",
        "0",
        "0",
        "0",
        "--db",
        db,
        "--cell",
        cell,
        "--format",
        "rapid-module",
    )
    assert "PERS tooldata tSpindle:=[TRUE,[[0,0,250],[1,0,0,0]]" in r.stdout
