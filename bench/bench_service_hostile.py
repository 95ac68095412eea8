"""Hostile load: normal-request latency while 20 hostile uploads are in flight, and 50 parallel recipe writers.

Against a real `doorloc serve` on 127.0.0.1 (``--open``: no keys, loopback). Each attack of the later
hostile-network probe, one at a time and with keys, is in bench/bench_service_attacks.py. Phases:

1. unloaded: ``--normal`` sequential POST /v1/locate of rendered 1080p doors; median and p90 latency;
2. the same while 20 hostile clients (in their own process) keep uploads in flight until the phase ends: decompression bombs
   (a PNG declaring 7000x7000 16-bit RGBA, 392 MB decoded; one declaring 30000x30000), slow uploads
   (declare 100 kB, send 10 bytes, stall until the server's deadline cuts them), garbage bytes and raw
   ``image/png`` bodies; prints the latency ratio to phase 1 (goal: <= 2), the hostile answers by status
   and the server's peak RSS. Phases 1 and 2 alternate ``--rounds`` times;
3. 50 threads PUT the same door recipe at once (each a different feed rate): failures (goal 0), wall
   time, and that the history grew by 50 versions.

    python bench/bench_service_hostile.py                     # 1 worker, 3 rounds of 8 + 8 normal requests
    python bench/bench_service_hostile.py --workers 2 --rounds 5
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import socket
import statistics
import struct
import threading
import time
import zlib
from collections import Counter
from concurrent.futures import ThreadPoolExecutor

import httpx
from service_harness import RECIPE, doorloc_serve, rendered_pngs, rss_mb


def png_bomb(w: int, h: int, depth: int, colour: int) -> bytes:
    """A PNG whose header declares w x h (depth bits, colour type) with a few compressed rows of data."""
    ihdr = struct.pack(">IIBBBBB", w, h, depth, colour, 0, 0, 0)
    row = 1 + w * {0: 1, 2: 3, 4: 2, 6: 4}[colour] * depth // 8
    idat = zlib.compress(b"\x00" * row * 64, 9)  # 64 rows of zeros: the rest of the image is missing
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
        + struct.pack(">I", 0)
        + b"IEND"
        + struct.pack(">I", zlib.crc32(b"IEND"))
    )


def slow_upload(base: str) -> int:
    """Declare 100 kB, send 10 bytes, wait for the server's answer (its deadline); the status, or -1."""
    host, port = base.removeprefix("http://").split(":")
    with socket.create_connection((host, int(port)), timeout=120) as s:
        s.sendall(
            b"POST /v1/locate HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: multipart/form-data; boundary=zz\r\n"
            b"Content-Length: 100000\r\n\r\n--zz\r\nCont"
        )
        data = s.recv(4096)
    return int(data.split(b" ", 2)[1]) if data.startswith(b"HTTP/1.1 ") else -1


def hostile_client(
    kind: str,
    base: str,
    stop: threading.Event,
    statuses: Counter,
    lock: threading.Lock,
    bombs: dict[str, bytes],
) -> None:
    with httpx.Client(base_url=base, timeout=120) as client:
        for _ in range(100_000):  # bounded; the phase ends it through `stop`
            if stop.is_set():
                return
            try:
                if kind == "slow":
                    status = slow_upload(base)
                elif kind == "garbage":
                    status = client.post(
                        "/v1/locate", files={"image": ("x.png", b"\x00garbage" * 5000, "image/png")}
                    ).status_code
                elif kind == "raw":
                    status = client.post(
                        "/v1/locate", content=bombs["bomb16"], headers={"Content-Type": "image/png"}
                    ).status_code
                else:
                    status = client.post(
                        "/v1/locate", files={"image": ("b.png", bombs[kind], "image/png")}
                    ).status_code
            except (httpx.HTTPError, OSError) as e:
                status = type(e).__name__
            with lock:
                statuses[f"{kind}:{status}"] += 1


def hostile_process(base: str, n: int, stop, out, running, nice: int = 0) -> None:  # noqa: ANN001 - multiprocessing
    """The hostile clients, in their own process: in the measuring process their threads would hold the GIL
    and slow the measuring client itself (on a plant network they are other machines). ``nice`` > 0 lowers
    their CPU priority, so on a one-machine benchmark their own CPU use steals less from the server."""
    if nice:
        os.nice(nice)
    kinds = ["bomb16", "bomb900mp", "slow", "garbage", "raw"]
    bombs = {"bomb16": png_bomb(7000, 7000, 16, 6), "bomb900mp": png_bomb(30000, 30000, 8, 0)}  # built once
    lock, statuses, stop_t = threading.Lock(), Counter(), threading.Event()
    threads = [
        threading.Thread(
            target=hostile_client, args=(kinds[k % len(kinds)], base, stop_t, statuses, lock, bombs)
        )
        for k in range(n)
    ]
    for t in threads:
        t.start()
    for _ in range(600):  # the measurement starts once hostile answers come back (bounded wait)
        with lock:
            if sum(statuses.values()) >= n:
                break
        time.sleep(0.05)
    running.set()
    stop.wait(600)
    stop_t.set()
    for t in threads:
        t.join(timeout=60)
    out.put(dict(statuses))


