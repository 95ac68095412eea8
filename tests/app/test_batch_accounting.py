"""Batch accounts for every file: special, empty, unreadable, huge and non-image files get a record with
the reason; workers die with the batch process; --resume refuses a results file made with another model."""

from __future__ import annotations

import json
import os
import signal
import struct
import subprocess
import sys
import time
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from doorloc.app.answer import DoorChoice
from doorloc.app.batch import (
    BatchItem,
    FileLimits,
    claims_an_image,
    locate_item,
    plan_batch,
    plan_folder,
    read_file_checked,
)
from doorloc.cell import load_cell

from .conftest import CELL_PATH, stand_in_locate

DOORLOC = [sys.executable, "-m", "doorloc"]


def _png_header_only(w: int, h: int, depth: int = 8, colour: int = 0) -> bytes:
    """A PNG whose IHDR declares w x h but holds no pixel data: decoding it would allocate the whole image."""
    ihdr = struct.pack(">IIBBBBB", w, h, depth, colour, 0, 0, 0)
    chunk = struct.pack(">I", 13) + b"IHDR" + ihdr + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr))
    idat = zlib.compress(b"\x00" * 1000)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk
        + struct.pack(">I", len(idat))
        + b"IDAT"
        + idat
        + struct.pack(">I", zlib.crc32(b"IDAT" + idat))
        + struct.pack(">I", 0)
        + b"IEND"
        + struct.pack(">I", zlib.crc32(b"IEND"))
    )


@pytest.fixture
def odd_folder(tmp_path):
    root = tmp_path / "in"
    root.mkdir()
    (root / "good.png").write_bytes(cv2.imencode(".png", np.full((48, 64), 120, np.uint8))[1].tobytes())
    (root / "empty.png").write_bytes(b"")
    (root / "notes.txt").write_text("hello\n")
    (root / "huge.png").write_bytes(_png_header_only(30000, 30000))  # 900 MP
    (root / "bomb16.png").write_bytes(_png_header_only(7000, 7000, 16, 6))  # 49 MP but 392 MB decoded
    os.mkfifo(root / "pipe.png")
    (root / "dangling.png").symlink_to(root / "nowhere.png")
    return root


def test_every_file_gets_a_record_with_its_reason(odd_folder, cell):
    items = plan_batch(odd_folder, cell)
    assert plan_folder(odd_folder, cell)[1] == ["notes.txt"]  # neither is nor claims to be an image: skipped
    assert {it.image for it in items} == {
        "good.png",
        "empty.png",
        "huge.png",
        "bomb16.png",
        "pipe.png",
        "dangling.png",
    }
    recs = {it.image: locate_item(it, cell, stand_in_locate) for it in items}
    codes = {k: (r["status"], r["error_code"]) for k, r in recs.items()}
    assert codes == {
        "good.png": ("answered", None),
        "empty.png": ("failed", "empty_file"),
        "huge.png": ("failed", "too_large"),
        "bomb16.png": ("failed", "too_large"),
        "pipe.png": ("failed", "not_a_regular_file"),
        "dangling.png": ("failed", "unreadable"),
    }
    assert "392 MB decoded" in recs["bomb16.png"]["error"]
    assert all(r["provenance"]["cell_sha256"] == cell.sha256 for r in recs.values())


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads files whatever their mode")
def test_an_unreadable_file_is_a_failed_record(tmp_path):
    p = tmp_path / "secret.png"
    p.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\x00" * 100)
    p.chmod(0)
    data, code, why = read_file_checked(str(p), FileLimits())
    assert data is None and code == "unreadable" and "ermission" in why


