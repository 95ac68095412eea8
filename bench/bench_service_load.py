"""Load: N concurrent clients post 1080p PNGs to a real `doorloc serve` on 127.0.0.1 for T seconds.

Prints errors (transport errors, non-200 answers, ok=false), throughput, p50/p99 latency and the
server's RSS (all its processes) at start and end.

    python bench/bench_service_load.py --clients 16 --seconds 60 --workers 2
"""

from __future__ import annotations

import argparse
import asyncio
import json
import statistics
import time

import httpx
from service_harness import doorloc_serve, rendered_pngs, rss_mb


async def _client(base: str, pngs: list, stop_at: float, k: int, latencies: list, errors: list) -> None:
    async with httpx.AsyncClient(base_url=base, timeout=120) as client:
        i = k
        while time.monotonic() < stop_at:
            data, _ = pngs[i % len(pngs)]
            i += 1
            t0 = time.perf_counter()
            try:
                r = await client.post("/v1/locate", files={"image": (f"door{i}.png", data, "image/png")})
                dt = time.perf_counter() - t0
                if r.status_code != 200:
                    errors.append(f"HTTP {r.status_code}: {r.text[:200]}")
                elif not r.json()["ok"]:
                    errors.append(f"refused: {r.json()['error']}")
                else:
                    latencies.append(dt)
            except httpx.HTTPError as e:
                errors.append(f"{type(e).__name__}: {e}")


async def _sample_rss(pid: int, stop_at: float, samples: list) -> None:
    while time.monotonic() < stop_at:
        samples.append(round(rss_mb(pid), 1))
        await asyncio.sleep(min(10.0, max(0.0, stop_at - time.monotonic())))


async def _run(
    base: str, pid: int, pngs: list, clients: int, seconds: float
) -> tuple[list, list, float, list]:
    latencies: list[float] = []
    errors: list[str] = []
    rss_samples: list[float] = []
    t0 = time.monotonic()
    stop_at = t0 + seconds
    await asyncio.gather(
        _sample_rss(pid, stop_at, rss_samples),
        *(_client(base, pngs, stop_at, k, latencies, errors) for k in range(clients)),
    )
    return latencies, errors, time.monotonic() - t0, rss_samples


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--clients", type=int, default=16)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--workers", type=int, default=2, help="doorloc serve --workers")
    ap.add_argument("--images", type=int, default=8, help="distinct rendered PNGs cycled through")
    args = ap.parse_args()

    pngs = rendered_pngs(args.images)
    with doorloc_serve(args.workers) as (base, pid):
        # one warm-up request per worker, so the first timed requests do not pay for imports
        with httpx.Client(base_url=base, timeout=120) as c:
            for k in range(args.workers):
                c.post("/v1/locate", files={"image": ("warm.png", pngs[k % len(pngs)][0], "image/png")})
        rss_start = rss_mb(pid)
        latencies, errors, wall, rss_samples = asyncio.run(_run(base, pid, pngs, args.clients, args.seconds))
        rss_end = rss_mb(pid)
    lat_ms = sorted(x * 1e3 for x in latencies)
    p = (lambda q: lat_ms[min(len(lat_ms) - 1, int(q * len(lat_ms)))]) if lat_ms else (lambda q: float("nan"))
    figures = {
        "clients": args.clients,
        "seconds": round(wall, 1),
        "workers": args.workers,
        "png_bytes_mean": int(statistics.mean(len(d) for d, _ in pngs)),
        "requests_ok": len(latencies),
        "errors": len(errors),
        "throughput_rps": round(len(latencies) / wall, 2),
        "latency_p50_ms": round(p(0.50), 1),
        "latency_p99_ms": round(p(0.99), 1),
        "latency_max_ms": round(lat_ms[-1], 1) if lat_ms else None,
        "rss_start_mb": round(rss_start, 1),
        "rss_end_mb": round(rss_end, 1),
        "rss_every_10s_mb": rss_samples,
    }
    print(json.dumps(figures))
    for e in errors[:10]:
        print("error:", e)
    print(
        f"{figures['requests_ok']} answered, {figures['errors']} errors in {figures['seconds']} s with {args.clients} clients: "
        f"{figures['throughput_rps']} req/s, p50 {figures['latency_p50_ms']} ms, p99 {figures['latency_p99_ms']} ms; "
        f"server RSS {figures['rss_start_mb']} MB -> {figures['rss_end_mb']} MB"
    )


if __name__ == "__main__":
    main()
