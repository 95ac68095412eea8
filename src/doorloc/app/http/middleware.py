"""Two pure-ASGI middlewares: the request-body size limit, and request ids with logs and metrics.

The body limit counts bytes as they arrive: a request that declares too large a ``Content-Length`` is
answered 413 before its body is read, and one that streams more than the limit is cut off at the
first chunk past it, so an oversized upload never sits in memory or on disk whole.
"""

from __future__ import annotations

import json
import logging
import math
import re
import time
import uuid
from typing import Any

import anyio
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from doorloc.app.http.metrics import ServiceMetrics
from doorloc.app.http.problems import PROBLEM_MEDIA_TYPE

__all__ = [
    "BodySizeLimit",
    "BodyTooLarge",
    "BodyTimeout",
    "LocateAdmission",
    "RequestContext",
    "send_problem",
]

_log = logging.getLogger("doorloc.http")
_REQUEST_ID = re.compile(r"^[A-Za-z0-9._-]{1,64}$")


def _too_large_sentence(limit: int) -> str:
    return (
        f"The request body is larger than this service accepts ({limit / 1e6:.1f} MB); "
        "send the camera image as PNG or JPEG without extra payload."
    )


class BodyTooLarge(StarletteHTTPException):
    """Raised from ``receive`` once the body passes the limit (FastAPI passes HTTPExceptions through)."""

    def __init__(self, limit: int) -> None:
        super().__init__(status_code=413, detail=_too_large_sentence(limit))


class BodySizeLimit:
    """Refuse request bodies larger than ``max_body_bytes`` with 413, while they stream."""

    def __init__(self, app: ASGIApp, max_body_bytes: int) -> None:
        self.app = app
        self.max_body_bytes = max_body_bytes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        limit = self.max_body_bytes
        declared = _header(scope, b"content-length")
        if declared is not None and declared.isdigit() and int(declared) > limit:
            await send_problem(scope, send, 413, "too_large", _too_large_sentence(limit))
            return
        received = 0
        started = False

        async def limited_receive() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit:
                    raise BodyTooLarge(limit)
            return message

        async def tracking_send(message: Message) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, limited_receive, tracking_send)
        except BodyTooLarge:
            # Normally the app's HTTPException handler answers; this catches reads outside a route.
            if started:
                raise
            await send_problem(scope, send, 413, "too_large", _too_large_sentence(limit))


class LocateAdmission:
    """Deadline and media type for ``POST /v1/locate``, decided before a byte of the body is read.

    - a body that is not ``multipart/form-data`` is refused 415 (a raw ``image/png`` body included);
    - each request gets a deadline (``scope["state"]["deadline"]``, monotonic seconds): a body that has not
      arrived by then is cut off with 408 (slow or stalled clients hold no CPU slot and no queue place
      meanwhile), and the route answers 503 Retry-After when its image could not get a CPU slot by then or
      the worker's queue is full (:func:`doorloc.app.http.routes_locate`).
    """

    def __init__(self, app: ASGIApp, deadline_s: float, path: str = "/v1/locate") -> None:
        self.app = app
        self.deadline_s = deadline_s
        self.path = path

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] != "POST" or scope["path"] != self.path:
            await self.app(scope, receive, send)
            return
        ctype = (_header(scope, b"content-type") or "").split(";")[0].strip().lower()
        if (
            ctype and ctype != "multipart/form-data"
        ):  # no type at all: the form's own 422 names the missing image
            await send_problem(
                scope,
                send,
                415,
                "not_multipart",
                f"POST {self.path} takes a multipart form with the image in the field 'image' "
                f"(curl -F image=@door.png), not a body of type '{ctype}'.",
            )
            return
        deadline = time.monotonic() + self.deadline_s
        scope.setdefault("state", {})["deadline"] = deadline

        async def receive_by_deadline() -> Message:
            left = deadline - time.monotonic()
            try:
                with anyio.fail_after(max(left, 0.001)):
                    return await receive()
            except TimeoutError:
                raise BodyTimeout(self.deadline_s) from None

        try:
            await self.app(scope, receive_by_deadline, send)
        except BodyTimeout as e:
            await send_problem(scope, send, 408, "request_timeout", str(e.detail))


class BodyTimeout(StarletteHTTPException):
    """The request body did not arrive within the request deadline (a slow or stalled client)."""

    def __init__(self, deadline_s: float) -> None:
        super().__init__(
            status_code=408,
            detail=(
                f"The upload did not arrive within {math.ceil(deadline_s)} s; send the image again over a faster link."
            ),
        )


class RequestContext:
    """Give each request an id (``X-Request-ID``, kept from the client when sane), log it as one JSON line,
    and count it in the app's metrics."""

    def __init__(self, app: ASGIApp, metrics: ServiceMetrics) -> None:
        self.app = app
        self.metrics = metrics

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        given = _header(scope, b"x-request-id")
        request_id = given if given and _REQUEST_ID.match(given) else uuid.uuid4().hex
        scope.setdefault("state", {})["request_id"] = request_id
        status = 500
        t0 = time.perf_counter()

        async def send_with_id(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = message["status"]
                message.setdefault("headers", [])
                message["headers"] = [*message["headers"], (b"x-request-id", request_id.encode())]
            await send(message)

        try:
            await self.app(scope, receive, send_with_id)
        finally:
            elapsed = time.perf_counter() - t0
            route = scope.get("route")
            route_name = getattr(route, "path", None) or "unmatched"
            self.metrics.observe_request(scope["method"], route_name, status, elapsed)
            _log.info(
                "request",
                extra={
                    "fields": {
                        "event": "request",
                        "request_id": request_id,
                        "method": scope["method"],
                        "path": scope["path"],
                        "route": route_name,
                        "status": status,
                        "duration_ms": round(elapsed * 1e3, 2),
                        "client": (scope.get("client") or ("", 0))[0],
                        "principal": scope.get("state", {}).get("principal"),
                    }
                },
            )


def _header(scope: Scope, name: bytes) -> str | None:
    for k, v in scope.get("headers", ()):
        if k == name:
            return v.decode("latin-1")
    return None


async def send_problem(
    scope: Scope,
    send: Send,
    status: int,
    code: str,
    detail: str,
    headers: list[tuple[bytes, bytes]] | None = None,
) -> None:
    from http import HTTPStatus

    body: dict[str, Any] = {
        "type": "about:blank",
        "title": HTTPStatus(status).phrase,
        "status": status,
        "detail": detail,
        "code": code,
    }
    request_id = scope.get("state", {}).get("request_id")
    if request_id:
        body["request_id"] = request_id
    payload = json.dumps(body).encode()
    await send(
        {
            "type": "http.response.start",
            "status": status,
            "headers": [
                (b"content-type", PROBLEM_MEDIA_TYPE.encode()),
                (b"content-length", str(len(payload)).encode()),
                (b"connection", b"close"),
                *(headers or []),
            ],
        }
    )
    await send({"type": "http.response.body", "body": payload})
