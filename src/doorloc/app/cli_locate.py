"""`doorloc locate`: one image in, the locate result (shared/SPEC.md section 3) out as JSON on stdout.

The JSON is the same answer `POST /v1/locate` gives (:func:`doorloc.app.services.answer_image`): the
result fields plus ``door_id``, ``door`` and, when the door was named by ``--door-id``, its hinge
``targets`` moved by the measured pose.

Exit codes: 0 the door was located; 1 locate refused the image (the JSON says why, ``ok=false``);
2 bad input (unreadable image, cell file, door size, unknown door id). The overlay, when asked for,
is written atomically (temporary file + rename) for answers and refusals alike.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from doorloc.app.cli_common import DbOption
from doorloc.app.errors import EXIT_OK, EXIT_REFUSED, EXIT_USAGE, fail

if TYPE_CHECKING:
    from doorloc.app.answer import Answer, DoorChoice
    from doorloc.cell import Cell
    from doorloc.vision.locate import LocateTrace


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
    db: DbOption = None,
    overlay: Annotated[
        Path | None, typer.Option("--overlay", help="write an annotated image here (PNG/JPEG)")
    ] = None,
    indent: Annotated[int, typer.Option(help="JSON indentation (0 = one line)")] = 2,
) -> None:
    """Locate the door in one image and print the result JSON (exit 0 located, 1 refused, 2 bad input)."""
    from doorloc.app.batch import FileLimits, read_file_checked
    from doorloc.app.cli_common import load_cell_or_fail, recipe_lookup
    from doorloc.app.services import DoorChoiceError, resolve_door

    cell = load_cell_or_fail(cell_file)
    sizes = {"width_mm": door_width, "thickness_mm": door_thickness, "height_mm": door_height}
    try:
        choice = resolve_door(
            cell, recipe_lookup(db), door_id=door_id, arris_mm=arris, arris_profile=arris_profile, **sizes
        )
    except DoorChoiceError as e:
        raise fail(str(e), EXIT_USAGE) from None
    # the batch's checks: no waiting on a FIFO, no decoding of an image that declares too many pixels
    data, _code, why = read_file_checked(str(image), FileLimits())
    if data is None:
        raise fail(why, EXIT_USAGE)
    answer = answer_with_overlay(data, str(image), cell, choice, overlay)
    typer.echo(json.dumps(answer.fields, indent=indent or None))
    raise typer.Exit(EXIT_OK if answer.response.ok else EXIT_REFUSED)  # a reach refusal too


def answer_with_overlay(
    data: bytes, name: str, cell: Cell, choice: DoorChoice, overlay: Path | None
) -> Answer:
    """:func:`doorloc.app.services.answer_image` of the file's bytes, the overlay written when asked for;
    exit 2 for an image that cannot be decoded or an overlay that cannot be written."""
    from doorloc.app.services import answer_image
    from doorloc.vision.imageio import ImageDecodeError
    from doorloc.vision.locate import LocateTrace

    trace = LocateTrace() if overlay is not None else None
    try:
        answer = answer_image(data, cell, choice, image_name=name, trace=trace)
    except ImageDecodeError as e:
        raise fail(str(e), EXIT_USAGE) from None
    if overlay is not None:
        write_overlay(overlay, answer, cell, choice, trace)
    return answer


def write_overlay(
    path: Path, answer: Answer, cell: Cell, choice: DoorChoice, trace: LocateTrace | None
) -> None:
    """Write the annotated image atomically; exit 2 with a sentence when it cannot be written."""
    from doorloc.fileio import atomic_write_image
    from doorloc.vision.overlay import draw_overlay

    try:
        assert answer.image is not None  # answer_image keeps the image it decoded
        atomic_write_image(path, draw_overlay(answer.image, answer.result, cell, choice.door, trace))
    except (OSError, ValueError) as e:
        raise fail(
            f"cannot write the overlay {path}: {getattr(e, 'strerror', None) or e}", EXIT_USAGE
        ) from None


def register(app: typer.Typer) -> None:
    """Add `doorloc locate` to the root app."""
    app.command("locate")(locate_cmd)
