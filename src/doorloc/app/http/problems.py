"""Errors as RFC 9457 ``application/problem+json``: a status, a short title and a sentence a person can act on.

Every route declares the problems it can answer with :func:`problem_responses`, so the OpenAPI document
lists every status code the API returns.
"""

from __future__ import annotations

import logging
from http import HTTPStatus
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import BaseModel, Field
from starlette.exceptions import HTTPException as StarletteHTTPException

__all__ = ["Problem", "ProblemError", "problem_response", "problem_responses", "install_problem_handlers"]

PROBLEM_MEDIA_TYPE = "application/problem+json"
_log = logging.getLogger("doorloc.http")


class Problem(BaseModel):
    """An error answer (RFC 9457)."""

    type: str = Field("about:blank", description="URI naming the kind of problem")
    title: str = Field(description="short summary of the kind of problem (the HTTP reason phrase)")
    status: int = Field(description="HTTP status code")
    detail: str = Field(description="what went wrong and what to do about it, as a sentence")
    code: str = Field(description="machine-readable reason, e.g. 'not_an_image', 'too_large'")
    request_id: str | None = Field(
        None, description="id of the request, as in the logs and the X-Request-ID header"
    )
    errors: list[dict[str, Any]] | None = Field(
        None, description="per-field validation errors, when there are several"
    )


class ProblemError(Exception):
    """Raise inside a route to answer with a problem: ``raise ProblemError(415, "not_an_image", "The upload ...")``."""

    def __init__(self, status: int, code: str, detail: str, headers: dict[str, str] | None = None) -> None:
        super().__init__(detail)
        self.status = status
        self.code = code
        self.detail = detail
        self.headers = headers


_DESCRIPTIONS = {
    400: "The request body cannot be parsed (a malformed multipart form, or JSON that is not UTF-8).",
    401: "Missing or wrong API key (X-API-Key header).",
    403: "The API key's role may not do this (operator: locate and read; engineer: also change recipes; metrics).",
    404: "No such resource.",
    413: "The request body is larger than the service accepts.",
    415: "The upload is not a PNG, JPEG, TIFF or BMP image (judged by its bytes).",
    422: "A field is missing or invalid, or the image cannot be decoded or declares too many pixels.",
    408: "The request body did not arrive within the request deadline.",
    429: "Too many wrong API keys from this address this minute (see Retry-After).",
    503: "The service is not ready (the cell or its calibration is not loaded), the recipe database is unreachable, "
    "or this worker is overloaded (see Retry-After).",
}


def problem_responses(*statuses: int) -> dict[int | str, dict[str, Any]]:
    """``responses=`` for a route: each status answered as application/problem+json with the Problem schema."""
    schema = Problem.model_json_schema()
    if 401 in statuses and 429 not in statuses:
        # a route that checks keys also answers 429 to an address past its wrong-key budget
        statuses = (*statuses, 429)
    return {
        s: {
            "description": _DESCRIPTIONS.get(s, HTTPStatus(s).phrase),
            "content": {PROBLEM_MEDIA_TYPE: {"schema": schema}},
        }
        for s in statuses
    }


def problem_response(
    request: Request | None,
    status: int,
    code: str,
    detail: str,
    headers: dict[str, str] | None = None,
    **extra: Any,
) -> JSONResponse:
    """The JSONResponse for one problem."""
    request_id = request.scope.get("state", {}).get("request_id") if request is not None else None
    body = Problem(
        title=HTTPStatus(status).phrase,
        status=status,
        detail=detail,
        code=code,
        request_id=request_id,
        **extra,
    )
    return JSONResponse(
        body.model_dump(mode="json", exclude_none=True),
        status_code=status,
        headers=headers,
        media_type=PROBLEM_MEDIA_TYPE,
    )


def _field_name(loc: tuple | list) -> str:
    parts = [str(p) for p in loc if p not in ("body", "query", "path", "header", "form")]
    return ".".join(parts) or "request"


