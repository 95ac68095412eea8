#!/usr/bin/env python
"""Frames/s of ``doorloc batch`` over a folder of 1080p frames ("many frames"), decode included.

The folder: the 81 grid fixtures (1080p grey, each with its door from truth.csv, written into a manifest),
repeated to ``--frames`` files, once as PNG and once as JPEG (quality 95). For each format, each worker
count and each path the job runs through the library calls ``doorloc batch`` makes
(:func:`doorloc.app.batch.run_local` for the one-frame path, :func:`doorloc.app.batch.run_batched` with
``--device cpu|cuda``), and the bench reports

- ``fps``: frames/s in steady state (from the end of the first ``2 * workers`` batches, at most half the
  frames, to the end of the last batch before the final ``workers`` ones, at most half the rest: the workers'
  start-up and the drain at the end, where workers run out of work, are out), and ``fps_job``: the whole
  job, start-up included;
- parity: every record of the batched paths against the one-frame record of the same file: the same
  status and refusal, pose within 0.001 mm / 0.0001 deg (the batched path's parity figure).

CUDA runs only where torch sees a GPU. The machine (CPU count, GPU name) is printed with the numbers.

Run:  python bench/bench_throughput.py [--frames 648] [--workers 1,2] [--devices none,cpu,cuda] [--json out.json]
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import shutil  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
GRID = REPO / "fixtures" / "rendered" / "grid"


def write_folder(root: Path, n_frames: int, ext: str) -> Path:
    """``n_frames`` grid frames as ``ext`` files under ``root`` plus ``manifest.csv``; returns the manifest."""
    import cv2

    with open(GRID / "truth.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    params = [cv2.IMWRITE_JPEG_QUALITY, 95] if ext == ".jpg" else []
    encoded = {}
    for r in rows:
        img = cv2.imread(str(GRID / r["image"]), cv2.IMREAD_UNCHANGED)
        encoded[r["image"]] = cv2.imencode(ext, img, params)[1].tobytes()
    root.mkdir(parents=True, exist_ok=True)
    manifest = root / "manifest.csv"
    with open(manifest, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["image", "width_mm", "thickness_mm", "height_mm"])
        for i in range(n_frames):
            r = rows[i % len(rows)]
            name = f"f{i:05d}{ext}"
            (root / name).write_bytes(encoded[r["image"]])
            w.writerow([name, r["width_mm"], r["thickness_mm"], r["height_mm"]])
    return manifest


def run(folder: Path, manifest: Path, workers: int, device: str | None, batch_size: int) -> dict:
    """One job over the folder; frames/s and the records by image name."""
    from doorloc.app import batch
    from doorloc.cell import load_cell

    cell = load_cell(GRID / "cell.yaml")
    items = batch.plan_batch(folder, cell, manifest, None, exclude=[manifest])
    if device is None:
        records = batch.run_local(items, cell, workers=workers)
    else:
        records = batch.run_batched(items, cell, device=device, batch_size=batch_size, workers=workers)
    t0 = time.perf_counter()
    stamps, out = [], {}
    for rec in records:
        stamps.append(time.perf_counter())
        out[rec["image"]] = rec
    # records of one batch arrive together: count from the end of a whole batch to the end of another
    per = batch_size if device else 1
    skip = min(len(stamps) // 2, 2 * max(1, workers) * per) // per * per
    # the drain (the last batch of each worker, while the others have run out of work) is left out too:
    # with a few batches per worker it would count idle workers against the path with the larger batches
    end = len(stamps) - min((len(stamps) - skip) // 2, max(1, workers) * per) // per * per
    steady = (end - skip) / (stamps[end - 1] - stamps[skip - 1]) if 0 < skip < end else float("nan")
    return {"fps": steady, "fps_job": len(stamps) / (stamps[-1] - t0), "n": len(stamps), "records": out}


def parity(ref: dict, got: dict) -> dict:
    """Records of another path against the one-frame path's."""
    status, pose = [], 0.0
    for name, a in ref.items():
        b = got[name]
        if (a["status"], a.get("error_code")) != (b["status"], b.get("error_code")):
            status.append(name)
            continue
        if a["ok"]:
            pose = max(
                pose,
                abs(a["x_mm"] - b["x_mm"]),
                abs(a["z_mm"] - b["z_mm"]),
                abs(a["yaw_deg"] - b["yaw_deg"]) * 10,  # 0.0001 deg counts as 0.001
            )
    fallbacks = sum("batched_fallback" in (r.get("diagnostics") or {}) for r in got.values())
    return {"status_mismatch": status, "max_pose_diff": pose, "fallbacks": fallbacks}


def machine() -> dict:
    out = {"cpus": os.cpu_count(), "platform": platform.platform(), "processor": platform.processor()}
    try:
        import torch

        out["torch"] = torch.__version__
        if torch.cuda.is_available():
            out["gpu"] = torch.cuda.get_device_name(0)
    except ImportError:
        out["torch"] = None
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=648)
    ap.add_argument("--workers", default="1,2", help="comma-separated worker counts ('all' = os.cpu_count())")
    ap.add_argument(
        "--devices", default="none,cpu,cuda", help="none = the one-frame path; cpu, cuda: batched"
    )
    ap.add_argument("--formats", default=".png,.jpg")
    ap.add_argument("--batch-size", type=int, default=32)
    ap.add_argument("--json")
    a = ap.parse_args()
    workers = [os.cpu_count() or 1 if w == "all" else int(w) for w in a.workers.split(",")]
    devices = [None if d == "none" else d for d in a.devices.split(",")]
    if "cuda" in devices:
        try:
            import torch

            if not torch.cuda.is_available():
                print("cuda: torch sees no GPU here; not measured")
                devices.remove("cuda")
        except ImportError:
            devices = [d for d in devices if d is None]
    res = {"machine": machine(), "frames": a.frames, "batch_size": a.batch_size, "runs": []}
    print(json.dumps(res["machine"]))
    tmp = Path(tempfile.mkdtemp(prefix="doorloc-throughput-"))
    try:
        for ext in a.formats.split(","):
            folder = tmp / ext.strip(".")
            manifest = write_folder(folder, a.frames, ext)
            for w in workers:
                ref = None
                for dev in devices:
                    r = run(folder, manifest, w, dev, a.batch_size)
                    row = {"format": ext, "workers": w, "path": dev or "one-frame", "fps": r["fps"]}
                    row["fps_job"] = r["fps_job"]
                    if dev is None:
                        ref = r["records"]
                    elif ref is not None:
                        row["parity"] = parity(ref, r["records"])
                    res["runs"].append(row)
                    print(
                        f"{ext:5s} workers {w:3d} {row['path']:10s} {row['fps']:8.1f} frames/s "
                        f"(job {row['fps_job']:.1f})"
                        + (f"  parity {row['parity']}" if "parity" in row else ""),
                        flush=True,
                    )
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