def normal_latencies(base: str, pngs: list, n: int) -> tuple[list[float], list[str]]:
    lat, errors = [], []
    with httpx.Client(base_url=base, timeout=120) as client:
        for i in range(n):
            data, _ = pngs[i % len(pngs)]
            t0 = time.perf_counter()
            r = client.post("/v1/locate", files={"image": (f"d{i}.png", data, "image/png")})
            dt = time.perf_counter() - t0
            if r.status_code != 200 or not r.json()["ok"]:
                errors.append(f"HTTP {r.status_code}: {r.text[:160]}")
            else:
                lat.append(dt)
    return lat, errors


def summary(lat: list[float]) -> str:
    if not lat:
        return "no answers"
    q = sorted(lat)
    return (
        f"median {statistics.median(q) * 1e3:.0f} ms, p90 {q[int(0.9 * (len(q) - 1))] * 1e3:.0f} ms, "
        f"max {q[-1] * 1e3:.0f} ms ({len(q)} requests)"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--normal", type=int, default=8, help="normal requests per block")
    ap.add_argument("--rounds", type=int, default=3, help="alternating unloaded/loaded blocks")
    ap.add_argument("--hostile", type=int, default=20)
    ap.add_argument("--writers", type=int, default=50)
    ap.add_argument("--hostile-nice", type=int, default=0, help="nice value of the hostile clients' process")
    args = ap.parse_args()

    pngs = rendered_pngs(4)
    env = {"OMP_NUM_THREADS": "1", "DOORLOC_REQUEST_DEADLINE_S": "10"}
    with doorloc_serve(args.workers, extra_env=env) as (base, pid):
        httpx.post(base + "/v1/locate", files={"image": ("warm.png", pngs[0][0], "image/png")}, timeout=120)
        # unloaded and loaded blocks alternate, so drifting load from other programs on the machine falls on both
        ctx = multiprocessing.get_context("spawn")
        lat0, lat1, err0, err1, statuses, peak, ratios = [], [], [], [], Counter(), 0.0, []
        window, sent_in_window = 0.0, 0
        for _ in range(args.rounds):
            u, e = normal_latencies(base, pngs, args.normal)
            lat0 += u
            err0 += e
            stop, out, running = ctx.Event(), ctx.Queue(), ctx.Event()
            hostile = ctx.Process(
                target=hostile_process, args=(base, args.hostile, stop, out, running, args.hostile_nice)
            )
            hostile.start()
            running.wait(120)  # every hostile client is sending
            time.sleep(0.5)
            window0 = time.monotonic()
            peak = max(peak, rss_mb(pid))
            h, e = normal_latencies(base, pngs, args.normal)
            peak = max(peak, rss_mb(pid))
            stop.set()
            window += time.monotonic() - window0
            got = Counter(out.get(timeout=120))
            sent_in_window += sum(got.values())
            statuses += got
            hostile.join(timeout=60)
            lat1 += h
            err1 += e
            if u and h:
                ratios.append(statistics.median(h) / statistics.median(u))
        print(f"unloaded:               {summary(lat0)}; errors {len(err0)}")
        print(f"{args.hostile} hostile in flight:   {summary(lat1)}; errors {len(err1)} {err1[:2]}")
        if lat0 and lat1:
            ratio = statistics.median(lat1) / statistics.median(lat0)
            print(
                f"median ratio loaded/unloaded: {ratio:.2f} (goal <= 2); per round: "
                + ", ".join(f"{r:.2f}" for r in ratios)
            )
        print(
            f"hostile clients: {args.hostile} in flight, nice {args.hostile_nice}, about "
            f"{sent_in_window / max(window, 1e-9):.0f} hostile requests/s (upper bound); answers:",
            ", ".join(f"{k} x{v}" for k, v in sorted(statuses.items())),
        )
        print(f"server RSS (all processes) during the hostile phase: peak {peak:.0f} MB")

        if args.writers < 1:
            return
        assert httpx.put(f"{base}/v1/doors/BENCH-1", json=RECIPE, timeout=60).status_code == 200
        before = len(httpx.get(f"{base}/v1/doors/BENCH-1/history", timeout=60).json()["versions"])

        def put(k: int) -> int | str:
            try:
                body = {**RECIPE, "feed_mm_s": 30 + k}
                return httpx.put(f"{base}/v1/doors/BENCH-1", json=body, timeout=120).status_code
            except httpx.HTTPError as e:
                return type(e).__name__

        t0 = time.perf_counter()
        with ThreadPoolExecutor(args.writers) as ex:
            results = list(ex.map(put, range(args.writers)))
        wall = time.perf_counter() - t0
        after = len(httpx.get(f"{base}/v1/doors/BENCH-1/history", timeout=60).json()["versions"])
        failures = [r for r in results if r != 200]
        print(
            f"{args.writers} parallel recipe writers: {len(failures)} failures {Counter(failures) or ''}, "
            f"{wall:.2f} s wall, history +{after - before} versions"
        )


if __name__ == "__main__":
    main()