def test_batch_cli_does_not_hang_on_a_fifo_and_counts_every_file(odd_folder, tmp_path):
    out = tmp_path / "r.jsonl"
    p = subprocess.run(
        [*DOORLOC, "batch", str(odd_folder), "--cell", str(CELL_PATH), "--out", str(out), "--workers", "1"],
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert p.returncode == 1, p.stderr
    recs = [json.loads(x) for x in out.read_text().splitlines()]
    assert len(recs) == 6
    assert "6 images:" in p.stderr and "5 failed" in p.stderr and "not_a_regular_file: 1" in p.stderr
    assert "empty_file: 1" in p.stderr and "too_large: 2" in p.stderr
    assert "skipped 1 file that is not an image (notes.txt)" in p.stderr


def test_a_folder_of_no_images_skips_them_with_a_count_and_exits_0(tmp_path):
    """A cell folder beside the images (cell.yaml, truth.csv, notes) is not a folder of failures."""
    root = tmp_path / "in"
    root.mkdir()
    (root / "cell.yaml").write_text("camera: {}\n")
    (root / "truth.csv").write_text("image,x_mm\n")
    (root / "notes.md").write_text("# notes\n")
    (root / "renamed.dat").write_bytes(cv2.imencode(".png", np.full((8, 8), 9, np.uint8))[1].tobytes())
    assert [n for n in plan_folder(root, load_cell(CELL_PATH))[1]] == ["cell.yaml", "notes.md", "truth.csv"]
    assert claims_an_image(root / "renamed.dat") and not claims_an_image(root / "notes.md")
    (root / "renamed.dat").unlink()
    out = tmp_path / "r.jsonl"
    p = subprocess.run(
        [*DOORLOC, "batch", str(root), "--cell", str(CELL_PATH), "--out", str(out), "--workers", "1"],
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert p.returncode == 0, p.stderr
    assert "skipped 3 files that are not an image (cell.yaml, notes.md, truth.csv)" in p.stderr
    assert "0 images" in p.stderr


def test_results_file_inside_the_folder_is_not_a_job_item(odd_folder, cell):
    items = plan_batch(odd_folder, cell, exclude=[odd_folder / "notes.txt"])
    assert "notes.txt" not in {it.image for it in items}


def test_resume_refuses_another_cell_file_naming_it(tmp_path):
    root = tmp_path / "in"
    root.mkdir()
    for k in range(2):
        (root / f"black{k}.png").write_bytes(cv2.imencode(".png", np.zeros((60, 80), np.uint8))[1].tobytes())
    out = tmp_path / "r.jsonl"
    p = subprocess.run(
        [*DOORLOC, "batch", str(root), "--cell", str(CELL_PATH), "--out", str(out), "--workers", "1"],
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert p.returncode == 1, p.stderr
    first = json.loads(out.read_text().splitlines()[0])
    assert set(first["provenance"]) >= {"version", "cell_sha256", "calibration_sha256", "recipe_version"}
    lines = out.read_text().splitlines()
    out.write_text(lines[0] + "\n")  # as if interrupted after one image
    other = tmp_path / "cell.yaml"
    other.write_text(Path(CELL_PATH).read_text().replace("face_y_mm: 0.0", "face_y_mm: 0.5"))
    assert other.read_text() != Path(CELL_PATH).read_text()
    p = subprocess.run(
        [*DOORLOC, "batch", str(root), "--cell", str(other), "--out", str(out), "--resume", "--workers", "1"],
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert p.returncode == 2
    assert "cannot resume: the cell file changed" in p.stderr and "cell_sha256" in p.stderr
    assert out.read_text() == lines[0] + "\n"  # nothing added
    # the same cell resumes
    p = subprocess.run(
        [
            *DOORLOC,
            "batch",
            str(root),
            "--cell",
            str(CELL_PATH),
            "--out",
            str(out),
            "--resume",
            "--workers",
            "1",
        ],
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert p.returncode == 1 and len(out.read_text().splitlines()) == 2


def _descendants(pid: int) -> set[int]:
    out, todo = set(), [pid]
    while todo:
        p = todo.pop()
        for task in Path(f"/proc/{p}/task").glob("*"):
            try:
                kids = [int(x) for x in (task / "children").read_text().split()]
            except OSError:
                continue
            out.update(kids)
            todo += kids
    return out


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_workers_die_with_the_batch_process(tmp_path, cell):
    """Issue defect: after kill -9 of `doorloc batch`, its worker processes survived for minutes."""
    from doorloc.pose import DoorPose
    from doorloc.sim.door import render_door

    root = tmp_path / "in"
    root.mkdir()
    img = render_door(cell, cell.default_door, DoorPose(0, 0, 0), seed=1).image
    png = cv2.imencode(".png", img)[1].tobytes()
    for k in range(12):
        (root / f"d{k:02d}.png").write_bytes(png)
    out = tmp_path / "r.jsonl"
    proc = subprocess.Popen(
        [*DOORLOC, "batch", str(root), "--cell", str(CELL_PATH), "--out", str(out), "--workers", "2"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    workers: set[int] = set()
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None and len(workers) < 2:
        workers = _descendants(proc.pid)
        time.sleep(0.1)
    assert proc.poll() is None and len(workers) >= 2, "the workers should be running"
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline and any(_alive(p) for p in workers):
        time.sleep(0.1)
    survivors = [p for p in workers if _alive(p)]
    for p in survivors:  # do not leave them behind even when the test fails
        os.kill(p, signal.SIGKILL)
    assert survivors == []


def test_a_bad_manifest_door_is_a_record_not_a_crash(tmp_path, cell):
    item = BatchItem(
        "x.png", str(tmp_path / "x.png"), DoorChoice(cell.default_door, "NOPE"), "no door recipe"
    )
    r = locate_item(item, cell, stand_in_locate)
    assert r["status"] == "failed" and r["error_code"] == "bad_job_row" and r["provenance"]["version"]
