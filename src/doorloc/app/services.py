"""The calls behind every face of doorloc: CLI commands, HTTP routes and the batch runner adapt these.

- :func:`resolve_door`: the door an image shows, from a recipe id or from its sizes (one rule for all).
- :func:`answer_image`: decode -> locate -> targets -> reach, as a typed :class:`~doorloc.app.answer.Answer`.
- :func:`reach_for_recipe`: the reach report of a stored door at a given pose (``doorloc reach``).

Each raises an error with a sentence a person can act on (:class:`DoorChoiceError`, :class:`ReachSetupError`,
:class:`doorloc.vision.imageio.ImageDecodeError`); the adapters turn it into an exit code or an HTTP status.
"""

from __future__ import annotations

import functools
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from doorloc.app.answer import (
    NO_POSE_NOTE,
    NO_REACH_NOTE,
    NO_RECIPE_NOTE,
    Answer,
    DoorChoice,
    DoorOut,
    LocateFn,
    LocateResponse,
    door_from_fields,
    overlay_png,
    provenance_of,
)
from doorloc.cell import Cell
from doorloc.pose import DoorPose
from doorloc.recipes.models import DoorRecipe, milling_problems
from doorloc.recipes.targets import Target, targets_for_pose
from doorloc.robot.reach import ReachReport, ReachSetup, reach_for_door, setup_for_cell
from doorloc.vision.result import LocateResult

if TYPE_CHECKING:  # the calibration modules load when a calibration runs
    from doorloc.calib.calibrate import Candidate
    from doorloc.calib.camera import CameraModel
    from doorloc.calib.cell import CellCalibration
    from doorloc.calib.detect import CharucoSpec, Chessboard
    from doorloc.calib.folder import CalibrationOutcome, DetectedViews, LoadedImage
    from doorloc.calib.io import CalibrationFile
    from doorloc.photometric.check import BoardCheck
    from doorloc.vision.board_response import BoardResponse

    Board = Chessboard | CharucoSpec

__all__ = [
    "DoorChoiceError",
    "RecipeLookup",
    "ReachOutcome",
    "ReachSetupError",
    "CameraCalibration",
    "CameraPlacement",
    "PlacementRefused",
    "answer_image",
    "answer_located",
    "calibrate_camera",
    "place_camera",
    "default_locate_fn",
    "reach_for_recipe",
    "reach_of_cell",
    "resolve_door",
]

#: ``door_id -> (recipe, version) | None``; may raise ValueError for a stored recipe today's rules refuse
RecipeLookup = Callable[[str], "tuple[DoorRecipe, int | None] | None"]

DoorProblem = Literal["ambiguous_door", "unknown_door", "invalid_door", "unusable_recipe"]


class DoorChoiceError(ValueError):
    """The door cannot be chosen; ``code`` says why (``ambiguous_door``, ``unknown_door``, ``invalid_door``,
    ``unusable_recipe``)."""

    def __init__(self, code: DoorProblem, message: str) -> None:
        super().__init__(message)
        self.code: DoorProblem = code


class ReachSetupError(ValueError):
    """The cell cannot be checked for reach (no robot named); the message says what to add."""


#: a kernel load slower than this was a compile (loading the cached kernels takes about a second)
COMPILE_NOTICE_S = 5.0


@functools.cache
def default_locate_fn() -> LocateFn:
    """The real pipeline, :func:`doorloc.vision.locate.locate` (imported on first use: it pulls in OpenCV).

    Its numba kernels are loaded from their disk cache (or compiled) here, once per process, so that the
    first locate's time is its own and not the kernels'. A compile (the first run on a machine: minutes) is
    announced once, with its duration, on the ``doorloc.app`` logger.
    """
    from doorloc.vision.locate import locate
    from doorloc.vision.warmup import compile_locate_kernels

    t0 = time.perf_counter()
    n = compile_locate_kernels()
    seconds = time.perf_counter() - t0
    if seconds > COMPILE_NOTICE_S:  # compiled, not loaded: say once why this first answer waited
        logging.getLogger("doorloc.app").warning(
            f"doorloc: locate's {n} numba kernels were compiled in {seconds:.1f} s; they are cached now, "
            "so later runs load them in about a second",
            extra={"fields": {"event": "kernels_compiled", "kernels": n, "seconds": round(seconds, 1)}},
        )
    return locate


