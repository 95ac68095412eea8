"""`doorloc render`: make a rendered data set (images, truth.csv, cell.yaml) with known truth.

The command parses and checks its arguments, then hands the work to :mod:`doorloc.sim.dataset`.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from doorloc.app.errors import EXIT_USAGE, fail

if TYPE_CHECKING:
    from doorloc.cell import Envelope
    from doorloc.domain import DoorSize
    from doorloc.pose import DoorPose


def parse_mm_list(text: str, what: str) -> list[float]:
    """``"30,50,100"`` -> ``[30.0, 50.0, 100.0]``; raises ValueError with a sentence."""
    try:
        vals = [float(v) for v in text.replace(";", ",").split(",") if v.strip()]
    except ValueError:
        raise ValueError(
            f"{what} must be a comma-separated list of millimetres (e.g. 30,50,100), got {text!r}"
        ) from None
    if not vals:
        raise ValueError(f"{what} is empty")
    return vals


def parse_effects(pairs: list[str]):
    """``["blur_sigma_px=0.8", "gamma=2.2"]`` -> :class:`~doorloc.sim.effects.Effects`."""
    from doorloc.sim.effects import Effects

    d = {}
    for p in pairs:
        if "=" not in p:
            raise ValueError(f"--effect must look like NAME=VALUE (e.g. blur_sigma_px=0.8), got {p!r}")
        k, v = p.split("=", 1)
        d[k.strip()] = v.strip()
    return Effects.from_dict(d)


def render(
    out_dir: Annotated[Path, typer.Argument(help="folder to write the images, truth.csv and cell.yaml into")],
    cell: Annotated[
        Path, typer.Option(help="cell file (camera, extrinsics, fixture, envelope, default door)")
    ],
    poses: Annotated[str, typer.Option(help="'grid' (full grid over the envelope) or 'random'")] = "grid",
    grid_steps: Annotated[int, typer.Option(min=1, help="grid values per axis (3: -e, 0, +e)")] = 3,
    count: Annotated[int, typer.Option(min=1, help="number of random poses")] = 20,
    seed: Annotated[int, typer.Option(help="seed of random poses, wood grain and noise")] = 0,
    thickness: Annotated[
        str | None, typer.Option(help="door thicknesses, mm, e.g. 30,50,100 (default: cell's door)")
    ] = None,
    width: Annotated[
        str | None, typer.Option(help="door widths, mm, e.g. 600,900 (default: cell's door)")
    ] = None,
    height: Annotated[float | None, typer.Option(help="door height, mm (default: cell's door)")] = None,
    arris: Annotated[
        float, typer.Option(help="arris (chamfer/rounding) size on the hinge-face and bottom edges, mm")
    ] = 0.0,
    effect: Annotated[
        list[str] | None, typer.Option(help="NAME=VALUE of doorloc.sim.effects.Effects, repeatable")
    ] = None,
    force: Annotated[
        bool, typer.Option("--force", help="write into a folder that already holds a truth.csv")
    ] = False,
) -> None:
    """Render door images with exactly known pose and corner pixel.

    Every thickness x width is rendered at every pose. Writes img_NNNN.png, truth.csv (pose, door,
    true corner pixel, effects; written last) and the cell.yaml to give the pipeline. Exit codes:
    0 done, 2 bad arguments or cell file.
    """
    from doorloc.cell import CellFileError, load_cell
    from doorloc.sim.dataset import dataset_items, write_dataset

    try:
        c = load_cell(cell)
    except CellFileError as e:
        raise fail(str(e), EXIT_USAGE) from None
    check_out_dir(out_dir, force)
    try:
        fx = parse_effects(effect or [])
        doors = door_list(c.default_door, thickness, width, height, arris)
        pose_list = pose_list_of(c.envelope, poses, grid_steps, count, seed)
    except ValueError as e:
        raise fail(str(e), EXIT_USAGE) from None
    items = dataset_items(doors, pose_list, seed)

    def progress(k: int, n: int) -> None:
        if k == n or k % 10 == 0:
            typer.echo(f"rendered {k}/{n}", err=True)

    try:
        truth = write_dataset(out_dir, c, items, fx, progress)
    except ValueError as e:  # e.g. a door that reaches behind the camera
        raise fail(str(e), EXIT_USAGE) from None
    except OSError as e:
        raise fail(f"cannot write to {out_dir}: {e.strerror or e}", EXIT_USAGE) from None
    typer.echo(f"wrote {len(items)} images, {truth} and {out_dir / 'cell.yaml'}")


def check_out_dir(out_dir: Path, force: bool) -> None:
    """Exit 2 when ``out_dir`` already holds a data set (unless ``force``) or is not a folder."""
    if (out_dir / "truth.csv").exists() and not force:
        raise fail(f"{out_dir} already holds a data set (truth.csv); choose another folder or pass --force")
    if out_dir.exists() and not out_dir.is_dir():
        raise fail(f"{out_dir} exists and is not a folder")


def door_list(
    default: DoorSize, thickness: str | None, width: str | None, height: float | None, arris: float
) -> list[DoorSize]:
    """Every thickness x width of ``--thickness``/``--width`` (the default door's where not given), mm."""
    from doorloc.domain import DoorSize

    thicknesses = parse_mm_list(thickness, "--thickness") if thickness else [default.thickness_mm]
    widths = parse_mm_list(width, "--width") if width else [default.width_mm]
    h = height if height is not None else default.height_mm
    return [DoorSize(w, t, h, arris) for w in widths for t in thicknesses]


def pose_list_of(envelope: Envelope, poses: str, grid_steps: int, count: int, seed: int) -> list[DoorPose]:
    """``--poses grid`` (``grid_steps`` per axis over the envelope) or ``random`` (``count``, seeded)."""
    from doorloc.sim.dataset import grid_poses, random_poses

    if poses == "grid":
        return grid_poses(envelope, grid_steps)
    if poses == "random":
        return random_poses(envelope, count, seed)
    raise ValueError(f"--poses must be 'grid' or 'random', got {poses!r}")


def register(app: typer.Typer) -> None:
    """Add `doorloc render` to the root app."""
    app.command("render")(render)
