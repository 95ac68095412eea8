"""`doorloc batch --device cpu --batch-size N`: the batched torch path writes the records of the one-frame path."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import pytest

pytest.importorskip("torch", reason="--device needs the optional torch extra")

REPO = Path(__file__).resolve().parents[2]
FIX = REPO / "fixtures" / "rendered" / "grid"
DOORLOC = [sys.executable, "-m", "doorloc"]


def _records(path: Path) -> dict[str, dict]:
    recs = [json.loads(x) for x in path.read_text().splitlines()]
    return {r["image"]: r for r in recs}


def _comparable(r: dict) -> dict:
    r = dict(r)
    r.pop("elapsed_ms", None)
    r["diagnostics"] = {
        k: v for k, v in (r.get("diagnostics") or {}).items() if k not in ("timing_ms", "batched_fallback")
    }
    return r


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    root = tmp_path_factory.mktemp("frames")
    for i in (13, 40, 41, 60, 61):  # 3 of them 50 mm doors (the cell's default door), 2 refused
        shutil.copy(FIX / f"img_{i:04d}.png", root / f"f{i}.png")
    img = cv2.imread(str(FIX / "img_0040.png"), cv2.IMREAD_UNCHANGED)
    cv2.imwrite(str(root / "deep.png"), img.astype("uint16") * 257)  # 16-bit: the batch falls back
    (root / "broken.png").write_bytes((FIX / "img_0041.png").read_bytes()[:5000])
    return root


def _batch(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*DOORLOC, "batch", *args], capture_output=True, text=True, timeout=300)


def test_batched_device_cpu_writes_the_one_frame_records(folder, tmp_path):
    cell = str(FIX / "cell.yaml")
    one, many = tmp_path / "one.jsonl", tmp_path / "many.jsonl"
    p1 = _batch(str(folder), "--cell", cell, "--out", str(one), "--workers", "1")
    p2 = _batch(
        str(folder),
        "--cell",
        cell,
        "--out",
        str(many),
        "--workers",
        "2",
        "--device",
        "cpu",
        "--batch-size",
        "3",
    )
    assert p1.returncode == p2.returncode, (p1.stderr, p2.stderr)
    a, b = _records(one), _records(many)
    assert set(a) == set(b) and len(a) == 7
    assert {k: _comparable(v) for k, v in a.items()} == {k: _comparable(v) for k, v in b.items()}
    assert "uint16" in b["deep.png"]["diagnostics"]["batched_fallback"]
    assert b["broken.png"]["status"] == "failed"
    assert sum(r["status"] == "answered" for r in b.values()) >= 3
    assert all("batched_fallback" not in r["diagnostics"] for k, r in b.items() if k.startswith("f"))


def test_unknown_device_is_refused_clearly(folder, tmp_path):
    p = _batch(
        str(folder), "--cell", str(FIX / "cell.yaml"), "--out", str(tmp_path / "x.jsonl"), "--device", "tpu"
    )
    assert p.returncode == 2 and "unknown device" in p.stderr and "Traceback" not in p.stderr
    assert not (tmp_path / "x.jsonl").exists() or (tmp_path / "x.jsonl").read_text() == ""


def test_a_chunk_located_together_gives_the_records_of_its_frames_alone(folder):
    # on CPU locate_chunk locates frame by frame; the whole-chunk call is the CUDA path's, held here on CPU
    import torch

    from doorloc.app.batch import FileLimits, _locate_together, locate_chunk, plan_batch
    from doorloc.cell import load_cell

    cell = load_cell(FIX / "cell.yaml")
    items = plan_batch(folder, cell)
    together = _locate_together(items, cell, torch.device("cpu"), FileLimits())
    alone = locate_chunk(items, cell, "cpu", FileLimits())
    by_image = {r["image"]: _comparable(r) for r in alone}
    assert len(together) == len(alone) == len(items) == 7
    assert {r["image"]: _comparable(r) for r in together} == by_image
    assert sum(r["status"] == "answered" for r in alone) >= 3 and by_image["broken.png"]["status"] == "failed"
