"""Hostile requests against a real `doorloc serve` process on 127.0.0.1.

Two services per module: ``svc`` (2 workers, API keys of each role, a 2 s header deadline) and ``tight``
(1 worker, open on loopback, 1 CPU slot, a queue of 2, a 3 s deadline, a 1 s decoding CPU limit with the
JPEG scan limit lifted, 3 wrong keys a minute) for overload, slow clients and decoding bombs; one test starts
its own open service to watch it close. Every loop is bounded; only loopback.
"""

from __future__ import annotations

import socket
import struct
import time
import zlib

import httpx
import pytest

from doorloc.app.access import KeyStore, Role
from doorloc.recipes.store import RecipeStore
from doorloc.sim.hostile import progressive_jpeg_bomb, tiff_header

from .conftest import launch_serve, png_bytes, stop_serve

# one test process starts the module's two services for all its tests (each service's worker processes take
# seconds to start; spread over two test processes, each started its own pair)
pytestmark = [pytest.mark.slow, pytest.mark.xdist_group("serve_hostile")]


def _png_header_only(w: int, h: int, depth: int = 8, colour: int = 0) -> bytes:
    ihdr = struct.pack(">IIBBBBB", w, h, depth, colour, 0, 0, 0)
    chunk = struct.pack(">I", 13) + b"IHDR" + ihdr + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr))
    raw = zlib.compress(b"\x00" * (1 + w * 8) * 8)  # 8 real rows, the rest missing
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk
        + struct.pack(">I", len(raw))
        + b"IDAT"
        + raw
        + struct.pack(">I", zlib.crc32(b"IDAT" + raw))
        + struct.pack(">I", 0)
        + b"IEND"
        + struct.pack(">I", zlib.crc32(b"IEND"))
    )


@pytest.fixture(scope="module")
def svc(tmp_path_factory, recipe_module):
    tmp = tmp_path_factory.mktemp("svc")
    with RecipeStore(f"sqlite:///{tmp / 'recipes.db'}") as store:
        keys = KeyStore(store.engine)
        secrets = {r: keys.create(f"{r.value} key", r).secret for r in Role}
        store.put(recipe_module)
    env = {"DOORLOC_HEADER_TIMEOUT_S": "2", "DOORLOC_AUTH_FAILURES_PER_MINUTE": "1000"}
    base, proc, log = launch_serve(tmp, "--workers", "2", env=env)
    yield base, {r: {"X-API-Key": s} for r, s in secrets.items()}, tmp
    stop_serve(proc, log)


