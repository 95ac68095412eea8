"""Shared by the service benchmarks: a real `doorloc serve` on 127.0.0.1, its memory, rendered 1080p PNGs."""

from __future__ import annotations

import contextlib
import functools
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import httpx

REPO = Path(__file__).resolve().parents[1]
CELL = REPO / "fixtures" / "cell_thesis.yaml"

#: the door recipe the service benchmarks store and locate against
RECIPE = {
    "door_id": "BENCH-1",
    "width_mm": 900,
    "height_mm": 2100,
    "thickness_mm": 50,
    "arris_mm": 0,
    "hinges": [
        {"z_mm": 250, "length_mm": 100, "width_mm": 30, "x_mm": 10, "depth_mm": 3, "corner_radius_mm": 8}
    ],
    "tool_diameter_mm": 16,
    "spindle_rpm": 18000,
    "feed_mm_s": 25,
}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def process_tree(pid: int) -> list[int]:
    """A process and all its live descendants (pids, the process first), from Linux's /proc."""
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        for task in Path(f"/proc/{p}/task").glob("*"):
            try:
                todo += [int(x) for x in (task / "children").read_text().split()]
            except OSError:
                pass
    return out


def affinity_of_tree(pid: int) -> dict[int, list[int]]:
    """The CPUs each process of a process tree may run on (pid -> sorted CPU numbers), from Linux."""
    out = {}
    for p in process_tree(pid):
        with contextlib.suppress(OSError):
            out[p] = sorted(os.sched_getaffinity(p))
    return out


def rss_mb(pid: int) -> float:
    """Resident memory of a process and all its descendants, MB (from /proc)."""
    total_kb = 0
    for p in process_tree(pid):
        with contextlib.suppress(OSError):
            for line in Path(f"/proc/{p}/status").read_text().splitlines():
                if line.startswith("VmRSS:"):
                    total_kb += int(line.split()[1])
    return total_kb / 1024


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process and all its live descendants, s (from /proc/PID/stat).

    Read before and after a load run, its difference is the CPU the server spent on the run, whatever
    else the machine did meanwhile (the load clients run on the same machine).
    """
    tick = os.sysconf("SC_CLK_TCK")
    total = 0
    for p in process_tree(pid):
        try:
            # the fields after the command name, which is in parentheses and may itself hold spaces
            fields = Path(f"/proc/{p}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        total += int(fields[11]) + int(fields[12])  # utime, stime (fields 14 and 15 of stat)
    return total / tick


@contextlib.contextmanager
def doorloc_serve(
    workers: int = 1,
    extra_env: dict[str, str] | None = None,
    keys: dict[str, str] | None = None,
    cpus: set[int] | None = None,
) -> Iterator[tuple[str, int]]:
    """Start `doorloc serve` on 127.0.0.1; yield (base URL, server pid) once /readyz answers 200.

    Without ``keys`` the service is open (``--open``, loopback). With ``keys`` (names -> role), each key is
    created first and the service demands keys; the dict's values are replaced by the keys' secrets.
    ``cpus``: the CPUs the service and every process it starts may run on (Linux affinity, set before it
    starts, so its workers inherit it); None: those of this process.
    """
    port = free_port()
    with tempfile.TemporaryDirectory() as tmp:
        url = f"sqlite:///{tmp}/recipes.db"
        env = {**os.environ, "DOORLOC_DATABASE_URL": url, **(extra_env or {})}
        access = ["--open", "--create-database"]
        if keys:
            from doorloc.app.access import KeyStore
            from doorloc.recipes.store import RecipeStore

            with RecipeStore(url) as store:
                made = KeyStore(store.engine)
                for name, role in list(keys.items()):
                    keys[name] = made.create(name, role).secret
            access = []
        log = open(Path(tmp) / "serve.log", "w")  # noqa: SIM115 - closed below
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "doorloc",
                "serve",
                "--cell",
                str(CELL),
                "--host",
                "127.0.0.1",
                "--port",
                str(port),
                "--workers",
                str(workers),
                "--log-level",
                "warning",
                *access,
            ],
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
            cwd=REPO,
            preexec_fn=None if cpus is None else functools.partial(os.sched_setaffinity, 0, cpus),
        )
        base = f"http://127.0.0.1:{port}"
        try:
            deadline = time.monotonic() + 120
            while True:
                if proc.poll() is not None:
                    raise RuntimeError(f"doorloc serve exited: {(Path(tmp) / 'serve.log').read_text()}")
                try:
                    if httpx.get(base + "/readyz", timeout=2).status_code == 200:
                        break
                except httpx.TransportError:
                    pass
                if time.monotonic() > deadline:
                    raise RuntimeError("doorloc serve did not become ready in 120 s")
                time.sleep(0.2)
            yield base, proc.pid
        finally:
            os.killpg(proc.pid, signal.SIGTERM)
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
            log.close()


def rendered_pngs(
    n: int, seed0: int = 0, jpeg_quality: int | None = None
) -> list[tuple[bytes, tuple[float, float, float]]]:
    """``n`` 1920x1080 PNGs of the nominal door at poses spread over the envelope, with their true poses;
    JPEGs of that quality where ``jpeg_quality`` is given."""
    import cv2
    import numpy as np

    from doorloc.cell import load_cell
    from doorloc.pose import DoorPose
    from doorloc.sim.door import render_door
    from doorloc.sim.effects import Effects

    # sensor noise, wood grain and a little blur: PNGs of the size a real camera's are (~1-2 MB), not ~10 kB
    effects = Effects(
        grain_contrast=0.08, blur_sigma_px=0.6, full_well_e=20000.0, read_noise_dn=1.5, vignetting=0.1
    )
    cell = load_cell(CELL)
    rng = np.random.default_rng(seed0)
    out = []
    for i in range(n):
        pose = DoorPose(float(rng.uniform(-9, 9)), float(rng.uniform(-9, 9)), float(rng.uniform(-1.8, 1.8)))
        img = render_door(cell, cell.default_door, pose, effects=effects, seed=seed0 + i).image
        encoded = (
            cv2.imencode(".png", img)
            if jpeg_quality is None
            else cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, jpeg_quality])
        )[1].tobytes()
        out.append((encoded, (pose.x_mm, pose.z_mm, pose.yaw_deg)))
    return out
