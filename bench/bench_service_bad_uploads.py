"""Bad uploads against a real `doorloc serve` on 127.0.0.1: each gets its 4xx with a sentence, the service
keeps serving, and its memory stays flat over many rounds.

Per round: no body, an empty file, a 25 MB body (declared length, and streamed chunked without one),
a text file named .png, a truncated PNG, a PNG header declaring 50000x50000; then one good upload.

    python bench/bench_service_bad_uploads.py --rounds 20
"""

from __future__ import annotations

import argparse
import json
import struct
import zlib

import httpx
from service_harness import doorloc_serve, rendered_pngs, rss_mb


def png_header(width: int, height: int) -> bytes:
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    idat = zlib.compress(b"\x00" * 64)
    return (
        b"\x89PNG\r\n\x1a\n"
        + struct.pack(">I", 13)
        + b"IHDR"
        + ihdr
        + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr))
        + struct.pack(">I", len(idat))
        + b"IDAT"
        + idat
        + struct.pack(">I", zlib.crc32(b"IDAT" + idat))
        + b"\x00\x00\x00\x00IEND\xaeB`\x82"
    )


def _streamed(total: int, chunk: int = 64 * 1024):
    head = (
        b'--b0undary\r\nContent-Disposition: form-data; name="image"; filename="big.png"\r\n'
        b"Content-Type: image/png\r\n\r\n\x89PNG\r\n\x1a\n"
    )
    yield head
    sent = len(head)
    while sent < total:
        yield b"\x00" * chunk
        sent += chunk


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--rounds", type=int, default=20)
    args = ap.parse_args()
    good, _ = rendered_pngs(1)[0]
    big = b"\x89PNG\r\n\x1a\n" + b"\x00" * (25 * 1000 * 1000)
    cases = {
        "no body": dict(),
        "empty file": dict(files={"image": ("empty.png", b"", "image/png")}),
        "25 MB body": dict(files={"image": ("big.png", big, "image/png")}),
        "text renamed .png": dict(files={"image": ("notes.png", b"just some text\n" * 100, "image/png")}),
        "truncated PNG": dict(files={"image": ("cut.png", good[: len(good) // 4], "image/png")}),
        "PNG declaring 50000x50000": dict(
            files={"image": ("huge.png", png_header(50000, 50000), "image/png")}
        ),
    }
    seen: dict[str, tuple[int, str]] = {}
    failures: list[str] = []
    rss = []
    with doorloc_serve(1) as (base, pid), httpx.Client(base_url=base, timeout=60) as client:
        client.post("/v1/locate", files={"image": ("warm.png", good, "image/png")})
        rss.append(rss_mb(pid))
        for _ in range(args.rounds):
            for name, kw in cases.items():
                r = client.post("/v1/locate", **kw)
                ok = (
                    400 <= r.status_code < 500 and r.headers.get("content-type") == "application/problem+json"
                )
                seen[name] = (r.status_code, r.json().get("detail", "") if ok else r.text[:200])
                if not ok:
                    failures.append(f"{name}: {r.status_code} {r.text[:200]}")
            # a 25 MB body streamed without Content-Length: the server must cut it off, not swallow it
            try:
                r = httpx.post(
                    base + "/v1/locate",
                    content=_streamed(25 * 1000 * 1000),
                    timeout=60,
                    headers={"content-type": "multipart/form-data; boundary=b0undary"},
                )
                seen["25 MB streamed, no length"] = (r.status_code, r.json().get("detail", ""))
                if r.status_code != 413:
                    failures.append(f"streamed: {r.status_code}")
            except (
                httpx.TransportError
            ) as e:  # the server may close the socket before the client has finished sending
                seen["25 MB streamed, no length"] = (
                    413,
                    f"connection closed by the server mid-upload ({type(e).__name__})",
                )
            r = client.post("/v1/locate", files={"image": ("good.png", good, "image/png")})
            if r.status_code != 200 or not r.json()["ok"]:
                failures.append(f"good upload after bad ones: {r.status_code} {r.text[:200]}")
            rss.append(rss_mb(pid))
    for name, (status, detail) in seen.items():
        print(f"{name:28s} -> {status}  {detail}")
    figures = {
        "rounds": args.rounds,
        "failures": len(failures),
        "rss_start_mb": round(rss[0], 1),
        "rss_end_mb": round(rss[-1], 1),
        "rss_max_mb": round(max(rss), 1),
    }
    print(json.dumps(figures))
    for f in failures[:10]:
        print("FAILURE:", f)


if __name__ == "__main__":
    main()
