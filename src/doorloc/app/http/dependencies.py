"""FastAPI dependencies: the app's state, readiness, and who the caller is (API key and role)."""

from __future__ import annotations

import hashlib
import hmac
import logging
from collections.abc import Callable
from typing import Any

import anyio.to_thread
from fastapi import Depends, Request, Security
from fastapi.security import APIKeyHeader

from doorloc.app.access import ANY_ACTIVE_TTL_S, LEGACY_KEY_NAME, Principal, Role, role_allows
from doorloc.app.http.problems import ProblemError
from doorloc.app.http.state import ServiceState

__all__ = [
    "get_state",
    "ready_state",
    "require_role",
    "require_api_key",
    "call_store",
    "resolve_principal",
    "ANONYMOUS",
]

_api_key_header = APIKeyHeader(
    name="X-API-Key",
    auto_error=False,
    description="an API key (doorloc keys create); required once any key exists or DOORLOC_API_KEY is set",
)
#: the caller when the service is open (``open_access``, loopback only, see doorloc serve --open) and has no key
ANONYMOUS = Principal("anonymous", Role.engineer)


def get_state(request: Request) -> ServiceState:
    return request.app.state.service


def _unauthorized(detail: str) -> ProblemError:
    return ProblemError(401, "unauthorized", detail, headers={"WWW-Authenticate": "APIKey"})


async def resolve_principal(state: ServiceState, given: str | None, client: str) -> Principal:
    """Who sent the request, from its X-API-Key (``given``) alone: no body has been read yet.

    401 for a missing or wrong key; 429 once ``client`` (its address) has sent more wrong keys this minute
    than ``auth_failures_per_minute`` (then only a key verified before passes, and a key not verified yet
    only on one of the address's few trials a minute: ``FailureBudget.may_try``); the anonymous engineer
    only on an open service (``open_access``, loopback) while no key has ever been seen. A service that has
    seen a key once never opens again, even when every key is revoked: it fails closed.
    """
    legacy = state.settings.api_key
    if given:
        retry = state.auth_failures.retry_after(client)
        if retry is not None:
            # over budget: a key verified before passes (no derivation), so a guesser sharing an address (a NAT,
            # a proxy) does not lock out the valid keys used from it; a key not verified yet is derived only on
            # one of the address's few trials a minute (each key once), known key id or not alike
            trial = state.auth_failures.may_try(client, given)
            known = (
                None if state.keys is None else await call_store(state.keys.authenticate, given, not trial)
            )
            if known is not None:
                state.keys_seen = True
                return known
            if trial:
                state.auth_failures.record(client)
            raise ProblemError(
                429,
                "too_many_failures",
                f"Too many wrong API keys from {client}; wait {retry} s (see Retry-After) and check the key.",
                headers={"Retry-After": str(retry)},
            )
        # the legacy single key: compare fixed-length digests so the comparison time says nothing about the key
        if legacy is not None and hmac.compare_digest(
            hashlib.sha256(given.encode()).digest(),
            hashlib.sha256(legacy.get_secret_value().encode()).digest(),
        ):
            return Principal(LEGACY_KEY_NAME, Role.engineer)
        if state.keys is None:
            raise _service_not_ready(state)
        who = await call_store(state.keys.authenticate, given)
        if who is None:
            state.auth_failures.record(client)
            raise _unauthorized(
                "The API key in X-API-Key is not valid (unknown, mistyped or revoked); "
                "ask the cell's administrator for a key (doorloc keys create)."
            )
        state.keys_seen = True
        return who
    if legacy is not None or state.keys_seen:
        raise _unauthorized(
            "This service needs an API key: send it in the X-API-Key header "
            "(ask the cell's administrator for it)."
        )
    if not state.settings.open_access:
        raise _unauthorized(
            "This service needs an API key in the X-API-Key header. If none exists yet, the administrator "
            "creates one (doorloc keys create --role engineer NAME)."
        )
    if state.keys is None:
        raise _service_not_ready(state)
    # the answer is remembered ANY_ACTIVE_TTL_S: no database round trip (nor thread hop) on every request
    keys_exist = state.keys.cached_any_active(ANY_ACTIVE_TTL_S)
    if keys_exist is None:
        keys_exist = await call_store(state.keys.any_active)
    if keys_exist:
        state.keys_seen = True  # from now on closed, whatever happens to the keys
        raise _unauthorized(
            "This service needs an API key: send it in the X-API-Key header "
            "(ask the cell's administrator for it)."
        )
    return ANONYMOUS


def require_role(role: Role) -> Callable[..., Any]:
    """A dependency: the caller (a :class:`Principal`), or 401 without a valid key, 403 when its role may not."""

    async def dependency(
        request: Request,
        state: ServiceState = Depends(get_state),
        given: str | None = Security(_api_key_header),
    ) -> Principal:
        # the key gate (doorloc.app.http.guards.KeyGate) has already resolved it, before the body was read
        who = request.scope.get("state", {}).get("who")
        if who is None:
            client = request.client.host if request.client else ""
            who = await resolve_principal(state, given, client)
        request.scope.setdefault("state", {})["principal"] = who.name
        if not role_allows(who.role, role):
            raise ProblemError(
                403,
                "forbidden",
                f"The key '{who.name}' has the role '{who.role}', which may not do this; it needs '{role}' "
                "(ask the cell's administrator for such a key).",
            )
        return who

    return dependency


#: kept for callers of the first API: the operator role
require_api_key = require_role(Role.operator)


def _service_not_ready(state: ServiceState) -> ProblemError:
    reason = state.load_error or "still starting"
    return ProblemError(
        503,
        "not_ready",
        f"The service is not ready ({reason}); fix the cell file or database and restart, or retry shortly.",
        headers={"Retry-After": "5"},
    )


def ready_state(state: ServiceState = Depends(get_state)) -> ServiceState:
    """The state, or 503 while the cell and calibration are not loaded."""
    if not state.ready:
        reason = state.load_error or "still starting"
        raise ProblemError(
            503,
            "not_ready",
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
            "recipe database error",
            extra={"fields": {"event": "database_error", "error": str(e).splitlines()[0]}},
        )
        raise ProblemError(
            503,
            "database_unavailable",
            "The recipe database cannot be reached right now; retry shortly, and tell the administrator if it persists.",
            headers={"Retry-After": "5"},
        ) from None
