"""FastAPI dependencies: the app's state, readiness, and the optional API key."""

from __future__ import annotations

import logging
import secrets
from collections.abc import Callable
from typing import Any

import anyio.to_thread
from fastapi import Depends, Request, Security
from fastapi.security import APIKeyHeader

from doorloc.app.http.problems import ProblemError
from doorloc.app.http.state import ServiceState

__all__ = ["get_state", "ready_state", "require_api_key", "call_store"]

_api_key_header = APIKeyHeader(
    name="X-API-Key", auto_error=False, description="required when the service runs with DOORLOC_API_KEY set"
)


def get_state(request: Request) -> ServiceState:
    return request.app.state.service


def require_api_key(
    state: ServiceState = Depends(get_state), given: str | None = Security(_api_key_header)
) -> None:
    """401 unless the request carries the configured key (no key configured: open)."""
    expected = state.settings.api_key
    if expected is None:
        return
    if given is None or not secrets.compare_digest(given.encode(), expected.get_secret_value().encode()):
        raise ProblemError(
            401, "unauthorized",
            "This service needs an API key: send it in the X-API-Key header (ask the cell's administrator for it).",
            headers={"WWW-Authenticate": "APIKey"},
        )


def ready_state(state: ServiceState = Depends(get_state)) -> ServiceState:
    """The state, or 503 while the cell and calibration are not loaded."""
    if not state.ready:
        reason = state.load_error or "still starting"
        raise ProblemError(
            503, "not_ready",
            f"The service is not ready to locate doors ({reason}); fix the cell file and restart, or retry shortly.",
            headers={"Retry-After": "5"},
        )
    return state


async def call_store(fn: Callable[..., Any], *args: Any) -> Any:
    """Run a recipe-store call in a worker thread; a database that fails answers 503, not 500.

    ValueError (a recipe the store refuses) passes through for the caller to answer 422.
    """
    from sqlalchemy.exc import SQLAlchemyError

    from doorloc.recipes.store import RecipeStoreError

    try:
        return await anyio.to_thread.run_sync(fn, *args)
    except (SQLAlchemyError, RecipeStoreError) as e:
        logging.getLogger("doorloc.http").error(
            "recipe database error", extra={"fields": {"event": "database_error", "error": str(e).splitlines()[0]}}
        )
        raise ProblemError(
            503, "database_unavailable",
            "The recipe database cannot be reached right now; retry shortly, and tell the administrator if it persists.",
            headers={"Retry-After": "5"},
        ) from None
