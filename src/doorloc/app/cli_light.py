"""`doorloc measure-light`: the cell's light, and with ``--response`` its camera's response, from images of its
doors (the work is in :mod:`doorloc.vision.cell_light` and :mod:`doorloc.vision.cell_response`)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from doorloc.app.errors import EXIT_REFUSED, fail

if TYPE_CHECKING:
    from doorloc.vision.cell_light import LightMeasurement
    from doorloc.vision.cell_response import ResponseMeasurement


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
    response: Annotated[
        bool,
        typer.Option(
            "--response",
            help="also measure the camera's response (camera.response_gamma) from the doors' roundings, "
            "where no board photographs measured it (about a minute for eight doors)",
        ),
    ] = False,
) -> None:
    """The direction of the cell's main light, measured from doors with rounded arrises -> the lines to add
    to the cell file's locate section. Each door is located once and its rounded strips scored under about
    230 trial directions (about 7 s for 8 doors on one core). With --response, each door is located with
    about 17 trial camera exponents and the exponent under which all the roundings fit matt arcs under one
    light best is the camera's, printed with its doubt for the camera section (where the doors share no
    lamp, each door's roundings under its own light, and no light is stated). Exit codes: 0 measured, 1
    the images cannot tell the light (or the response), 2 bad arguments or files."""
    from doorloc.app import batch
    from doorloc.cell import CellFileError
    from doorloc.vision.cell_light import LightNotMeasurable
    from doorloc.vision.cell_response import ResponseNotMeasurable
    from doorloc.vision.imageio import ImageDecodeError

    def progress(line: str) -> None:
        typer.echo(line, err=True)

    try:
        if response:
            r = batch.measure_response_in_folder(images_dir, cell, manifest, progress=progress)
            m = r.light
        else:
            m = batch.measure_light_in_folder(images_dir, cell, manifest, progress=progress)
    except (LightNotMeasurable, ResponseNotMeasurable) as e:
        raise fail(str(e), EXIT_REFUSED) from None
    except (CellFileError, batch.BatchSetupError, ImageDecodeError) as e:
        raise fail(str(e)) from None
    lines = _response_lines(r) if response else []
    light = _light_lines(m)
    knee = _shoulder_line(r) if response else None
    if knee is not None:
        light = [*(light or ["locate:"]), knee]
    typer.echo(f"add to {cell}:\n" + "\n".join([*lines, *light]))


def _response_lines(r: ResponseMeasurement) -> list[str]:
    """Print what the response measurement found (and any warning); the camera section's lines to add."""
    typer.echo(
        f"the camera's response: gamma {r.gamma:.3f} +- {r.sigma:.3f} (exponents {r.gamma / r.factor:.2f}-"
        f"{r.gamma * r.factor:.2f} fit the roundings alike; {r.strips} rounded strips of {r.doors} doors, "
        f"score {dict(r.scores)[r.gamma]:.3f}; the cell's {r.cell_gamma:.2f} scores {r.cell_score:.3f})"
    )
    if r.cell_ruled_out:
        typer.echo(
            f"warning: the cell's camera.response_gamma {r.cell_gamma:g} lies outside what the doors allow: "
            "check the camera's gamma setting, or take the measured value",
            err=True,
        )
    return ["camera:", f"  response_gamma: {r.gamma:.3f}", f"  response_gamma_sigma: {r.sigma:.3f}"]


def _shoulder_line(r: ResponseMeasurement) -> str | None:
    """Print what the doors said of a shoulder in the response; the locate section's line lifting its doubt
    where they rule it out (None elsewhere)."""
    s = r.shoulder
    if s is None:
        return None
    typer.echo(
        f"a shoulder in the response from {s.knee:g} of full scale: the roundings fit it at best at {s.shouldered:.3f} "
        f"against {s.plain:.3f} as a power law, "
        + (
            f"ruled out up to {s.reached:.2f}, the brightest level of the doors"
            if s.ruled_out
            else "not ruled out (locate doubts it on doors whose image reaches above it)"
        )
    )
    return f"  response_shoulder_knee: {s.doubted_from:.2f}" if s.ruled_out else None


def _light_lines(m: LightMeasurement | None) -> list[str]:
    """Print the measured light (and any warning); the locate section's lines stating it (none where the doors
    share no lamp, ``m`` None)."""
    if m is None:
        typer.echo(
            "the cell's light: none common to the doors (each door's roundings read under its own light)"
        )
        return []
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
    return [
        "locate:",
        f"  light_direction_deg: [{az:.1f}, {el:.1f}]",
        f"  light_direction_sigma_deg: {m.sigma_deg:g}",
    ]


def register(app: typer.Typer) -> None:
    """Add `doorloc measure-light` to the root app."""
    app.command("measure-light")(measure_light_cmd)
