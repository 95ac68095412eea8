"""`doorloc serve` as a real process on 127.0.0.1: starts, becomes ready, answers, stops on SIGTERM."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import cv2
import httpx
import pytest

from doorloc.pose import DoorPose
from doorloc.sim.door import render_door

CELL_FILE = str(Path(__file__).resolve().parents[2] / "fixtures" / "cell_thesis.yaml")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_serve_with_two_workers_answers_and_stops(cell, tmp_path):
    port = _free_port()
    env = {**os.environ, "DOORLOC_DATABASE_URL": f"sqlite:///{tmp_path / 'recipes.db'}"}
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "doorloc",
            "serve",
            "--cell",
            CELL_FILE,
            "--host",
            "127.0.0.1",
            "--port",
            str(port),
            "--workers",
            "2",
            "--open",
            "--create-database",
        ],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 90
        ready = None
        while time.monotonic() < deadline and proc.poll() is None:
            try:
                ready = httpx.get(base + "/readyz", timeout=2)
                if ready.status_code == 200:
                    break
            except httpx.TransportError:
                pass
            time.sleep(0.2)
        assert ready is not None and ready.status_code == 200, "the service did not become ready"
        truth = DoorPose(-2.0, 6.0, -0.4)
        png = cv2.imencode(".png", render_door(cell, cell.default_door, truth, seed=5).image)[1].tobytes()
        r = httpx.post(base + "/v1/locate", files={"image": ("door.png", png, "image/png")}, timeout=60)
        assert r.status_code == 200, r.text
        assert r.json()["x_mm"] == pytest.approx(truth.x_mm, abs=0.05)
        assert r.headers["x-request-id"]
    finally:
        os.killpg(proc.pid, signal.SIGTERM)
        out, _ = proc.communicate(timeout=30)
    assert proc.returncode == 0, out
    # structured request log: one JSON line per request, with its id
    assert '"event": "request"' in out and '"route": "/v1/locate"' in out
    # uvicorn's own lines (start-up, shut-down) in the same JSON form, not its plain "INFO:     ..." text
    assert '"logger": "uvicorn.error"' in out
    assert not [line for line in out.splitlines() if line.startswith(("INFO:", "WARNING:", "ERROR:"))], out


def test_serve_refuses_a_broken_cell_file_with_a_sentence(tmp_path):
    bad = tmp_path / "cell.yaml"
    bad.write_text("camera: [1, 2\n")
    p = subprocess.run(
        [sys.executable, "-m", "doorloc", "serve", "--cell", str(bad)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert p.returncode == 2
    assert "not valid YAML" in p.stderr and "Traceback" not in p.stderr


def test_workers_share_the_cpus_for_locating_unless_told(monkeypatch):
    from doorloc.app.settings import ServiceSettings, default_locate_concurrency

    assert default_locate_concurrency(1, cpus=8) == 8
    assert default_locate_concurrency(2, cpus=8) == 4
    assert default_locate_concurrency(3, cpus=2) == 1  # never none
    monkeypatch.delenv("DOORLOC_LOCATE_CONCURRENCY", raising=False)
    assert ServiceSettings().locate_concurrency == default_locate_concurrency(1)
    monkeypatch.setenv("DOORLOC_LOCATE_CONCURRENCY", "3")  # what `doorloc serve` sets, unless given
    assert ServiceSettings().locate_concurrency == 3


def test_the_default_cpu_slots_are_the_cpus_the_service_may_run_on(monkeypatch):
    """A service pinned to some CPUs (taskset, a container's CPU set) counts those, not the machine's."""
    import os

    from doorloc.app.settings import default_locate_concurrency

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {3, 5, 6}, raising=False)
    monkeypatch.setattr(os, "cpu_count", lambda: 64)
    assert default_locate_concurrency(1) == 3
    assert default_locate_concurrency(2) == 1
