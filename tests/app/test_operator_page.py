"""The operator page in headless Chromium (Debian's chromium, driven by Playwright): upload, see the pose.

Runs against a real uvicorn server on 127.0.0.1 with the real pipeline. Skipped where Chromium is not
installed, except in CI (DOORLOC_CI=1), where a missing browser is a failure.
"""

from __future__ import annotations

import os
import shutil
import socket
import threading
import time
from pathlib import Path

import cv2
import pytest

pytestmark = pytest.mark.browser

CHROMIUM = os.environ.get("DOORLOC_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]


def _require_chromium() -> None:
    have = Path(CHROMIUM).exists() or shutil.which(CHROMIUM)
    if have:
        return
    message = f"Chromium not found at {CHROMIUM} (apt-get install chromium, or set DOORLOC_CHROMIUM)"
    if os.environ.get("DOORLOC_CI") == "1":
        pytest.fail(message + "; CI must run the browser test")
    pytest.skip(message)


@pytest.fixture
def live_server(cell, store):
    """The app with the real pipeline, served by uvicorn on 127.0.0.1 in a thread; yields its base URL.
    Where no browser can run the tests, they skip before the service starts (its worker processes take
    seconds)."""
    _require_chromium()
    import uvicorn

    from doorloc.app.http import create_app

    from .conftest import dev_settings

    app = create_app(dev_settings(), cell=cell, store=store)
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.bind(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    server = uvicorn.Server(uvicorn.Config(app, log_level="warning", lifespan="on"))
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    # Its start-up loads locate's kernels in every worker process: seconds on a quiet machine, far more on a
    # busy CI runner, so this waits until the server either starts or its thread ends (a failed start-up);
    # the long bound only keeps a hung start from hanging the run.
    deadline = time.monotonic() + 600
    while not server.started and thread.is_alive() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert server.started, "the test server did not start"
    yield f"http://127.0.0.1:{port}"
    server.should_exit = True
    thread.join(timeout=10)
    sock.close()


def test_upload_shows_pose_overlay_and_targets_then_an_error_sentence(live_server, cell, tmp_path):
    from playwright.sync_api import sync_playwright

    from doorloc.pose import DoorPose
    from doorloc.sim.door import render_door

    truth = DoorPose(4.0, -3.0, 0.7)
    door_png = tmp_path / "door.png"
    door_png.write_bytes(
        cv2.imencode(".png", render_door(cell, cell.default_door, truth, seed=3).image)[1].tobytes()
    )
    notes = tmp_path / "notes.png"
    notes.write_text("this is not an image\n")

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS, headless=True)
        try:
            # wait_for_function evaluates strings, which the page's CSP forbids
            page = browser.new_page(bypass_csp=True)
            page.goto(live_server + "/")
            page.wait_for_function("document.getElementById('ready').textContent === 'ready'", timeout=20_000)

            page.fill("#door_id", "D-100")
            page.set_input_files("#image", str(door_png))
            page.wait_for_function(
                "document.getElementById('pose-x').textContent.trim() !== ''", timeout=60_000
            )
            assert float(page.text_content("#pose-x")) == pytest.approx(truth.x_mm, abs=0.05)
            assert float(page.text_content("#pose-z")) == pytest.approx(truth.z_mm, abs=0.05)
            assert float(page.text_content("#pose-yaw")) == pytest.approx(truth.yaw_deg, abs=0.02)
            assert page.text_content("#status") == "located"
            assert page.get_attribute("#overlay", "src").startswith("data:image/png;base64,")
            assert page.locator("#targets tbody tr").count() > 0
            assert page.locator("#quality tbody tr").count() > 0
            assert page.is_hidden("#error")

            page.set_input_files("#image", str(notes))
            page.wait_for_selector("#error:not([hidden])", timeout=20_000)
            assert "is not a PNG, JPEG, TIFF or BMP image" in page.text_content("#error")
        finally:
            browser.close()


def _dominant(answer: dict, key: str, index: int) -> str:
    """The term the page should name for one pose value (the rule it states, computed from the JSON)."""
    d = answer["diagnostics"]
    if d.get("uncertainty_budget") is not None:
        parts = {t["source"]: t[key] for t in d["uncertainty_budget"]}
    else:
        parts = {name: t[index] for name, t in d["uncertainty_terms"].items()}
    return max(parts, key=lambda k: parts[k]).replace("_", " ")


def test_pose_values_show_their_one_sigma_and_the_dominant_uncertainty_term(live_server, cell, tmp_path):
    import numpy as np
    from playwright.sync_api import sync_playwright

    from doorloc.pose import DoorPose
    from doorloc.sim.door import render_door

    door_png = tmp_path / "door.png"
    rendered = render_door(cell, cell.default_door, DoorPose(-2.0, 5.0, -0.4), seed=11).image
    door_png.write_bytes(cv2.imencode(".png", rendered)[1].tobytes())
    # a budget whose largest entry differs per pose value, so the page must pick per value, by name
    budget = [
        {"source": "calibration", "x_mm": 0.004, "z_mm": 0.001, "yaw_deg": 0.0001, "thickness_mm": 0.002},
        {"source": "edge_noise", "x_mm": 0.001, "z_mm": 0.003, "yaw_deg": 0.0002, "thickness_mm": 0.001},
        {"source": "jpeg_tilt", "x_mm": 0.0005, "z_mm": 0.0005, "yaw_deg": 0.0009, "thickness_mm": 0.0},
        {"source": "far_face", "x_mm": 0.0, "z_mm": 0.0, "yaw_deg": 0.0, "thickness_mm": 0.006},
    ]

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS, headless=True)
        try:
            page = browser.new_page(bypass_csp=True)  # as above: wait_for_function evaluates strings
            page.goto(live_server + "/")
            page.wait_for_function("document.getElementById('ready').textContent === 'ready'", timeout=20_000)
            page.fill("#door_id", "D-100")

            # 1. the answer as the service gives it
            with page.expect_response(lambda r: "/v1/locate" in r.url) as got:
                page.set_input_files("#image", str(door_png))
            answer = got.value.json()
            assert answer["ok"], answer["error"]
            page.wait_for_function("document.getElementById('sigma-x').textContent.startsWith('±')")
            for row, key, index in (("x", "x_mm", 0), ("z", "z_mm", 1), ("yaw", "yaw_deg", 2)):
                shown = page.text_content(f"#sigma-{row}")
                assert float(shown.removeprefix("± ")) == pytest.approx(answer["uncertainty"][key], rel=0.05)
                assert page.text_content(f"#dominant-{row}") == _dominant(answer, key, index)
            sigma_t = answer["diagnostics"]["thickness_check"]["sigma_mm"]
            assert float(page.text_content("#sigma-thickness").removeprefix("± ")) == pytest.approx(
                sigma_t, rel=0.05
            )
            if "uncertainty_budget" not in answer["diagnostics"]:  # the named terms have no thickness part
                assert page.text_content("#dominant-thickness") == ""

            # 2. the same answer with a budget: each value names its own largest term
            budgeted = {**answer, "diagnostics": {**answer["diagnostics"], "uncertainty_budget": budget}}
            page.route("**/v1/locate*", lambda route: route.fulfill(json=budgeted))
            page.set_input_files("#image", [])
            page.set_input_files("#image", str(door_png))
            page.wait_for_function("document.getElementById('dominant-x').textContent === 'calibration'")
            assert page.text_content("#dominant-z") == "edge noise"
            assert page.text_content("#dominant-yaw") == "jpeg tilt"
            assert page.text_content("#dominant-thickness") == "far face"

            # 3. a refusal shows no sigma and names no term
            page.unroute("**/v1/locate*")
            black = tmp_path / "black.png"
            width, height = cell.camera.image_size
            black.write_bytes(cv2.imencode(".png", np.zeros((height, width), np.uint8))[1].tobytes())
            page.set_input_files("#image", str(black))
            page.wait_for_function("document.getElementById('status').textContent === 'refused'")
            assert page.text_content("#sigma-x") == "—"
            assert page.text_content("#dominant-x") == ""
        finally:
            browser.close()


