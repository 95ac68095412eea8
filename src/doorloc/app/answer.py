"""One image in, one answer out: the flow the HTTP service and the batch runner share.

``decode -> locate -> targets (when the door has a recipe) -> optional RAPID text / overlay``.

The answer is the SPEC section 3 result (:class:`doorloc.vision.result.LocateResult`) as a JSON-ready
dict, plus the door it was measured as (``door_id``, ``door``) and the robot targets of its recipe in the
cell frame (``targets``; empty with a ``targets_note`` when there is no recipe or no pose).

The locate function is a parameter so callers (and tests) can choose it; by default it is
:func:`doorloc.vision.locate.locate`.
"""

from __future__ import annotations

import base64
import functools
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from doorloc.cell import Cell, DoorSize

__all__ = [
    "Answer",
    "DoorChoice",
    "LocateFn",
    "answer_image",
    "default_locate_fn",
    "door_from_fields",
    "overlay_png",
    "provenance_of",
    "NO_RECIPE_NOTE",
]

#: ``locate(image, cell, door, *, image_name="", config=None, trace=None) -> LocateResult``
LocateFn = Callable[..., Any]

NO_RECIPE_NOTE = (
    "no targets: the door was given by its dimensions, not by a door_id with a recipe; "
    "send door_id to get hinge targets"
)
NO_POSE_NOTE = "no targets: the door was not located (see error)"
NO_REACH_NOTE = "no targets: the robot cannot follow them (see error and reach)"


@dataclass(frozen=True)
class Answer:
    """The locate result itself, and the JSON-ready answer built from it."""

    result: Any  # doorloc.vision.result.LocateResult
    fields: dict[str, Any]


@dataclass(frozen=True)
class DoorChoice:
    """The door an image shows: its nominal size, and its id and recipe when it came from the database."""

    door: DoorSize
    door_id: str | None = None
    recipe: Any | None = None  # doorloc.recipes.models.DoorRecipe
    recipe_version: int | None = None  # the stored recipe's version (results name it in their provenance)

    @classmethod
    def from_recipe(
        cls, recipe: Any, cell: Cell | None = None, arris_mm: float | None = None, version: int | None = None
    ) -> DoorChoice:
        """The door a stored recipe describes (its size, id, the recipe for the targets and its version).

        A recipe gives the arris size (``arris_mm``); its profile (chamfer or round) is the cell's
        (``door.arris_profile``). ``arris_mm``, when given, overrides the recipe's (a manifest column).
        """
        door = recipe.door_size()
        if cell is not None:
            door = replace(door, arris_profile=cell.default_door.arris_profile)
        if arris_mm is not None:
            door = replace(door, arris_mm=float(arris_mm))
        return cls(door, recipe.door_id, recipe, version)


@functools.cache
def default_locate_fn() -> LocateFn:
    """The real pipeline, :func:`doorloc.vision.locate.locate` (imported on first use: it pulls in OpenCV).

    Its numba kernels are loaded from their disk cache (or compiled) here, once per process, so that the
    first locate's time is its own and not the kernels' (~0.5 s).
    """
    from doorloc.vision.jit import compile_kernels
    from doorloc.vision.locate import locate

    compile_kernels()
    return locate


def door_from_fields(
    cell: Cell,
    width_mm: float | None = None,
    thickness_mm: float | None = None,
    height_mm: float | None = None,
    arris_mm: float | None = None,
    arris_profile: str | None = None,
) -> DoorSize:
    """A door from whichever dimensions were given, the cell's default door filling the rest (mm).

    Raises ValueError naming the field for a size outside :data:`doorloc.limits.DOOR_RANGES_MM` or an arris
    not below half the thickness.
    """
    from doorloc.limits import DoorRangeError, door_size_problems

    d = cell.default_door
    thickness = float(thickness_mm) if thickness_mm is not None else d.thickness_mm
    if arris_mm is not None:
        arris = float(arris_mm)
    else:
        # No arris given: the cell's typical one applies where it fits this door.
        arris = d.arris_mm if d.arris_mm < thickness / 2 else 0.0
    width = float(width_mm) if width_mm is not None else d.width_mm
    height = float(height_mm) if height_mm is not None else d.height_mm
    problems = door_size_problems(width, thickness, height, arris)
    if problems:
        raise DoorRangeError(problems[0][0], "; ".join(p[1] for p in problems))
    return DoorSize(width, thickness, height, arris, arris_profile or d.arris_profile)  # type: ignore[arg-type]


def provenance_of(cell: Cell, choice: DoorChoice) -> dict[str, Any]:
    """SPEC section 3 ``provenance`` of an answer about ``choice`` in ``cell`` (also for records no locate made)."""
    from doorloc import __version__

    return {
        "version": __version__,
        "cell_sha256": cell.sha256,
        "calibration_sha256": cell.calibration_sha256,
        "recipe_version": choice.recipe_version,
    }