def resolve_door(
    cell: Cell,
    lookup: RecipeLookup | None,
    *,
    door_id: str | None = None,
    width_mm: float | None = None,
    thickness_mm: float | None = None,
    height_mm: float | None = None,
    arris_mm: float | None = None,
    arris_profile: str | None = None,
) -> DoorChoice:
    """The door an image shows: the stored recipe ``door_id`` (via ``lookup``), else the given sizes (mm).

    Sizes left out come from the cell's default door. ``arris_mm`` and ``arris_profile`` override the
    recipe's and the cell's. Raises :class:`DoorChoiceError`: ``ambiguous_door`` (an id and sizes),
    ``unknown_door`` (no such recipe), ``invalid_door`` (a size outside the accepted ranges),
    ``unusable_recipe`` (a stored recipe today's rules refuse).
    """
    if door_id is None:
        try:
            return DoorChoice(
                door_from_fields(cell, width_mm, thickness_mm, height_mm, arris_mm, arris_profile)
            )
        except ValueError as e:
            raise DoorChoiceError("invalid_door", f"the door size is not usable: {e}") from None
    if any(v is not None for v in (width_mm, thickness_mm, height_mm)):
        raise DoorChoiceError(
            "ambiguous_door",
            "give either a door id (its recipe has the door's size) or the door's width/thickness/height, not both",
        )
    try:
        found = lookup(door_id) if lookup is not None else None
    except ValueError as e:  # a stored recipe that today's rules refuse
        raise DoorChoiceError(
            "invalid_door", f"the stored recipe of door {door_id!r} is not usable: {e}"
        ) from None
    if found is None:
        raise DoorChoiceError(
            "unknown_door",
            f"no door recipe with id {door_id!r} in the recipe database; import it first (doorloc recipes "
            "import, or PUT /v1/doors/ID) or give the door's size instead",
        )
    recipe, version = found
    _check_milling(recipe, cell)
    try:
        choice = DoorChoice.from_recipe(recipe, cell, arris_mm, version)
        if arris_profile is not None:
            choice = replace(choice, door=replace(choice.door, arris_profile=arris_profile))  # type: ignore[arg-type]
    except ValueError as e:
        raise DoorChoiceError("invalid_door", f"the door size is not usable: {e}") from None
    return choice


def _check_milling(recipe: DoorRecipe, cell: Cell) -> None:
    """``unusable_recipe`` for a stored recipe beyond the cell's spindle or cutter (its ``milling:`` section)."""
    problems = milling_problems(recipe, cell.milling)
    if problems:
        raise DoorChoiceError(
            "unusable_recipe",
            f"the recipe of door {recipe.door_id!r} asks more than this cell's spindle and cutter give: "
            + "; ".join(p.message for p in problems)
            + "; correct the recipe (PUT /v1/doors/ID or doorloc recipes import --replace)",
        )


def reach_of_cell(cell: Cell, recipe: DoorRecipe, pose: DoorPose, face_y_mm: float) -> ReachReport | None:
    """The reach report of ``recipe``'s targets at ``pose`` when ``cell`` names a robot, else None.

    The one reach path: :func:`doorloc.robot.reach.reach_for_door` with the cell's tool orientation.
    """
    setup = setup_for_cell(cell)
    return None if setup is None else reach_for_door(setup, recipe, pose, face_y_mm)


def _targets_and_reach(
    cell: Cell, choice: DoorChoice, result: LocateResult
) -> tuple[list[Target], str | None, ReachReport | None]:
    """The cell-frame targets of the choice's recipe at the measured pose, why there are none, the reach."""
    if choice.recipe is None:
        return [], NO_RECIPE_NOTE, None
    if not result.ok or result.x_mm is None or result.z_mm is None or result.yaw_deg is None:
        return [], NO_POSE_NOTE, None
    pose = DoorPose(result.x_mm, result.z_mm, result.yaw_deg)
    face_y = cell.face_y(choice.door)
    targets = targets_for_pose(choice.recipe, pose, face_y)
    return targets, None, (reach_of_cell(cell, choice.recipe, pose, face_y) if targets else None)


