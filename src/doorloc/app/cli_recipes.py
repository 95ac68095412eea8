"""`doorloc recipes ...` (the recipe database) and `doorloc targets` (robot targets for a measured pose).

The database is ``--db URL``, else ``$DOORLOC_DATABASE_URL``, else ``./doorloc.db`` (SQLite);
see :func:`doorloc.recipes.store.database_url`. Opening it upgrades its schema to the newest
migration. Heavy imports live inside the commands so ``doorloc --help`` stays fast.
"""

from __future__ import annotations

import json
import sys
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from doorloc.app.cli_common import DbOption, PoseCommand, PoseOption, load_cell_or_fail, open_store
from doorloc.app.errors import EXIT_FAILED, EXIT_REFUSED, EXIT_USAGE, fail

if TYPE_CHECKING:
    from doorloc.cell import Fixture
    from doorloc.limits import MillingLimits
    from doorloc.recipes.models import DoorRecipe
    from doorloc.recipes.rapid import RobotSetup


#: ``--cell`` of the commands that only need the cell's spindle and cutter bounds (its ``milling:`` section)
MillingCellOption = Annotated[
    Path | None,
    typer.Option(
        "--cell",
        help="cell.yaml whose milling: section (spindle speeds, feeds, tool reach) bounds the recipes; "
        "default: doorloc's defaults",
    ),
]


class ListFormat(StrEnum):
    table = "table"
    json = "json"


class RecipeFormat(StrEnum):
    json = "json"
    csv = "csv"


class TargetFormat(StrEnum):
    json = "json"
    rapid_text = "rapid-text"
    rapid_module = "rapid-module"


def _emit(text: str, out: Path | None) -> None:
    if out is None:
        sys.stdout.write(text)
        return
    from doorloc.fileio import atomic_write_text

    try:
        atomic_write_text(out, text)
    except OSError as e:
        raise fail(f"cannot write {out}: {e.strerror or e}", EXIT_FAILED) from None
    typer.echo(f"wrote {out}", err=True)


def _recipe_json(recipe) -> dict:
    return recipe.model_dump(mode="json")


recipes_app = typer.Typer(
    name="recipes", help="The door-recipe database: import, list, show, export.", no_args_is_help=True
)


@recipes_app.command("init-db")
def init_db(db: DbOption = None) -> None:
    """Create or upgrade the recipe database schema (Alembic 'upgrade head') and print its revision."""
    from doorloc.recipes.store import redacted_url, schema_revision

    store = open_store(db)
    with store:
        typer.echo(f"{redacted_url(store.url)}: schema at revision {schema_revision(store.engine)}")


def _cli_user() -> str:
    """Who runs the command, for the recipe history (``cli:<login>``)."""
    import getpass

    try:
        return f"cli:{getpass.getuser()}"
    except (KeyError, OSError):  # no login name (e.g. a container's numeric user)
        return "cli:unknown"


def _echo_changes(changed: dict) -> None:
    """What an import would change in stored recipes (stderr; at most 20 doors, 6 changes each)."""
    for door_id, changes in list(changed.items())[:20]:
        shown = "; ".join(str(c) for c in changes[:6]) + (
            f"; ... {len(changes) - 6} more" if len(changes) > 6 else ""
        )
        typer.echo(f"  {door_id} would change: {shown}", err=True)
    if len(changed) > 20:
        typer.echo(f"  ... and {len(changed) - 20} more door(s)", err=True)


@recipes_app.command("import")
def import_cmd(
    file: Path = typer.Argument(
        ..., help="recipe file: .csv or .xlsx, one row per hinge, door fields repeated"
    ),
    db: DbOption = None,
    dry_run: bool = typer.Option(
        False, "--dry-run", help="check the file and show what would change; write nothing"
    ),
    replace: bool = typer.Option(
        False, "--replace", help="overwrite stored recipes that differ (each a new version)"
    ),
    cell: MillingCellOption = None,
) -> None:
    """Import a recipe file in one transaction: all its doors, or (with any bad row) none.

    Doors already stored with a different recipe are listed with what would change; they are only
    overwritten with --replace (each a new version in the history). --cell: its spindle and cutter bounds.
    """
    recipes = _read_recipe_file(file, cell)
    hinges = sum(len(r.hinges) for r in recipes)
    if dry_run and db is None:
        typer.echo(f"{file}: {len(recipes)} door(s), {hinges} hinge(s) OK (dry run, nothing written)")
        return
    from sqlalchemy.exc import SQLAlchemyError

    with open_store(db) as store:
        preview = store.preview(recipes)
        changed = {k: v for k, v in preview.items() if v}
        new = sum(v is None for v in preview.values())
        _echo_changes(changed)
        summary = (
            f"{file}: {len(recipes)} door(s), {hinges} hinge(s): {new} new, {len(changed)} changed, "
            f"{len(recipes) - new - len(changed)} unchanged"
        )
        if dry_run:
            typer.echo(summary + " (dry run, nothing written)")
            return
        if changed and not replace:
            raise fail(
                f"{summary}; {len(changed)} stored recipe(s) would be overwritten (listed above): pass "
                "--replace to do so, nothing was written",
                EXIT_REFUSED,
            )
        try:
            store.put_many(recipes, by=_cli_user())
        except SQLAlchemyError as e:
            raise fail(f"import failed, nothing written: {str(e).splitlines()[0]}", EXIT_FAILED) from None
    typer.echo(
        f"imported {len(recipes)} door(s), {hinges} hinge(s) from {file} ({new} new, {len(changed)} changed)"
    )


