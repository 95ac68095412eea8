"""The cell file (``cell.yaml``, shared/SPEC.md section 2): camera, extrinsics, fixture, envelope, default door.

Everything a locate call needs to know about the robot cell, as small frozen values. Loading resolves
``camera.calibration`` relative to the cell file and accepts both calibration formats; inline
``camera_matrix``/``dist_coeffs`` override what the calibration file says.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Annotated, Any, Literal, get_args

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError, model_validator

from doorloc.calib.camera import CameraModel, Extrinsics, PosedCamera
from doorloc.calib.io import CalibrationFileError, load_calibration
from doorloc.domain import ArrisProfile, DoorSize
from doorloc.fileio import atomic_write_text
from doorloc.limits import DEFAULT_MILLING_LIMITS, MillingLimits
from doorloc.photometric.model import PhotometricModel
from doorloc.robot.section import RobotSectionError, robot_section_from_doc
from doorloc.vision.config import LocateConfig

__all__ = [
    "ArrisProfile",
    "Fixture",
    "Envelope",
    "DoorSize",
    "Cell",
    "CellFileError",
    "load_cell",
    "parse_cell",
    "cell_to_dict",
    "edge_camera_cell",
    "save_cell",
]


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
class Cell:
    """One robot cell: calibrated camera placed in the cell frame, fixture, envelope and default door.

    Attributes
    ----------
    response_gamma : float
        The camera's response ``grey = light ** (1 / gamma)`` (``camera.response_gamma``): 1 for a linear
        machine-vision camera, about 2.2 for an sRGB-like one. A cell that does not state it takes the one
        its calibration file measured (``response_gamma``, ``doorloc calibrate``), with
        ``locate.response_unmeasured_factor`` from that measurement's sigma unless the cell sets it.
    response_gamma_sigma : float or None
        1-sigma of ``response_gamma`` where it was measured (``camera.response_gamma_sigma``; taken from the
        calibration file with its exponent, written by ``doorloc cell init`` and by the model check); None
        where it was not. A measured exponent is weighed against the one an image's plain edges show
        (:class:`doorloc.vision.response.ResponseFit`): locate replaces it by the image's where the two
        disagree or the image measured it much better, and otherwise counts the measurement's own doubt
        in the answer's uncertainty (a single real photograph's own sigma understates its scatter several
        times, see :func:`doorloc.vision.board_response.board_response`).
    camera_photometry : PhotometricModel or None
        The camera's photometric model where its calibration file's (``photometric_model``, written by
        ``doorloc check-model --boards``), or the cell's own inline (``camera.photometric_model``, as a saved
        cell writes it), says something locate uses: a response beyond a power law (a pedestal, a shoulder,
        a white level below full scale, curvature), through which locate maps each image's levels to those a
        camera of ``response_gamma`` would store (:func:`doorloc.vision.luminance.camera_levels`), or a point
        spread that moves every edge against the corners' frame (``edge_shift_u_px``, ``edge_shift_v_px``),
        which locate takes off its edges, or the model's measured error on the camera's real edges
        (``residual_edge_px``), which locate counts in every edge's doubt. None where there is no such model
        (the power law ``response_gamma`` is then the whole response).
    stored_bits : int or None
        The bits of the camera's levels in its 16-bit images (``camera.stored_bits``, or its calibration
        file's ``stored_bits``, which ``doorloc calibrate`` reads off the board photographs): a 12-bit camera
        that stores 0-4095 says 12, and locate brings its levels to the 16-bit scale
        (:func:`doorloc.vision.luminance.luminance_plane`). None: 16-bit images span 0-65535 (and one whose
        levels all stay within 12 bits is refused, its depth asked for).
    locate : LocateConfig
        The ``locate:`` section: thresholds and settings of the pipeline that a cell sets once.
    robot_section : dict or None
        The ``robot:`` section as written (robot model, base, tool; shared/SPEC.md section 9).
    milling : MillingLimits
        The ``milling:`` section: the spindle's speed range, the feeds and the hinge cutter's reach that bound
        every recipe milled here (doorloc's defaults, :mod:`doorloc.limits`, for what the file leaves out).
    provenance : dict
        What made this file (e.g. the model check that extended it: dataset, date, software version).
    sha256, calibration_sha256 : str or None
        Hashes of the cell file's bytes and of the calibration it uses (of the calibration file, or of the
        inline camera model), echoed in every result so an answer says which model produced it.
    calibration_covariance, calibration_covariance_names : ndarray or None, tuple of str
        Covariance of the camera's free intrinsics from its calibration file (None when the file has
        none, or the cell overrides the camera inline); locate carries it into every answer's uncertainty.
    """

    camera: CameraModel
    extrinsics: Extrinsics
    fixture: Fixture = field(default_factory=Fixture)
    envelope: Envelope = field(default_factory=Envelope)
    default_door: DoorSize = field(default_factory=DoorSize)
    source: str | None = None
    response_gamma: float = 1.0
    locate: LocateConfig = field(default_factory=LocateConfig)
    response_gamma_sigma: float | None = None
    robot_section: dict[str, Any] | None = None
    provenance: dict[str, Any] = field(default_factory=dict)
    sha256: str | None = None
    calibration_sha256: str | None = None
    calibration_covariance: np.ndarray | None = field(default=None, compare=False)
    calibration_covariance_names: tuple[str, ...] = ()
    camera_photometry: PhotometricModel | None = None
    milling: MillingLimits = DEFAULT_MILLING_LIMITS
    stored_bits: int | None = None

    @property
    def posed_camera(self) -> PosedCamera:
        return PosedCamera(self.camera, self.extrinsics)

    def face_y(self, door: DoorSize) -> float:
        return self.fixture.face_y(door.width_mm)

    def with_extrinsics(self, extrinsics: Extrinsics) -> Cell:
        return replace(self, extrinsics=extrinsics)


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class _ExtrinsicsDoc(_Section):
    rvec: tuple[float, float, float]
    tvec_mm: tuple[float, float, float]


class _CameraDoc(_Section):
    calibration: str | None = None
    image_size: tuple[int, int] | None = None
    camera_matrix: list[list[float]] | None = None
    dist_coeffs: list[float] | None = None
    extrinsics: _ExtrinsicsDoc
    response_gamma: float = Field(1.0, gt=0.25, lt=5.0)
    response_gamma_sigma: float | None = Field(None, gt=0.0, lt=5.0)
    #: the bits of the camera's levels in its 16-bit images (a 12-bit camera storing 0-4095: 12)
    stored_bits: int | None = Field(None, ge=8, le=16)
    #: the camera's photometric model (its parameters), inline: a cell saved with its camera inline keeps
    #: what its calibration file's ``photometric_model`` said that locate uses
    photometric_model: dict[str, float] | None = None

    @model_validator(mode="before")
    @classmethod
    def _needs_a_camera_model(cls, data: Any) -> Any:
        if (
            isinstance(data, dict)
            and "calibration" not in data
            and not {"camera_matrix", "image_size"} <= set(data)
        ):
            raise ValueError("camera needs 'calibration: FILE' or both 'camera_matrix' and 'image_size'")
        return data


class _FixtureDoc(_Section):
    reference_width_mm: float = 900.0
    face_y_mm: float = 0.0
    face_shift_per_width: float = -0.5


class _EnvelopeDoc(_Section):
    x_mm: float = Field(10.0, gt=0)
    z_mm: float = Field(10.0, gt=0)
    yaw_deg: float = Field(2.0, gt=0)


class _DoorDoc(_Section):
    width_mm: float = 900.0
    thickness_mm: float = 50.0
    height_mm: float = 2100.0
    arris_mm: float = 0.0
    arris_profile: Literal["chamfer", "round"] = "chamfer"


PositiveNum = Annotated[float, Field(gt=0, allow_inf_nan=False)]


class _MillingDoc(_Section):
    """The spindle and the hinge cutter (``milling:``); a key left out is doorloc's default (doorloc.limits).

    The upper ends stay below what no spindle or robot feed is (100,000 rev/min, 5,000 mm/s): a typo there
    would otherwise open the recipes' own bounds.
    """

    spindle_rpm: tuple[PositiveNum, PositiveNum] | None = None
    feed_mm_s: tuple[PositiveNum, PositiveNum] | None = None
    tool_reach_mm: PositiveNum | None = None

    @model_validator(mode="after")
    def _ranges(self) -> _MillingDoc:
        for name, top in (("spindle_rpm", 100_000.0), ("feed_mm_s", 5_000.0)):
            r = getattr(self, name)
            if r is not None and not r[0] < r[1] <= top:
                raise ValueError(
                    f"{name} must be [lowest, highest] with lowest < highest <= {top:g}, got {list(r)}"
                )
        return self

    def limits(self, source: str) -> MillingLimits:
        given = {k: v for k, v in self.model_dump().items() if v is not None}
        return replace(DEFAULT_MILLING_LIMITS, **given, source=source, stated=frozenset(given))


class _CellDoc(_Section):
    camera: _CameraDoc
    fixture: _FixtureDoc = Field(default_factory=_FixtureDoc)
    envelope: _EnvelopeDoc = Field(default_factory=_EnvelopeDoc)
    door: _DoorDoc = Field(default_factory=_DoorDoc)
    locate: dict[str, Any] = Field(default_factory=dict)
    robot: dict[str, Any] | None = None
    milling: _MillingDoc = Field(default_factory=_MillingDoc)
    provenance: dict[str, Any] = Field(default_factory=dict)


def _allowed_keys(model: type[BaseModel], loc: tuple) -> list[str]:
    """Field names of the section that ``loc`` (a pydantic error location, ending in the bad key) lies in."""
    m: Any = model
    for part in loc[:-1]:
        field_info = getattr(m, "model_fields", {}).get(part)
        if field_info is None:
            break
        ann = field_info.annotation
        m = next((a for a in (ann, *get_args(ann)) if isinstance(a, type) and issubclass(a, BaseModel)), None)
        if m is None:
            return []
    return list(getattr(m, "model_fields", {}))


def _explain(err: ValidationError, source: str) -> str:
    """One sentence per problem, each naming the key's full path (and the allowed keys for an unknown one)."""
    msgs = []
    for e in err.errors():
        loc = tuple(e["loc"])
        where = ".".join(str(p) for p in loc)
        if e["type"] == "extra_forbidden":
            allowed = _allowed_keys(_CellDoc, loc)
            section = ".".join(str(p) for p in loc[:-1]) or "top level"
            msgs.append(f"unknown key '{where}' ({section} allows: {', '.join(allowed)})")
        elif e["type"] == "missing":
            msgs.append(f"missing key '{where}'")
        elif e["type"] == "value_error":
            msgs.append(f"{where}: {e['msg'].removeprefix('Value error, ')}")
        else:
            msgs.append(f"'{where}': {e['msg']} (got {e.get('input')!r})")
    return f"{source}: " + "; ".join(msgs)