def _refused_for_reach(result: LocateResult, reach: ReachReport) -> dict[str, Any]:
    """Targets the robot cannot follow are wrong targets: the answer becomes a refusal (SPEC section 9)."""
    return {
        "measured_pose": {"x_mm": result.x_mm, "z_mm": result.z_mm, "yaw_deg": result.yaw_deg},
        "ok": False,
        "error_code": reach.error_code,
        "error": f"the robot cannot mill this door here: {reach.reason}",
        "x_mm": None,
        "z_mm": None,
        "yaw_deg": None,
        "uncertainty": None,
    }


def answer_image(
    image: np.ndarray | bytes,
    cell: Cell,
    choice: DoorChoice,
    *,
    image_name: str,
    locate_fn: LocateFn | None = None,
    rapid: bool = False,
    overlay: bool = False,
    trace: Any | None = None,
    jpeg_quality: int | None = None,
) -> Answer:
    """Locate the door in ``image``, turn its recipe into cell-frame targets and check the robot reaches them.

    Parameters
    ----------
    image : ndarray (H, W) or (H, W, 3), uint8 or uint16; or the encoded file's bytes
        The camera image in the calibrated pixel frame; bytes are decoded first
        (:class:`doorloc.vision.imageio.ImageDecodeError` when they cannot be).
    cell, choice
        The robot cell; the door (size, and the recipe when it has one: :func:`resolve_door`).
    image_name : str
        Name reported in the result's ``image`` field.
    locate_fn : callable, optional
        Replaces :func:`doorloc.vision.locate.locate`.
    rapid, overlay : bool
        Add ``rapid`` (the targets as RAPID-readable text; null without targets) and ``overlay_png``.
    trace : doorloc.vision.locate.LocateTrace, optional
        Filled by locate with what it saw (to draw an overlay without locating twice).
    jpeg_quality : int, optional
        The JPEG quality of the file the image came from, 0 for another format
        (:func:`doorloc.vision.imageio.stored_jpeg_quality`); read from the bytes when None and the image
        is bytes, else 0 (not known: locate's JPEG doubt then rests on the blocks the image shows).

    Returns
    -------
    Answer
        ``.result`` the LocateResult; ``.response`` the :class:`~doorloc.app.answer.LocateResponse`: SPEC
        section 3 fields plus ``door_id``, ``door`` (mm), ``targets`` (cell frame, mm; quaternions scalar
        first), ``targets_note`` (why the list is empty) and, when the cell names a robot, ``reach``. A
        target the robot cannot follow turns the answer into a refusal (``ok`` false, ``error_code`` the
        reach reason, pose fields null, the measured pose under ``measured_pose``, no targets).
    """
    t0 = time.thread_time()
    if isinstance(image, bytes):
        from doorloc.vision.imageio import decode_image, stored_jpeg_quality

        if jpeg_quality is None:
            jpeg_quality = stored_jpeg_quality(image)
        image = decode_image(image, name=image_name)
    t1 = time.thread_time()
    if overlay and trace is None:
        from doorloc.vision.locate import LocateTrace

        trace = LocateTrace()
    locate = locate_fn or default_locate_fn()
    result = locate(
        image,
        cell,
        choice.door,
        image_name=image_name,
        jpeg_quality=jpeg_quality or 0,
        **({} if trace is None else {"trace": trace}),
    )
    drawn = overlay_png(image, result, cell, choice.door, trace) if overlay else None
    answer = answer_located(result, cell, choice, rapid=rapid, overlay=drawn, requested_overlay=overlay)
    cpu_ms = {"decode": (t1 - t0) * 1e3, "locate": (time.thread_time() - t1) * 1e3}
    return replace(answer, cpu_ms=cpu_ms, image=image)