@recipes_app.command("history")
def history_cmd(
    door_id: str = typer.Argument(..., help="door id (barcode)"),
    db: DbOption = None,
    as_json: bool = typer.Option(False, "--json", help="print JSON (with each version's whole recipe)"),
) -> None:
    """Every version of a door recipe: who changed what, when."""
    with open_store(db) as store:
        versions = store.history(door_id)
    if not versions:
        raise fail(f"no recipe for door {door_id!r} was ever stored")
    if as_json:
        typer.echo(
            json.dumps(
                [
                    {
                        "version": v.version,
                        "action": v.action,
                        "changed_by": v.changed_by,
                        "changed_at": v.changed_at.isoformat() if v.changed_at else None,
                        "changes": [c.__dict__ for c in v.changes],
                        "recipe": v.recipe.model_dump(mode="json") if v.recipe else None,
                    }
                    for v in versions
                ],
                indent=2,
            )
        )
        return
    for v in versions:
        when = v.changed_at.isoformat(timespec="seconds") if v.changed_at else "?"
        what = "; ".join(str(c) for c in v.changes) if v.changes else ""
        typer.echo(f"v{v.version:<4} {v.action:<8} {when:<25} {v.changed_by:<20} {what}")


@recipes_app.command("delete")
def delete_cmd(
    door_id: str = typer.Argument(..., help="door id (barcode)"),
    db: DbOption = None,
) -> None:
    """Retire a door recipe: locate and targets no longer use it; its history stays."""
    with open_store(db) as store:
        if not store.delete(door_id, by=_cli_user()):
            raise fail(f"no recipe for door {door_id!r} in the database")
    typer.echo(
        f"retired the recipe of door {door_id} (its history is kept: doorloc recipes history {door_id})"
    )


@recipes_app.command("list")
def list_cmd(
    db: DbOption = None,
    fmt: ListFormat = typer.Option(ListFormat.table, "--format", help="table or json"),
) -> None:
    """List the stored recipes (door id, size, number of hinges)."""
    store = open_store(db)
    with store:
        rows = store.list()
    if fmt is ListFormat.json:
        typer.echo(
            json.dumps(
                [
                    {
                        "door_id": r.door_id,
                        "width_mm": r.width_mm,
                        "height_mm": r.height_mm,
                        "thickness_mm": r.thickness_mm,
                        "hinges": r.hinge_count,
                    }
                    for r in rows
                ],
                indent=2,
            )
        )
        return
    typer.echo(f"{'door_id':<24} {'width':>8} {'height':>8} {'thick':>7} {'hinges':>6}")
    for r in rows:
        typer.echo(
            f"{r.door_id:<24} {r.width_mm:>8g} {r.height_mm:>8g} {r.thickness_mm:>7g} {r.hinge_count:>6d}"
        )
    typer.echo(f"{len(rows)} recipe(s)", err=True)


@recipes_app.command("show")
def show_cmd(
    door_id: str = typer.Argument(..., help="door id (barcode)"),
    db: DbOption = None,
    fmt: RecipeFormat = typer.Option(RecipeFormat.json, "--format", help="json or csv (the import layout)"),
) -> None:
    """Print one recipe."""
    from doorloc.recipes.importer import recipes_to_csv

    store = open_store(db)
    with store:
        recipe = store.get(door_id)
    if recipe is None:
        raise fail(
            f"no recipe for door {door_id!r} in the database; import one with 'doorloc recipes import'"
        )
    if fmt is RecipeFormat.csv:
        sys.stdout.write(recipes_to_csv([recipe]))
    else:
        typer.echo(json.dumps(_recipe_json(recipe), indent=2))


@recipes_app.command("export")
def export_cmd(
    db: DbOption = None,
    out: Path = typer.Option(None, "--out", "-o", help="output file (written atomically); default stdout"),
    fmt: RecipeFormat = typer.Option(
        None, "--format", help="csv (the import layout) or json; default from --out"
    ),
) -> None:
    """Export every recipe: CSV in the import layout (re-importable) or a JSON list."""
    from doorloc.recipes.importer import recipes_to_csv

    if fmt is None:
        fmt = RecipeFormat.json if out is not None and out.suffix.lower() == ".json" else RecipeFormat.csv
    store = open_store(db)
    with store:
        recipes = list(store.iter_recipes())
    text = (
        json.dumps([_recipe_json(r) for r in recipes], indent=2) + "\n"
        if fmt is RecipeFormat.json
        else recipes_to_csv(recipes)
    )
    _emit(text, out)


