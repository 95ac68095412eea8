"""Door recipes: ``GET /v1/doors`` (paged), ``GET|PUT|DELETE /v1/doors/{door_id}``,
``GET /v1/doors/{door_id}/history``.

Reading needs the operator role, changing the engineer role. Every change is a new version recorded with
the key's name and the time (the audit trail); answers carry the version in ``X-Recipe-Version``.
A door id that itself ends in ``/history`` cannot be read through ``GET /v1/doors/{id}`` (the history route
answers); its recipe is still reachable through locate and the CLI.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Body, Depends, Path, Query, Response
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import ValidationError

from doorloc.app.access import Principal, Role
from doorloc.app.http.dependencies import call_store, ready_state, require_role
from doorloc.app.http.problems import ProblemError, problem_responses
from doorloc.app.http.schemas import DoorList, RecipeHistory, RecipeVersionOut
from doorloc.app.http.state import ServiceState
from doorloc.recipes.models import DOOR_ID_PATTERN, MILLING, DoorRecipe

__all__ = ["router"]

router = APIRouter(prefix="/v1/doors", tags=["doors"])

Operator = Annotated[Principal, Depends(require_role(Role.operator))]
Engineer = Annotated[Principal, Depends(require_role(Role.engineer))]

# ":path" because door ids may contain '/' (barcodes); the pattern still bounds what is accepted.
DoorId = Annotated[str, Path(pattern=DOOR_ID_PATTERN, description="the door's barcode")]


@router.get(
    "", response_model=DoorList, responses=problem_responses(401, 403, 422, 503), summary="List door ids"
)
async def list_doors(
    _who: Operator,
    state: Annotated[ServiceState, Depends(ready_state)],
    limit: Annotated[int, Query(ge=1, le=1000, description="ids per page")] = 100,
    offset: Annotated[int, Query(ge=0, le=10_000_000, description="index of the first id")] = 0,
) -> DoorList:
    rows = await call_store(lambda: state.recipes.list(limit=limit, offset=offset))
    total = await call_store(state.recipes.count)
    ids = [i if isinstance(i, str) else i.door_id for i in rows]
    more = offset + len(ids) < total
    return DoorList(
        door_ids=ids, total=total, limit=limit, offset=offset, next_offset=offset + len(ids) if more else None
    )


@router.get(
    "/{door_id:path}/history",
    response_model=RecipeHistory,
    responses=problem_responses(401, 403, 404, 422, 503),
    summary="Every version of a door recipe: who changed what, when",
)
async def door_history(
    door_id: DoorId, _who: Operator, state: Annotated[ServiceState, Depends(ready_state)]
) -> RecipeHistory:
    versions = await call_store(state.recipes.history, door_id)
    if not versions:
        raise ProblemError(
            404, "unknown_door", f"There is no door recipe with id '{door_id}', and there never was."
        )
    return RecipeHistory(
        door_id=door_id,
        versions=[
            RecipeVersionOut(
                door_id=v.door_id,
                version=v.version,
                action=v.action,
                changed_by=v.changed_by,
                changed_at=v.changed_at.isoformat() if v.changed_at else None,
                changes=[c.__dict__ for c in v.changes],
                recipe=v.recipe.model_dump(mode="json") if v.recipe is not None else None,
            )
            for v in versions
        ],
    )


@router.get(
    "/{door_id:path}",
    response_model=DoorRecipe,
    responses=problem_responses(401, 403, 404, 422, 503),
    summary="Get a door recipe",
)
async def get_door(
    door_id: DoorId, _who: Operator, state: Annotated[ServiceState, Depends(ready_state)]
) -> Response:
    found = await call_store(state.recipes.get_versioned, door_id)
    if found is None:
        raise ProblemError(404, "unknown_door", f"There is no door recipe with id '{door_id}'; PUT it first.")
    return _recipe_answer(*found)


def _recipe_answer(recipe: DoorRecipe, version: int) -> Response:
    """The recipe as stored, its version in ``X-Recipe-Version``. Answered as it is, not validated again as a
    response model: that would hold it to doorloc's default spindle bounds instead of the cell's."""
    return JSONResponse(recipe.model_dump(mode="json"), headers={"X-Recipe-Version": str(version)})


# 404 too: a path holding characters no door id has (e.g. a newline) matches no route at all.
@router.put(
    "/{door_id:path}",
    response_model=DoorRecipe,
    responses=problem_responses(400, 401, 403, 404, 413, 422, 503),
    summary="Create or replace a door recipe (a new version in its history)",
    # the body is a DoorRecipe, validated against the cell's spindle and cutter (its milling: section)
    openapi_extra={
        "requestBody": {
            "required": True,
            "content": {"application/json": {"schema": {"$ref": "#/components/schemas/DoorRecipe"}}},
        }
    },
)
async def put_door(
    door_id: DoorId,
    body: Annotated[dict[str, Any], Body()],
    who: Engineer,
    state: Annotated[ServiceState, Depends(ready_state)],
) -> Response:
    """Store the recipe as a new version; its spindle speed, feed and hinge depths must keep within the cell's
    spindle and cutter (the cell file's ``milling:`` section, else doorloc's defaults), the 422 naming the bound."""
    assert state.cell is not None  # ready_state
    try:
        recipe = DoorRecipe.model_validate(body, context={MILLING: state.cell.milling})
    except ValidationError as e:
        raise RequestValidationError(
            [{**err, "loc": ("body", *err["loc"])} for err in e.errors(include_url=False)]
        ) from None
    if recipe.door_id != door_id:
        raise ProblemError(
            422,
            "door_id_mismatch",
            f"The recipe's door_id '{recipe.door_id}' differs from the one in the URL '{door_id}'; make them equal.",
        )
    try:
        version = await call_store(lambda: state.recipes.put(recipe, by=who.name))
    except ValueError as e:
        raise ProblemError(422, "invalid_recipe", f"The recipe cannot be stored: {e}.") from None
    return _recipe_answer(recipe, version)


@router.delete(
    "/{door_id:path}",
    status_code=204,
    responses=problem_responses(401, 403, 404, 422, 503),
    summary="Retire a door recipe (its history stays)",
)
async def delete_door(
    door_id: DoorId, who: Engineer, state: Annotated[ServiceState, Depends(ready_state)]
) -> Response:
    if not await call_store(lambda: state.recipes.delete(door_id, by=who.name)):
        raise ProblemError(404, "unknown_door", f"There is no door recipe with id '{door_id}' to retire.")
    return Response(status_code=204)