def answer_located(
    result: LocateResult,
    cell: Cell,
    choice: DoorChoice,
    *,
    rapid: bool = False,
    overlay: str | None = None,
    requested_overlay: bool = False,
) -> Answer:
    """The answer to a located image (:func:`answer_image` once locate has run, wherever it ran): the
    recipe's targets moved by the pose, the reach check, ``rapid`` when asked for, and ``overlay`` (a base64
    PNG drawn already, or None; ``requested_overlay``: it was asked for, so the answer shows it even null).
    ``cpu_ms`` is left empty and ``image`` None: the caller knows them."""
    targets, note, reach = _targets_and_reach(cell, choice, result)
    fields = result.model_dump()
    # locate's own provenance (what it measured with) stands; the recipe version is the choice's
    seen = fields.get("provenance") or {}
    fields["provenance"] = provenance_of(cell, choice).model_dump() | {
        k: v for k, v in seen.items() if k != "recipe_version"
    }
    if reach is not None and not reach.feasible:
        fields |= _refused_for_reach(result, reach)
        targets, note = [], NO_REACH_NOTE
    response = LocateResponse(
        **fields,
        door_id=choice.door_id,
        door=DoorOut.of(choice.door),
        targets=targets,
        targets_note=note,
        reach=reach,
        rapid=_rapid(targets) if rapid else None,
        overlay_png=overlay,
    )
    requested = frozenset(k for k, on in (("rapid", rapid), ("overlay_png", requested_overlay)) if on)
    return Answer(result, response, requested=requested)


def _rapid(targets: list[Target]) -> str | None:
    if not targets:
        return None
    from doorloc.recipes.rapid import rapid_text

    return rapid_text(targets)


# ---------------------------------------------------------------------------------------------- reach


@dataclass(frozen=True)
class ReachOutcome:
    """A reach report and what it was made with: the cell file, whether it is the bundled one, the robot."""

    report: ReachReport
    setup: ReachSetup
    cell_path: Path
    bundled_cell: bool

    @property
    def robot(self) -> str:
        return str(self.setup.section.model)

    def describe(self) -> str:
        """One line naming the cell and robot used (for a person; the report itself goes to stdout)."""
        where = "the bundled thesis cell" if self.bundled_cell else f"cell {self.cell_path}"
        hint = " (give --cell for your own cell)" if self.bundled_cell else ""
        return f"reach with {where}, robot {self.robot}{hint}"


def reach_for_recipe(
    door_id: str, pose: DoorPose, lookup: RecipeLookup, cell_path: str | Path | None = None
) -> ReachOutcome:
    """Reach, joints, singularity and deflection of every hinge target of the stored door at ``pose``.

    ``cell_path`` None: the bundled thesis cell (:func:`doorloc.robot.reach.thesis_cell_path`). Raises
    :class:`doorloc.cell.CellFileError` or a robot file error (a bad cell), :class:`ReachSetupError` (the
    cell names no robot), :class:`DoorChoiceError` (no such recipe).
    """
    from doorloc.cell import load_cell
    from doorloc.robot.reach import thesis_cell_path

    bundled = cell_path is None
    path = Path(thesis_cell_path() if cell_path is None else cell_path)
    cell = load_cell(path)
    setup = setup_for_cell(cell)
    if setup is None:
        raise ReachSetupError(
            f"{path}: "
            + (
                "has no robot: section, so there is no robot to check; add one naming the robot and where it "
                "stands (robot: {model: irb6600-175-2.55, base: ..., tool: ...}; shared/SPEC.md section 9)"
                if not cell.robot_section
                else "the robot: section names no robot model; add model: (e.g. robot: {model: irb6600-175-2.55})"
            )
        )
    found = lookup(door_id)
    if found is None:
        raise DoorChoiceError(
            "unknown_door",
            f"no recipe for door {door_id!r} in the database; import one with 'doorloc recipes import'",
        )
    recipe = found[0]
    _check_milling(recipe, cell)
    report = reach_for_door(setup, recipe, pose, cell.face_y(recipe.door_size()))
    return ReachOutcome(report, setup, path, bundled)


# ---------------------------------------------------------------------------------------------- calibration


@dataclass(frozen=True)
class CameraCalibration:
    """A camera calibrated from a folder of board photographs, ready to write.

    ``calibration`` is the file's content (the measured camera response in it when there was one, and the
    camera's photometric model where its optics were measured); ``response`` the response measured on the
    chessboard's squares (None: not measured, and ``response_problem`` says why when the measurement itself
    failed); ``optics`` the board check that measured the optics (None: not asked for or not possible, and
    ``optics_problem`` says why where asked for).
    """

    outcome: CalibrationOutcome
    calibration: CalibrationFile
    response: BoardResponse | None
    response_problem: str | None = None
    optics: BoardCheck | None = None
    optics_problem: str | None = None


