"""A job's doors located as `doorloc batch` locates them: the camera's response the cell only states, measured
first from the job's own rounded doors (:func:`doorloc.app.batch.batch_response`), against the cell as stated.

Each job is one cell and one camera: an exponent drawn from 1.0-2.4 and stated in the cell without a
measurement (``locate.response_unmeasured_factor`` 2.2, the default), and ``--doors`` doors drawn in turn
from the arris bench's sets (``--sets``; by default ``round``, ``chamfer``, ``ambient`` and ``small``: every
door under its own light, as `bench/bench_arris_range.py` draws them, its arris told in its recipe). The
images are written as PNG files, planned as a folder job, the response measured from up to eight of the
rounded doors, and every door located twice: with the cell as stated (``--stated-response``) and with the
measured one (the default). Per job: the measurement, and for each way the answered share, RMS of x, z and
yaw, and the shares within 2 claimed sigma and beyond 5 (the arris bench's summary); over all jobs, the
same. ``--gamma-per-door`` draws every door's camera exponent apart (one job of several cameras, which the
cell's one ``response_gamma`` does not describe): what the measurement does where its premise is broken.

    OMP_NUM_THREADS=1 PYTHONPATH=src python bench/bench_batch_response.py [--jobs 2] [--doors 16]
        [--seed 8800] [--sets round,chamfer,ambient,small] [--gamma-per-door]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from bench_arris_range import Outcome, draw, summary  # noqa: E402

from doorloc.app.answer import DoorChoice  # noqa: E402
from doorloc.app.batch import BatchItem, batch_response  # noqa: E402
from doorloc.cell import load_cell  # noqa: E402
from doorloc.sim.door import render_door  # noqa: E402
from doorloc.vision.locate import locate  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _located(image, cell, door, pose) -> Outcome:
    """The bench's row of one door located in ``cell``, against its true pose (and the locate's thread CPU)."""
    t0 = time.thread_time()
    res = locate(image, cell, door)
    took = time.thread_time() - t0
    if not res.ok:
        return Outcome(res.error_code, locate_s=took)
    u = res.uncertainty
    return Outcome(
        None,
        (res.x_mm - pose.x_mm, res.z_mm - pose.z_mm, res.yaw_deg - pose.yaw_deg, math.nan),
        (u.x_mm, u.z_mm, u.yaw_deg, math.nan),
        locate_s=took,
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--doors", type=int, default=16, help="doors a job")
    ap.add_argument("--seed", type=int, default=8800)
    ap.add_argument("--sets", default="round,chamfer,ambient,small", help="arris bench sets, in turn")
    ap.add_argument(
        "--gamma-per-door",
        action="store_true",
        help="every door's camera exponent drawn apart (several cameras in one job; the cell states the first's)",
    )
    args = ap.parse_args()
    base = load_cell(ROOT / "fixtures" / "cell_thesis.yaml")
    sets = args.sets.split(",")
    totals: dict[str, list[Outcome]] = {"stated": [], "measured from the job's doors": []}
    for job in range(args.jobs):
        rng = np.random.default_rng([args.seed, job])
        gamma = float(rng.uniform(1.0, 2.4))
        cell = dataclasses.replace(base, response_gamma=gamma)
        with tempfile.TemporaryDirectory() as tmp:
            items, truth = [], []
            for i in range(args.doors):
                seed = args.seed * 100 + 1000 * job + i
                door, pose, fx, own_gamma = draw(sets[i % len(sets)], i, seed)
                fx = dataclasses.replace(fx, gamma=own_gamma if args.gamma_per_door else gamma)
                image = render_door(cell, door, pose, effects=fx, seed=seed).image
                path = Path(tmp) / f"door_{i:03d}.png"
                cv2.imwrite(str(path), image)
                items.append(BatchItem(path.name, str(path), DoorChoice(door)))
                truth.append((image, door, pose))
            t0 = time.thread_time()
            said = batch_response(items, cell)
            took = time.thread_time() - t0
        m = said.measurement
        print(
            f"job {job}: camera {gamma:.3f}{' (the first door; each its own)' if args.gamma_per_door else ''}; "
            + (
                f"measured {m.gamma:.3f}, factor {m.factor:.3f}: the camera's "
                f"{'inside' if m.gamma / m.factor <= gamma <= m.gamma * m.factor else 'OUTSIDE'}"
                f"{' (each door its own light)' if m.own_lights else ''}"
                + (
                    f"; a shoulder from {m.shoulder.knee:g} scored {m.shoulder.shouldered:.3f} against "
                    f"{m.shoulder.plain:.3f}, doubted from {m.shoulder.doubted_from:.2f}"
                    if m.shoulder is not None
                    else ""
                )
                if m is not None
                else f"not measured: {said.sentence}"
            )
            + f" ({took:.0f} s thread CPU)"
        )
        for label, way_cell in (("stated", cell), ("measured from the job's doors", said.cell)):
            rows = [_located(image, way_cell, door, pose) for image, door, pose in truth]
            totals[label] += rows
            summary(f"  {label}", rows)
    if args.jobs > 1:
        for label, rows in totals.items():
            summary(f"all {args.jobs} jobs, {label}", rows)


if __name__ == "__main__":
    main()
