"""Fixtures of the app tests: the thesis cell, a stand-in locate, a recipe, an app wired to them."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import cv2
import numpy as np
import pytest
from fastapi.testclient import TestClient

from doorloc.app.http import create_app
from doorloc.app.settings import ServiceSettings
from doorloc.cell import load_cell
from doorloc.recipes.models import DoorRecipe, Hinge
from doorloc.recipes.store import RecipeStore
from doorloc.vision.result import LocateResult

REPO = Path(__file__).resolve().parents[2]
CELL_PATH = REPO / "fixtures" / "cell_thesis.yaml"


def stand_in_locate(image, cell, door, *, image_name="", config=None, trace=None, jpeg_quality=0):
    """A locate that answers at once: a fixed pose, or a refusal for an all-black image."""
    if int(np.max(image)) == 0:
        return LocateResult.refusal(
            image_name, "no_door", "No door edge found in the image; check the lighting."
        )
    return LocateResult(
        image=image_name,
        ok=True,
        x_mm=1.25,
        z_mm=-2.5,
        yaw_deg=0.3,
        thickness_mm=door.thickness_mm,
        scale_mm_per_px=0.206,
        corner_px=[802.0, 708.0],
        elapsed_ms=1.0,
    )


def dev_settings(**settings) -> ServiceSettings:
    """Settings of an in-process test app: open access (no key needed while none exists) and the test
    clients' host names, unless ``settings`` say otherwise."""
    return ServiceSettings(
        **{"open_access": True, "allowed_hosts": ["testserver", "test", "127.0.0.1"], **settings}
    )


def post_locate(client, image: bytes, name: str, query: str = "", **form: str) -> dict:
    """POST ``image`` (named ``name``; its type from the suffix) to ``/v1/locate{query}`` with the form fields,
    assert HTTP 200 and return the answer."""
    mime = "image/jpeg" if name.endswith((".jpg", ".jpeg")) else "image/png"
    r = client.post(f"/v1/locate{query}", files={"image": (name, image, mime)}, data=form)
    assert r.status_code == 200, r.text
    return r.json()


def server_timing(header: str) -> dict[str, dict[str, str]]:
    """A ``Server-Timing`` header's metrics: ``{name: {"dur": ..., "desc": ...}}`` (the parameters as sent)."""
    metrics = {}
    for part in header.split(","):
        name, *params = (p.strip() for p in part.split(";"))
        metrics[name] = dict(p.split("=", 1) for p in params)
    return metrics


def png_bytes(image: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", image)
    assert ok
    return buf.tobytes()


@pytest.fixture(scope="session")
def cell():
    return load_cell(CELL_PATH)


@pytest.fixture
def recipe() -> DoorRecipe:
    return door_d100()


def door_d100() -> DoorRecipe:
    """The app tests' door D-100: 900 x 2100 x 50 mm, two hinges."""
    return DoorRecipe(
        door_id="D-100",
        width_mm=900,
        height_mm=2100,
        thickness_mm=50,
        hinges=[
            Hinge(z_mm=250, length_mm=100, width_mm=30, x_mm=10, depth_mm=3, corner_radius_mm=8),
            Hinge(z_mm=1700, length_mm=100, width_mm=30, x_mm=10, depth_mm=3, corner_radius_mm=8),
        ],
        tool_diameter_mm=16,
        spindle_rpm=18000,
        feed_mm_s=25,
    )


@pytest.fixture
def store(recipe):
    yield from recipe_store(recipe)


def recipe_store(recipe: DoorRecipe):
    """A fixture's body: yields an in-memory recipe store holding ``recipe``, closed when the fixture ends."""
    s = RecipeStore("sqlite://")
    s.put(recipe)
    yield s
    s.close()


@pytest.fixture
def make_client(cell, store):
    """``make_client(**settings)``: a TestClient on an app with the stand-in locate (lifespan run).

    Open access (no key needed while none exists) and the TestClient's host name unless the settings say
    otherwise."""
    yield from app_clients(cell, store, stand_in_locate)


def app_clients(cell, store, locate_fn=None):
    """A fixture's body: yields ``make(**settings)``, which makes a TestClient on an app with ``locate_fn``
    (None: the real pipeline, in the service's worker processes unless the settings say threads), lifespan
    run; every client made is closed when the fixture ends."""
    clients = []

    def make(**settings) -> TestClient:
        app = create_app(dev_settings(**settings), cell=cell, store=store, locate_fn=locate_fn)
        c = TestClient(app, raise_server_exceptions=False)
        c.__enter__()
        clients.append(c)
        return c

    yield make
    for c in clients:
        c.__exit__(None, None, None)


@pytest.fixture
def client(make_client) -> TestClient:
    return make_client()


@pytest.fixture(scope="session")
def small_png() -> bytes:
    img = np.full((48, 64), 128, np.uint8)
    img[20:, 30:] = 200
    return png_bytes(img)


@pytest.fixture(scope="session")
def encode_png():
    return png_bytes


# ---------------------------------------------------------------------------------------------- real processes


def free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def launch_serve(tmp, *args: str, env: dict[str, str] | None = None, scheme: str = "http", verify=None):
    """A real ``doorloc serve`` on 127.0.0.1 (database in ``tmp``), ready; ``(base_url, process, log file)``."""
    import os
    import subprocess
    import sys
    import time

    import httpx

    port = free_port()
    full_env = {**os.environ, "DOORLOC_DATABASE_URL": f"sqlite:///{tmp / 'recipes.db'}", **(env or {})}
    full_env["PYTHONPATH"] = str(REPO / "src") + os.pathsep + full_env.get("PYTHONPATH", "")
    log = open(tmp / f"serve-{port}.log", "w")  # noqa: SIM115 - closed by stop_serve
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "doorloc",
            "serve",
            "--cell",
            str(CELL_PATH),
            "--host",
            "127.0.0.1",
            "--port",
            str(port),
            *args,
        ],
        env=full_env,
        stdout=log,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    base = f"{scheme}://127.0.0.1:{port}"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        try:
            if (
                httpx.get(
                    base + "/readyz", timeout=2, verify=verify if verify is not None else True
                ).status_code
                == 200
            ):
                return base, proc, log
        except httpx.TransportError:
            pass
        time.sleep(0.2)
    stop_serve(proc, log)
    raise AssertionError(
        f"doorloc serve did not become ready: {(tmp / f'serve-{port}.log').read_text()[-3000:]}"
    )


def stop_serve(proc, log) -> None:
    import os
    import signal
    import subprocess

    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=30)
    log.close()


@pytest.fixture
def start_serve():
    """``start_serve(tmp_path, *args, env=..., scheme="http", verify=None)``: a real ``doorloc serve`` on
    127.0.0.1, ready; returns ``(base_url, process)``; stopped afterwards."""
    started = []

    def start(tmp, *args: str, env: dict[str, str] | None = None, scheme: str = "http", verify=None):
        base, proc, log = launch_serve(tmp, *args, env=env, scheme=scheme, verify=verify)
        started.append((proc, log))
        return base, proc

    yield start
    for proc, log in started:
        stop_serve(proc, log)


@pytest.fixture
def refusal_waits(monkeypatch) -> list[float]:
    """The waits before refusals (``admission.hold_refusal``), recorded instead of slept: the admission
    module alone sees this anyio, so the service's own loops keep sleeping for real."""
    import doorloc.app.http.admission as admission

    waits: list[float] = []

    async def no_sleep(s: float) -> None:
        waits.append(s)

    monkeypatch.setattr(
        admission, "anyio", SimpleNamespace(sleep=no_sleep, fail_after=admission.anyio.fail_after)
    )
    return waits
