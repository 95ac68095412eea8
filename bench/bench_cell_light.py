"""The cell's light measured from its doors, and what locate gains with it on doors held out.

Each cell draws one light (azimuth +-10..80 deg either side, elevation -30..60 deg, as the arris bench's
lights), one camera exponent (1.0-2.4, stated in the cell as measured, ``response_unmeasured_factor``
1.11) and renders doors with rounded arrises of 0.5-3 mm as the arris bench's ``round`` set draws them
(blur, albedos, noise, poses), every door under the cell's light. The light is measured from the first
``--measure`` doors (:func:`doorloc.vision.cell_light.measure_cell_light`); the next ``--test`` doors are
located four ways: no light stated (the free shading, ``locate.light_from_door`` off), each door's own
light (``light_from_door``, the default), the measured light with its measured doubt, and the renderer's
own light (the default doubt). Per cell: the measured direction, its angle from the true
one, its doubt and any other direction the doors could not rule out; per way: the answered share and the
refusals, and RMS of x, z and yaw with the shares within 2 claimed sigma and beyond 5 (the arris bench's
summary). The time the measurement took (thread CPU, the first cell's includes compiling).

    OMP_NUM_THREADS=1 PYTHONPATH=src python bench/bench_cell_light.py [--cells 3] [--first-cell 0]
        [--measure 8] [--test 16] [--seed 8500] [--ambient]

``--ambient``: the same doors under ambient light alone; the measurement is to refuse (no direction).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from bench_arris_range import Outcome, draw, summary  # noqa: E402

from doorloc.cell import load_cell  # noqa: E402
from doorloc.pose import directions_apart_deg  # noqa: E402
from doorloc.sim.door import render_door  # noqa: E402
from doorloc.vision.cell_light import LightNotMeasurable, measure_cell_light  # noqa: E402
from doorloc.vision.locate import locate  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=3)
    ap.add_argument("--first-cell", type=int, default=0)
    ap.add_argument("--measure", type=int, default=8, help="doors the light is measured from")
    ap.add_argument("--test", type=int, default=16, help="doors located after, held out")
    ap.add_argument("--seed", type=int, default=8500)
    ap.add_argument(
        "--ambient",
        action="store_true",
        help="the cell's doors under ambient light alone (the lamp's share added to it): no direction to measure",
    )
    args = ap.parse_args()
    base = load_cell(ROOT / "fixtures" / "cell_thesis.yaml")
    for c in range(args.first_cell, args.first_cell + args.cells):
        rng = np.random.default_rng([args.seed, c])
        light = (float(rng.choice([-1, 1]) * rng.uniform(10, 80)), float(rng.uniform(-30, 60)))
        gamma = float(rng.uniform(1.0, 2.4))
        cell = dataclasses.replace(
            base,
            response_gamma=gamma,
            locate=dataclasses.replace(base.locate, response_unmeasured_factor=1.11),
        )
        frames = []
        for i in range(args.measure + args.test):
            seed = args.seed * 100 + 1000 * c + i
            door, pose, fx, _ = draw("round", i, seed)
            fx = dataclasses.replace(
                fx, light_azimuth_deg=light[0], light_elevation_deg=light[1], gamma=gamma
            )
            if args.ambient:
                fx = dataclasses.replace(
                    fx, light_ambient=fx.light_ambient + fx.light_directional, light_directional=0.0
                )
            frames.append((render_door(cell, door, pose, effects=fx, seed=seed).image, door, pose))
        t0 = time.thread_time()
        try:
            m = measure_cell_light([(im, d) for im, d, _ in frames[: args.measure]], cell)
        except LightNotMeasurable as e:
            print(f"cell {c}: {'ambient light' if args.ambient else 'the lamp'}; not measured: {e}")
            continue
        took = time.thread_time() - t0
        off = directions_apart_deg(m.direction_deg, light)
        print(
            f"cell {c}: light [{light[0]:+.1f}, {light[1]:+.1f}], gamma {gamma:.2f}; measured "
            f"[{m.direction_deg[0]:+.1f}, {m.direction_deg[1]:+.1f}] +- {m.sigma_deg:g} deg ({off:.1f} deg off; "
            f"{m.strips} strips of {m.doors} doors, score {m.score:.3f}; {took:.1f} s thread CPU)"
            + (
                f"; also [{m.runner_up_deg[0]:+.0f}, {m.runner_up_deg[1]:+.0f}] at {m.runner_up_score:.3f}"
                if m.runner_up_deg
                else ""
            )
        )
        ways = {
            "no light": dataclasses.replace(cell.locate, light_direction_deg=None, light_from_door=False),
            "each door's own": dataclasses.replace(
                cell.locate, light_direction_deg=None, light_from_door=True
            ),
            "measured": dataclasses.replace(
                cell.locate, light_direction_deg=m.direction_deg, light_direction_sigma_deg=m.sigma_deg
            ),
            "true": dataclasses.replace(cell.locate, light_direction_deg=light),
        }
        for label, cfg in ways.items():
            rows = []
            for im, door, pose in frames[args.measure :]:
                r = locate(im, cell, door, config=cfg)
                rows.append(
                    Outcome(
                        None,
                        (r.x_mm - pose.x_mm, r.z_mm - pose.z_mm, r.yaw_deg - pose.yaw_deg, math.nan),
                        (r.uncertainty.x_mm, r.uncertainty.z_mm, r.uncertainty.yaw_deg, math.nan),
                    )
                    if r.ok
                    else Outcome(r.error_code)
                )
            summary(f"  {label}", rows)
        sys.stdout.flush()


if __name__ == "__main__":
    main()
