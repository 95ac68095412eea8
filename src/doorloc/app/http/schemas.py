"""Response bodies of the HTTP API (request bodies are the library's own models, e.g. DoorRecipe)."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, Field

from doorloc.app.answer import DoorOut, LocateResponse

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


class CellInfo(BaseModel):
    """The cell and camera calibration in use, with content ids for audit trails."""

    cell_id: str = Field(
        description="'sha256:' + the cell file's SHA-256, the provenance.cell_sha256 of every result made with it"
    )
    calibration_id: str = Field(
        description="'sha256:' + the camera calibration's SHA-256, the provenance.calibration_sha256 of results"
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
    cell_id: str | None = Field(
        None,
        description="'sha256:' + the cell file's SHA-256 (as in /v1/cell and results' provenance.cell_sha256)",
    )
    calibration_id: str | None = Field(
        None, description="'sha256:' + the camera calibration's SHA-256 (as in provenance.calibration_sha256)"
    )


class DoorList(BaseModel):
    """One page of the door ids in the recipe database (ordered by id)."""

    door_ids: list[str] = Field(description="the door ids on this page, in id order")
    total: int = Field(description="how many recipes are stored")
    limit: int = Field(description="page size used")
    offset: int = Field(description="index of the first id on this page")
    next_offset: int | None = Field(None, description="offset of the next page, null on the last page")


class RecipeChangeOut(BaseModel):
    field: str = Field(
        description="changed field, e.g. 'width_mm' or 'hinges[1].z_mm' ('hinges': their number)"
    )
    old: Any = Field(None, description="the value before the change (null: the field was not set)")
    new: Any = Field(None, description="the value after the change (null: the field was removed)")


class RecipeVersionOut(BaseModel):
    """One change of a door recipe: who, when, what."""

    door_id: str = Field(description="the door recipe's id")
    version: int = Field(description="recipe version, counting from 1")
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
    door_id: str = Field(description="the door recipe's id")
    versions: list[RecipeVersionOut] = Field(description="every version, oldest first")
