"""Render time of one 1920x1080 door image on one core (goal: median <= 1 s).

Thread pools are pinned to one thread before numpy/OpenCV load. Prints the median and quartiles over
the +-10 mm / +-2 deg pose grid, plain and with every cheap effect on (grain, light, vignetting, blur,
noise, gamma), with and without distortion, and with a chamfered arris.

    /work/venv/bin/python bench/bench_render.py [--repeat 3]
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_v] = "1"

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from doorloc.calib.camera import CameraModel  # noqa: E402
from doorloc.cell import DoorSize, load_cell  # noqa: E402
from doorloc.pose import DoorPose  # noqa: E402
from doorloc.sim.door import render_door  # noqa: E402
from doorloc.sim.effects import Effects  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=1, help="renders per pose")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    cell = load_cell(ROOT / "fixtures" / "cell_thesis.yaml")
    cam = cell.camera
    distorted = dataclasses.replace(
        cell, camera=CameraModel(cam.camera_matrix, [-0.08, 0.05, 0.0, 0.0, 0.0], cam.image_size)
    )
    effects_on = Effects(
        grain_contrast=0.08,
        light_directional=0.5,
        vignetting=0.2,
        gradient_u=0.1,
        blur_sigma_px=0.8,
        full_well_e=20000,
        read_noise_dn=1.0,
        gamma=2.2,
    )
    poses = [DoorPose(x, z, y) for x in (-10, 0, 10) for z in (-10, 0, 10) for y in (-2, 0, 2)]
    cases = {
        "plain": (cell, DoorSize(900, 50, 2100), Effects()),
        "all effects": (cell, DoorSize(900, 50, 2100), effects_on),
        "distortion + effects": (distorted, DoorSize(900, 50, 2100), effects_on),
        "arris 3 mm + effects": (cell, DoorSize(900, 40, 2100, arris_mm=3.0), effects_on),
    }
    render_door(cell, DoorSize(), DoorPose())  # warm-up (imports, caches)
    print(f"1920x1080 door render, one thread, {len(poses)} poses x {args.repeat}")
    all_times = []
    for name, (c, door, fx) in cases.items():
        times = []
        for i, pose in enumerate(poses):
            for r in range(args.repeat):
                t0 = time.perf_counter()
                render_door(c, door, pose, effects=fx, seed=i * 10 + r)
                times.append(time.perf_counter() - t0)
        q1, med, q3 = np.percentile(times, [25, 50, 75])
        all_times += times
        print(
            f"  {name:24s} median {med * 1000:7.1f} ms  (q1 {q1 * 1000:6.1f}, q3 {q3 * 1000:6.1f}, max {max(times) * 1000:6.1f})"
        )
    print(f"overall median {np.median(all_times) * 1000:.1f} ms (acceptance: <= 1000 ms)")


if __name__ == "__main__":
    main()
