"""Operations: liveness, readiness, metrics, the cell in use, and the operator page."""

from __future__ import annotations

from importlib import resources
from pathlib import PurePath
from typing import Annotated

from fastapi import APIRouter, Depends
from fastapi.responses import HTMLResponse, Response

from doorloc.app.access import Role
from doorloc.app.http.dependencies import get_state, ready_state, require_role
from doorloc.app.http.metrics import CONTENT_TYPE_LATEST
from doorloc.app.http.problems import ProblemError, problem_responses
from doorloc.app.http.schemas import CellInfo, Health, Readiness
from doorloc.app.http.state import ServiceState
from doorloc.cell import cell_to_dict

__all__ = ["router"]

router = APIRouter()


@router.get("/healthz", response_model=Health, tags=["ops"], summary="Liveness: the process answers")
async def healthz() -> Health:
    return Health(status="ok")


@router.get(
    "/readyz",
    response_model=Readiness,
    tags=["ops"],
    responses=problem_responses(503),
    summary="Readiness: the cell and calibration are loaded",
)
async def readyz(state: Annotated[ServiceState, Depends(ready_state)]) -> Readiness:
    if state.overloaded:
        raise ProblemError(
            503,
            "overloaded",
            f"This worker is at its limit ({state.admitted} locate requests running or queued); retry shortly.",
            headers={"Retry-After": "2"},
        )
    return Readiness(status="ready", access=state.access_mode, **state.cell_ids())


@router.get(
    "/metrics",
    tags=["ops"],
    response_class=Response,
    summary="Prometheus metrics of this worker process",
    responses={
        200: {
            "content": {CONTENT_TYPE_LATEST.split(";")[0]: {"schema": {"type": "string"}}},
            "description": "Prometheus text exposition format",
        },
        **problem_responses(401, 403, 503),
    },
    dependencies=[Depends(require_role(Role.metrics))],
)
async def metrics(state: Annotated[ServiceState, Depends(get_state)]) -> Response:
    return Response(state.metrics.exposition(), media_type=CONTENT_TYPE_LATEST)


@router.get(
    "/v1/cell",
    response_model=CellInfo,
    tags=["cell"],
    responses=problem_responses(401, 403, 503),
    dependencies=[Depends(require_role(Role.operator))],
    summary="The cell and camera calibration in use",
)
async def get_cell(state: Annotated[ServiceState, Depends(ready_state)]) -> CellInfo:
    assert state.cell is not None
    # the file's name only: its absolute path tells a caller about the server's file system, not the cell
    source = PurePath(state.cell.source).name if state.cell.source else None
    return CellInfo(source=source, cell=cell_to_dict(state.cell), **state.cell_ids())


@router.get("/", response_class=HTMLResponse, include_in_schema=False)
async def operator_page() -> HTMLResponse:
    html = resources.files("doorloc.app").joinpath("static/index.html").read_text(encoding="utf-8")
    return HTMLResponse(html)


@router.get("/docs", response_class=HTMLResponse, include_in_schema=False)
async def api_docs() -> HTMLResponse:
    """Swagger UI from the package's own files (static/vendor/swagger-ui): nothing is loaded from another site."""
    html = resources.files("doorloc.app").joinpath("static/docs.html").read_text(encoding="utf-8")
    return HTMLResponse(html)
