"""`doorloc cell init`: a starting cell file from a camera calibration (the work is in
:mod:`doorloc.calib.cell_init`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from doorloc.app.errors import fail

cell_app = typer.Typer(help="Cell files (cell.yaml): start one for a new cell.", no_args_is_help=True)


@cell_app.command("init")
def init(
    calibration: Annotated[
        Path, typer.Option(help="camera calibration (OpenCV FileStorage or ROS camera_info YAML)")
    ],
    out: Annotated[Path, typer.Option(help="cell file to write")],
    camera_at: Annotated[
        tuple[float, float, float],
        typer.Option(
            help="nominal camera centre in the cell frame, mm (X across the door, Y towards it, Z up)"
        ),
    ] = (30.0, -350.0, 40.0),
    door_width: Annotated[float, typer.Option(help="default door width, mm")] = 900.0,
    door_thickness: Annotated[float, typer.Option(help="default door thickness, mm")] = 50.0,
    door_height: Annotated[float, typer.Option(help="default door height, mm")] = 2100.0,
    force: Annotated[bool, typer.Option("--force", help="replace an existing --out")] = False,
) -> None:
    """Write a starting cell.yaml: the calibration, a nominal reference-mount placement, the thesis
    fixture and envelope, and the default door. Then measure the placement with `doorloc calibrate-cell`.
    Exit codes: 0 written, 2 bad arguments or files (nothing written)."""
    from doorloc.calib.cell_init import StartingCell, write_starting_cell
    from doorloc.cell import CellFileError, DoorSize

    try:
        start = StartingCell(
            camera_centre_mm=camera_at, default_door=DoorSize(door_width, door_thickness, door_height)
        )
        write_starting_cell(calibration, out, start, overwrite=force)
    except (CellFileError, ValueError) as e:
        raise fail(f"{e}; nothing written") from None
    typer.echo(
        f"wrote {out}; next: doorloc calibrate-cell BOARD.png --cell {out} --pattern COLSxROWS "
        f"--square MM --board-origin X Y Z --out {out}"
    )


def register(app: typer.Typer) -> None:
    """Add `doorloc cell` to the root app."""
    app.add_typer(cell_app, name="cell")