@pytest.fixture(scope="module")
def tight(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("tight")
    env = {
        "DOORLOC_LOCATE_CONCURRENCY": "1",
        "DOORLOC_MAX_QUEUE": "2",
        "DOORLOC_REQUEST_DEADLINE_S": "3",
        "DOORLOC_MAX_JPEG_SCANS": "1000000",  # so that a scan bomb reaches the decoder and its CPU limit
        "DOORLOC_DECODE_CPU_S": "1",
        "DOORLOC_AUTH_FAILURES_PER_MINUTE": "3",
        "DOORLOC_ALLOWED_HOSTS": "127.0.0.1,x",  # the raw-socket clients below send "Host: x"
    }
    base, proc, log = launch_serve(tmp, "--workers", "1", "--open", "--create-database", env=env)
    yield base
    stop_serve(proc, log)


@pytest.fixture(scope="module")
def recipe_module():
    from doorloc.recipes.models import DoorRecipe, Hinge

    return DoorRecipe(
        door_id="D-100",
        width_mm=900,
        height_mm=2100,
        thickness_mm=50,
        hinges=[Hinge(z_mm=250, length_mm=100, width_mm=30, x_mm=10, depth_mm=3, corner_radius_mm=8)],
        tool_diameter_mm=16,
        spindle_rpm=18000,
        feed_mm_s=25,
    )


def _problem(r: httpx.Response, status: int, code: str | None = None) -> dict:
    assert r.status_code == status, r.text
    assert r.headers["content-type"].startswith("application/problem+json"), r.headers
    body = r.json()
    assert body["status"] == status and body["detail"]
    if code is not None:
        assert body["code"] == code, body
    return body


def _img(png: bytes, name: str = "door.png") -> dict:
    return {"image": (name, png, "image/png")}


SMALL = png_bytes(__import__("numpy").full((48, 64), 130, __import__("numpy").uint8))


# ---------------------------------------------------------------------------------------------- access


def test_recipe_change_needs_an_engineer_key(svc, recipe_module):
    base, h, _ = svc
    wider = recipe_module.model_dump(mode="json") | {"width_mm": 1350}
    _problem(httpx.put(f"{base}/v1/doors/D-100", json=wider, timeout=30), 401, "unauthorized")
    _problem(
        httpx.put(f"{base}/v1/doors/D-100", json=wider, headers=h[Role.operator], timeout=30),
        403,
        "forbidden",
    )
    assert httpx.get(f"{base}/v1/doors/D-100", headers=h[Role.operator], timeout=30).json()["width_mm"] == 900
    r = httpx.put(f"{base}/v1/doors/D-100", json=wider, headers=h[Role.engineer], timeout=30)
    assert r.status_code == 200, r.text


def test_metrics_need_their_role(svc):
    base, h, _ = svc
    _problem(httpx.get(f"{base}/metrics", timeout=30), 401)
    _problem(httpx.get(f"{base}/metrics", headers=h[Role.operator], timeout=30), 403)
    assert httpx.get(f"{base}/metrics", headers=h[Role.metrics], timeout=30).status_code == 200
    _problem(httpx.post(f"{base}/v1/locate", files=_img(SMALL), headers=h[Role.metrics], timeout=30), 403)


def test_wrong_and_malformed_keys(svc):
    base, _, _ = svc
    for key in (b"x", b"dlk_000000000000_" + b"A" * 43, b"dlk_" + b"z" * 200, "\u00e9\u00e9".encode()):
        r = httpx.get(f"{base}/v1/doors", headers=[(b"X-API-Key", key)], timeout=30)
        _problem(r, 401, "unauthorized")


# ---------------------------------------------------------------------------------------------- uploads


def test_a_small_png_declaring_a_huge_16_bit_rgba_image_is_refused_before_decoding(svc):
    """Issue defect: a 381 kB 7000x7000 16-bit RGBA PNG (under the pixel limit) was decoded in full."""
    base, h, _ = svc
    bomb = _png_header_only(7000, 7000, 16, 6)
    t0 = time.monotonic()
    body = _problem(
        httpx.post(f"{base}/v1/locate", files=_img(bomb), headers=h[Role.operator], timeout=60),
        422,
        "too_many_pixels",
    )
    assert "392 MB" in body["detail"]
    assert time.monotonic() - t0 < 30  # generous: only shows the answer came back at all


def test_nan_and_absurd_sizes(svc):
    base, h, _ = svc
    for form in ({"width_mm": "nan"}, {"width_mm": "1e308"}, {"thickness_mm": "10000"}, {"height_mm": "-1"}):
        r = httpx.post(
            f"{base}/v1/locate", files=_img(SMALL), data=form, headers=h[Role.operator], timeout=30
        )
        body = _problem(r, 422)
        assert next(iter(form)) in body["detail"]


def test_raw_image_body_is_415(svc):
    """Issue defect: a raw image/png body got 422 instead of 415."""
    base, h, _ = svc
    r = httpx.post(
        f"{base}/v1/locate",
        content=SMALL,
        headers={**h[Role.operator], "Content-Type": "image/png"},
        timeout=30,
    )
    _problem(r, 415, "not_multipart")


# ---------------------------------------------------------------------------------------------- bounded work


def _slow_upload(base: str) -> socket.socket:
    """Start a multipart upload that declares 100 kB and sends 10 bytes (a slow or stalled client)."""
    host, port = base.removeprefix("http://").split(":")
    s = socket.create_connection((host, int(port)), timeout=15)
    s.sendall(
        b"POST /v1/locate HTTP/1.1\r\nHost: x\r\nContent-Type: multipart/form-data; boundary=zz\r\n"
        b"Content-Length: 100000\r\n\r\n--zz\r\nCont"
    )
    return s


def _read_status(s: socket.socket) -> int:
    data = b""
    deadline = time.monotonic() + 15
    while b"\r\n" not in data and time.monotonic() < deadline:
        chunk = s.recv(4096)
        if not chunk:
            break
        data += chunk
    return int(data.split(b" ", 2)[1]) if data.startswith(b"HTTP/1.1 ") else -1


def test_slow_clients_are_cut_at_the_deadline_and_block_nobody(tight):
    """Issue defect: no timeout; slow uploads could hold the service."""
    slow = [_slow_upload(tight) for _ in range(6)]  # more than the worker's CPU slot + queue
    try:
        time.sleep(0.3)
        r = httpx.post(f"{tight}/v1/locate", files=_img(SMALL), timeout=30)
        assert r.status_code == 200, r.text  # uploads in transit take no CPU slot and no queue place
        assert [_read_status(s) for s in slow] == [408] * 6  # cut at the 3 s deadline
    finally:
        for s in slow:
            s.close()


def test_overload_answers_503_retry_after(tight, cell):
    """Issue defect: no queue limit; a normal request waited 51 s behind 20 hostile uploads."""
    from doorloc.pose import DoorPose
    from doorloc.sim.door import render_door

    png = png_bytes(render_door(cell, cell.default_door, DoorPose(1, 2, 0.3), seed=3).image)
    # 12 uploads sent whole but for their last byte, then all last bytes at once: the 12 images reach the
    # worker within milliseconds of each other, while one locate takes far longer
    body = (
        b'--zz\r\nContent-Disposition: form-data; name="image"; filename="d.png"\r\n'
        b"Content-Type: image/png\r\n\r\n" + png + b"\r\n--zz--\r\n"
    )
    head = (
        b"POST /v1/locate HTTP/1.1\r\nHost: x\r\nContent-Type: multipart/form-data; boundary=zz\r\n"
        b"Content-Length: " + str(len(body)).encode() + b"\r\nConnection: close\r\n\r\n"
    )
    host, port = tight.removeprefix("http://").split(":")
    socks = [socket.create_connection((host, int(port)), timeout=60) for _ in range(12)]
    try:
        for s_ in socks:
            s_.sendall(head + body[:-1])
        for s_ in socks:
            s_.sendall(body[-1:])
        raw = []
        for s_ in socks:
            data = b""
            for _ in range(10_000):  # bounded read of one answer
                chunk = s_.recv(65536)
                if not chunk:
                    break
                data += chunk
            raw.append(data)
    finally:
        for s_ in socks:
            s_.close()
    statuses = [int(d.split(b" ", 2)[1]) for d in raw]
    assert set(statuses) <= {200, 503} and statuses.count(200) >= 1, statuses
    overloaded = [d for d in raw if d.startswith(b"HTTP/1.1 503")]
    # 1 CPU slot + a queue of 2: 9 refusals when all 12 arrive before one is measured (fewer on a busy machine)
    assert len(overloaded) >= 1, statuses
    for d in overloaded:
        assert b"retry-after: " in d.lower() and b'"code":"overloaded"' in d.replace(b" ", b"")
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and httpx.get(f"{tight}/readyz", timeout=30).status_code != 200:
        time.sleep(0.1)
    assert httpx.post(f"{tight}/v1/locate", files=_img(png), timeout=60).status_code == 200


# ---------------------------------------------------------------------------------------------- recipes


def test_50_parallel_recipe_writers_all_succeed_and_each_is_a_version(svc, recipe_module):
    """Issue defect: 15-16 of 20 parallel PUTs got 503 'database is locked' on the default SQLite database."""
    from concurrent.futures import ThreadPoolExecutor

    base, h, _ = svc
    before = len(
        httpx.get(f"{base}/v1/doors/D-100/history", headers=h[Role.operator], timeout=30).json()["versions"]
    )

    def put(k: int) -> int:
        body = recipe_module.model_dump(mode="json") | {"feed_mm_s": 100 + k}
        return httpx.put(
            f"{base}/v1/doors/D-100", json=body, headers=h[Role.engineer], timeout=120
        ).status_code

    with ThreadPoolExecutor(50) as ex:
        statuses = list(ex.map(put, range(50)))
    assert statuses == [200] * 50
    versions = httpx.get(f"{base}/v1/doors/D-100/history", headers=h[Role.operator], timeout=30).json()[
        "versions"
    ]
    assert len(versions) == before + 50
    assert {v["changed_by"] for v in versions[-50:]} == {"engineer key"}


# ---------------------------------------------------------------------------------------------- metrics


def _sample(text: str, name: str, **labels: str) -> float | None:
    want = ",".join(f'{k}="{v}"' for k, v in sorted(labels.items()))
    for line in text.splitlines():
        if line.startswith(name + "{"):
            got = ",".join(sorted(line[len(name) + 1 : line.index("}")].split(",")))
            if got == want:
                return float(line.rsplit(" ", 1)[1])
    return None


def test_metrics_add_up_every_worker(svc):
    """Issue defect: with --workers 2 a counter read 67 and 95 on alternate scrapes."""
    base, h, _ = svc
    for _ in range(30):
        assert httpx.get(f"{base}/healthz", timeout=30).status_code == 200
    reads = []
    for _ in range(6):  # new connections: the kernel spreads them over both workers
        text = httpx.get(f"{base}/metrics", headers=h[Role.metrics], timeout=30).text
        reads.append(
            _sample(text, "doorloc_http_requests_total", method="GET", route="/healthz", status="200")
        )
        pids = {
            line.split('pid="')[1].split('"')[0]
            for line in text.splitlines()
            if line.startswith("doorloc_worker_resident_memory_bytes{")
        }
    assert reads[0] is not None and reads[0] >= 30
    assert len(set(reads)) == 1, reads
    assert len(pids) == 2  # process figures of both workers


# ---------------------------------------------------------------------------------------------- protocol-level


def _raw(base: str, payload: bytes) -> tuple[int, dict[str, str], bytes]:
    host, port = base.removeprefix("http://").split(":")
    with socket.create_connection((host, int(port)), timeout=15) as s:
        s.sendall(payload)
        data = b""
        deadline = time.monotonic() + 15
        while time.monotonic() < deadline:
            chunk = s.recv(65536)
            if not chunk:
                break
            data += chunk
    head, _, body = data.partition(b"\r\n\r\n")
    lines = head.decode("latin-1").split("\r\n")
    headers = {k.strip().lower(): v.strip() for k, _, v in (x.partition(":") for x in lines[1:])}
    return int(lines[0].split()[1]), headers, body


@pytest.mark.parametrize(
    "payload",
    [
        b"GARBAGE\r\n\r\n",
        b"GET /healthz HTTP/1.1\r\nHost: x\r\nBad Header\r\n\r\n",
        b"POST /v1/locate HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\nzz\r\n",
    ],
)
def test_the_servers_own_400s_are_problem_json(svc, payload):
    """Issue defect: uvicorn's own 400 answers were plain text."""
    import json

    base, _, _ = svc
    status, headers, body = _raw(base, payload)
    assert status == 400
    assert headers["content-type"] == "application/problem+json"
    assert json.loads(body)["code"] == "malformed_http"


def test_405_names_the_allowed_methods(svc):
    """Issue defect: a 405 said 'use .' with an empty Allow header."""
    base, h, _ = svc
    r = httpx.patch(f"{base}/v1/doors/D-100", headers=h[Role.engineer], timeout=30)
    body = _problem(r, 405, "method_not_allowed")
    assert r.headers["allow"] == "GET, PUT, DELETE" and "use GET or PUT or DELETE" in body["detail"]
    r = httpx.get(f"{base}/v1/locate", timeout=30)
    assert _problem(r, 405)["detail"].endswith("use POST.") and r.headers["allow"] == "POST"


def test_two_image_parts_are_refused(svc):
    """Issue defect: two 'image' parts silently took the last."""
    base, h, _ = svc
    files = [("image", ("a.png", SMALL, "image/png")), ("image", ("b.png", SMALL, "image/png"))]
    _problem(
        httpx.post(f"{base}/v1/locate", files=files, headers=h[Role.operator], timeout=30),
        422,
        "several_images",
    )


def test_broken_multipart_is_a_problem(svc):
    base, h, _ = svc
    r = httpx.post(
        f"{base}/v1/locate",
        content=b"--x\r\nnot a part",
        headers={**h[Role.operator], "Content-Type": "multipart/form-data; boundary=x"},
        timeout=30,
    )
    assert r.status_code in (400, 422) and r.headers["content-type"] == "application/problem+json"


def test_cell_info_does_not_show_the_servers_paths(svc):
    """Issue defect: /v1/cell showed the cell file's absolute path."""
    base, h, _ = svc
    r = httpx.get(f"{base}/v1/cell", headers=h[Role.operator], timeout=30)
    assert r.status_code == 200
    assert r.json()["source"] == "cell_thesis.yaml" and "/" not in r.text.split('"source"')[1].split(",")[0]


def test_locate_answers_name_their_provenance(svc):
    base, h, _ = svc
    r = httpx.post(
        f"{base}/v1/locate",
        files=_img(SMALL),
        data={"door_id": "D-100"},
        headers=h[Role.operator],
        timeout=60,
    )
    assert r.status_code == 200, r.text
    prov = r.json()["provenance"]
    assert prov["version"] and len(prov["cell_sha256"]) == 64 and len(prov["calibration_sha256"]) == 64
    assert isinstance(prov["recipe_version"], int) and prov["recipe_version"] >= 1


def test_paging_is_bounded(svc):
    base, h, _ = svc
    _problem(
        httpx.get(f"{base}/v1/doors", params={"limit": 10**6}, headers=h[Role.operator], timeout=30), 422
    )
    page = httpx.get(f"{base}/v1/doors", params={"limit": 1}, headers=h[Role.operator], timeout=30).json()
    assert page["limit"] == 1 and page["total"] >= 1


# ---------------------------------------------------------------------------------------------- decoding bombs


def test_a_jpeg_with_thousands_of_scans_is_refused_before_decoding(svc):
    """Issue defect: a 908 KB progressive JPEG of 60,000 near-empty scans cost 12 s of decoding."""
    base, h, _ = svc
    bomb = progressive_jpeg_bomb(5000)
    body = _problem(
        httpx.post(f"{base}/v1/locate", files=_img(bomb, "b.jpg"), headers=h[Role.operator], timeout=60),
        422,
        "decode_limit",
    )
    assert "5" in body["detail"] and "scans" in body["detail"]


def test_a_decoder_past_its_cpu_limit_ends_its_worker_and_the_service_goes_on(tight):
    """Issue defect: decoding was not bounded in time; two bombs made every other locate wait 30 s for a 503.

    Here the scan limit is lifted, so the bomb reaches the decoder: its process is ended at 1 s of CPU."""
    bomb = progressive_jpeg_bomb(40000)  # ~7 s of decoding on one core
    r = httpx.post(f"{tight}/v1/locate", files=_img(bomb, "b.jpg"), timeout=60)
    # ended at 1 s of CPU (422), or, on a machine too busy to give it that within the 3 s deadline, at the
    # deadline (503): bounded either way (tests/app/test_decodepool.py holds the CPU limit by itself)
    body = _problem(r, r.status_code)
    assert (r.status_code, body["code"]) in ((422, "decode_limit"), (503, "overloaded")), body
    assert "CPU" in body["detail"] or "deadline" in body["detail"]
    assert httpx.get(f"{tight}/readyz", timeout=30).status_code == 200
    assert httpx.post(f"{tight}/v1/locate", files=_img(SMALL), timeout=60).status_code == 200


def _descendants(pid: int) -> list[int]:
    from pathlib import Path

    out, todo = [], [pid]
    while todo:
        for task in Path(f"/proc/{todo.pop()}/task").glob("*/children"):
            kids = [int(k) for k in task.read_text().split()]
            out += kids
            todo += kids
    return out


def test_locate_runs_in_a_process_with_cpu_and_memory_limits(tmp_path, cell):
    """The locate step of a request runs in a worker process with a CPU-time and a memory limit (a pathological
    image ends that process, 422 locate_limit: tests/app/test_decodepool.py ends one at its CPU limit) that
    holds locate's kernels; a real door is still measured."""
    from pathlib import Path

    from doorloc.pose import DoorPose
    from doorloc.sim.door import render_door

    env = {"DOORLOC_LOCATE_CONCURRENCY": "1", "DOORLOC_LOCATE_MEMORY_BYTES": "300000000"}
    base, proc, log = launch_serve(tmp_path, "--workers", "1", "--open", "--create-database", env=env)
    try:
        truth = DoorPose(1.0, -2.0, 0.3)
        door = png_bytes(render_door(cell, cell.default_door, truth, seed=5).image)
        r = httpx.post(f"{base}/v1/locate", files=_img(door), timeout=60)
        assert r.status_code == 200 and abs(r.json()["x_mm"] - truth.x_mm) < 0.05, r.text

        def jit_loaded(pid: int) -> bool:
            return "llvmlite" in Path(f"/proc/{pid}/maps").read_text()

        import os

        locators = [p for p in _descendants(proc.pid) if jit_loaded(p)]
        # one CPU slot: one locating process, and one 15 nice levels lower for a client over its share
        own = os.getpriority(os.PRIO_PROCESS, 0)
        nices = sorted(os.getpriority(os.PRIO_PROCESS, p) for p in locators)
        assert nices == [own, min(own + 15, 19)], (locators, nices)
        for locator in locators:
            limits = Path(f"/proc/{locator}/limits").read_text().splitlines()
            cpu = next(line for line in limits if line.startswith("Max cpu time"))
            memory = next(line for line in limits if line.startswith("Max address space"))
            assert memory.split()[3] != "unlimited", limits  # from its start
            # the one that located has a CPU limit too (set per job, from the first on); told apart from the
            # idle lower one by its level (the same where this process runs at 19 already)
            if own < 19 and os.getpriority(os.PRIO_PROCESS, locator) == own:
                assert cpu.split()[3] != "unlimited", limits
    finally:
        stop_serve(proc, log)


def test_tiff_tiles_and_float_samples_are_counted_before_decoding(svc):
    """Issue defect: a 260 KB TIFF of 64x64 px with 16368^2 tiles took 1 GB; 32-bit floats counted as 16-bit."""
    base, h, _ = svc
    tiles = tiff_header(64, 64, tile=16368, bits=16)
    body = _problem(
        httpx.post(f"{base}/v1/locate", files=_img(tiles, "t.tif"), headers=h[Role.operator], timeout=60), 422
    )
    assert "tiles" in body["detail"]
    floats = tiff_header(4000, 3000, tile=None, bits=32, sample_format=3)
    body = _problem(
        httpx.post(f"{base}/v1/locate", files=_img(floats, "f.tif"), headers=h[Role.operator], timeout=60),
        422,
    )
    assert "32-bit" in body["detail"]


def test_a_stream_of_decoding_bombs_is_answered_a_few_times_a_second(svc):
    """Four clients posting TIFF tile bombs were answered about 140 times a second (each upload parsed and
    logged beside every other client's work); each refusal now waits the image refusal delay (0.5 s), so one
    connection sending them back to back is answered at most a few times a second."""
    base, h, _ = svc
    tiles = tiff_header(64, 64, tile=16368, bits=16)
    answered, t0 = 0, time.monotonic()
    with httpx.Client(base_url=base, headers=h[Role.operator], timeout=60) as client:
        while time.monotonic() - t0 < 2.0:
            _problem(client.post("/v1/locate", files=_img(tiles, "t.tif")), 422, "decode_limit")
            answered += 1
    assert 1 <= answered <= 5, answered


# ---------------------------------------------------------------------------------------------- the server's own limits


def _status_of(s: socket.socket, wait_s: float = 15) -> int:
    s.settimeout(wait_s)
    return _read_status(s)


def test_a_huge_header_is_refused_431_after_its_first_chunks(svc):
    """Issue defect: one request with a 100 MB header cost 13 s of CPU on the event loop, keyless."""
    base, _, _ = svc
    host, port = base.removeprefix("http://").split(":")
    with socket.create_connection((host, int(port)), timeout=15) as s:
        s.sendall(b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Big: ")
        try:
            for _ in range(64):  # 4 MB of one header value at most; the server closes long before
                s.sendall(b"a" * 65536)
        except OSError:
            pass  # the server answered and closed while we were still sending
        assert _status_of(s) == 431
    assert httpx.get(f"{base}/healthz", timeout=30).status_code == 200


def test_too_many_header_fields_are_431(svc):
    base, _, _ = svc
    fields = b"".join(b"X-F%d: v\r\n" % i for i in range(300))
    status, headers, body = _raw(base, b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n" + fields + b"\r\n")
    assert status == 431 and headers["content-type"] == "application/problem+json"


def test_headers_sent_slowly_are_cut_at_the_header_deadline(svc):
    """Issue defect: a connection sending its headers slowly was still open after 125 s."""
    base, _, _ = svc
    host, port = base.removeprefix("http://").split(":")
    with socket.create_connection((host, int(port)), timeout=15) as s:
        s.sendall(b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: ")
        assert _status_of(s) == 408  # the fixture's 2 s header deadline; never the 15 s socket timeout


def test_a_keyless_upload_is_refused_before_its_body_is_sent(svc):
    """Issue defect: a keyless 19 MB upload was spooled to disk (and a 19 MB PUT parsed) before the 401."""
    base, _, _ = svc
    host, port = base.removeprefix("http://").split(":")
    for head in (
        b"POST /v1/locate HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: multipart/form-data; boundary=zz\r\n"
        b"Content-Length: 19000000\r\n\r\n",
        b"PUT /v1/doors/D-100 HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
        b"Content-Length: 19000000\r\n\r\n",
    ):
        with socket.create_connection((host, int(port)), timeout=15) as s:
            s.sendall(head)  # and not a byte of the body: the answer must come anyway
            assert _status_of(s) == 401


# ---------------------------------------------------------------------------------------------- failing closed


def test_an_open_service_closes_for_good_once_a_key_exists(tmp_path):
    """Issue defect: revoking the last key made keyless requests succeed again (an engineer's PUT as 'anonymous');
    an open service answered any Host (DNS rebinding). With --workers 1, SIGTERM left its metrics folder."""
    temp = tmp_path / "temp"
    temp.mkdir()
    base, proc, log = launch_serve(tmp_path, "--open", "--create-database", env={"TMPDIR": str(temp)})
    try:
        assert httpx.get(f"{base}/readyz", timeout=30).json()["access"] == "open"
        assert httpx.get(f"{base}/v1/doors", timeout=30).status_code == 200
        _problem(
            httpx.get(f"{base}/v1/doors", headers={"Host": "rebound.example"}, timeout=30), 400, "bad_host"
        )
        with RecipeStore(f"sqlite:///{tmp_path / 'recipes.db'}") as store:
            keys = KeyStore(store.engine)
            keys.create("only key", Role.engineer)
            for _ in range(100):  # the open service notices within its 2 s cache
                if httpx.get(f"{base}/v1/doors", timeout=30).status_code == 401:
                    break
                time.sleep(0.1)
            keys.revoke("only key")
        for _ in range(3):
            _problem(httpx.get(f"{base}/v1/doors", timeout=30), 401, "unauthorized")
            time.sleep(1.1)
        assert httpx.get(f"{base}/readyz", timeout=30).json()["access"] == "keys"
    finally:
        stop_serve(proc, log)
    assert proc.returncode == 0
    assert not list(temp.glob("doorloc-metrics-*"))


def test_a_missing_database_is_an_error_not_a_fresh_one(tmp_path):
    import subprocess
    import sys

    from .conftest import CELL_PATH, REPO

    env = {"PATH": "/usr/bin:/bin", "PYTHONPATH": str(REPO / "src")}
    url = f"sqlite:///{tmp_path / 'mistyped.db'}"
    cmd = [
        sys.executable,
        "-m",
        "doorloc",
        "serve",
        "--cell",
        str(CELL_PATH),
        "--database-url",
        url,
        "--open",
    ]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=env)
    assert p.returncode == 2, p.stderr
    assert "does not exist" in p.stderr and "Traceback" not in p.stderr
    assert not (tmp_path / "mistyped.db").exists()


def test_wrong_keys_from_one_client_are_limited(tight):
    """Issue defect: nothing bounded key guessing."""
    for _ in range(3):
        _problem(httpx.get(f"{tight}/v1/doors", headers={"X-API-Key": "dlk_000000000000_" + "A" * 43}), 401)
    r = httpx.get(f"{tight}/v1/doors", headers={"X-API-Key": "dlk_000000000000_" + "B" * 43}, timeout=30)
    _problem(r, 429, "too_many_failures")
    assert int(r.headers["retry-after"]) >= 1


# ---------------------------------------------------------------------------------------------- answers and recipes


def test_no_overlay_for_a_refused_image(svc, cell):
    """Issue defect: ?overlay=true was drawn for a refused 7.2 MB JPEG (a 97 MB answer)."""
    import numpy as np

    base, h, _ = svc
    w, hh = cell.camera.image_size
    black = png_bytes(np.zeros((hh, w), np.uint8))
    r = httpx.post(f"{base}/v1/locate?overlay=true", files=_img(black), headers=h[Role.operator], timeout=60)
    assert r.status_code == 200 and r.json()["ok"] is False
    assert r.json()["overlay_png"] is None


@pytest.mark.parametrize(
    ("change", "field", "bound"),
    [
        ({"hinges": [{"depth_mm": 35}]}, "depth_mm", "25 mm"),
        ({"feed_mm_s": 5000}, "feed_mm_s", "500 mm/s"),
        ({"spindle_rpm": 100000}, "spindle_rpm", "30000 rev/min"),
    ],
)
def test_recipes_beyond_the_tool_and_spindle_are_refused_naming_the_bound(
    svc, recipe_module, change, field, bound
):
    """Issue defect: a hinge 800 mm deep, 5000 mm/s and 100,000 rpm were stored and sent on to the robot."""
    base, h, _ = svc
    body = recipe_module.model_dump(mode="json")
    if "hinges" in change:
        body["hinges"] = [body["hinges"][0] | change["hinges"][0]]
    else:
        body |= change
    r = httpx.put(f"{base}/v1/doors/D-100", json=body, headers=h[Role.engineer], timeout=30)
    detail = _problem(r, 422)["detail"]
    assert field in detail and bound in detail, detail


# ---------------------------------------------------------------------------------------------- browsers


def test_security_headers_on_every_answer(svc):
    """Issue defect: no CSP, X-Frame-Options, nosniff."""
    base, h, _ = svc
    for r in (
        httpx.get(f"{base}/", timeout=30),
        httpx.get(f"{base}/docs", timeout=30),
        httpx.get(f"{base}/v1/doors", timeout=30),
        httpx.get(f"{base}/v1/doors", headers=h[Role.operator], timeout=30),
    ):
        assert "frame-ancestors 'none'" in r.headers["content-security-policy"]
        assert "script-src 'self'" in r.headers["content-security-policy"]
        assert r.headers["x-frame-options"] == "DENY" and r.headers["x-content-type-options"] == "nosniff"
        assert "strict-transport-security" not in r.headers  # plain HTTP here; HTTPS adds it


def test_the_api_docs_load_only_bundled_same_origin_files(svc):
    """Issue defect: /docs and /redoc loaded unpinned scripts from a public CDN on the service's origin."""
    import hashlib
    import re

    base, _, _ = svc
    page = httpx.get(f"{base}/docs", timeout=30).text
    refs = re.findall(r'(?:src|href)="([^"]+)"', page)
    assert refs and all(ref.startswith("/static/") for ref in refs), refs
    from .conftest import REPO

    recorded = (REPO / "src/doorloc/app/static/vendor/swagger-ui/VENDORED.md").read_text()
    for ref in refs:
        r = httpx.get(base + ref, timeout=30)
        assert r.status_code == 200, ref
        if "/vendor/" in ref:
            assert hashlib.sha256(r.content).hexdigest() in recorded, ref
    assert 'integrity="sha384-' in page
    assert httpx.get(f"{base}/redoc", timeout=30).status_code == 404


def test_forwarded_for_is_not_believed_without_configured_proxies(svc):
    """Issue defect: X-Forwarded-For was trusted from 127.0.0.1, so behind nginx any client set the logged address."""
    import json

    base, _, tmp = svc
    httpx.get(
        f"{base}/healthz", headers={"X-Forwarded-For": "203.0.113.9", "X-Request-ID": "xff-probe"}, timeout=30
    )
    port = base.rsplit(":", 1)[1]
    lines = []
    for _ in range(50):  # the log line is written as the answer goes out
        lines = [ln for ln in (tmp / f"serve-{port}.log").read_text().splitlines() if "xff-probe" in ln]
        if lines:
            break
        time.sleep(0.1)
    assert lines and json.loads(lines[0])["client"] == "127.0.0.1"
