"""ASGI guards that decide on a request from its head alone, before any of its body is read.

- :class:`HostCheck`: the ``Host`` header must name this service (a configured list), so a page on another
  site cannot reach a loopback service through DNS rebinding;
- :class:`KeyGate`: every ``/v1`` request and ``/metrics`` needs a valid API key, checked here, so a keyless
  19 MB upload is answered 401 without a byte of it being spooled or parsed (FastAPI reads a route's body
  before its dependencies run); a refused key's answer waits ``auth_refusal_delay_s`` (``hold_refusal``: a
  flood of them is then answered a few times a second per connection); the caller found is handed to the
  route in ``scope["state"]["who"]``;
- :class:`BodyDeadline`: a body (other than an image upload, which has its own deadline) that has not
  arrived within ``body_timeout_s`` is answered 408;
- :class:`SecurityHeaders`: CSP, frame denial, nosniff, no referrer, and HSTS on HTTPS, on every answer.
"""

from __future__ import annotations

import time

import anyio
from starlette.routing import BaseRoute, Match
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from doorloc.app.http.admission import address_of, client_of, hold_refusal, shedding_problem
from doorloc.app.http.dependencies import resolve_principal
from doorloc.app.http.middleware import BodyTimeout, send_problem
from doorloc.app.http.problems import ProblemError
from doorloc.app.http.state import ServiceState

__all__ = [
    "HostCheck",
    "KeyGate",
    "LocateShedding",
    "BodyDeadline",
    "SecurityHeaders",
    "host_name",
    "CONTENT_SECURITY_POLICY",
]

#: same-origin scripts and styles only (the operator page and the bundled API docs ship theirs); overlays are
#: data: URLs; no page may frame this one
CONTENT_SECURITY_POLICY = (
    "default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data: blob:; "
    "connect-src 'self'; font-src 'self'; object-src 'none'; base-uri 'none'; form-action 'self'; "
    "frame-ancestors 'none'"
)


def _header(scope: Scope, name: bytes) -> str | None:
    for k, v in scope.get("headers", ()):
        if k == name:
            return v.decode("latin-1")
    return None


def host_name(host_header: str) -> str:
    """The name in a ``Host`` header without its port, lower case (``[::1]:8000`` -> ``::1``)."""
    h = host_header.strip().lower()
    if h.startswith("["):
        return h[1 : h.find("]")] if "]" in h else h[1:]
    return h.rsplit(":", 1)[0] if h.count(":") == 1 else h


class HostCheck:
    """Answer 400 ``bad_host`` to a request whose ``Host`` is not in ``allowed`` ('*': any, except when
    ``open_access``: an open service answers only to the names listed, never to any)."""

    def __init__(self, app: ASGIApp, allowed: list[str], open_access: bool) -> None:
        self.app = app
        self.allowed = {host_name(a) for a in allowed}
        self.any_host = "*" in self.allowed and not open_access

    def _ok(self, name: str) -> bool:
        return self.any_host or name in self.allowed

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        given = _header(scope, b"host")
        if given is None or not self._ok(host_name(given)):
            await send_problem(
                scope,
                send,
                400,
                "bad_host",
                f"This service does not answer to the host name {given!r}; reach it by one of its configured "
                "names (the administrator lists them in DOORLOC_ALLOWED_HOSTS).",
            )
            return
        await self.app(scope, receive, send)


class KeyGate:
    """Resolve the caller of every keyed path (``/v1/...``, ``/metrics``) from its headers; 401/429 before
    the body is read.

    Only requests a route will take (path and method match one of ``routes``): a wrong method or path is
    answered 405/404 by the router, which reads no body either.
    """

    def __init__(
        self,
        app: ASGIApp,
        state: ServiceState,
        routes: list[BaseRoute],
        prefixes: tuple[str, ...] = ("/v1/", "/metrics"),
    ) -> None:
        self.app = app
        self.state = state
        self.routes = routes
        self.prefixes = prefixes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if (
            scope["type"] != "http"
            or not scope["path"].startswith(self.prefixes)
            or not any(r.matches(scope)[0] == Match.FULL for r in self.routes)
        ):
            await self.app(scope, receive, send)
            return
        given = _header(scope, b"x-api-key")
        client = (scope.get("client") or ("", 0))[0]
        try:
            who = await resolve_principal(self.state, given, client)
        except ProblemError as e:
            if e.status in (401, 429):
                await hold_refusal(self.state, self.state.settings.auth_refusal_delay_s)
            headers = [(k.lower().encode(), v.encode()) for k, v in (e.headers or {}).items()]
            await send_problem(scope, send, e.status, e.code, e.detail, headers)
            return
        state = scope.setdefault("state", {})
        state["who"] = who
        state["principal"] = who.name
        await self.app(scope, receive, send)


class LocateShedding:
    """Answer 503 Retry-After to an image upload that the worker's queue, or its client's share of it, has no
    room for, before its body is read: a flooding client's refused uploads cost no multipart parsing."""

    def __init__(self, app: ASGIApp, state: ServiceState, path: str = "/v1/locate") -> None:
        self.app = app
        self.state = state
        self.path = path

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http" and scope["method"] == "POST" and scope["path"] == self.path:
            problem = shedding_problem(self.state, client_of(scope.get("state", {})), address_of(scope))
            if problem is not None:
                headers = [(k.lower().encode(), v.encode()) for k, v in (problem.headers or {}).items()]
                await send_problem(scope, send, problem.status, problem.code, problem.detail, headers)
                return
        await self.app(scope, receive, send)


class BodyDeadline:
    """Cut off a request body that has not arrived ``timeout_s`` after the request began (408); the image
    upload path (``skip``) has the request deadline of :class:`~doorloc.app.http.middleware.LocateAdmission`."""

    def __init__(self, app: ASGIApp, timeout_s: float, skip: str = "/v1/locate") -> None:
        self.app = app
        self.timeout_s = timeout_s
        self.skip = skip

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["path"] == self.skip:
            await self.app(scope, receive, send)
            return
        deadline = time.monotonic() + self.timeout_s

        async def receive_by_deadline() -> Message:
            try:
                with anyio.fail_after(max(deadline - time.monotonic(), 0.001)):
                    return await receive()
            except TimeoutError:
                raise BodyTimeout(self.timeout_s) from None

        started = False

        async def tracking_send(message: Message) -> None:
            nonlocal started
            started = started or message["type"] == "http.response.start"
            await send(message)

        try:
            await self.app(scope, receive_by_deadline, tracking_send)
        except BodyTimeout as e:
            if started:
                raise
            await send_problem(scope, send, 408, "request_timeout", str(e.detail))


class SecurityHeaders:
    """Add the browser-facing security headers to every answer (HSTS only over HTTPS)."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        extra = [
            (b"content-security-policy", CONTENT_SECURITY_POLICY.encode()),
            (b"x-frame-options", b"DENY"),
            (b"x-content-type-options", b"nosniff"),
            (b"referrer-policy", b"no-referrer"),
        ]
        if scope.get("scheme") == "https":
            extra.append((b"strict-transport-security", b"max-age=31536000"))

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                have = {k.lower() for k, _ in message.get("headers", [])}
                message["headers"] = [*message.get("headers", []), *(h for h in extra if h[0] not in have)]
            await send(message)

        await self.app(scope, receive, send_with_headers)