def test_api_docs_render_with_the_network_cut_and_the_key_stays_in_the_tab(live_server):
    """/docs runs from the bundled Swagger UI: every request to another origin is refused here, and the page
    still renders the API. The operator page keeps a key in sessionStorage (this tab), never localStorage."""
    from playwright.sync_api import sync_playwright

    foreign: list[str] = []

    def only_this_origin(route):
        if route.request.url.startswith(live_server):
            route.continue_()
        else:
            foreign.append(route.request.url)
            route.abort()

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS, headless=True)
        try:
            page = browser.new_page()
            page.route("**/*", only_this_origin)
            violations: list[str] = []
            page.on(
                "console",
                lambda m: violations.append(m.text) if "Content Security Policy" in m.text else None,
            )
            page.goto(live_server + "/docs")
            page.wait_for_selector(".swagger-ui .info .title", timeout=30_000)
            assert "doorloc" in page.text_content(".swagger-ui .info .title")
            page.wait_for_selector(".opblock-summary-path", timeout=30_000)
            assert "/v1/locate" in page.locator(".opblock-summary-path").all_text_contents()
            assert foreign == [] and violations == [], (foreign, violations)

            page.goto(live_server + "/")
            page.click("summary")  # the key field is folded away
            page.fill("#api_key", "dlk_example_key")
            page.evaluate("apiHeaders()")
            assert page.evaluate("sessionStorage.getItem('doorloc.api_key')") == "dlk_example_key"
            assert page.evaluate("localStorage.getItem('doorloc.api_key')") is None
        finally:
            browser.close()
