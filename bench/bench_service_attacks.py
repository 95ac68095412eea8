"""Each attack of the hostile-network probe against a real `doorloc serve`: its answers, the server's CPU and
memory while it runs, and a normal locate's time during it against the same service unloaded.

The service runs on 127.0.0.1 with API keys ("normal": the measuring client, sending from 127.0.0.2 as
another machine would; "attacker": operator, the attacking clients, from 127.0.0.1; "admin": engineer). For
each attack: ``--normal`` sequential locates of rendered 1080p doors unloaded (median), then the attack's
clients start (threads in their own process, so their GIL does not slow the measuring client), the same
locates are timed during it, and the server's CPU seconds (all its processes, from /proc) over that window
and its peak resident memory are read. Every attack loop is bounded and ends with its window. Printed as a
Markdown table (docs/deploy.md holds one).

    python bench/bench_service_attacks.py --workers 1
    python bench/bench_service_attacks.py --workers 2 --only jpeg_scans,fair_flood
    python bench/bench_service_attacks.py --workers 1 --server-cpus 0 --client-cpus 1

``--server-cpus`` / ``--client-cpus`` (Linux): the service (and every process it starts) runs only on the first
CPU set, this script, its measuring client and the attack clients only on the second, so that the attackers'
own CPU does not slow the server's answers; the affinity read back from every process, and ``uptime`` at the
start and the end (other work on the machine still shares its CPUs), are printed with the table. Without them
everything shares every CPU. ``--attack-nice N`` (Unix): the attack clients run N nice levels below the
measuring client, as if on other machines: with only two CPUs they otherwise share the measuring client's
CPU with it, and a normal locate would wait for its own client to get the CPU, whatever the server does.

The attacks (the probe's numbering):

1. ``jpeg_scans``: 2 clients post a progressive JPEG with 60,000 empty scans (~1.3 MB; 10 s of decoding once);
2. ``header_100mb``: 1 client sends a 100 MB header, keyless; ``slow_headers``: 20 connections trickle theirs;
3. ``revoke_last_key``: every key revoked, then a keyless recipe PUT (run last);
4. ``tiff_tiles``: 4 clients post a 64x64 TIFF with 16368^2 tiles, and a 4000x3000 32-bit float TIFF;
5. ``keyless_19mb``: 20 clients post 19 MB without a key;
6. ``wrong_keys``: 20 clients send a known key id with wrong secrets (and the timing of known vs unknown ids);
7. ``overlay_refused``: ?overlay=true on a 7 MB noise JPEG that locate refuses (the answer's size);
8. ``recipe_bounds``: PUT a hinge 800 mm deep, a feed of 5000 mm/s, 100,000 rpm;
9. ``docs_headers``: /docs and its security headers (what it loads from other origins);
10. ``fair_flood``: 20 clients (one key) flood valid locates honouring Retry-After; the normal client's 503s.
"""

from __future__ import annotations

import argparse
import multiprocessing
import socket
import statistics
import threading
import time
from collections import Counter

import httpx
from service_harness import RECIPE, affinity_of_tree, cpu_seconds, doorloc_serve, rendered_pngs, rss_mb

from doorloc.sim.hostile import progressive_jpeg_bomb, tiff_header

LOAD_ATTACKS = [
    "jpeg_scans",
    "header_100mb",
    "slow_headers",
    "tiff_tiles",
    "keyless_19mb",
    "wrong_keys",
    "overlay_refused",
    "fair_flood",
]


# ---------------------------------------------------------------------------------------------- payloads


def noise_jpeg(w: int = 4000, h: int = 3000) -> bytes:
    import cv2
    import numpy as np

    img = np.random.default_rng(1).integers(0, 255, (h, w), np.uint8)
    return cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes()


def _status(data: bytes) -> int | str:
    return int(data.split(b" ", 2)[1]) if data.startswith(b"HTTP/1.1 ") else "closed"


def _flood(host: str, port: str, head: bytes, fill: bytes, chunks: int) -> int | str:
    """Send ``head``, then ``chunks`` 64 kB chunks of ``fill`` unless the server closes first; its status."""
    with socket.create_connection((host, int(port)), timeout=60) as s:
        s.sendall(head)
        try:
            for _ in range(chunks):
                s.sendall(fill * 65536)
        except OSError:
            pass
        return _raw_until_answer(s)


def _raw_until_answer(s: socket.socket) -> int | str:
    data = b""
    s.settimeout(60)
    try:
        while b"\r\n" not in data:
            chunk = s.recv(4096)
            if not chunk:
                break
            data += chunk
    except OSError as e:
        return type(e).__name__
    return _status(data)


# ---------------------------------------------------------------------------------------------- attack clients


