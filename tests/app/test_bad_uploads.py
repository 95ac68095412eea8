"""Bad uploads each get their 4xx with a sentence, before any decoding, and the service keeps serving."""

from __future__ import annotations

import struct
import zlib

import pytest


def _png_header_only(width: int, height: int) -> bytes:
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    chunk = struct.pack(">I", 13) + b"IHDR" + ihdr + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr))
    # a tiny valid-looking IDAT so only the declared size is wrong
    idat = zlib.compress(b"\x00" * 16)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk
        + struct.pack(">I", len(idat))
        + b"IDAT"
        + idat
        + struct.pack(">I", zlib.crc32(b"IDAT" + idat))
        + b"\x00\x00\x00\x00IEND\xaeB`\x82"
    )


def _assert_problem(r, status: int, code: str) -> None:
    assert r.status_code == status, r.text
    assert r.headers["content-type"] == "application/problem+json"
    body = r.json()
    assert body["status"] == status and body["code"] == code
    assert body["detail"][0].isupper() and body["detail"].rstrip().endswith((".", ")"))
    assert "Traceback" not in body["detail"]


def _still_serving(client, small_png) -> None:
    r = client.post("/v1/locate", files={"image": ("ok.png", small_png, "image/png")})
    assert r.status_code == 200 and r.json()["ok"] is True


def test_no_body_at_all(client, small_png):
    r = client.post("/v1/locate")
    _assert_problem(r, 422, "invalid_request")
    assert "'image' is required" in r.json()["detail"]
    _still_serving(client, small_png)


def test_empty_file(client, small_png):
    _assert_problem(
        client.post("/v1/locate", files={"image": ("e.png", b"", "image/png")}), 422, "empty_image"
    )
    _still_serving(client, small_png)


def test_25_mb_body_is_413(client, small_png):
    big = b"\x89PNG\r\n\x1a\n" + b"\x00" * (25 * 1000 * 1000)
    r = client.post("/v1/locate", files={"image": ("big.png", big, "image/png")})
    _assert_problem(r, 413, "too_large")
    assert "20.0 MB" in r.json()["detail"]
    _still_serving(client, small_png)


def test_limit_is_enforced_while_streaming_not_after(make_client, small_png):
    """A chunked body (no Content-Length) is cut off at the first chunk past the limit.

    Driven at the ASGI level: the test client would buffer the whole body before the app saw it.
    """
    import anyio

    client = make_client(max_upload_bytes=10_000)
    chunks_read = 0
    sent = []

    part_head = (
        b'--xyz\r\nContent-Disposition: form-data; name="image"; filename="a.png"\r\n'
        b"Content-Type: image/png\r\n\r\n\x89PNG\r\n\x1a\n"
    )

    async def receive():
        nonlocal chunks_read
        chunks_read += 1
        body = part_head if chunks_read == 1 else b"\x00" * 1000
        return {"type": "http.request", "body": body, "more_body": chunks_read < 1000}  # 1 MB in all

    async def send(message):
        sent.append(message)

    scope = {
        "type": "http",
        "asgi": {"version": "3.0"},
        "http_version": "1.1",
        "method": "POST",
        "scheme": "http",
        "path": "/v1/locate",
        "raw_path": b"/v1/locate",
        "root_path": "",
        "query_string": b"",
        "headers": [
            (b"host", b"test"),
            (b"content-type", b"multipart/form-data; boundary=xyz"),
            (b"transfer-encoding", b"chunked"),
        ],
        "client": ("127.0.0.1", 1),
        "server": ("127.0.0.1", 80),
    }
    anyio.run(client.app, scope, receive, send)
    assert sent[0]["type"] == "http.response.start" and sent[0]["status"] == 413
    assert 11 <= chunks_read < 20  # stopped just past 10 kB, never read the megabyte
    _still_serving(client, small_png)


def test_declared_content_length_over_the_limit_is_refused_unread(make_client):
    client = make_client(max_upload_bytes=1000)
    r = client.post(
        "/v1/locate", content=b"x" * 5000, headers={"content-type": "multipart/form-data; boundary=xyz"}
    )
    _assert_problem(r, 413, "too_large")