def calibrate_camera(
    images_dir: str | Path,
    board: Board,
    *,
    candidates: tuple[Candidate, ...] | None = None,
    n_folds: int = 5,
    min_views: int = 4,
    camera_name: str = "doorloc",
    measure_optics: bool = False,
    progress: Callable[[str], None] | None = None,
) -> CameraCalibration:
    """Calibrate a camera from the board photographs in ``images_dir`` and measure its response; with
    ``measure_optics`` (chessboards only) also its optics and its response beyond a power law, as
    ``doorloc check-model --boards`` measures them (:func:`camera_optics`), into the calibration.

    Raises :class:`doorloc.calib.folder.TooFewViewsError` (its ``detected`` says what each image gave),
    :class:`doorloc.calib.calibrate.CalibrationError`, :class:`doorloc.calib.folder.CalibrationInputError`.
    """
    from doorloc.calib.calibrate import CANDIDATES
    from doorloc.calib.detect import Chessboard, stored_bits_of
    from doorloc.calib.folder import (
        TooFewViewsError,
        calibrate_detected,
        detect_views,
        full_board_views,
        read_folder,
    )
    from doorloc.vision.board_response import board_response

    # read and searched once: the calibration, the response and the optics are measured on the same views
    images = read_folder(images_dir)
    try:
        outcome = calibrate_detected(
            detect_views(images, board),
            candidates=candidates or tuple(CANDIDATES),
            n_folds=n_folds,
            min_views=min_views,
        )
    except TooFewViewsError as e:
        if not isinstance(board, Chessboard) or (seen := _board_seen_instead(images_dir, board)) is None:
            raise
        raise TooFewViewsError(
            f"{e}; the photographs show a {seen[0]}x{seen[1]} chessboard (inner corners), not "
            f"{board.cols}x{board.rows}: give --pattern {seen[0]}x{seen[1]}",
            e.detected,
        ) from None
    cal = outcome.calibration_file(camera_name)
    # a 10- or 12-bit camera storing its levels from 0 in 16-bit photographs: locate must read its doors so
    cal = replace(cal, stored_bits=stored_bits_of(im for _, im, _ in images))
    if not isinstance(board, Chessboard):  # a ChArUco board's corners need not all be seen
        return CameraCalibration(outcome, cal, None)
    # the response and the optics are extra measurements: neither failing costs the calibration, nor the other
    response, response_problem = None, None
    try:
        views = full_board_views(images, outcome.detected.scan, board)
        response = board_response(views, board.cols, board.rows)
    except Exception as e:  # noqa: BLE001 - an extra measurement (above)
        response_problem = f"{type(e).__name__}: {e}"
    if response is not None:
        cal = replace(cal, response_gamma=response.gamma, response_gamma_sigma=response.sigma)
    if not measure_optics:
        return CameraCalibration(outcome, cal, response, response_problem)
    from doorloc.photometric.check import BoardCheckError

    try:
        check, cal = camera_optics(images, outcome.detected, images_dir, board, cal, progress)
    except BoardCheckError as e:  # too few photographs with squares to read
        return CameraCalibration(outcome, cal, response, response_problem, optics_problem=str(e))
    except Exception as e:  # noqa: BLE001 - an extra measurement (above)
        return CameraCalibration(
            outcome, cal, response, response_problem, optics_problem=f"{type(e).__name__}: {e}"
        )
    return CameraCalibration(outcome, cal, response, response_problem, optics=check)


def camera_optics(
    images: list[LoadedImage],
    detected: DetectedViews,
    images_dir: str | Path,
    board: Chessboard,
    calibration: CalibrationFile,
    progress: Callable[[str], None] | None = None,
) -> tuple[BoardCheck, CalibrationFile]:
    """The photometric board check (:func:`doorloc.photometric.check.check_photographs`: the camera's response
    beyond a power law, its point spread, a held-out edge residual) on the chessboard photographs read from
    ``images_dir`` (``images``, the board found in them: ``detected``, as the calibration left them) through
    ``calibration``'s camera, and ``calibration`` with its photometric model added. Raises
    :class:`doorloc.photometric.check.BoardCheckError` where the photographs cannot be used."""
    from datetime import UTC, datetime

    from doorloc.photometric.check import check_photographs, measure_detected
    from doorloc.photometric.report import extended_calibration

    measured = measure_detected(
        images,
        detected,
        board,
        calibration.camera,
        "calibrated from the same photographs",
        images_dir,
        progress=progress,
        stored_bits=calibration.stored_bits,
    )
    check = check_photographs(measured.photographs, progress=progress)
    command = (
        f"doorloc calibrate {Path(images_dir).name} --pattern {board.cols}x{board.rows} "
        f"--square {board.square_mm:g} --optics"
    )
    return check, extended_calibration(check, calibration, command, datetime.now(UTC).strftime("%Y-%m-%d"))