def attack_client(  # noqa: ANN001
    kind: str,
    k: int,
    base: str,
    keys: dict,
    stop: threading.Event,
    out: Counter,
    lock,
    door_png: bytes | None,
) -> None:
    host, port = base.removeprefix("http://").split(":")
    att = {"X-API-Key": keys["attacker"]}
    payloads = {}
    if kind == "jpeg_scans":
        payloads["f"] = progressive_jpeg_bomb(60_000)
    elif kind == "tiff_tiles":
        payloads["f"] = (
            tiff_header(64, 64, 16368, bits=16, data_bytes=250_000)
            if k % 2 == 0
            else tiff_header(4000, 3000, None, 32, 3, data_bytes=250_000)
        )
    elif kind == "overlay_refused":
        payloads["f"] = noise_jpeg()
    elif kind == "fair_flood":
        payloads["f"] = door_png
    with httpx.Client(base_url=base, timeout=120) as client:
        for _ in range(10_000):  # bounded; the window ends it through `stop`
            if stop.is_set():
                return
            extra = ""
            try:
                if kind in ("jpeg_scans", "tiff_tiles"):
                    r = client.post(
                        "/v1/locate", files={"image": ("x", payloads["f"], "image/jpeg")}, headers=att
                    )
                    status: int | str = r.status_code
                elif kind == "overlay_refused":
                    r = client.post(
                        "/v1/locate?overlay=true",
                        files={"image": ("n.jpg", payloads["f"], "image/jpeg")},
                        headers=att,
                    )
                    status, extra = r.status_code, f" ({len(r.content) / 1e3:.0f} kB)"
                elif kind == "fair_flood":
                    r = client.post(
                        "/v1/locate", files={"image": ("d.png", payloads["f"], "image/png")}, headers=att
                    )
                    status = r.status_code
                    if status == 503:
                        stop.wait(float(r.headers.get("retry-after", "1")))
                elif kind == "wrong_keys":
                    wrong = keys["attacker"][:-6] + f"{k:03d}AAA"
                    r = client.get("/v1/doors", headers={"X-API-Key": wrong})
                    status = r.status_code
                    if status == 429:
                        stop.wait(1.0)
                elif kind == "keyless_19mb":
                    status = _flood(
                        host,
                        port,
                        b"POST /v1/locate HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                        b"Content-Type: multipart/form-data; boundary=zz\r\nContent-Length: 19000000\r\n\r\n",
                        b"\0",
                        290,  # 19 MB in 64 kB chunks, unless the server closes first
                    )
                elif kind == "header_100mb":
                    status = _flood(
                        host,
                        port,
                        b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Big: ",
                        b"a",
                        1600,  # 100 MB in 64 kB chunks, unless the server closes first
                    )
                elif kind == "slow_headers":
                    with socket.create_connection((host, int(port)), timeout=120) as s:
                        s.sendall(b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n")
                        try:
                            for _ in range(300):  # one byte a second until the server gives up on us
                                s.sendall(b"X")
                                if stop.wait(1.0):
                                    break
                        except OSError:
                            pass
                        status = _raw_until_answer(s)
                else:
                    raise ValueError(kind)
            except (httpx.HTTPError, OSError) as e:
                status = type(e).__name__
            with lock:
                out[f"{status}{extra}"] += 1


def attack_process(kind: str, n: int, base: str, keys: dict, stop, running, out, nice: int = 0) -> None:  # noqa: ANN001
    if nice > 0:
        import os

        os.nice(nice)  # before any client thread starts: they inherit it
    lock, statuses, stop_t = threading.Lock(), Counter(), threading.Event()
    door_png = rendered_pngs(1, seed0=50)[0][0] if kind == "fair_flood" else None  # once, before the start
    threads = [
        threading.Thread(target=attack_client, args=(kind, k, base, keys, stop_t, statuses, lock, door_png))
        for k in range(n)
    ]
    for t in threads:
        t.start()
    time.sleep(1.0)  # the attack is under way before the measurement starts
    running.set()
    stop.wait(600)
    stop_t.set()
    for t in threads:
        t.join(timeout=120)
    out.put(dict(statuses))


# ---------------------------------------------------------------------------------------------- measuring


#: the measuring client's own address (Linux routes all of 127/8 to loopback): the attack clients all send from
#: 127.0.0.1, as if from one machine, and the measuring client is another machine's, so a budget or share per
#: address that the attackers exhaust is not also its own (from an address over its wrong-key budget, a valid
#: key a worker has not verified yet is checked only on a few trials a minute, which the guessers use up)
NORMAL_ADDRESS = "127.0.0.2"


def normal_times(base: str, key: str, pngs: list, n: int) -> tuple[list[float], Counter]:
    lat, statuses = [], Counter()
    transport = httpx.HTTPTransport(local_address=NORMAL_ADDRESS)
    with httpx.Client(base_url=base, timeout=120, transport=transport) as client:
        for i in range(n):
            t0 = time.perf_counter()
            r = client.post(
                "/v1/locate",
                files={"image": (f"d{i}.png", pngs[i % len(pngs)][0], "image/png")},
                headers={"X-API-Key": key},
            )
            statuses[r.status_code] += 1
            if r.status_code == 200:
                lat.append(time.perf_counter() - t0)
    return lat, statuses


CLIENTS = {
    "jpeg_scans": 2,
    "header_100mb": 1,
    "slow_headers": 20,
    "tiff_tiles": 4,
    "keyless_19mb": 20,
    "wrong_keys": 20,
    "overlay_refused": 1,
    "fair_flood": 20,
}


def run_attack(kind: str, base: str, pid: int, keys: dict, pngs: list, n: int, attack_nice: int = 0) -> dict:
    unloaded, _ = normal_times(base, keys["normal"], pngs, n)
    ctx = multiprocessing.get_context("spawn")
    stop, running, out = ctx.Event(), ctx.Event(), ctx.Queue()
    proc = ctx.Process(
        target=attack_process, args=(kind, CLIENTS[kind], base, keys, stop, running, out, attack_nice)
    )
    proc.start()
    running.wait(180)
    peak = [rss_mb(pid)]
    sampling = threading.Event()

    def sample() -> None:
        while not sampling.wait(0.2):
            peak[0] = max(peak[0], rss_mb(pid))

    sampler = threading.Thread(target=sample)
    sampler.start()
    cpu0, t0 = cpu_seconds(pid), time.monotonic()
    loaded, normal_statuses = normal_times(base, keys["normal"], pngs, n)
    window = time.monotonic() - t0
    cpu = cpu_seconds(pid) - cpu0
    stop.set()
    statuses = Counter(out.get(timeout=300))
    proc.join(timeout=120)
    sampling.set()
    sampler.join()
    u = statistics.median(unloaded) if unloaded else float("nan")
    lo = statistics.median(loaded) if loaded else float("nan")
    return {
        "attack": kind,
        "answers": ", ".join(f"{k} x{v}" for k, v in sorted(statuses.items(), key=lambda kv: str(kv[0]))),
        "cpu": f"{cpu / window:.2f} cores",
        "rss": f"{peak[0]:.0f} MB",
        "unloaded": f"{u * 1e3:.0f} ms",
        "during": f"{lo * 1e3:.0f} ms",
        "ratio": f"{lo / u:.2f}",
        "normal": ", ".join(f"{k} x{v}" for k, v in sorted(normal_statuses.items())),
    }


def single_checks(base: str, keys: dict) -> list[dict]:
    rows = []
    adm = {"X-API-Key": keys["admin"]}
    # 6: timing of a known key id with a wrong secret against an unknown id
    known = keys["attacker"][:-4] + "ZZZZ"
    unknown = "dlk_000000000000_" + "Z" * 43
    t = {"known": [], "unknown": []}
    with httpx.Client(base_url=base, timeout=60) as c:
        for _ in range(4):  # within the failure budget of the (default) 10 a minute
            for name, key in (("known", known), ("unknown", unknown)):
                c.get("/healthz")  # the connection warm, the same for both
                t1 = time.perf_counter()
                c.get("/v1/doors", headers={"X-API-Key": key})
                t[name].append(time.perf_counter() - t1)
    rows.append(
        {
            "attack": "key timing (known id, wrong secret / unknown id)",
            "answers": f"{statistics.median(t['known']) * 1e3:.1f} ms / {statistics.median(t['unknown']) * 1e3:.1f} ms",
        }
    )
    # 8: recipes beyond the tool and spindle
    got = []
    for change in (
        {"hinges": [{**RECIPE["hinges"][0], "depth_mm": 800}]},
        {"feed_mm_s": 5000},
        {"spindle_rpm": 100000},
    ):
        r = httpx.put(f"{base}/v1/doors/BENCH-1", json={**RECIPE, **change}, headers=adm, timeout=60)
        got.append(f"{r.status_code} ({next(iter(change))})")
    rows.append({"attack": "recipe_bounds", "answers": ", ".join(got)})
    # 9: /docs: headers, and what it would load from elsewhere
    import re

    r = httpx.get(f"{base}/docs", timeout=60)
    refs = re.findall(r'(?:src|href)="([^"]+)"', r.text)
    foreign = [x for x in refs if not x.startswith("/")]
    rows.append(
        {
            "attack": "docs_headers",
            "answers": f"{r.status_code}; CSP {'yes' if 'content-security-policy' in r.headers else 'NO'}, "
            f"X-Frame-Options {r.headers.get('x-frame-options')}, nosniff "
            f"{'yes' if r.headers.get('x-content-type-options') == 'nosniff' else 'NO'}; "
            f"{len(foreign)} foreign references",
        }
    )
    return rows


def revoke_last_key(base: str, keys: dict) -> dict:
    """3: revoke every key (through the database), then a keyless recipe PUT."""
    import os

    from doorloc.app.access import KeyStore
    from doorloc.recipes.store import RecipeStore

    with RecipeStore(os.environ["BENCH_DATABASE_URL"]) as store:
        ks = KeyStore(store.engine)
        for name in ("normal", "attacker", "admin"):
            ks.revoke(name)
    time.sleep(2.5)  # past any cache
    r = httpx.put(f"{base}/v1/doors/BENCH-1", json=RECIPE, timeout=60)
    ready = httpx.get(f"{base}/readyz", timeout=60).json()
    return {
        "attack": "revoke_last_key",
        "answers": f"keyless PUT {r.status_code}; /readyz access '{ready.get('access')}'",
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--normal", type=int, default=6, help="normal locates per block (unloaded, then during)")
    ap.add_argument("--only", default="", help="comma-separated attacks (default: all)")
    ap.add_argument("--server-cpus", default="", help="CPUs of the service, e.g. 0 or 0-1 (default: all)")
    ap.add_argument(
        "--client-cpus", default="", help="CPUs of this script and the attack clients, e.g. 1 (default: all)"
    )
    ap.add_argument(
        "--attack-nice", type=int, default=0, help="nice levels of the attack clients below the measuring one"
    )
    args = ap.parse_args()
    only = [a for a in args.only.split(",") if a] or LOAD_ATTACKS
    server_cpus, client_cpus = _cpu_set(args.server_cpus), _cpu_set(args.client_cpus)
    import os
    import subprocess

    if client_cpus is not None:
        os.sched_setaffinity(0, client_cpus)  # before any client starts: they inherit it
    uptime_start = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()

    pngs = rendered_pngs(3)
    keys = {"normal": "operator", "attacker": "operator", "admin": "engineer"}
    env = {"OMP_NUM_THREADS": "1", "DOORLOC_REQUEST_DEADLINE_S": "10"}
    with doorloc_serve(args.workers, extra_env=env, keys=keys, cpus=server_cpus) as (base, pid):
        server_affinity = affinity_of_tree(pid)
        os.environ["BENCH_DATABASE_URL"] = "sqlite:///" + str(_database_of(pid))
        adm = {"X-API-Key": keys["admin"]}
        assert httpx.put(f"{base}/v1/doors/BENCH-1", json=RECIPE, headers=adm, timeout=60).status_code == 200
        normal_times(base, keys["normal"], pngs, 2)  # warm
        # the single checks first: the key timing needs a fresh wrong-key budget
        rows = single_checks(base, keys)
        rows += [
            run_attack(kind, base, pid, keys, pngs, args.normal, args.attack_nice)
            for kind in only
            if kind in LOAD_ATTACKS
        ]
        rows.append(revoke_last_key(base, keys))
        server_affinity |= affinity_of_tree(pid)  # the workers started since (replacements) too
    uptime_end = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    print(
        f"\n{args.workers} worker(s); normal locate = 1080p rendered door, {args.normal} per block; attack "
        f"clients {args.attack_nice} nice levels below it"
    )
    print(f"machine: {os.cpu_count()} CPUs; uptime at the start: {uptime_start}; at the end: {uptime_end}")
    cpus_of_server = sorted({c for cs in server_affinity.values() for c in cs})
    print(
        f"affinity: server, its {len(server_affinity)} processes: CPUs {cpus_of_server}; this script, the "
        f"measuring and attack clients: CPUs {sorted(os.sched_getaffinity(0))}\n"
    )
    cols = ["attack", "answers", "cpu", "rss", "unloaded", "during", "ratio", "normal"]
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for r in rows:
        print("| " + " | ".join(str(r.get(c, "")) for c in cols) + " |")


def _cpu_set(text: str) -> set[int] | None:
    """``"0"``, ``"0,2"`` or ``"0-3"`` as a set of CPU numbers; "" -> None (every CPU)."""
    if not text:
        return None
    cpus: set[int] = set()
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        cpus |= set(range(int(lo), int(hi or lo) + 1))
    return cpus


def _database_of(pid: int):  # noqa: ANN202
    """The recipe database file of the serve process (its DOORLOC_DATABASE_URL)."""
    from pathlib import Path

    env = Path(f"/proc/{pid}/environ").read_bytes().split(b"\0")
    url = next(e for e in env if e.startswith(b"DOORLOC_DATABASE_URL=")).split(b"=", 1)[1].decode()
    return Path(url.removeprefix("sqlite:///"))


if __name__ == "__main__":
    main()
