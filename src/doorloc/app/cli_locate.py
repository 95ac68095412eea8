"""`doorloc locate`: one image in, the locate result (shared/SPEC.md section 3) out as JSON on stdout.

The JSON is the same answer `POST /v1/locate` gives (:func:`doorloc.app.answer.answer_image`): the
result fields plus ``door_id``, ``door`` and, when the door was named by ``--door-id``, its hinge
``targets`` moved by the measured pose.

Exit codes: 0 the door was located; 1 locate refused the image (the JSON says why, ``ok=false``);
2 bad input (unreadable image, cell file, door size, unknown door id). The overlay, when asked for,
is written atomically (temporary file + rename) for answers and refusals alike.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Annotated

import typer

from doorloc.app.errors import EXIT_OK, EXIT_REFUSED, EXIT_USAGE, fail


def _door_choice(cell, width, thickness, height, arris, door_id, db, profile=None):
    """The door to look for: a recipe from the database (``--door-id``) or the given sizes."""
    from doorloc.app.answer import DoorChoice, door_from_fields

    if door_id is None:
        return DoorChoice(door_from_fields(cell, width, thickness, height, arris, profile))
    if any(v is not None for v in (width, thickness, height)):
        raise ValueError("give either --door-id or --door-width/--door-thickness/--door-height, not both")
    from doorloc.recipes.store import RecipeStore, database_url

    with RecipeStore(database_url(db) if db else database_url()) as store:
        found = store.get_versioned(door_id)
    if found is None:
        raise ValueError(
            f"no door recipe with id {door_id!r} in the recipe database; import it first "
            "(doorloc recipes import) or give the door size with --door-width/--door-thickness"
        )
    recipe, version = found
    choice = DoorChoice.from_recipe(recipe, cell, arris, version)
    if profile is None:
        return choice
    return replace(choice, door=replace(choice.door, arris_profile=profile))


def register(app: typer.Typer) -> None:
    """Add this area's subcommands to the root app."""

    @app.command("locate")
    def locate_cmd(
        image: Annotated[Path, typer.Argument(help="camera image (PNG, JPEG, TIFF, BMP; 8 or 16 bit)")],
        cell_file: Annotated[Path, typer.Option("--cell", help="cell file (cell.yaml)")],
        door_width: Annotated[
            float | None, typer.Option("--door-width", help="door width, mm (sets the hinge-face depth)")
        ] = None,
        door_thickness: Annotated[
            float | None, typer.Option("--door-thickness", help="door thickness, mm")
        ] = None,
        door_height: Annotated[float | None, typer.Option("--door-height", help="door height, mm")] = None,
        arris: Annotated[
            float | None,
            typer.Option(
                "--door-arris",
                "--arris",
                help="arris chamfer/rounding size, mm (default: the recipe's, else the cell's door.arris_mm)",
            ),
        ] = None,
        arris_profile: Annotated[
            str | None,
            typer.Option(
                "--arris-profile",
                help="arris profile: chamfer or round (default: the cell's door.arris_profile)",
            ),
        ] = None,
        door_id: Annotated[
            str | None, typer.Option("--door-id", help="take the door size from this recipe")
        ] = None,
        db: Annotated[
            str | None, typer.Option("--db", help="recipe database URL (default: DOORLOC_DATABASE_URL)")
        ] = None,
        overlay: Annotated[
            Path | None, typer.Option("--overlay", help="write an annotated image here (PNG/JPEG)")
        ] = None,
        indent: Annotated[int, typer.Option(help="JSON indentation (0 = one line)")] = 2,
    ) -> None:
        """Locate the door in one image and print the result JSON (exit 0 located, 1 refused, 2 bad input)."""
        from doorloc.app.answer import answer_image
        from doorloc.cell import CellFileError, load_cell
        from doorloc.vision.imageio import ImageDecodeError, decode_image
        from doorloc.vision.locate import LocateTrace

        try:
            cell = load_cell(cell_file)
        except CellFileError as e:
            raise fail(str(e), EXIT_USAGE) from None
        try:
            choice = _door_choice(
                cell, door_width, door_thickness, door_height, arris, door_id, db, arris_profile
            )
        except (ValueError, RuntimeError) as e:
            raise fail(str(e), EXIT_USAGE) from None
        from doorloc.app.batch import FileLimits, read_file_checked

        # the batch's checks: no waiting on a FIFO, no decoding of an image that declares too many pixels
        data, _code, why = read_file_checked(str(image), FileLimits())
        if data is None:
            raise fail(why, EXIT_USAGE)
        try:
            img = decode_image(data, name=str(image))
        except ImageDecodeError as e:
            raise fail(str(e), EXIT_USAGE) from None
        trace = LocateTrace()
        answer = answer_image(img, cell, choice, image_name=str(image), trace=trace)
        if overlay is not None:
            from doorloc.fileio import atomic_write_image
            from doorloc.vision.overlay import draw_overlay

            try:
                atomic_write_image(overlay, draw_overlay(img, answer.result, cell, choice.door, trace))
            except (OSError, ValueError) as e:
                raise fail(
                    f"cannot write the overlay {overlay}: {getattr(e, 'strerror', None) or e}", EXIT_USAGE
                ) from None
        typer.echo(json.dumps(answer.fields, indent=indent or None))
        raise typer.Exit(EXIT_OK if answer.fields["ok"] else EXIT_REFUSED)  # a reach refusal too
