"""Batch resilience: N rendered images, `doorloc batch` killed with SIGKILL at a random moment, then resumed.

Checks: exactly N records, no duplicate, no torn line, each identical to an uninterrupted run's record
(ignoring the timings: elapsed_ms and diagnostics.timing_ms). Then the Ray backend on the first M
images gives the same records as the local backend.

    python bench/bench_batch_resume.py --images 200 --ray-images 50 --workers 2
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CELL = REPO / "fixtures" / "cell_thesis.yaml"


def _render(args: tuple[int, str]) -> None:
    import cv2
    import numpy as np

    from doorloc.cell import load_cell
    from doorloc.pose import DoorPose
    from doorloc.sim.door import render_door
    from doorloc.sim.effects import Effects

    i, path = args
    rng = np.random.default_rng(i)
    cell = load_cell(CELL)
    pose = DoorPose(float(rng.uniform(-9, 9)), float(rng.uniform(-9, 9)), float(rng.uniform(-1.8, 1.8)))
    effects = Effects(grain_contrast=0.08, blur_sigma_px=0.6, full_well_e=20000.0, read_noise_dn=1.5)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(path, render_door(cell, cell.default_door, pose, effects=effects, seed=i).image)


def _batch(folder: Path, out: Path, workers: int, *extra: str) -> list[str]:
    return [
        sys.executable,
        "-m",
        "doorloc",
        "batch",
        str(folder),
        "--cell",
        str(CELL),
        "--out",
        str(out),
        "--workers",
        str(workers),
        *extra,
    ]


def _records(path: Path) -> dict[str, dict]:
    data = path.read_bytes()
    assert data.endswith(b"\n"), "torn last line"
    recs = [json.loads(line) for line in data.splitlines()]
    by_image = {}
    for r in recs:
        r.pop("elapsed_ms", None)
        (r.get("diagnostics") or {}).pop("timing_ms", None)
        by_image[r["image"]] = r
    return by_image, len(recs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--images", type=int, default=200)
    ap.add_argument("--ray-images", type=int, default=50)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=None, help="seed of the kill moment (default: random)")
    args = ap.parse_args()
    seed = args.seed if args.seed is not None else random.randrange(1 << 30)
    rng = random.Random(seed)

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        root = tmp / "doors"
        # first M images in one sub-folder (the Ray comparison runs on it), the rest in others
        paths = [
            str(
                root
                / (f"part1/door{i:04d}.png" if i < args.ray_images else f"part{2 + i % 3}/door{i:04d}.png")
            )
            for i in range(args.images)
        ]
        t0 = time.perf_counter()
        with ProcessPoolExecutor(args.workers) as pool:
            list(pool.map(_render, list(enumerate(paths)), chunksize=4))
        print(f"rendered {args.images} images in {time.perf_counter() - t0:.1f} s")

        ref = tmp / "reference.jsonl"
        t0 = time.perf_counter()
        subprocess.run(_batch(root, ref, args.workers), check=False, capture_output=True)
        full_s = time.perf_counter() - t0
        reference, n_ref = _records(ref)
        print(f"uninterrupted run: {n_ref} records in {full_s:.1f} s")

        out = tmp / "killed.jsonl"
        kill_after = rng.uniform(0.1, 0.9) * full_s
        proc = subprocess.Popen(
            _batch(root, out, args.workers),
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
        )
        time.sleep(kill_after)
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        raw = out.read_bytes() if out.exists() else b""
        complete, torn = raw.count(b"\n"), len(raw) - (raw.rfind(b"\n") + 1)
        print(
            f"killed with SIGKILL after {kill_after:.1f} s (seed {seed}): {complete} complete lines, "
            f"torn tail: {torn} bytes"
        )
        p = subprocess.run(_batch(root, out, args.workers, "--resume"), capture_output=True, text=True)
        print("resume:", p.stderr.strip().splitlines()[-1])
        resumed, n_res = _records(out)
        same = resumed == reference
        print(
            json.dumps(
                {
                    "images": args.images,
                    "records_after_resume": n_res,
                    "distinct_images": len(resumed),
                    "identical_to_uninterrupted": same,
                }
            )
        )

        ray_out, local_out = tmp / "ray.jsonl", tmp / "local50.jsonl"
        part1 = root / "part1"
        subprocess.run(_batch(part1, local_out, args.workers), capture_output=True)
        t0 = time.perf_counter()
        p = subprocess.run(
            _batch(part1, ray_out, args.workers, "--backend", "ray"), capture_output=True, text=True
        )
        if p.returncode not in (0, 1):
            print("ray backend failed:", p.stderr[-2000:])
            return
        ray_recs, n_ray = _records(ray_out)
        local_recs, _ = _records(local_out)
        print(
            json.dumps(
                {
                    "ray_images": args.ray_images,
                    "ray_records": n_ray,
                    "ray_seconds": round(time.perf_counter() - t0, 1),
                    "ray_identical_to_local": ray_recs == local_recs,
                }
            )
        )


if __name__ == "__main__":
    main()