def measured_response_factor(gamma: float, sigma: float) -> float:
    """``locate.response_unmeasured_factor`` for a camera response measured as ``gamma +- sigma`` (1 sigma):
    its 2-sigma range as a factor, ``1 + 2 sigma / gamma``."""
    return 1.0 + 2.0 * sigma / gamma


def _locate_config(section: dict[str, Any], source: str) -> LocateConfig:
    """The ``locate:`` section as a :class:`LocateConfig`: its keys are the config's fields, typed."""
    allowed = [f.name for f in dataclasses.fields(LocateConfig)]
    unknown = [k for k in section if k not in allowed]
    if unknown:
        raise CellFileError(
            f"{source}: unknown key 'locate.{unknown[0]}' (locate allows: {', '.join(allowed)})"
        )
    try:
        # A stdlib dataclass validated by pydantic: types are checked and coerced ("6" -> 6.0 is refused
        # in strict mode, but YAML already gives numbers as numbers).
        return TypeAdapter(LocateConfig).validate_python(section)
    except ValidationError as e:
        raise CellFileError(_explain_plain(e, source, "locate")) from None


def _explain_plain(err: ValidationError, source: str, prefix: str) -> str:
    return f"{source}: " + "; ".join(
        f"'{prefix}.{'.'.join(str(p) for p in e['loc'])}': {e['msg']} (got {e.get('input')!r})"
        for e in err.errors()
    )


