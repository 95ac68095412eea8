"""The cell file (``cell.yaml``, shared/SPEC.md section 2): camera, extrinsics, fixture, envelope, default door.

Everything a locate call needs to know about the robot cell, as small frozen values. Loading resolves
``camera.calibration`` relative to the cell file and accepts both calibration formats; inline
``camera_matrix``/``dist_coeffs`` override what the calibration file says.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from doorloc.calib.camera import CameraModel, Extrinsics, PosedCamera
from doorloc.calib.io import CalibrationFileError, load_calibration
from doorloc.fileio import atomic_write_text

__all__ = ["Fixture", "Envelope", "DoorSize", "Cell", "CellFileError", "load_cell", "parse_cell", "cell_to_dict", "save_cell"]


class CellFileError(ValueError):
    """A cell file that cannot be used; the message names the file and the key."""


@dataclass(frozen=True)
class Fixture:
    """Where the hinge face lies for a door of a given width.

    ``face_y(W) = face_y_mm + face_shift_per_width * (W - reference_width_mm)`` (mm, cell +Y).
    ``face_shift_per_width`` is -0.5 for a door centred on the fixture, 0 for a camera on a slider,
    -1 for a stop on the far edge.
    """

    reference_width_mm: float = 900.0
    face_y_mm: float = 0.0
    face_shift_per_width: float = -0.5

    def face_y(self, width_mm: float) -> float:
        """Hinge-face depth (cell Y, mm) for a door ``width_mm`` wide."""
        return self.face_y_mm + self.face_shift_per_width * (width_mm - self.reference_width_mm)


@dataclass(frozen=True)
class Envelope:
    """Placement tolerance the fixture guarantees: |x| <= x_mm, |z| <= z_mm, |yaw| <= yaw_deg."""

    x_mm: float = 10.0
    z_mm: float = 10.0
    yaw_deg: float = 2.0


@dataclass(frozen=True)
class DoorSize:
    """Nominal door dimensions, mm. Optional arris (chamfer/rounding) size on the hinge-face edges."""

    width_mm: float = 900.0
    thickness_mm: float = 50.0
    height_mm: float = 2100.0
    arris_mm: float = 0.0

    def __post_init__(self) -> None:
        for name in ("width_mm", "thickness_mm", "height_mm"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and np.isfinite(v) and v > 0):
                raise ValueError(f"door {name} must be a positive number of millimetres, got {v!r}")
        if not (0 <= self.arris_mm < self.thickness_mm / 2):
            raise ValueError(f"door arris_mm must be in [0, thickness/2), got {self.arris_mm!r}")


@dataclass(frozen=True)
class Cell:
    """One robot cell: calibrated camera placed in the cell frame, fixture, envelope and default door."""

    camera: CameraModel
    extrinsics: Extrinsics
    fixture: Fixture = field(default_factory=Fixture)
    envelope: Envelope = field(default_factory=Envelope)
    default_door: DoorSize = field(default_factory=DoorSize)
    source: str | None = None

    @property
    def posed_camera(self) -> PosedCamera:
        return PosedCamera(self.camera, self.extrinsics)

    def face_y(self, door: DoorSize) -> float:
        return self.fixture.face_y(door.width_mm)

    def with_extrinsics(self, extrinsics: Extrinsics) -> Cell:
        return replace(self, extrinsics=extrinsics)


def _req(d: dict, key: str, where: str) -> Any:
    if not isinstance(d, dict) or key not in d:
        raise CellFileError(f"{where}: missing key '{key}'")
    return d[key]


def parse_cell(doc: dict, base_dir: str | os.PathLike | None = None, source: str = "cell.yaml") -> Cell:
    """Build a :class:`Cell` from the parsed YAML mapping of a cell file."""
    if not isinstance(doc, dict):
        raise CellFileError(f"{source}: expected a mapping with keys camera, fixture, envelope, door")
    cam_doc = _req(doc, "camera", source)
    try:
        K = dist = size = None
        observed = None
        if "calibration" in cam_doc:
            cal_path = Path(cam_doc["calibration"])
            if not cal_path.is_absolute() and base_dir is not None:
                cal_path = Path(base_dir) / cal_path
            cal = load_calibration(cal_path)
            K, dist, size, observed = (
                cal.camera.camera_matrix, cal.camera.dist_coeffs, cal.camera.image_size, cal.camera.observed_radius_px,
            )
        if "camera_matrix" in cam_doc:
            K = np.asarray(cam_doc["camera_matrix"], float)
        if "dist_coeffs" in cam_doc:
            dist = np.asarray(cam_doc["dist_coeffs"], float)
        if "image_size" in cam_doc:
            size = tuple(int(v) for v in cam_doc["image_size"])
        if K is None or size is None:
            raise CellFileError(
                f"{source}: camera needs 'calibration: FILE' or both 'camera_matrix' and 'image_size'"
            )
        if dist is None:
            dist = np.zeros(5)
        camera = CameraModel(K, dist, size, observed)
        ext_doc = _req(cam_doc, "extrinsics", f"{source}: camera")
        extrinsics = Extrinsics(_req(ext_doc, "rvec", f"{source}: camera.extrinsics"),
                                _req(ext_doc, "tvec_mm", f"{source}: camera.extrinsics"))
        fx = doc.get("fixture", {}) or {}
        fixture = Fixture(
            float(fx.get("reference_width_mm", 900.0)),
            float(fx.get("face_y_mm", 0.0)),
            float(fx.get("face_shift_per_width", -0.5)),
        )
        ev = doc.get("envelope", {}) or {}
        envelope = Envelope(float(ev.get("x_mm", 10.0)), float(ev.get("z_mm", 10.0)), float(ev.get("yaw_deg", 2.0)))
        dd = doc.get("door", {}) or {}
        door = DoorSize(
            float(dd.get("width_mm", 900.0)),
            float(dd.get("thickness_mm", 50.0)),
            float(dd.get("height_mm", 2100.0)),
            float(dd.get("arris_mm", 0.0)),
        )
    except CalibrationFileError as e:
        raise CellFileError(f"{source}: camera.calibration: {e}") from None
    except CellFileError:
        raise
    except (ValueError, TypeError) as e:
        raise CellFileError(f"{source}: {e}") from None
    return Cell(camera, extrinsics, fixture, envelope, door, str(source))


def load_cell(path: str | os.PathLike) -> Cell:
    """Read ``cell.yaml``. Raises :class:`CellFileError` with a message a person can act on."""
    p = Path(path)
    try:
        doc = yaml.safe_load(p.read_text(encoding="utf-8"))
    except OSError as e:
        raise CellFileError(f"cannot read cell file {p}: {e.strerror or e}") from None
    except yaml.YAMLError as e:
        raise CellFileError(f"{p}: not valid YAML ({e})") from None
    return parse_cell(doc, p.parent, str(p))


def cell_to_dict(cell: Cell) -> dict:
    """The cell as a YAML-ready mapping with the camera inline (SPEC section 2 keys)."""
    cam = cell.camera
    return {
        "camera": {
            "image_size": list(cam.image_size),
            "camera_matrix": cam.camera_matrix.tolist(),
            "dist_coeffs": cam.dist_coeffs.tolist(),
            "extrinsics": {"rvec": cell.extrinsics.rvec.tolist(), "tvec_mm": cell.extrinsics.tvec_mm.tolist()},
        },
        "fixture": {
            "reference_width_mm": cell.fixture.reference_width_mm,
            "face_y_mm": cell.fixture.face_y_mm,
            "face_shift_per_width": cell.fixture.face_shift_per_width,
        },
        "envelope": {"x_mm": cell.envelope.x_mm, "z_mm": cell.envelope.z_mm, "yaw_deg": cell.envelope.yaw_deg},
        "door": {
            "width_mm": cell.default_door.width_mm,
            "thickness_mm": cell.default_door.thickness_mm,
            "height_mm": cell.default_door.height_mm,
            "arris_mm": cell.default_door.arris_mm,
        },
    }


def save_cell(cell: Cell, path: str | os.PathLike) -> None:
    """Write the cell (camera inline) atomically."""
    atomic_write_text(path, yaml.safe_dump(cell_to_dict(cell), sort_keys=False, default_flow_style=None))
