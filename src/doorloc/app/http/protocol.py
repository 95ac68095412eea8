"""uvicorn's HTTP protocol with its own 400 answers (malformed request line, headers, chunking) as problem+json.

uvicorn answers a request it cannot parse itself, before any ASGI app sees it, with a plain-text 400;
the only way to change that body is its protocol class, so this module subclasses the one uvicorn would
pick (httptools when installed, else h11) and overrides ``send_400_response`` alone.
``doorloc serve`` passes ``http="doorloc.app.http.protocol:ProblemJsonHTTP"``.
"""

from __future__ import annotations

import json

from doorloc.app.http.problems import PROBLEM_MEDIA_TYPE

__all__ = ["ProblemJsonHTTP", "problem_400_body"]


def problem_400_body(msg: str) -> bytes:
    """The problem+json body of a request uvicorn could not parse (``msg`` is its reason)."""
    return json.dumps({
        "type": "about:blank", "title": "Bad Request", "status": 400, "code": "malformed_http",
        "detail": f"The request is not valid HTTP/1.1 ({msg.rstrip('.')}); check the client or proxy that sent it.",
    }).encode()


try:
    from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol as _Base

    class ProblemJsonHTTP(_Base):
        """HttpToolsProtocol whose own 400 answers are problem+json."""

        def send_400_response(self, msg: str) -> None:
            body = problem_400_body(msg)
            head = [b"HTTP/1.1 400 Bad Request\r\n"]
            for name, value in self.server_state.default_headers:
                head += [name, b": ", value, b"\r\n"]
            head += [b"content-type: ", PROBLEM_MEDIA_TYPE.encode(), b"\r\n",
                     b"content-length: ", str(len(body)).encode(), b"\r\n", b"connection: close\r\n\r\n"]
            self.transport.write(b"".join(head) + body)
            self.transport.close()

except ImportError:  # pragma: no cover - uvicorn[standard] brings httptools; plain uvicorn uses h11
    import h11
    from uvicorn.protocols.http.h11_impl import H11Protocol as _H11Base

    class ProblemJsonHTTP(_H11Base):  # type: ignore[no-redef]
        """H11Protocol whose own 400 answers are problem+json."""

        def send_400_response(self, msg: str) -> None:
            body = problem_400_body(msg)
            headers = [(b"content-type", PROBLEM_MEDIA_TYPE.encode()), (b"connection", b"close"),
                       (b"content-length", str(len(body)).encode())]
            self.transport.write(self.conn.send(h11.Response(status_code=400, headers=headers, reason=b"Bad Request")))
            self.transport.write(self.conn.send(h11.Data(data=body)))
            self.transport.write(self.conn.send(h11.EndOfMessage()))
            self.transport.close()
