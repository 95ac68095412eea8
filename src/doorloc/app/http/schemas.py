"""Response bodies of the HTTP API (request bodies are the library's own models, e.g. DoorRecipe)."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, Field

from doorloc.recipes.targets import Target
from doorloc.robot.reach import ReachReport
from doorloc.vision.result import LocateResult

__all__ = [
    "DoorOut",
    "LocateResponse",
    "CellInfo",
    "Health",
    "Readiness",
    "DoorList",
    "RecipeHistory",
    "RecipeVersionOut",
]


class DoorOut(BaseModel):
    """The nominal door the image was measured as, mm."""

    width_mm: float
    thickness_mm: float
    height_mm: float


class LocateResponse(LocateResult):
    """The SPEC section 3 result plus the door and its robot targets."""

    door_id: str | None = Field(
        None, description="the recipe used, or null when the door was given by its size"
    )
    door: DoorOut
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


class CellInfo(BaseModel):
    """The cell and camera calibration in use, with content ids for audit trails."""

    cell_id: str = Field(
        description="content hash of the whole cell (camera, extrinsics, fixture, envelope, door)"
    )
    calibration_id: str = Field(
        description="content hash of the camera calibration (K, distortion, image size)"
    )
    source: str | None = Field(None, description="name of the cell file (without its folder)")
    cell: dict[str, Any] = Field(description="the cell in SPEC section 2 layout, camera inline")


class Health(BaseModel):
    status: str = Field(description="'ok' while the process answers")


class Readiness(BaseModel):
    status: str = Field(description="'ready' when the cell and calibration are loaded")
    access: str = Field(
        "keys",
        description="'keys': every /v1 request needs an API key; 'open': none needed (loopback development)",
    )
    cell_id: str | None = None
    calibration_id: str | None = None


class DoorList(BaseModel):
    """One page of the door ids in the recipe database (ordered by id)."""

    door_ids: list[str]
    total: int = Field(description="how many recipes are stored")
    limit: int = Field(description="page size used")
    offset: int = Field(description="index of the first id on this page")
    next_offset: int | None = Field(None, description="offset of the next page, null on the last page")


class RecipeChangeOut(BaseModel):
    field: str = Field(
        description="changed field, e.g. 'width_mm' or 'hinges[1].z_mm' ('hinges': their number)"
    )
    old: Any = None
    new: Any = None


class RecipeVersionOut(BaseModel):
    """One change of a door recipe: who, when, what."""

    door_id: str
    version: int
    action: str = Field(
        description="created, updated, deleted (retired) or migrated (stored before history existed)"
    )
    changed_by: str = Field(description="name of the API key (or 'cli:<user>') that made the change")
    changed_at: str | None = Field(None, description="when, ISO 8601")
    changes: list[RecipeChangeOut] = Field(
        default_factory=list, description="fields that differ from the version before"
    )
    recipe: dict[str, Any] | None = Field(None, description="the whole recipe as stored in this version")


class RecipeHistory(BaseModel):
    door_id: str
    versions: list[RecipeVersionOut]
