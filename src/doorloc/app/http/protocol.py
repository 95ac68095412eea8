"""uvicorn's HTTP protocol with its own 400 answers (malformed request line, headers, chunking) as problem+json.

uvicorn answers a request it cannot parse itself, before any ASGI app sees it, with a plain-text 400;
the only way to change that body is its protocol class, so this module subclasses the one uvicorn picks
when httptools is installed (uvicorn[standard]) and overrides ``send_400_response`` alone. ``doorloc serve``
passes ``http="doorloc.app.http.protocol:ProblemJsonHTTP"`` when httptools is there (else uvicorn's own).
Import this module only then.
"""

from __future__ import annotations

import json

from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol

from doorloc.app.http.problems import PROBLEM_MEDIA_TYPE

__all__ = ["ProblemJsonHTTP", "problem_400_body"]


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
    """HttpToolsProtocol whose own 400 answers are problem+json."""

    def send_400_response(self, msg: str) -> None:
        body = problem_400_body(msg)
        head = [b"HTTP/1.1 400 Bad Request\r\n"]
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
