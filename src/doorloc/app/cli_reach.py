"""`doorloc reach`: can the robot mill this door at this pose? (shared/SPEC.md section 9)

Exit codes: 0 every target feasible, 1 not (the output says which target and why), 2 bad input
(unknown door, bad cell or robot file, a cell that names no robot), 3 the recipe database could not be
opened. Which cell and robot were used goes to stderr; the report alone to stdout.
"""

from __future__ import annotations

import sys
from enum import StrEnum
from pathlib import Path

import typer

from doorloc.app.cli_common import DbOption, PoseCommand, PoseOption, recipe_lookup
from doorloc.app.errors import EXIT_REFUSED, fail


class ReachFormat(StrEnum):
    json = "json"
    table = "table"


def reach_cmd(
    door_id: str = typer.Option(..., "--door-id", help="door id (barcode) of a stored recipe"),
    pose: PoseOption = ...,  # type: ignore[assignment]
    cell: Path = typer.Option(
        None, "--cell", help="cell.yaml with a robot: section; default: the bundled thesis cell"
    ),
    db: DbOption = None,
    fmt: ReachFormat = typer.Option(ReachFormat.json, "--format", help="json or table"),
    plot: Path = typer.Option(None, "--plot", help="write the (r, z) work window with the targets as a PNG"),
) -> None:
    """Reach, joint limits, singularity and deflection of every hinge target of a door at a pose.

    Exit 0 when every target is feasible, 1 when not, 2 for bad input.
    """
    from doorloc.app.services import reach_for_recipe
    from doorloc.cell import CellFileError
    from doorloc.pose import DoorPose
    from doorloc.robot.reach import report_table

    try:
        outcome = reach_for_recipe(door_id, DoorPose(*pose), recipe_lookup(db), cell)
    except (CellFileError, ValueError) as e:  # robot section/file errors, no robot, no recipe
        raise fail(str(e)) from None
    typer.echo(f"doorloc: {outcome.describe()}", err=True)
    if plot is not None:
        from doorloc.fileio import atomic_write_bytes
        from doorloc.robot.window import window_png

        try:
            atomic_write_bytes(plot, window_png(outcome.setup, outcome.report))
        except OSError as e:
            raise fail(f"cannot write {plot}: {e.strerror or e}") from None
    report = outcome.report
    sys.stdout.write(
        report.model_dump_json(indent=2) + "\n" if fmt is ReachFormat.json else report_table(report)
    )
    if not report.feasible:
        raise typer.Exit(EXIT_REFUSED)


def register(app: typer.Typer) -> None:
    """Add `doorloc reach` to the root app."""
    app.command("reach", cls=PoseCommand)(reach_cmd)
