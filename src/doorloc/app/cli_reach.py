"""`doorloc reach`: can the robot mill this door at this pose? (shared/SPEC.md section 9)

Exit codes: 0 every target feasible, 1 not (the output says which target and why), 2 bad input
(unknown door, bad cell or robot file), 3 the recipe database could not be opened.
"""

from __future__ import annotations

import sys
from enum import StrEnum
from pathlib import Path

import typer

from doorloc.app.cli_recipes import DB_HELP, _open_store
from doorloc.app.errors import EXIT_REFUSED, fail


class ReachFormat(StrEnum):
    json = "json"
    table = "table"


def reach_cmd(
    door_id: str = typer.Option(..., "--door-id", help="door id (barcode) of a stored recipe"),
    pose: tuple[float, float, float] = typer.Option(..., "--pose", help="measured pose: X_MM Z_MM YAW_DEG"),
    cell: Path = typer.Option(
        None, "--cell", help="cell.yaml with a robot: section; default: the bundled thesis cell"
    ),
    db: str = typer.Option(None, "--db", help=DB_HELP),
    fmt: ReachFormat = typer.Option(ReachFormat.json, "--format", help="json or table"),
    plot: Path = typer.Option(None, "--plot", help="write the (r, z) work window with the targets as a PNG"),
) -> None:
    """Reach, joint limits, singularity and deflection of every hinge target of a door at a pose.

    Exit 0 when every target is feasible, 1 when not, 2 for bad input.
    """
    from doorloc.cell import CellFileError, load_cell
    from doorloc.pose import DoorPose
    from doorloc.robot.reach import reach_for_door, report_table, setup_for_cell, thesis_cell_path

    try:
        the_cell = load_cell(cell if cell is not None else thesis_cell_path())
        setup = setup_for_cell(the_cell)
    except (CellFileError, ValueError) as e:  # RobotSectionError / RobotFileError are ValueErrors
        raise fail(str(e)) from None
    if setup is None:
        raise fail(
            f"{cell}: the robot: section names no robot model (robot: {{model: irb6600-175-2.55, ...}})"
        )
    with _open_store(db) as store:
        recipe = store.get(door_id)
    if recipe is None:
        raise fail(
            f"no recipe for door {door_id!r} in the database; import one with 'doorloc recipes import'"
        )
    report = reach_for_door(setup, recipe, DoorPose(*pose), the_cell.face_y(recipe.door_size()))
    if plot is not None:
        from doorloc.fileio import atomic_write_bytes
        from doorloc.robot.window import window_png

        try:
            atomic_write_bytes(plot, window_png(setup, report))
        except OSError as e:
            raise fail(f"cannot write {plot}: {e.strerror or e}") from None
    sys.stdout.write(
        report.model_dump_json(indent=2) + "\n" if fmt is ReachFormat.json else report_table(report)
    )
    if not report.feasible:
        raise typer.Exit(EXIT_REFUSED)


def register(app: typer.Typer) -> None:
    """Add `doorloc reach` to the root app."""
    app.command("reach")(reach_cmd)