def targets_cmd(
    door_id: str = typer.Option(..., "--door-id", help="door id (barcode) of a stored recipe"),
    pose: PoseOption = ...,  # type: ignore[assignment]
    fmt: TargetFormat = typer.Option(TargetFormat.json, "--format", help="json, rapid-text or rapid-module"),
    cell: Path = typer.Option(
        None,
        "--cell",
        help="cell.yaml: fixture (hinge-face depth) and optional robot: section (tool/wobj data)",
    ),
    db: DbOption = None,
    out: Path = typer.Option(None, "--out", "-o", help="output file (written atomically); default stdout"),
    clearance: float = typer.Option(
        10.0, "--clearance", min=0.0, help="approach/retract distance before the face, mm"
    ),
) -> None:
    """Robot targets (cell frame) for a stored door recipe at a measured pose.

    Without --cell the hinge-face depth comes from the default fixture (face_y_mm 0 at a 900 mm door,
    -0.5 mm per mm of width) and the RAPID module uses the default tool/work-object data.
    """
    from doorloc.pose import DoorPose
    from doorloc.recipes.rapid import rapid_module, rapid_text
    from doorloc.recipes.targets import targets_for_pose

    fixture, robot, milling = _fixture_and_robot(cell)
    recipe = _stored_recipe(db, door_id, milling)
    door_pose = DoorPose(*pose)
    face_y = fixture.face_y(recipe.width_mm)
    targets = targets_for_pose(
        recipe, door_pose, face_y, clearance_mm=clearance, base_orientation=robot.base_orientation()
    )
    if fmt is TargetFormat.rapid_text:
        text = rapid_text(targets)
    elif fmt is TargetFormat.rapid_module:
        text = rapid_module(recipe, targets, robot, pose=door_pose, face_y_mm=face_y)
    else:
        text = (
            json.dumps(
                {
                    "door_id": recipe.door_id,
                    "pose": {"x_mm": door_pose.x_mm, "z_mm": door_pose.z_mm, "yaw_deg": door_pose.yaw_deg},
                    "face_y_mm": face_y,
                    "targets": [t.model_dump(mode="json") for t in targets],
                },
                indent=2,
            )
            + "\n"
        )
    _emit(text, out)


def _read_recipe_file(file: Path, cell: Path | None) -> list[DoorRecipe]:
    """The recipes of ``file`` held to ``cell``'s spindle and cutter bounds; exit 2 with what is wrong."""
    from doorloc.recipes.importer import RecipeImportError, load_recipe_file

    milling = _milling_of(cell)
    if not file.is_file():
        raise fail(f"no such recipe file: {file}")
    try:
        recipes = load_recipe_file(file, milling)
    except RecipeImportError as e:
        raise fail(str(e), EXIT_USAGE) from None
    except OSError as e:
        raise fail(f"cannot read {file}: {e.strerror or e}") from None
    except Exception as e:  # e.g. a damaged .xlsx (zip/xml errors from openpyxl)
        raise fail(f"cannot read {file} as a recipe file: {e.__class__.__name__}: {e}") from None
    return recipes


def _milling_of(cell: Path | None) -> MillingLimits:
    """The cell file's spindle and cutter bounds (doorloc's defaults without a cell); exit 2 for a bad file."""
    from doorloc.limits import DEFAULT_MILLING_LIMITS

    return DEFAULT_MILLING_LIMITS if cell is None else load_cell_or_fail(cell).milling


def _stored_recipe(db: str | None, door_id: str, milling: MillingLimits) -> DoorRecipe:
    """The stored recipe of ``door_id``, held to the cell's spindle and cutter; exit 2 without one or beyond them."""
    from doorloc.recipes.models import milling_problems

    with open_store(db) as store:
        recipe = store.get(door_id)
    if recipe is None:
        raise fail(
            f"no recipe for door {door_id!r} in the database; import one with 'doorloc recipes import'"
        )
    problems = milling_problems(recipe, milling)
    if problems:
        raise fail(
            f"the recipe of door {door_id!r} asks more than the cell's spindle and cutter give: "
            + "; ".join(p.message for p in problems)
        )
    return recipe


def _fixture_and_robot(cell: Path | None) -> tuple[Fixture, RobotSetup, MillingLimits]:
    """The cell file's fixture, RAPID robot data and milling bounds (the defaults without a cell); exit 2 for
    a bad file."""
    from pydantic import ValidationError

    from doorloc.cell import CellFileError, Fixture, load_cell
    from doorloc.limits import DEFAULT_MILLING_LIMITS
    from doorloc.recipes.rapid import RobotSetup, robot_setup_from_cell_file

    if cell is None:
        return Fixture(), RobotSetup(), DEFAULT_MILLING_LIMITS
    try:
        loaded = load_cell(cell)
        return loaded.fixture, robot_setup_from_cell_file(cell), loaded.milling
    except CellFileError as e:
        raise fail(str(e)) from None
    except ValidationError as e:
        first = e.errors(include_url=False)[0]
        raise fail(f"{cell}: robot.{'.'.join(map(str, first['loc']))}: {first['msg']}") from None


def register(app: typer.Typer) -> None:
    """Add this area's subcommands to the root app."""
    app.add_typer(recipes_app, name="recipes")
    app.command("targets", cls=PoseCommand)(targets_cmd)
