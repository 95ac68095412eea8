"""`doorloc batch` on rendered doors through the real pipeline: records, failures as records, resume, kill -9."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from doorloc.app.batch import BatchSetupError, ResultsLog, find_images, plan_batch, summarize
from doorloc.pose import DoorPose
from doorloc.sim.door import render_door

DOORLOC = [sys.executable, "-m", "doorloc"]
CELL_FILE = str(Path(__file__).resolve().parents[2] / "fixtures" / "cell_thesis.yaml")
POSES = [
    DoorPose(0.0, 0.0, 0.0),
    DoorPose(3.0, -4.0, 0.8),
    DoorPose(-6.0, 5.0, -1.5),
    DoorPose(8.0, 2.0, 1.2),
]


@pytest.fixture(scope="module")
def door_folder(tmp_path_factory, cell):
    """4 rendered doors (one in a sub-folder, one with a misleading name), a truncated PNG, a black image,
    a text file named .png and a README: 6 images by content."""
    root = tmp_path_factory.mktemp("doors")
    (root / "line2").mkdir()
    truth = {}
    names = ["a.png", "line2/b.png", "c.tif", "d_image.dat"]
    for i, (name, pose) in enumerate(zip(names, POSES, strict=True)):
        rd = render_door(cell, cell.default_door, pose, seed=i)
        ok, buf = cv2.imencode(".tif" if name.endswith(".tif") else ".png", rd.image)
        (root / name).write_bytes(buf.tobytes())
        truth[name] = pose
    good = (root / "a.png").read_bytes()
    (root / "broken.png").write_bytes(good[: len(good) // 3])
    (root / "black.png").write_bytes(cv2.imencode(".png", np.zeros((1080, 1920), np.uint8))[1].tobytes())
    (root / "notes.png").write_text("not an image\n")
    (root / "README.txt").write_text("doors from line 2\n")
    return root, truth


def _records(path: Path) -> dict[str, dict]:
    lines = path.read_bytes().split(b"\n")
    assert lines[-1] == b""  # ends with a complete line
    recs = [json.loads(x) for x in lines[:-1]]
    by_image = {r["image"]: r for r in recs}
    assert len(by_image) == len(recs), "duplicate records"
    return by_image


def _comparable(r: dict) -> dict:
    """A record without its timings (elapsed_ms, per-stage timing_ms), which differ run to run."""
    r = dict(r)
    r.pop("elapsed_ms", None)
    r["diagnostics"] = {k: v for k, v in (r.get("diagnostics") or {}).items() if k != "timing_ms"}
    return r


def _batch(*args: str, timeout: float = 240) -> subprocess.CompletedProcess:
    return subprocess.run([*DOORLOC, "batch", *args], capture_output=True, text=True, timeout=timeout)


def test_find_images_goes_by_content_not_by_name(door_folder):
    root, _ = door_folder
    found = sorted(p.relative_to(root).as_posix() for p in find_images(root))
    assert found == ["a.png", "black.png", "broken.png", "c.tif", "d_image.dat", "line2/b.png"]


def test_batch_end_to_end(door_folder, tmp_path, cell):
    root, truth = door_folder
    out = tmp_path / "results.jsonl"
    p = _batch(str(root), "--cell", CELL_FILE, "--out", str(out), "--workers", "2")
    assert p.returncode == 1, p.stderr  # some images refused/failed
    recs = _records(out)
    # every image gets a record, by content or by name (notes.png claims to be one and is not); a file that
    # neither is nor claims to be an image is skipped, and counted where the person sees the summary
    assert set(recs) == {
        "a.png",
        "black.png",
        "broken.png",
        "c.tif",
        "d_image.dat",
        "line2/b.png",
        "notes.png",
    }
    assert "skipped 1 file that is not an image (README.txt)" in p.stderr
    for name, pose in truth.items():
        r = recs[name]
        assert r["ok"] is True and r["status"] == "answered", r
        assert r["x_mm"] == pytest.approx(pose.x_mm, abs=0.05)
        assert r["z_mm"] == pytest.approx(pose.z_mm, abs=0.05)
        assert r["yaw_deg"] == pytest.approx(pose.yaw_deg, abs=0.02)
    assert recs["black.png"]["status"] == "refused" and recs["black.png"]["error"]
    assert recs["broken.png"]["status"] == "failed" and recs["broken.png"]["error_code"] == "unreadable_image"
    assert recs["notes.png"]["status"] == "failed" and recs["notes.png"]["error_code"] == "not_an_image"
    assert "7 images: 4 answered, 1 refused" in p.stderr and "2 failed" in p.stderr


def test_existing_results_are_never_overwritten(door_folder, tmp_path):
    root, _ = door_folder
    out = tmp_path / "results.jsonl"
    out.write_text('{"image": "x"}\n')
    p = _batch(str(root), "--cell", CELL_FILE, "--out", str(out))
    assert p.returncode == 2
    assert "--resume" in p.stderr and "Traceback" not in p.stderr
    assert out.read_text() == '{"image": "x"}\n'


def test_resume_drops_a_torn_line_and_runs_only_what_is_missing(door_folder, tmp_path):
    root, _ = door_folder
    full = tmp_path / "full.jsonl"
    assert _batch(str(root), "--cell", CELL_FILE, "--out", str(full), "--workers", "1").returncode == 1
    reference = _records(full)
    lines = full.read_bytes().split(b"\n")[:-1]
    cut = tmp_path / "cut.jsonl"
    # as if killed while writing the 4th record: 3 complete lines and half of the 4th
    cut.write_bytes(b"\n".join(lines[:3]) + b"\n" + lines[3][: len(lines[3]) // 2])
    p = _batch(str(root), "--cell", CELL_FILE, "--out", str(cut), "--resume", "--workers", "1")
    assert p.returncode == 1, p.stderr
    assert "3 were already done" in p.stderr
    resumed = _records(cut)
    assert {k: _comparable(v) for k, v in resumed.items()} == {
        k: _comparable(v) for k, v in reference.items()
    }


def test_kill_9_then_resume_gives_the_same_records(door_folder, tmp_path):
    root, _ = door_folder
    reference_out = tmp_path / "reference.jsonl"
    assert (
        _batch(str(root), "--cell", CELL_FILE, "--out", str(reference_out), "--workers", "2").returncode == 1
    )
    out = tmp_path / "killed.jsonl"
    proc = subprocess.Popen(
        [*DOORLOC, "batch", str(root), "--cell", CELL_FILE, "--out", str(out), "--workers", "1"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if out.exists() and out.read_bytes().count(b"\n") >= 2:
            break
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)
    n_before = out.read_bytes().count(b"\n")
    assert 2 <= n_before < 8, "the kill should land mid-run"
    p = _batch(str(root), "--cell", CELL_FILE, "--out", str(out), "--resume", "--workers", "2")
    assert p.returncode == 1, p.stderr
    got, ref = _records(out), _records(reference_out)
    assert {k: _comparable(v) for k, v in got.items()} == {k: _comparable(v) for k, v in ref.items()}


def test_manifest_with_door_ids_and_sizes(door_folder, tmp_path, cell, recipe):
    from doorloc.recipes.store import RecipeStore

    root, truth = door_folder
    db = f"sqlite:///{tmp_path / 'recipes.db'}"
    with RecipeStore(db) as store:
        store.put(recipe)
    manifest = tmp_path / "manifest.csv"
    manifest.write_text(
        "image,door_id,width_mm,thickness_mm\na.png,D-100,,\nline2/b.png,,900,50\nc.tif,NOPE,,\n"
    )
    out = tmp_path / "m.jsonl"
    p = _batch(
        str(root),
        "--cell",
        CELL_FILE,
        "--out",
        str(out),
        "--manifest",
        str(manifest),
        "--database-url",
        db,
        "--workers",
        "1",
    )
    assert p.returncode == 1, p.stderr
    recs = _records(out)
    assert set(recs) == {"a.png", "line2/b.png", "c.tif"}
    assert recs["a.png"]["door_id"] == "D-100" and len(recs["a.png"]["targets"]) > 0
    assert recs["line2/b.png"]["targets"] == [] and recs["line2/b.png"]["ok"] is True
    assert recs["c.tif"]["status"] == "failed" and "NOPE" in recs["c.tif"]["error"]


def test_bad_manifest_is_a_sentence(door_folder, tmp_path, cell):
    root, _ = door_folder
    m = tmp_path / "m.csv"
    m.write_text("image,width_mm\na.png,wide\n")
    with pytest.raises(BatchSetupError, match="line 2: width_mm 'wide' is not a number"):
        plan_batch(root, cell, m)
    m.write_text("file\na.png\n")
    with pytest.raises(BatchSetupError, match="'image'"):
        plan_batch(root, cell, m)


def test_results_log_refuses_a_foreign_file(tmp_path):
    f = tmp_path / "r.jsonl"
    f.write_text("hello\nworld\n")
    with pytest.raises(BatchSetupError, match="line 1 is not a doorloc result record"):
        ResultsLog(f, resume=True)


def test_summary_counts_refusals_by_reason():
    recs = [
        {"ok": True, "status": "answered"},
        {"ok": False, "status": "refused", "error_code": "no_door"},
        {"ok": False, "status": "refused", "error_code": "no_door"},
        {"ok": False, "status": "failed"},
    ]
    s = summarize(recs)
    assert (s.answered, s.refused, s.failed) == (1, {"no_door": 2}, 1)
    assert s.text() == "4 images: 1 answered, 2 refused (no_door: 2), 1 failed"


def test_ray_backend_gives_the_same_records(door_folder, tmp_path, cell):
    pytest.importorskip("ray", reason="the ray backend needs 'doorloc[ray]'")
    from doorloc.app.batch import locate_item, run_ray

    root, _ = door_folder
    items = [it for it in plan_batch(root, cell) if it.image in ("a.png", "c.tif", "broken.png")]
    local = {it.image: locate_item(it, cell) for it in items}
    on_ray = {r["image"]: r for r in run_ray(items, cell, workers=2)}
    assert {k: _comparable(v) for k, v in on_ray.items()} == {k: _comparable(v) for k, v in local.items()}
