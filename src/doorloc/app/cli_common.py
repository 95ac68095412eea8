"""What every `doorloc` command shares: the recipe-database option, opening the database, loading a cell.

One option name for the recipe database everywhere, ``--db URL`` (``--database-url``, its older spelling on
``serve`` and ``batch``, is still accepted there, hidden); without it ``$DOORLOC_DATABASE_URL``, else
``./doorloc.db`` (:func:`doorloc.recipes.store.database_url`).
"""

from __future__ import annotations

from os import PathLike
from typing import TYPE_CHECKING, Annotated, Any

import typer
from typer.core import TyperCommand

from doorloc.app.errors import EXIT_FAILED, EXIT_USAGE, fail

if TYPE_CHECKING:
    from doorloc.app.services import RecipeLookup
    from doorloc.cell import Cell
    from doorloc.recipes.store import RecipeStore

__all__ = [
    "DB_HELP",
    "DbAliasOption",
    "DbOption",
    "PoseCommand",
    "PoseOption",
    "load_cell_or_fail",
    "open_store",
    "recipe_lookup",
]

DB_HELP = "recipe database URL (SQLAlchemy); default: $DOORLOC_DATABASE_URL, else ./doorloc.db (SQLite)"

#: ``--db URL``: the recipe database of every command that reads or writes recipes or keys
DbOption = Annotated[str | None, typer.Option("--db", metavar="URL", help=DB_HELP)]
#: ``--database-url``: the older spelling ``serve`` and ``batch`` took; hidden, still accepted
DbAliasOption = Annotated[str | None, typer.Option("--database-url", hidden=True)]


def open_store(db: str | None) -> RecipeStore:
    """The recipe store at ``db`` (None: the environment's or the default); exit 3 when it cannot be opened."""
    from doorloc.recipes.store import RecipeStore, RecipeStoreError, database_url

    try:
        return RecipeStore(database_url(db) if db else database_url())
    except RecipeStoreError as e:
        raise fail(str(e), EXIT_FAILED) from None


def recipe_lookup(db: str | None) -> RecipeLookup:
    """``door_id -> (recipe, version) | None`` from the recipe database, opened on the first look-up."""
    store: RecipeStore | None = None

    def lookup(door_id: str):  # noqa: ANN202 - RecipeLookup
        nonlocal store
        if store is None:
            store = open_store(db)
        return store.get_versioned(door_id)

    return lookup


def load_cell_or_fail(path: str | PathLike[str]) -> Cell:
    """The cell file at ``path``; exit 2 with the file's own sentence when it cannot be used."""
    from doorloc.cell import CellFileError, load_cell

    try:
        return load_cell(path)
    except CellFileError as e:
        raise fail(str(e), EXIT_USAGE) from None


#: ``--pose X Z YAW``: a measured pose, cell frame (mm, mm, degrees); ``X,Z,YAW`` in one word works too
PoseOption = Annotated[
    tuple[float, float, float],
    typer.Option(
        "--pose", metavar="X Z YAW", help="measured pose: x mm, z mm, yaw degrees (also as X,Z,YAW)"
    ),
]


class PoseCommand(TyperCommand):
    """A command whose ``--pose`` takes ``X Z YAW`` or, as people paste it, ``X,Z,YAW`` in one word."""

    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:  # ctx: the click Context typer runs
        out: list[str] = []
        for i, a in enumerate(args):
            if a.startswith("--pose=") and "," in a:
                out += ["--pose", *a.split("=", 1)[1].split(",")]
            elif i > 0 and args[i - 1] == "--pose" and "," in a:
                out += [p for p in a.split(",") if p.strip()]
            else:
                out.append(a)
        return super().parse_args(ctx, out)