def _sha256_file(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _sha256_camera(camera: CameraModel) -> str:
    """A stable hash of an inline camera model (what the camera part of a calibration file would hash)."""
    doc = {
        "image_size": list(camera.image_size),
        "camera_matrix": [[float(v) for v in row] for row in camera.camera_matrix],
        "dist_coeffs": [float(v) for v in camera.dist_coeffs],
    }
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def parse_cell(
    doc: Any, base_dir: str | os.PathLike | None = None, source: str = "cell.yaml", sha256: str | None = None
) -> Cell:
    """Build a :class:`Cell` from the parsed YAML mapping of a cell file.

    Validation is strict: an unknown or misspelt key anywhere is a :class:`CellFileError` that names the key
    and the keys allowed where it stands (a silently ignored ``envelope: {x: 2}`` would leave a default
    tolerance in force that nobody chose). ``sha256`` is the file's hash (for the results' provenance).
    """
    if not isinstance(doc, dict):
        raise CellFileError(f"{source}: expected a mapping with keys camera, fixture, envelope, door")
    cal_ref = doc.get("camera", {}).get("calibration") if isinstance(doc.get("camera"), dict) else None
    if isinstance(cal_ref, str | os.PathLike):
        cal_path = Path(cal_ref)
        if not cal_path.is_absolute() and base_dir is not None:
            cal_path = Path(base_dir) / cal_path
        if not cal_path.is_file():
            raise CellFileError(f"{source}: camera.calibration: no calibration file at {cal_path}")
    try:
        cd = _CellDoc.model_validate(doc)
    except ValidationError as e:
        raise CellFileError(_explain(e, source)) from None
    if cd.robot is not None:
        # the robot: section has its own strict model (doorloc.robot.section); check it here so a typo
        # in it is an error of the cell file like any other
        try:
            robot_section_from_doc(cd.robot, source)
        except RobotSectionError as e:
            raise CellFileError(str(e)) from None
    cam_doc = cd.camera
    try:
        K = dist = size = None
        observed = None
        calibration_sha = None
        cov: np.ndarray | None = None
        cov_names: tuple[str, ...] = ()
        measured_response: tuple[float, float] | None = None
        camera_photometry: PhotometricModel | None = None
        stored_bits = cam_doc.stored_bits
        if cam_doc.calibration is not None:
            cal_path = Path(cam_doc.calibration)
            if not cal_path.is_absolute() and base_dir is not None:
                cal_path = Path(base_dir) / cal_path
            cal = load_calibration(cal_path)
            calibration_sha = _sha256_file(cal_path)
            K, dist, size, observed = (
                cal.camera.camera_matrix,
                cal.camera.dist_coeffs,
                cal.camera.image_size,
                cal.camera.observed_radius_px,
            )
            cov, cov_names = cal.covariance, cal.covariance_names
            if cal.response_gamma is not None and cal.response_gamma_sigma is not None:
                measured_response = (cal.response_gamma, cal.response_gamma_sigma)
            if cal.photometric_model:
                camera_photometry = _used_by_locate(PhotometricModel.from_dict(cal.photometric_model))
            if stored_bits is None:
                stored_bits = cal.stored_bits
        if cam_doc.photometric_model is not None:
            camera_photometry = _used_by_locate(PhotometricModel.from_dict(cam_doc.photometric_model))
        if cam_doc.camera_matrix is not None:
            K = np.asarray(cam_doc.camera_matrix, float)
        if cam_doc.dist_coeffs is not None:
            dist = np.asarray(cam_doc.dist_coeffs, float)
        if cam_doc.image_size is not None:
            size = cam_doc.image_size
        if K is None or size is None:
            raise CellFileError(
                f"{source}: camera needs 'calibration: FILE' or both 'camera_matrix' and 'image_size'"
            )
        if dist is None:
            dist = np.zeros(5)
        camera = CameraModel(K, dist, size, observed)
        if calibration_sha is None or cam_doc.camera_matrix is not None or cam_doc.dist_coeffs is not None:
            calibration_sha = _sha256_camera(camera)
            cov, cov_names = None, ()  # an inline camera is not the one the covariance describes
        extrinsics = Extrinsics(np.asarray(cam_doc.extrinsics.rvec), np.asarray(cam_doc.extrinsics.tvec_mm))
        fixture = Fixture(**cd.fixture.model_dump())
        envelope = Envelope(**cd.envelope.model_dump())
        door = DoorSize(**cd.door.model_dump())
    except CalibrationFileError as e:
        raise CellFileError(f"{source}: camera.calibration: {e}") from None
    except CellFileError:
        raise
    except (ValueError, TypeError) as e:
        raise CellFileError(f"{source}: {e}") from None
    locate = _locate_config(cd.locate, source)
    response_gamma, response_sigma = cam_doc.response_gamma, cam_doc.response_gamma_sigma
    if measured_response is not None and "response_gamma" not in cam_doc.model_fields_set:
        # The calibration file carries the response measured on its photographs (doorloc calibrate): a
        # cell that does not state its own takes it with its sigma (unless the cell states that), known
        # within its 2-sigma range (unless the cell's locate section sets that doubt itself); all are
        # echoed in every result like any cell setting.
        response_gamma = measured_response[0]
        if response_sigma is None:
            response_sigma = measured_response[1]
    if response_sigma is not None and "response_unmeasured_factor" not in (cd.locate or {}):
        locate = replace(
            locate, response_unmeasured_factor=measured_response_factor(response_gamma, response_sigma)
        )
    return Cell(
        camera,
        extrinsics,
        fixture,
        envelope,
        door,
        str(source),
        response_gamma=response_gamma,
        locate=locate,
        response_gamma_sigma=response_sigma,
        robot_section=cd.robot,
        provenance=dict(cd.provenance),
        sha256=sha256 or hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest(),
        calibration_sha256=calibration_sha,
        calibration_covariance=cov,
        calibration_covariance_names=cov_names,
        camera_photometry=camera_photometry,
        milling=cd.milling.limits(str(source)),
        stored_bits=stored_bits,
    )


def load_cell(path: str | os.PathLike) -> Cell:
    """Read ``cell.yaml``. Raises :class:`CellFileError` with a message a person can act on."""
    p = Path(path)
    try:
        raw = p.read_bytes()
        doc = yaml.safe_load(raw.decode("utf-8"))
    except OSError as e:
        raise CellFileError(f"cannot read cell file {p}: {e.strerror or e}") from None
    except UnicodeDecodeError:
        raise CellFileError(
            f"{p}: not a text file (a cell file is YAML, see shared/SPEC.md section 2)"
        ) from None
    except yaml.YAMLError as e:
        raise CellFileError(f"{p}: not valid YAML ({e})") from None
    return parse_cell(doc, p.parent, str(p), sha256=hashlib.sha256(raw).hexdigest())


def _used_by_locate(model: PhotometricModel) -> PhotometricModel | None:
    """``model`` where it says something locate uses (:attr:`PhotometricModel.used_by_locate`), else None."""
    return model if model.used_by_locate else None


def edge_camera_cell(cell: Cell) -> Cell:
    """``cell`` with the camera its edges are seen through: where the camera's point spread moves every edge
    by ``(edge_shift_u_px, edge_shift_v_px)`` against the corners' frame its calibration was made in
    (:attr:`Cell.camera_photometry`), the principal point moved by that much, which moves the
    image of every edge, and nothing else, by it; ``cell`` itself where there is no such shift. Locate reads
    its edges through it; the renderer draws them through it."""
    pm = cell.camera_photometry
    if pm is None or not pm.moves_edges:
        return cell
    cam = cell.camera
    K = cam.camera_matrix.copy()
    K[0, 2] += pm.edge_shift_u_px
    K[1, 2] += pm.edge_shift_v_px
    return replace(cell, camera=CameraModel(K, cam.dist_coeffs, cam.image_size, cam.observed_radius_px))


def cell_to_dict(cell: Cell) -> dict:
    """The cell as a YAML-ready mapping with the camera inline (SPEC section 2 keys)."""
    cam = cell.camera
    doc: dict[str, Any] = {
        "camera": {
            "image_size": list(cam.image_size),
            "camera_matrix": cam.camera_matrix.tolist(),
            "dist_coeffs": cam.dist_coeffs.tolist(),
            "extrinsics": {
                "rvec": cell.extrinsics.rvec.tolist(),
                "tvec_mm": cell.extrinsics.tvec_mm.tolist(),
            },
            "response_gamma": cell.response_gamma,
            **(
                {"response_gamma_sigma": cell.response_gamma_sigma}
                if cell.response_gamma_sigma is not None
                else {}
            ),
            **(
                {"photometric_model": cell.camera_photometry.locate_parameters()}
                if cell.camera_photometry is not None
                else {}
            ),
            **({"stored_bits": cell.stored_bits} if cell.stored_bits is not None else {}),
        },
        "fixture": {
            "reference_width_mm": cell.fixture.reference_width_mm,
            "face_y_mm": cell.fixture.face_y_mm,
            "face_shift_per_width": cell.fixture.face_shift_per_width,
        },
        "envelope": {
            "x_mm": cell.envelope.x_mm,
            "z_mm": cell.envelope.z_mm,
            "yaw_deg": cell.envelope.yaw_deg,
        },
        "door": {
            "width_mm": cell.default_door.width_mm,
            "thickness_mm": cell.default_door.thickness_mm,
            "height_mm": cell.default_door.height_mm,
            "arris_mm": cell.default_door.arris_mm,
            "arris_profile": cell.default_door.arris_profile,
        },
    }
    changed = {
        k: list(v) if isinstance(v, tuple) else v
        for k, v in dataclasses.asdict(cell.locate).items()
        if v != getattr(LocateConfig(), k)
    }
    if changed:
        doc["locate"] = changed
    if cell.robot_section is not None:
        doc["robot"] = cell.robot_section
    milling = {k: getattr(cell.milling, k) for k in sorted(cell.milling.stated)}
    if milling:
        doc["milling"] = {k: list(v) if isinstance(v, tuple) else v for k, v in milling.items()}
    if cell.provenance:
        doc["provenance"] = cell.provenance
    return doc


def save_cell(cell: Cell, path: str | os.PathLike) -> None:
    """Write the cell (camera inline) atomically."""
    atomic_write_text(path, yaml.safe_dump(cell_to_dict(cell), sort_keys=False, default_flow_style=None))
