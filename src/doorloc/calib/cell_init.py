"""A starting cell file from a camera calibration (`doorloc cell init`).

A new cell needs a ``cell.yaml`` before ``doorloc calibrate-cell`` can measure where the camera is:
the calibration, a nominal camera placement, and the fixture, envelope and default door. This module
writes that file. The placement is only a starting value in the reference mount (SPEC section 1: the
camera looks along +Y, image-right is +X, image-up is +Z); ``calibrate-cell`` replaces it with the
measured one.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from doorloc.cell import Cell, CellFileError, DoorSize, Envelope, Fixture, cell_to_dict, parse_cell
from doorloc.fileio import atomic_write_text

__all__ = [
    "REFERENCE_MOUNT_RVEC",
    "StartingCell",
    "placed_cell_yaml",
    "reference_from",
    "starting_cell_document",
    "write_starting_cell",
]

#: Rodrigues vector of the reference mount: a rotation of +90 deg about X takes cell +Y (into the door)
#: to the camera's optical axis and cell +Z (up) to image-up.
REFERENCE_MOUNT_RVEC = (float(np.pi / 2), 0.0, 0.0)


@dataclass(frozen=True)
class StartingCell:
    """What a new cell file says before the cell is calibrated.

    Attributes
    ----------
    camera_centre_mm : tuple of 3 floats
        Nominal camera centre in the cell frame, mm. The thesis cell: 30 mm beside the reference
        corner in X, 350 mm in front of the hinge face (Y = -350), 40 mm up.
    response_gamma : float or None
        The camera's response ``grey = light ** (1 / gamma)``: 1 for a linear machine-vision camera. None:
        the one the calibration file measured on its photographs (``doorloc calibrate``), written with its
        sigma (``camera.response_gamma_sigma``, from which the cell takes the doubt it allows); 1.0 when it
        has none.
    fixture, envelope, default_door
        The cell's fixture, placement tolerance and the door assumed when a request names none.
    """

    camera_centre_mm: tuple[float, float, float] = (30.0, -350.0, 40.0)
    response_gamma: float | None = None
    fixture: Fixture = field(default_factory=Fixture)
    envelope: Envelope = field(default_factory=Envelope)
    default_door: DoorSize = field(default_factory=DoorSize)


def _reference_mount_tvec(camera_centre_mm: tuple[float, float, float]) -> list[float]:
    """``tvec = -R @ C`` for the reference mount and camera centre ``C`` (cell frame, mm)."""
    rotation = Rotation.from_rotvec(REFERENCE_MOUNT_RVEC).as_matrix()
    tvec = -rotation @ np.asarray(camera_centre_mm, float)
    return [round(float(v), 9) + 0.0 for v in tvec]  # + 0.0: no "-0.0" in the file


def starting_cell_document(
    calibration: str | os.PathLike, cell_path: str | os.PathLike, start: StartingCell | None = None
) -> dict[str, Any]:
    """The YAML mapping of a starting cell file (SPEC section 2), checked by the cell parser.

    Parameters
    ----------
    calibration : path
        The camera calibration (OpenCV FileStorage or ROS camera_info YAML).
    cell_path : path
        Where the cell file will be written; ``camera.calibration`` is stored relative to its folder
        (:func:`reference_from`), so the two files move together.
    start : StartingCell, optional
        Nominal placement, fixture, envelope and door (the thesis cell's values when None).

    Raises
    ------
    CellFileError
        The calibration cannot be read, or the values do not make a valid cell.
    """
    start = start or StartingCell()
    base = Path(cell_path).resolve().parent
    cal_ref = reference_from(calibration, cell_path)
    doc: dict[str, Any] = {
        "camera": {
            "calibration": cal_ref,
            "extrinsics": {
                "rvec": list(REFERENCE_MOUNT_RVEC),
                "tvec_mm": _reference_mount_tvec(start.camera_centre_mm),
            },
            "response_gamma": start.response_gamma,
        },
        "fixture": asdict(start.fixture),
        "envelope": asdict(start.envelope),
        "door": asdict(start.default_door),
    }
    if start.response_gamma is None:
        # the cell file's own rule (doorloc.cell.parse_cell): a cell that states no response takes the one its
        # calibration measured, with the doubt it allows; written out here where a person sees both
        del doc["camera"]["response_gamma"]
        cell = parse_cell(doc, base, str(cell_path))
        doc["camera"]["response_gamma"] = cell.response_gamma
        if cell.response_gamma_sigma is not None:  # (the doubt it allows follows from it, parse_cell)
            doc["camera"]["response_gamma_sigma"] = cell.response_gamma_sigma
    parse_cell(doc, base, str(cell_path))  # the same checks locate will make, before anything is written
    return doc


def write_starting_cell(
    calibration: str | os.PathLike,
    cell_path: str | os.PathLike,
    start: StartingCell | None = None,
    overwrite: bool = False,
) -> dict[str, Any]:
    """Write a starting ``cell.yaml`` atomically and return its mapping.

    Raises
    ------
    CellFileError
        As :func:`starting_cell_document`, or ``cell_path`` exists and ``overwrite`` is False (a
        calibrated cell file is never replaced by a starting one by accident).
    """
    if Path(cell_path).exists() and not overwrite:
        raise CellFileError(f"{cell_path} already exists; choose another --out or pass --force to replace it")
    doc = starting_cell_document(calibration, cell_path, start)
    header = (
        "# Starting cell file written by `doorloc cell init`. The camera placement below is nominal\n"
        "# (reference mount); measure it with one board image on the hinge-face plane:\n"
        f"#   doorloc calibrate-cell BOARD.png --cell {Path(cell_path).name} --pattern COLSxROWS --square MM \\\n"
        f"#     --board-origin X Y Z --out {Path(cell_path).name}\n"
    )
    atomic_write_text(cell_path, header + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None))
    return doc


def reference_from(target: str | os.PathLike, cell_path: str | os.PathLike) -> str:
    """``target`` as a cell file at ``cell_path`` names it: relative to the cell file's folder (``../x.yaml``
    included), so a cell folder can be moved or checked out elsewhere; absolute only where no relative
    path exists (another drive)."""
    target_abs = Path(target).resolve()
    try:
        return Path(os.path.relpath(target_abs, Path(cell_path).resolve().parent)).as_posix()
    except ValueError:  # Windows: another drive
        return str(target_abs)


def placed_cell_yaml(
    cell_path: str | os.PathLike, placed: Cell, placed_by: dict[str, Any], out_path: str | os.PathLike
) -> str:
    """The text of the cell file ``placed`` (new extrinsics) to be written at ``out_path``.

    A reference to a calibration file in the cell file at ``cell_path`` is kept (it carries
    ``observed_radius_px``), rebased to ``out_path``'s folder; ``placed_by`` is kept under
    ``provenance.cell_calibration`` (what placed the camera).
    """
    doc = cell_to_dict(placed)
    try:
        raw = yaml.safe_load(Path(cell_path).read_text(encoding="utf-8")) or {}
        cal_ref = (raw.get("camera") or {}).get("calibration")
    except (OSError, yaml.YAMLError):
        cal_ref = None
    if cal_ref:
        p = Path(cal_ref)
        if not p.is_absolute():
            p = Path(cell_path).parent / p
        doc["camera"] = {"calibration": reference_from(p, out_path), **doc["camera"]}
    doc.setdefault("provenance", {})["cell_calibration"] = placed_by
    return yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)
