"""One limited worker process per request decodes the upload and locates in it (the real pipeline): the answer
is the one the service gives when it decodes and locates in its own threads, and a decoding bomb is still
refused as a decode. A progressive JPEG or a TIFF is decoded in a decoding-only process first (its header bounds
its decoding work only loosely), so such a bomb never ends a worker holding locate's kernels."""

from __future__ import annotations

import pytest

from doorloc.pose import DoorPose
from doorloc.sim.door import render_door
from doorloc.sim.hostile import progressive_jpeg_bomb

from .conftest import app_clients, png_bytes, post_locate, server_timing

#: what differs between two locates of the same image: the time they took
TIMINGS = {"elapsed_ms"}


@pytest.fixture
def real_client(cell, store):
    """``real_client(**settings)``: a TestClient on an app with the real locate (lifespan run)."""
    yield from app_clients(cell, store)


def _without_timings(answer: dict) -> dict:
    """The answer less its timings: ``elapsed_ms``, the diagnostics' ``timing_ms``, and the overlay (compared
    by :func:`_same_overlay`: it prints ``elapsed_ms``)."""
    out = {k: v for k, v in answer.items() if k not in TIMINGS and k != "overlay_png"}
    if out.get("diagnostics"):
        out["diagnostics"] = {k: v for k, v in out["diagnostics"].items() if k != "timing_ms"}
    return out


def _same_overlay(a: str | None, b: str | None) -> None:
    """The same overlay but for the one printed time: the differing pixels fit in one number's box."""
    import base64

    import cv2
    import numpy as np

    assert (a is None) == (b is None)
    if a is None or b is None:
        return
    ia, ib = (
        cv2.imdecode(np.frombuffer(base64.b64decode(x), np.uint8), cv2.IMREAD_UNCHANGED) for x in (a, b)
    )
    assert ia.shape == ib.shape
    differ = np.argwhere((ia != ib).reshape(ia.shape[0], ia.shape[1], -1).any(axis=2))
    if len(differ):
        rows, cols = differ.max(axis=0) - differ.min(axis=0) + 1
        assert rows <= 24 and cols <= 160, (rows, cols)  # "123.4 ms" in the overlay's text box


@pytest.mark.parametrize("seed", [7, 11])
def test_one_job_answers_as_the_threads_do(real_client, cell, recipe, seed):
    import numpy as np

    rng = np.random.default_rng(seed)
    truth = DoorPose(float(rng.uniform(-8, 8)), float(rng.uniform(-8, 8)), float(rng.uniform(-1.5, 1.5)))
    print(f"seed {seed}: {truth}")
    import cv2

    rendered = render_door(cell, recipe.door_size(), truth, seed=seed).image
    door = png_bytes(rendered)
    progressive = cv2.imencode(
        ".jpg", rendered, [cv2.IMWRITE_JPEG_QUALITY, 98, cv2.IMWRITE_JPEG_PROGRESSIVE, 1]
    )[1].tobytes()
    black = png_bytes(np.zeros((1080, 1920), np.uint8))
    workers = real_client(locate_concurrency=1)
    threads = real_client(decode_in_threads=True)
    state = workers.app.state.service
    assert (
        state.locates_in_workers
        and state.workers is not None
        and not threads.app.state.service.locates_in_workers
    )
    for png, query in ((door, "?overlay=true&rapid=true"), (black, "?overlay=true"), (door, "")):
        assert state.decoders is not None and not state.decoders._workers  # one job: no decoding-only process
        answers, cost_ms = [], []
        for c in (workers, threads):
            r = c.post(
                f"/v1/locate{query}", files={"image": ("d.png", png, "image/png")}, data={"door_id": "D-100"}
            )
            assert r.status_code == 200, r.text
            timings = server_timing(r.headers["server-timing"])
            assert set(timings) == {"decode", "locate"}
            cost_ms.append(sum(float(m["dur"]) for m in timings.values()))
            answers.append(r.json())
        assert _without_timings(answers[0]) == _without_timings(answers[1]), query
        if png is door and not query:
            # what the image cost counts the worker process's CPU too: the request's own thread only hands
            # the bytes over and waits (its share alone was about a twentieth of the threads' figure)
            assert cost_ms[0] > 0.3 * cost_ms[1], cost_ms
        _same_overlay(answers[0].get("overlay_png"), answers[1].get("overlay_png"))
        # drawn (by the worker) when asked for, for the located door only
        drawn = isinstance(answers[0]["overlay_png"], str)
        assert drawn == ("overlay" in query and png is door), answers[0]["ok"]
    located = answers[0]
    assert located["ok"] and abs(located["x_mm"] - truth.x_mm) < 0.1 and located["targets"]
    assert located["diagnostics"]["jpeg_quality"] is None
    # a progressive JPEG: decoded in a decoding-only process, then located by the worker, as in the threads
    answers = []
    for c in (workers, threads):
        answers.append(post_locate(c, progressive, "d.jpg", "?overlay=true", door_id="D-100"))
    assert _without_timings(answers[0]) == _without_timings(answers[1])
    _same_overlay(answers[0]["overlay_png"], answers[1]["overlay_png"])
    assert answers[0]["ok"] and len(state.decoders._workers) == 1
    assert answers[0]["diagnostics"]["jpeg_quality"] == 98  # read from the file, told to the worker
    assert state.workers.killed == 0 and state.decoders.killed == 0


def test_a_decoding_bomb_is_refused_with_the_decode_wording_and_the_locating_worker_kept(
    real_client, cell, recipe
):
    """A progressive JPEG bomb (scan limit lifted) ends a decoding-only process: 422 decode_limit, the locating
    worker keeps its kernels and locates the next image at once. (The one-job path with a bomb in it:
    tests/app/test_decodepool.py.)"""
    workers = real_client(locate_concurrency=1, decode_cpu_s=1, max_jpeg_scans=100_000)
    state = workers.app.state.service
    before = [w.process.pid for w in state.workers._workers]
    r = workers.post("/v1/locate", files={"image": ("b.jpg", progressive_jpeg_bomb(40_000), "image/jpeg")})
    body = r.json()
    assert (r.status_code, body["code"]) == (422, "decode_limit"), body
    assert body["detail"].startswith("Decoding the image took more than 1 s of CPU time"), body
    assert state.decoders.killed == 1 and state.workers.killed == 0
    door = png_bytes(render_door(cell, recipe.door_size(), DoorPose(1.0, -2.0, 0.3), seed=5).image)
    r = workers.post("/v1/locate", files={"image": ("d.png", door, "image/png")}, data={"door_id": "D-100"})
    assert r.status_code == 200 and r.json()["ok"], r.text
    assert [w.process.pid for w in state.workers._workers] == before  # the same worker located it
