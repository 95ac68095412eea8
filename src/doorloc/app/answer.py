"""The answer to one image: the door it was measured as, and the typed answer the service layer returns.

The answer is the SPEC section 3 result (:class:`doorloc.vision.result.LocateResult`) plus the door it was
measured as (``door_id``, ``door``), the robot targets of its recipe in the cell frame (``targets``;
empty with a ``targets_note`` when there is no recipe or no pose) and, when the cell names a robot, the
reach report. :func:`doorloc.app.services.answer_image` makes it; the CLI prints it, the HTTP route
returns it, the batch runner appends it.
"""

from __future__ import annotations

import base64
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from pydantic import BaseModel, Field

from doorloc.cell import Cell
from doorloc.domain import DoorSize
from doorloc.recipes.models import DoorRecipe
from doorloc.recipes.targets import Target
from doorloc.robot.reach import ReachReport
from doorloc.vision.result import LocateResult, Provenance

__all__ = [
    "Answer",
    "DoorChoice",
    "DoorOut",
    "LocateFn",
    "LocateResponse",
    "door_from_fields",
    "overlay_png",
    "provenance_of",
    "NO_RECIPE_NOTE",
    "NO_POSE_NOTE",
    "NO_REACH_NOTE",
]

#: ``locate(image, cell, door, *, image_name="", config=None, trace=None, jpeg_quality=0) -> LocateResult``
LocateFn = Callable[..., LocateResult]

NO_RECIPE_NOTE = (
    "no targets: the door was given by its dimensions, not by a door_id with a recipe; "
    "send door_id to get hinge targets"
)
NO_POSE_NOTE = "no targets: the door was not located (see error)"
NO_REACH_NOTE = "no targets: the robot cannot follow them (see error and reach)"


class DoorOut(BaseModel):
    """The nominal door the image was measured as, mm."""

    width_mm: float = Field(description="nominal door width (along cell +Y), mm")
    thickness_mm: float = Field(description="nominal door thickness (along cell +X), mm")
    height_mm: float = Field(description="nominal door height (along cell +Z), mm")

    @classmethod
    def of(cls, door: DoorSize) -> DoorOut:
        return cls(width_mm=door.width_mm, thickness_mm=door.thickness_mm, height_mm=door.height_mm)


class LocateResponse(LocateResult):
    """The SPEC section 3 result plus the door and its robot targets."""

    door_id: str | None = Field(
        None, description="the recipe used, or null when the door was given by its size"
    )
    door: DoorOut = Field(description="the nominal door the image was measured as (recipe or given size), mm")
    targets: list[Target] = Field(
        description="hinge targets in the cell frame; empty without a recipe or a pose"
    )
    targets_note: str | None = Field(None, description="why targets is empty, else null")
    rapid: str | None = Field(None, description="with ?rapid=true: the targets as RAPID-readable text")
    overlay_png: str | None = Field(
        None,
        description="with ?overlay=true: the overlay image, base64-encoded PNG (only for an answered image "
        "of at most DOORLOC_OVERLAY_MAX_PIXELS)",
    )
    reach: ReachReport | None = Field(
        None,
        description="when the cell names a robot: reach, joints, confdata, inverse condition and deflection per "
        "target (SPEC section 9); an infeasible target turns the answer into a refusal",
    )
    measured_pose: dict[str, float] | None = Field(
        None, description="on a reach refusal: the pose that was measured (x_mm, z_mm, yaw_deg)"
    )


#: answer fields a JSON line or the CLI carries only when they were asked for or happened
_ON_REQUEST = ("rapid", "overlay_png", "measured_pose")


@dataclass(frozen=True)
class Answer:
    """The locate result itself, the typed answer built from it, and what it cost.

    ``cpu_ms``: thread CPU time, ms, of decoding (``decode``, 0 for an image given decoded) and of measuring
    (``locate``: locate, targets, reach and what else the answer holds).
    """

    result: LocateResult
    response: LocateResponse
    cpu_ms: dict[str, float] = field(default_factory=dict)
    #: the optional fields that were asked for (shown even when null)
    requested: frozenset[str] = frozenset()
    #: the decoded image the answer is about (to draw an overlay from)
    image: np.ndarray | None = field(default=None, repr=False, compare=False)

    @property
    def fields(self) -> dict[str, Any]:
        """The answer as a JSON-ready dict, optional fields (``rapid``, ``overlay_png``, ``measured_pose``) only
        when asked for or present."""
        r = self.response
        drop = {k for k in _ON_REQUEST if getattr(r, k) is None and k not in self.requested}
        return r.model_dump(mode="json", exclude=drop)


@dataclass(frozen=True)
class DoorChoice:
    """The door an image shows: its nominal size, and its id and recipe when it came from the database."""

    door: DoorSize
    door_id: str | None = None
    recipe: DoorRecipe | None = None
    recipe_version: int | None = None  # the stored recipe's version (results name it in their provenance)

    @classmethod
    def from_recipe(
        cls,
        recipe: DoorRecipe,
        cell: Cell | None = None,
        arris_mm: float | None = None,
        version: int | None = None,
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


def provenance_of(cell: Cell, choice: DoorChoice) -> Provenance:
    """SPEC section 3 ``provenance`` of an answer about ``choice`` in ``cell`` (also for records no locate made)."""
    from doorloc import __version__

    return Provenance(
        version=__version__,
        cell_sha256=cell.sha256,
        calibration_sha256=cell.calibration_sha256,
        recipe_version=choice.recipe_version,
    )


def overlay_png(
    image: np.ndarray, result: LocateResult, cell: Cell, door: DoorSize, trace: Any | None = None
) -> str:
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