def _board_seen_instead(
    images_dir: str | Path, board: Chessboard, at_most: int = 3
) -> tuple[int, int] | None:
    """The chessboard the first images without ``board`` show instead (a wrong ``--pattern``), or None."""
    from doorloc.calib.detect import nearby_chessboard
    from doorloc.calib.folder import read_folder

    looked = 0
    for _name, image, _why in read_folder(images_dir):
        if image is None or looked >= at_most:
            continue
        looked += 1
        seen = nearby_chessboard(image, board)
        if seen is not None:
            return seen
    return None


class PlacementRefused(ValueError):
    """The board image cannot place the camera (no board, a poor fit); nothing is written."""


@dataclass(frozen=True)
class CameraPlacement:
    """The camera placed in the cell by one board image: the fit, and the cell file text to write."""

    fit: CellCalibration
    cell_yaml: str
    #: the board's corners found in the image, px
    corners_px: np.ndarray
    #: the camera placed (intrinsics as in the cell file; its extrinsics are ``fit.extrinsics``)
    camera: CameraModel


def place_camera(
    cell_path: Path,
    image_path: Path,
    board: Board,
    board_origin_mm: tuple[float, float, float],
    board_x_axis: tuple[float, float, float],
    board_y_axis: tuple[float, float, float],
    *,
    board_label: str,
    out_path: Path,
    max_rms_px: float,
) -> CameraPlacement:
    """Camera extrinsics from one image of a board at a known place in the cell (mm, cell frame).

    ``board_label`` names the board in messages and in the written provenance (``9x6``).

    Raises :class:`doorloc.cell.CellFileError` or ValueError (unusable files: exit 2 in the CLI) and
    :class:`PlacementRefused` (no board, a fit worse than ``max_rms_px``).
    """
    from doorloc.calib.cell import CellCalibrationError, board_points_in_cell, calibrate_cell_extrinsics
    from doorloc.calib.cell_init import placed_cell_yaml
    from doorloc.calib.detect import detect_board
    from doorloc.calib.folder import read_image_file
    from doorloc.cell import load_cell

    cell = load_cell(cell_path)
    im, err = read_image_file(image_path)
    if im is None:
        raise ValueError(f"{image_path} {err}")
    size = cell.camera.image_size
    if (im.shape[1], im.shape[0]) != size:
        raise ValueError(
            f"{image_path} is {im.shape[1]}x{im.shape[0]} but the cell's camera was calibrated at {size[0]}x{size[1]}"
        )
    det = detect_board(im, board)
    if det is None:
        raise PlacementRefused(f"no board ({board_label}) found in {image_path}; nothing written")
    try:
        pts = board_points_in_cell(det.object_points(board), board_origin_mm, board_x_axis, board_y_axis)
        fit = calibrate_cell_extrinsics(cell.camera, pts, det.corners_px, cell.face_y(cell.default_door))
    except CellCalibrationError as e:
        raise PlacementRefused(f"{e}; nothing written") from None
    if fit.rms_px > max_rms_px:
        raise PlacementRefused(
            f"board reprojection RMS {fit.rms_px:.2f} px exceeds --max-rms {max_rms_px} px: check "
            "--board-origin, the axes and that the board lies flat; nothing written"
        )
    placed_by = {
        "image": str(image_path),
        "board": board_label,
        "square_mm": board.square_mm,
        "board_origin_mm": list(board_origin_mm),
        **fit.to_dict(),
    }
    text = placed_cell_yaml(cell_path, cell.with_extrinsics(fit.extrinsics), placed_by, out_path)
    return CameraPlacement(fit, text, det.corners_px, cell.camera)
