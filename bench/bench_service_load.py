"""Load: N concurrent clients post 1080p PNGs (``--jpeg``: JPEGs) to a real `doorloc serve` for T seconds.

Prints errors (transport errors, non-200 answers, ok=false), throughput, p50/p99 latency and the
server's RSS (all its processes) at start and end.

The service figure, requests per second per core next to ``1000 / (decode + locate ms)``: the load
clients run on the same machine as the server, so the wall-clock rate per core would charge the server
for the clients' CPU. Instead the server's own CPU seconds over the run (all its processes, from /proc)
give ``requests per server CPU-second``, which is the rate per core of a server that has its cores to
itself. The ideal next to it is measured twice: in this process on the same PNGs before the run (the
median thread-CPU time of ``decode_image`` + ``locate``, one thread), and by the server itself during the
run (each answer's ``Server-Timing``: the CPU ms, its thread's and the worker processes', of decoding and
measuring that very request; their mean). The second is immune to the machine's speed drifting between
the two measurements (a shared machine's speed moved the first by a third from run to run); its share of
the server's CPU seconds is the fraction of the server's time spent measuring images, the rest being
HTTP, parsing, queueing and the event loop. A third ideal times decode + locate alone in one process per CPU at once
(no HTTP, no clients): what each core does when every core is busy, as in a loaded server.

    python bench/bench_service_load.py --clients 16 --seconds 60 --workers 2
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import time
from multiprocessing.queues import Queue
from multiprocessing.synchronize import Barrier

import httpx
from service_harness import CELL, cpu_seconds, doorloc_serve, rendered_pngs, rss_mb


def _server_cpu_ms(header: str) -> float:
    """The sum of a ``Server-Timing`` header's durations (doorloc: decode and locate, CPU ms)."""
    total = 0.0
    for part in header.split(","):
        for param in part.split(";")[1:]:
            key, _, value = param.strip().partition("=")
            if key == "dur":
                total += float(value)
    return total


async def _client(
    base: str, pngs: list, stop_at: float, k: int, latencies: list, errors: list, server_ms: list
) -> None:
    async with httpx.AsyncClient(base_url=base, timeout=120) as client:
        i = k
        while time.monotonic() < stop_at:
            data, _ = pngs[i % len(pngs)]
            i += 1
            t0 = time.perf_counter()
            try:
                r = await client.post("/v1/locate", files={"image": _upload(f"door{i}", data)})
                dt = time.perf_counter() - t0
                if r.status_code != 200:
                    errors.append(f"HTTP {r.status_code}: {r.text[:200]}")
                elif not r.json()["ok"]:
                    errors.append(f"refused: {r.json()['error']}")
                else:
                    latencies.append(dt)
                    server_ms.append(_server_cpu_ms(r.headers.get("server-timing", "")))
            except httpx.HTTPError as e:
                errors.append(f"{type(e).__name__}: {e}")


def _upload(stem: str, data: bytes) -> tuple[str, bytes, str]:
    """A multipart image part for ``data``, named and typed by its format (a JPEG's first bytes, else PNG)."""
    return (
        (f"{stem}.jpg", data, "image/jpeg") if data[:2] == b"\xff\xd8" else (f"{stem}.png", data, "image/png")
    )


async def _sample_rss(pid: int, stop_at: float, samples: list) -> None:
    while time.monotonic() < stop_at:
        samples.append(round(rss_mb(pid), 1))
        await asyncio.sleep(min(10.0, max(0.0, stop_at - time.monotonic())))


async def _run(
    base: str, pid: int, pngs: list, clients: int, seconds: float
) -> tuple[list, list, float, list, list]:
    latencies: list[float] = []
    errors: list[str] = []
    rss_samples: list[float] = []
    server_ms: list[float] = []
    t0 = time.monotonic()
    stop_at = t0 + seconds
    await asyncio.gather(
        _sample_rss(pid, stop_at, rss_samples),
        *(_client(base, pngs, stop_at, k, latencies, errors, server_ms) for k in range(clients)),
    )
    return latencies, errors, time.monotonic() - t0, rss_samples, server_ms


def decode_and_locate_ms(pngs: list, repeats: int = 5) -> float:
    """Median thread-CPU ms of decode + locate of each PNG in this process (the best of ``repeats``)."""
    import cv2

    from doorloc.cell import load_cell
    from doorloc.vision.imageio import decode_image
    from doorloc.vision.locate import locate

    cv2.setNumThreads(1)  # the per-core figure: one thread, as each server worker thread runs
    cell = load_cell(CELL)
    times = []
    for data, _ in pngs:
        best = float("inf")
        for _ in range(repeats):
            t0 = time.thread_time()
            locate(decode_image(data), cell, cell.default_door)
            best = min(best, time.thread_time() - t0)
        times.append(best * 1e3)
    return statistics.median(times)


def _timed_at_once(pngs: list, barrier: Barrier, results: Queue) -> None:
    """One of :func:`decode_and_locate_ms_at_once`'s processes: warm up, wait for the others, time."""
    decode_and_locate_ms(pngs, repeats=1)  # imports and compiled kernels loaded before the clock starts
    barrier.wait()
    results.put(decode_and_locate_ms(pngs))


