"""uvicorn's HTTP protocol with the server's own limits, and its own answers as problem+json.

Limits a request's head (request line and headers) before the application sees it, per connection:

- at most ``max_header_bytes`` of head and ``max_headers`` header fields, else 431 and the connection is
  closed: the head is fed to the parser chunk by chunk and checked after each, so a 100 MB header costs the
  parsing of one ~256 kB chunk past the limit, not 13 s of CPU on the event loop;
- the head must arrive within ``header_timeout_s`` of the connection's start (or of the previous answer on
  a kept-alive connection), else 408 and close: a client sending headers slowly holds nothing for long
  (uvicorn itself times out only idle kept-alive connections).

The limits come from the service's settings (``DOORLOC_*``), read once per worker process.

uvicorn answers a request it cannot parse itself, before any ASGI app sees it, with a plain-text 400;
the only way to change that body is its protocol class, so this module subclasses the one uvicorn picks
when httptools is installed (uvicorn[standard]) and overrides ``send_400_response`` alone. ``doorloc serve``
passes ``http="doorloc.app.http.protocol:ProblemJsonHTTP"`` when httptools is there (else uvicorn's own).
Import this module only then.
"""

from __future__ import annotations

import asyncio
import functools
import json
from http import HTTPStatus
from typing import Any

from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol

from doorloc.app.http.problems import PROBLEM_MEDIA_TYPE

__all__ = ["ProblemJsonHTTP", "problem_400_body", "HeadLimits"]


@functools.cache
def _limits() -> tuple[int, int, float]:
    from doorloc.app.settings import ServiceSettings

    s = ServiceSettings()
    return s.max_header_bytes, s.max_headers, s.header_timeout_s


class HeadLimits:
    """The head limits in force (from the settings)."""

    @staticmethod
    def current() -> tuple[int, int, float]:
        """``(max_header_bytes, max_headers, header_timeout_s)``."""
        return _limits()


def problem_400_body(msg: str) -> bytes:
    """The problem+json body of a request uvicorn could not parse (``msg`` is its reason)."""
    return json.dumps(
        {
            "type": "about:blank",
            "title": "Bad Request",
            "status": 400,
            "code": "malformed_http",
            "detail": f"The request is not valid HTTP/1.1 ({msg.rstrip('.')}); check the client or proxy that sent it.",
        }
    ).encode()


class ProblemJsonHTTP(HttpToolsProtocol):
    """HttpToolsProtocol with head limits (size, field count, time) and problem+json answers of its own."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.max_head_bytes, self.max_head_fields, self.head_timeout_s = HeadLimits.current()
        self._in_head = True
        self._head_bytes = 0
        self._head_fields = 0
        self._head_timer: asyncio.TimerHandle | None = None
        self._refused = False

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        self._arm_head_timer()

    def connection_lost(self, exc: Exception | None) -> None:
        self._disarm_head_timer()
        super().connection_lost(exc)

    def _arm_head_timer(self) -> None:
        self._disarm_head_timer()
        self._head_timer = self.loop.call_later(self.head_timeout_s, self._head_timed_out)

    def _disarm_head_timer(self) -> None:
        if self._head_timer is not None:
            self._head_timer.cancel()
            self._head_timer = None

    def _head_timed_out(self) -> None:
        self._head_timer = None
        if self._in_head and not self.transport.is_closing():
            self._refuse(
                408,
                "header_timeout",
                f"The request's headers did not arrive within {self.head_timeout_s:g} s; send them at once.",
            )

    def _refuse(self, status: int, code: str, detail: str) -> None:
        self._refused = True
        self._disarm_head_timer()
        self._write_problem(status, code, detail)

    def data_received(self, data: bytes) -> None:
        if self._refused:
            return
        if self._in_head:
            self._head_bytes += len(data)
        super().data_received(data)
        if self._refused or self.transport.is_closing():
            return
        # checked after feeding: a chunk that completes the head is never refused for the body behind it
        if self._in_head and self._head_bytes > self.max_head_bytes:
            self._refuse(
                431,
                "headers_too_large",
                f"The request's line and headers exceed {self.max_head_bytes} bytes; send a smaller request.",
            )

    def on_message_begin(self) -> None:
        super().on_message_begin()
        self._in_head = True
        self._head_fields = 0
        if self._head_timer is None:
            self._arm_head_timer()

    def on_header(self, name: bytes, value: bytes) -> None:
        self._head_fields += 1
        if self._head_fields > self.max_head_fields:
            return  # not kept; refused once the head is complete
        super().on_header(name, value)

    def on_headers_complete(self) -> None:
        self._in_head = False
        self._disarm_head_timer()
        if self._head_fields > self.max_head_fields:
            self._refuse(
                431,
                "too_many_headers",
                f"The request has {self._head_fields} header fields, more than {self.max_head_fields}; "
                "send fewer.",
            )
            return
        super().on_headers_complete()

    def on_body(self, body: bytes) -> None:
        if not self._refused:
            super().on_body(body)

    def on_message_complete(self) -> None:
        if not self._refused:
            super().on_message_complete()

    def on_response_complete(self) -> None:
        super().on_response_complete()
        # the next request's head is timed from this answer (uvicorn's keep-alive timer closes an idle one)
        self._in_head = True
        self._head_bytes = 0

    def send_400_response(self, msg: str) -> None:
        self._refused = True
        self._disarm_head_timer()
        self._send_problem_and_close(400, problem_400_body(msg))

    def _write_problem(self, status: int, code: str, detail: str) -> None:
        body = json.dumps(
            {
                "type": "about:blank",
                "title": HTTPStatus(status).phrase,
                "status": status,
                "code": code,
                "detail": detail,
            }
        ).encode()
        self._send_problem_and_close(status, body)

    def _send_problem_and_close(self, status: int, body: bytes) -> None:
        """Write a problem+json answer with the server's default headers, then close the connection."""
        head = [f"HTTP/1.1 {status} {HTTPStatus(status).phrase}\r\n".encode()]
        for name, value in self.server_state.default_headers:
            head += [name, b": ", value, b"\r\n"]
        head += [
            b"content-type: ",
            PROBLEM_MEDIA_TYPE.encode(),
            b"\r\n",
            b"content-length: ",
            str(len(body)).encode(),
            b"\r\n",
            b"connection: close\r\n\r\n",
        ]
        self.transport.write(b"".join(head) + body)
        self.transport.close()