def test_text_renamed_png_is_415(client, small_png):
    r = client.post("/v1/locate", files={"image": ("notes.png", b"hello, this is text\n" * 50, "image/png")})
    _assert_problem(r, 415, "not_an_image")
    _still_serving(client, small_png)


@pytest.mark.parametrize("keep", [30, 200])
def test_truncated_png_is_422(client, small_png, keep):
    r = client.post("/v1/locate", files={"image": ("cut.png", small_png[:keep], "image/png")})
    _assert_problem(r, 422, "undecodable_image")
    _still_serving(client, small_png)


def test_png_header_declaring_50000_squared_is_refused_before_decoding(client, small_png, monkeypatch):
    import doorloc.vision.imageio as imageio

    def must_not_decode(*a, **k):  # pragma: no cover - reaching it is the failure
        raise AssertionError("the image was decoded")

    monkeypatch.setattr(imageio, "decode_image", must_not_decode)
    r = client.post("/v1/locate", files={"image": ("huge.png", _png_header_only(50000, 50000), "image/png")})
    _assert_problem(r, 422, "too_many_pixels")
    assert "50000x50000" in r.json()["detail"]
    monkeypatch.undo()
    _still_serving(client, small_png)


def test_an_upload_that_is_no_measurable_image_is_answered_after_the_refusal_delay(
    make_client, small_png, refusal_waits
):
    """A decoding bomb, a file that is no image and a truncated one wait ``image_refusal_delay_s`` before their
    4xx (a stream of them is then answered a few times a second per connection); a measurable image and a
    request refused for its door choice never wait; once a quarter of ``max_connections`` are waiting, further
    refusals are answered at once."""
    waits = refusal_waits
    client = make_client(image_refusal_delay_s=0.6, max_connections=8)
    _still_serving(client, small_png)
    r = client.post(
        "/v1/locate", files={"image": ("d.png", small_png, "image/png")}, data={"door_id": "NO-SUCH"}
    )
    assert r.status_code == 422 and waits == []
    bomb = _png_header_only(50000, 50000)
    _assert_problem(
        client.post("/v1/locate", files={"image": ("b.png", bomb, "image/png")}), 422, "too_many_pixels"
    )
    _assert_problem(
        client.post("/v1/locate", files={"image": ("t.png", b"text" * 9, "image/png")}), 415, "not_an_image"
    )
    cut = client.post("/v1/locate", files={"image": ("c.png", small_png[:200], "image/png")})
    _assert_problem(cut, 422, "undecodable_image")
    assert waits == [0.6, 0.6, 0.6]
    client.app.state.service.refusals_waiting = 2  # a quarter of 8 connections already waiting
    _assert_problem(
        client.post("/v1/locate", files={"image": ("b.png", bomb, "image/png")}), 422, "too_many_pixels"
    )
    assert waits == [0.6, 0.6, 0.6]


def test_rejections_are_counted_by_reason(client):
    client.post("/v1/locate", files={"image": ("t.png", b"text", "image/png")})
    assert 'doorloc_rejected_uploads_total{reason="not_an_image"} 1.0' in client.get("/metrics").text


def test_exif_orientation_is_ignored(client, monkeypatch):
    """A JPEG tagged 'rotate 90' keeps its stored pixel layout (the calibration's frame)."""
    import io

    import numpy as np
    from PIL import Image

    from doorloc.app.http import routes_locate  # noqa: F401 - the module whose decode path is used
    from doorloc.vision.imageio import decode_image

    img = Image.fromarray(np.tile(np.arange(64, dtype=np.uint8), (48, 1)))  # 64 wide, 48 high
    exif = Image.Exif()
    exif[0x0112] = 6  # orientation: rotate 90 CW to display
    buf = io.BytesIO()
    img.save(buf, format="JPEG", exif=exif.tobytes())
    assert decode_image(buf.getvalue()).shape == (48, 64)
    seen = {}

    def spy(image, cell, door, *, image_name="", config=None, jpeg_quality=0):
        seen["shape"] = image.shape
        from doorloc.vision.result import LocateResult

        return LocateResult.refusal(image_name, "no_door", "No door.")

    client.app.state.service.locate_fn = spy
    r = client.post("/v1/locate", files={"image": ("rot.jpg", buf.getvalue(), "image/jpeg")})
    assert r.status_code == 200
    assert seen["shape"][:2] == (48, 64)