def decode_and_locate_ms_at_once(pngs: list, processes: int) -> float:
    """:func:`decode_and_locate_ms` timed in ``processes`` processes at the same time (the median of theirs).

    A loaded server keeps every core busy: where cores share caches and memory (or a host's other tenants),
    one thread's decode + locate costs more then than on an idle machine. This is the ideal of a server
    whose cores all measure at once, with nothing of HTTP in it.
    """
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    barrier, results = ctx.Barrier(processes), ctx.Queue()
    procs = [ctx.Process(target=_timed_at_once, args=(pngs, barrier, results)) for _ in range(processes)]
    for p in procs:
        p.start()
    times = [results.get(timeout=600) for _ in procs]
    for p in procs:
        p.join()
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--clients", type=int, default=16)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--workers", type=int, default=2, help="doorloc serve --workers")
    ap.add_argument("--images", type=int, default=8, help="distinct rendered PNGs cycled through")
    ap.add_argument("--jpeg", type=int, metavar="QUALITY", help="post JPEGs of this quality instead of PNGs")
    ap.add_argument(
        "--max-queue",
        type=int,
        help="DOORLOC_MAX_QUEUE of the server (default: --clients, so that every client's request may wait "
        "for a CPU slot in any one worker instead of being turned away with 503 and sent again at once)",
    )
    args = ap.parse_args()

    pngs = rendered_pngs(args.images, jpeg_quality=args.jpeg)
    ideal_ms = decode_and_locate_ms(pngs)
    busy = os.cpu_count() or 1
    loaded_ms = decode_and_locate_ms_at_once(pngs, busy)
    max_queue = args.clients if args.max_queue is None else args.max_queue
    with doorloc_serve(args.workers, {"DOORLOC_MAX_QUEUE": str(max_queue)}) as (base, pid):
        # one warm-up request per worker, so the first timed requests do not pay for imports
        with httpx.Client(base_url=base, timeout=120) as c:
            for k in range(args.workers):
                c.post("/v1/locate", files={"image": _upload("warm", pngs[k % len(pngs)][0])})
        rss_start, cpu_start = rss_mb(pid), cpu_seconds(pid)
        client_cpu_start = time.process_time()
        latencies, errors, wall, rss_samples, server_ms = asyncio.run(
            _run(base, pid, pngs, args.clients, args.seconds)
        )
        client_cpu_s = time.process_time() - client_cpu_start
        rss_end, cpu_end = rss_mb(pid), cpu_seconds(pid)
    server_cpu_s = cpu_end - cpu_start
    lat_ms = sorted(x * 1e3 for x in latencies)
    p = (lambda q: lat_ms[min(len(lat_ms) - 1, int(q * len(lat_ms)))]) if lat_ms else (lambda q: float("nan"))
    figures = {
        "clients": args.clients,
        "seconds": round(wall, 1),
        "workers": args.workers,
        "max_queue": max_queue,
        "image_format": "png" if args.jpeg is None else f"jpeg {args.jpeg}",
        "png_bytes_mean": int(statistics.mean(len(d) for d, _ in pngs)),  # (the JPEGs' with --jpeg)
        "requests_ok": len(latencies),
        "errors": len(errors),
        "throughput_rps": round(len(latencies) / wall, 2),
        "latency_p50_ms": round(p(0.50), 1),
        "latency_p99_ms": round(p(0.99), 1),
        "latency_max_ms": round(lat_ms[-1], 1) if lat_ms else None,
        "p99_over_p50": round(p(0.99) / p(0.50), 2) if lat_ms else None,
        "cpu_count": os.cpu_count(),
        "server_cpu_s": round(server_cpu_s, 1),
        # the load clients' own CPU (this process): taken from the same cores as the server's
        "client_cpu_s": round(client_cpu_s, 1),
        "rps_per_server_cpu_s": round(len(latencies) / server_cpu_s, 2) if server_cpu_s > 0 else None,
        "decode_locate_ms": round(ideal_ms, 2),
        "ideal_rps_per_core": round(1000.0 / ideal_ms, 2),
        # the same timed in one process per CPU at once, no HTTP: what each core does when all are busy
        "decode_locate_ms_all_cpus_busy": round(loaded_ms, 2),
        "ideal_rps_per_core_all_cpus_busy": round(1000.0 / loaded_ms, 2),
        # the same, timed by the server on each answered request (Server-Timing), during the run
        "server_decode_locate_ms": round(statistics.mean(server_ms), 2) if server_ms else None,
        "server_ideal_rps_per_core": round(1000.0 / statistics.mean(server_ms), 2) if server_ms else None,
        "measuring_share_of_server_cpu": (
            round(sum(server_ms) / 1e3 / server_cpu_s, 3) if server_ms and server_cpu_s > 0 else None
        ),
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
    if figures["rps_per_server_cpu_s"]:
        print(
            f"per core: {figures['rps_per_server_cpu_s']} req per server CPU-second "
            f"({figures['server_cpu_s']} CPU-s, {os.cpu_count()} CPUs), "
            f"ideal 1000 / {figures['decode_locate_ms']} ms = {figures['ideal_rps_per_core']}: "
            f"{100 * figures['rps_per_server_cpu_s'] / figures['ideal_rps_per_core']:.0f} % of it; "
            f"p99 / p50 = {figures['p99_over_p50']}"
        )
    if figures["rps_per_server_cpu_s"]:
        print(
            f"with every CPU measuring at once ({busy} processes, no HTTP): decode + locate "
            f"{figures['decode_locate_ms_all_cpus_busy']} ms, ideal {figures['ideal_rps_per_core_all_cpus_busy']} "
            f"req per core: {100 * figures['rps_per_server_cpu_s'] / figures['ideal_rps_per_core_all_cpus_busy']:.0f} % of it"
        )
    if figures["measuring_share_of_server_cpu"] is not None:
        print(
            f"timed by the server (Server-Timing, mean decode + locate {figures['server_decode_locate_ms']} ms "
            f"during the run): ideal {figures['server_ideal_rps_per_core']} req per core, "
            f"{100 * figures['measuring_share_of_server_cpu']:.0f} % of the server's CPU spent measuring images"
        )


if __name__ == "__main__":
    main()