def answer_image(
    image: np.ndarray,
    cell: Cell,
    choice: DoorChoice,
    *,
    image_name: str,
    locate_fn: LocateFn | None = None,
    rapid: bool = False,
    trace: Any | None = None,
) -> Answer:
    """Locate the door in ``image`` and turn its recipe into cell-frame targets.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3), uint8 or uint16
        The camera image in the calibrated pixel frame.
    cell : Cell
        The robot cell (camera, fixture, envelope).
    choice : DoorChoice
        Door size, and the recipe when the door has one.
    image_name : str
        Name reported in the result's ``image`` field.
    locate_fn : callable, optional
        Replaces :func:`doorloc.vision.locate.locate`.
    rapid : bool
        Add ``rapid``: the targets as RAPID-readable text (None without targets).
    trace : doorloc.vision.locate.LocateTrace, optional
        Filled by locate with what it saw; pass the same trace to :func:`overlay_png` so the overlay
        does not run locate a second time.

    Returns
    -------
    Answer
        ``.result`` the LocateResult; ``.fields`` the JSON-ready answer: SPEC section 3 fields plus ``door_id``, ``door`` (mm), ``targets`` (list of dicts: name, x_mm,
        y_mm, z_mm, quat, hinge), ``targets_note`` (why the list is empty, else None) and, on request, ``rapid``.
        When the cell names a robot, ``reach`` (:class:`doorloc.robot.reach.ReachReport`, else None); a target
        the robot cannot follow turns the answer into a refusal (``ok`` false, ``error_code`` the reach
        reason, pose fields null, the measured pose under ``measured_pose``, no targets).
    """
    locate = locate_fn or default_locate_fn()
    extra = {} if trace is None else {"trace": trace}
    result = locate(image, cell, choice.door, image_name=image_name, **extra)
    answer = result.model_dump(mode="json")
    answer["provenance"] = provenance_of(cell, choice) | {
        k: v for k, v in (answer.get("provenance") or {}).items() if k != "recipe_version"
    }
    answer["door_id"] = choice.door_id
    answer["door"] = {
        "width_mm": choice.door.width_mm,
        "thickness_mm": choice.door.thickness_mm,
        "height_mm": choice.door.height_mm,
    }
    targets: list[Any] = []
    if choice.recipe is None:
        note: str | None = NO_RECIPE_NOTE
    elif not result.ok:
        note = NO_POSE_NOTE
    else:
        from doorloc.pose import DoorPose
        from doorloc.recipes.targets import targets_for_pose

        pose = DoorPose(result.x_mm, result.z_mm, result.yaw_deg)
        targets = targets_for_pose(choice.recipe, pose, cell.face_y(choice.door))
        note = None
    reach = _reach_block(cell, targets)
    answer["reach"] = None if reach is None else reach.model_dump(mode="json")
    if reach is not None and not reach.feasible:
        # targets the robot cannot follow are wrong targets: the answer becomes a refusal (SPEC section 9)
        answer["measured_pose"] = {k: answer[k] for k in ("x_mm", "z_mm", "yaw_deg")}
        answer.update(
            ok=False,
            error_code=reach.error_code,
            error=f"the robot cannot mill this door here: {reach.reason}",
            x_mm=None,
            z_mm=None,
            yaw_deg=None,
            uncertainty=None,
        )
        targets, note = [], NO_REACH_NOTE
    answer["targets"] = [t.model_dump(mode="json") for t in targets]
    answer["targets_note"] = note
    if rapid:
        if targets:
            from doorloc.recipes.rapid import rapid_text

            answer["rapid"] = rapid_text(targets)
        else:
            answer["rapid"] = None
    return Answer(result, answer)


def _reach_block(cell: Cell, targets: list[Any]) -> Any | None:
    """The reach report of the targets when the cell names a robot (None without a robot or targets)."""
    if not targets or not cell.robot_section:
        return None
    from doorloc.robot.reach import check_reach, setup_for_cell

    setup = setup_for_cell(cell)
    if setup is None:
        return None
    if setup.section.spindle_axis != "y":
        # the targets carry the spindle on tool +Y; re-express them for a tool frame with the spindle on +Z
        from scipy.spatial.transform import Rotation

        from doorloc.recipes.targets import TOOL_Z_ALONG_CELL_Y

        to_z = Rotation.from_quat(TOOL_Z_ALONG_CELL_Y, scalar_first=True)
        quats = (Rotation.from_quat([t.quat for t in targets], scalar_first=True) * to_z).as_quat(
            scalar_first=True
        )
        quats[quats[:, 0] < 0] *= -1
        targets = [
            t.model_copy(update={"quat": tuple(q)}) for t, q in zip(targets, quats.tolist(), strict=True)
        ]
    return check_reach(setup, targets)


def overlay_png(image: np.ndarray, result: Any, cell: Cell, door: DoorSize, trace: Any | None = None) -> str:
    """The overlay (edges, corner, pose drawn on the image) as a base64-encoded PNG string.

    ``trace`` is the LocateTrace of the call that produced ``result``; without it locate runs again.
    """
    import cv2

    from doorloc.vision.overlay import draw_overlay

    bgr = draw_overlay(image, result, cell, door, trace)
    ok, buf = cv2.imencode(".png", bgr, [cv2.IMWRITE_PNG_COMPRESSION, 1])
    if not ok:  # pragma: no cover - OpenCV encodes any uint8 BGR array
        raise RuntimeError("could not encode the overlay as PNG")
    return base64.b64encode(buf.tobytes()).decode("ascii")
