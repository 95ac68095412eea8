"""`doorloc measure-light`: the cell's light from images of its doors (the work is in
:mod:`doorloc.vision.cell_light`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from doorloc.app.errors import EXIT_REFUSED, fail


def measure_light_cmd(
    images_dir: Annotated[
        Path, typer.Argument(help="folder of images of doors with rounded arrises in the cell")
    ],
    cell: Annotated[Path, typer.Option(help="cell file (cell.yaml)")],
    manifest: Annotated[
        Path | None,
        typer.Option(
            help="CSV: image, width_mm, thickness_mm[, height_mm][, arris_mm]; default: the cell's door"
        ),
    ] = None,
) -> None:
    """The direction of the cell's main light, measured from doors with rounded arrises -> the lines to add
    to the cell file's locate section. Each door is located once and its rounded strips scored under about
    70 trial directions (about 5 s for 8 doors on one core). Exit codes: 0 measured, 1 the images
    cannot tell the light, 2 bad arguments or files."""
    from doorloc.app.batch import BatchSetupError, measure_light_in_folder
    from doorloc.cell import CellFileError
    from doorloc.vision.cell_light import LightNotMeasurable
    from doorloc.vision.imageio import ImageDecodeError

    try:
        m = measure_light_in_folder(
            images_dir, cell, manifest, progress=lambda line: typer.echo(line, err=True)
        )
    except LightNotMeasurable as e:
        raise fail(str(e), EXIT_REFUSED) from None
    except (CellFileError, BatchSetupError, ImageDecodeError) as e:
        raise fail(str(e)) from None
    az, el = m.direction_deg
    typer.echo(
        f"the cell's light: azimuth {az:+.1f}, elevation {el:+.1f} deg, +- {m.sigma_deg:g} deg "
        f"({m.strips} rounded strips of {m.doors} doors; mean log misfit over a free shading {m.score:.3f})"
    )
    if m.runner_up_deg is not None:
        typer.echo(
            f"warning: a light at azimuth {m.runner_up_deg[0]:+.0f}, elevation {m.runner_up_deg[1]:+.0f} deg "
            f"fits almost as well ({m.runner_up_score:.3f}): check which side of the camera the lamp is on",
            err=True,
        )
    typer.echo(
        f"add to {cell}:\nlocate:\n  light_direction_deg: [{az:.1f}, {el:.1f}]\n  light_direction_sigma_deg: {m.sigma_deg:g}"
    )


def register(app: typer.Typer) -> None:
    """Add `doorloc measure-light` to the root app."""
    app.command("measure-light")(measure_light_cmd)
