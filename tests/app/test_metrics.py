"""Internal errors are counted apart from refusals; process figures are exported."""

from __future__ import annotations

import numpy as np
from fastapi.testclient import TestClient

from doorloc.app.http import create_app
from doorloc.vision.result import LocateResult

from .conftest import dev_settings, png_bytes


def _buggy_locate(image, cell, door, *, image_name="", config=None, trace=None, jpeg_quality=0):
    return LocateResult.refusal(image_name, "internal_error", "locate failed (ValueError); report incident 1")


def test_internal_errors_are_not_refusals(cell, store):
    """Issue defect: internal errors were counted as refusals."""
    app = create_app(dev_settings(), cell=cell, store=store, locate_fn=_buggy_locate)
    with TestClient(app) as c:
        r = c.post(
            "/v1/locate", files={"image": ("a.png", png_bytes(np.full((8, 8), 9, np.uint8)), "image/png")}
        )
        assert r.status_code == 200 and r.json()["error_code"] == "internal_error"
        text = c.get("/metrics").text
    assert 'doorloc_internal_errors_total{where="locate"} 1.0' in text
    assert 'doorloc_locate_results_total{outcome="internal_error"} 1.0' in text
    assert 'doorloc_locate_refusals_total{reason="internal_error"}' not in text
    assert "doorloc_worker_resident_memory_bytes" in text and "doorloc_worker_cpu_seconds" in text


def test_readyz_says_overloaded_while_the_queue_is_full(client):
    state = client.app.state.service
    assert client.get("/readyz").status_code == 200
    state.admitted = state.capacity
    try:
        r = client.get("/readyz")
        assert r.status_code == 503 and r.json()["code"] == "overloaded" and r.headers["retry-after"]
        r = client.post(
            "/v1/locate", files={"image": ("a.png", png_bytes(np.full((8, 8), 9, np.uint8)), "image/png")}
        )
        assert r.status_code == 503 and r.json()["code"] == "overloaded" and int(r.headers["retry-after"]) > 0
    finally:
        state.admitted = 0
    assert client.get("/readyz").status_code == 200
