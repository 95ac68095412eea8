"""Door recipes: ``GET /v1/doors``, ``GET /v1/doors/{door_id}``, ``PUT /v1/doors/{door_id}``."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, Path

from doorloc.app.access import Principal, Role
from doorloc.app.http.dependencies import call_store, ready_state, require_role
from doorloc.app.http.problems import ProblemError, problem_responses
from doorloc.app.http.schemas import DoorList
from doorloc.app.http.state import ServiceState
from doorloc.recipes.models import DOOR_ID_PATTERN, DoorRecipe

__all__ = ["router"]

router = APIRouter(prefix="/v1/doors", tags=["doors"])

Operator = Annotated[Principal, Depends(require_role(Role.operator))]
Engineer = Annotated[Principal, Depends(require_role(Role.engineer))]

# ":path" because door ids may contain '/' (barcodes); the pattern still bounds what is accepted.
DoorId = Annotated[str, Path(pattern=DOOR_ID_PATTERN, description="the door's barcode")]


@router.get("", response_model=DoorList, responses=problem_responses(401, 403, 503), summary="List door ids")
async def list_doors(_who: Operator, state: Annotated[ServiceState, Depends(ready_state)]) -> DoorList:
    ids = await call_store(state.store.list)
    return DoorList(door_ids=[i if isinstance(i, str) else i.door_id for i in ids])


@router.get(
    "/{door_id:path}", response_model=DoorRecipe, responses=problem_responses(401, 403, 404, 422, 503),
    summary="Get a door recipe",
)
async def get_door(door_id: DoorId, _who: Operator, state: Annotated[ServiceState, Depends(ready_state)]) -> DoorRecipe:
    recipe = await call_store(state.store.get, door_id)
    if recipe is None:
        raise ProblemError(404, "unknown_door", f"There is no door recipe with id '{door_id}'; PUT it first.")
    return recipe


# 404 too: a path holding characters no door id has (e.g. a newline) matches no route at all.
@router.put(
    "/{door_id:path}", response_model=DoorRecipe, responses=problem_responses(400, 401, 403, 404, 413, 422, 503),
    summary="Create or replace a door recipe",
)
async def put_door(
    door_id: DoorId, recipe: DoorRecipe, who: Engineer, state: Annotated[ServiceState, Depends(ready_state)]
) -> DoorRecipe:
    if recipe.door_id != door_id:
        raise ProblemError(
            422, "door_id_mismatch",
            f"The recipe's door_id '{recipe.door_id}' differs from the one in the URL '{door_id}'; make them equal.",
        )
    try:
        await call_store(state.store.put, recipe)
    except ValueError as e:
        raise ProblemError(422, "invalid_recipe", f"The recipe cannot be stored: {e}.") from None
    return recipe