def _validation_sentence(errors: list[dict[str, Any]]) -> str:
    sentences = []
    for e in errors[:5]:
        name = _field_name(e.get("loc", ()))
        if e.get("type") == "missing":
            sentences.append(f"'{name}' is required")
        else:
            sentences.append(f"'{name}': {str(e.get('msg', 'invalid value')).removeprefix('Value error, ')}")
    more = f" (and {len(errors) - 5} more)" if len(errors) > 5 else ""
    return "Invalid request: " + "; ".join(sentences) + more + "."


_HTTP_CODES = {
    400: "malformed_body",
    401: "unauthorized",
    404: "not_found",
    405: "method_not_allowed",
    413: "too_large",
    503: "not_ready",
}


def _allowed_methods(request: Request) -> list[str]:
    """Methods some route answers on this path (a path can have one route per method, e.g. GET and PUT).

    Asks every route whether it fully matches the path with each method in turn: routers nest (FastAPI's
    included routers do not expose their routes' methods), but every route can say whether it matches.
    """
    from starlette.routing import Match

    allowed = []
    for method in ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS"):
        scope = {**request.scope, "method": method}
        if any(route.matches(scope)[0] == Match.FULL for route in request.app.router.routes):
            allowed.append(method)
    return allowed


def install_problem_handlers(app: FastAPI) -> None:
    """Answer every error, expected or not, as problem+json (never a stack trace)."""

    @app.exception_handler(ProblemError)
    async def _problem(request: Request, exc: ProblemError) -> JSONResponse:
        return problem_response(request, exc.status, exc.code, exc.detail, exc.headers)

    from doorloc.recipes.store import StoredRecipeInvalid

    @app.exception_handler(StoredRecipeInvalid)
    async def _stored_invalid(request: Request, exc: StoredRecipeInvalid) -> JSONResponse:
        return problem_response(
            request, 422, "invalid_stored_recipe", str(exc)[0].upper() + str(exc)[1:] + "."
        )

    @app.exception_handler(RequestValidationError)
    async def _invalid(request: Request, exc: RequestValidationError) -> JSONResponse:
        errors = [
            {
                "field": _field_name(e.get("loc", ())),
                "message": str(e.get("msg", "")).removeprefix("Value error, "),
                "type": str(e.get("type", "")),
            }
            for e in exc.errors()
        ]
        return problem_response(
            request, 422, "invalid_request", _validation_sentence(list(exc.errors())), errors=errors
        )

    @app.exception_handler(StarletteHTTPException)
    async def _http(request: Request, exc: StarletteHTTPException) -> JSONResponse:
        status = exc.status_code
        code = _HTTP_CODES.get(status, "http_error")
        if status == 404:
            detail = f"There is nothing at {request.url.path}; see /docs for the endpoints."
        elif status == 405:
            allowed = _allowed_methods(request) or ["GET"]
            detail = f"{request.method} is not allowed on {request.url.path}; use {' or '.join(allowed)}."
            return problem_response(request, 405, "method_not_allowed", detail, {"Allow": ", ".join(allowed)})
        elif status == 400:
            detail = (
                "The request body cannot be parsed: send images as a multipart form with the field 'image' "
                "(curl -F image=@door.png) and recipes as UTF-8 JSON."
            )
        else:
            detail = str(exc.detail) if exc.detail else HTTPStatus(status).phrase
            if not detail.endswith("."):
                detail += "."
        return problem_response(request, status, code, detail, getattr(exc, "headers", None))

    @app.exception_handler(Exception)
    async def _unexpected(request: Request, exc: Exception) -> JSONResponse:
        request_id = request.scope.get("state", {}).get("request_id")
        service = getattr(request.app.state, "service", None)
        if service is not None:
            service.metrics.internal_errors.labels("request").inc()
        _log.error(
            "unexpected error",
            exc_info=exc,
            extra={
                "fields": {"event": "internal_error", "incident_id": request_id, "path": request.url.path}
            },
        )
        return problem_response(
            request,
            500,
            "internal_error",
            f"The service failed on this request; it has been logged with incident id {request_id}. Try again, and "
            "report that id if it persists.",
        )
